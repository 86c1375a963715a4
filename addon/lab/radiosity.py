"""Radiosity in Blender: patches from the scene, visibility rays, solution as vertex colours and light maps,
and the Cycles irradiance bake of the same scene for comparison (seed 004; core in addon.core.radiosity).

Units: B radiosity (exitance) and H irradiance in W/m²; an Emission shader's Strength is the emitted
radiance L_e (E_i = π L_e). The comparison is the light-map pipeline's irradiance bake (addon.bake) of the
result objects: the scene's own materials drive the bounces, emitters included.
"""
import os
import time

import bpy
import numpy as np

from ..core import charts, exr
from ..core import radiosity as core
from ..core.errors import InputError
from ..core.fileio import write_json
from ..progress import Progress
from . import scene as scn

COLLECTION = "IL Radiosity"
ATTRIBUTE = "IL Radiosity E"
UV = "IL Radiosity Atlas"
REPORT = "radiosity_report.json"


# ----------------------------------------------------------------------------- scene in, scene out


def build_cornell_scene(name="IL Cornell", light_radiance=15.0):
    """The built-in Cornell-box-like room (core.cornell_box) as a new Cycles scene with a black world."""
    sc = scn.new_scene(name, (128, 128))
    scn.world(sc, 0.0)
    for m in core.cornell_box(light_radiance):
        me = bpy.data.meshes.new(m["name"])
        me.from_pydata([tuple(v) for v in m["vertices"]], [], [tuple(f) for f in m["faces"]])
        me.update()
        obj = scn.link(sc, bpy.data.objects.new(m["name"], me))
        obj.data.materials.append(_material(f"IL {m['name']}", m["rho"], m["emission"]))
    scn.camera(sc, "Camera", (0.0, -0.98, 1.0), target=(0.0, 1.0, 1.0), lens=14.0)
    return sc


def _material(name, rho, emission):
    mat = scn.empty_material(name)
    nt = mat.node_tree
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    if max(emission) > 0:
        em = nt.nodes.new("ShaderNodeEmission")
        em.inputs["Color"].default_value = (*[e / max(emission) for e in emission], 1.0)
        em.inputs["Strength"].default_value = max(emission)
        nt.links.new(em.outputs[0], out.inputs["Surface"])
    else:
        d = nt.nodes.new("ShaderNodeBsdfDiffuse")
        d.inputs["Color"].default_value = (*rho, 1.0)
        d.inputs["Roughness"].default_value = 0.0
        nt.links.new(d.outputs[0], out.inputs["Surface"])
    mat.diffuse_color = (*rho, 1.0)
    return mat


def material_rho_emission(mat):
    """(ρ RGB, L_e RGB) of a material: Diffuse BSDF / Principled base colour, Emission / Principled emission.

    Only unlinked default values are read; anything textured is refused.
    """
    if mat is None or mat.node_tree is None:
        return np.full(3, 0.8), np.zeros(3)
    rho, le = np.zeros(3), np.zeros(3)
    for n in mat.node_tree.nodes:
        if n.bl_idname == "ShaderNodeBsdfDiffuse":
            rho = _value(n, "Color", mat)
        elif n.bl_idname == "ShaderNodeBsdfPrincipled":
            rho = _value(n, "Base Color", mat)
            s = n.inputs.get("Emission Strength")
            if s is not None and s.default_value > 0:
                le = _value(n, "Emission Color", mat) * s.default_value
        elif n.bl_idname == "ShaderNodeEmission":
            le = _value(n, "Color", mat) * n.inputs["Strength"].default_value
    return np.clip(rho, 0.0, 0.999), le


def _value(node, name, mat):
    sock = node.inputs[name]
    if sock.is_linked:
        raise InputError(f"material '{mat.name}': {node.name}.{name} is driven by other nodes (a texture or node "
                         f"setup); radiosity needs plain colours (Diffuse, Principled or Emission, nothing linked)")
    return np.array(sock.default_value[:3], np.float64)


def meshes_from_scene(scene, objects=None):
    """World-space mesh arrays of the visible mesh objects (or ``objects``), one material per object slot."""
    deps = scene.view_layers[0].depsgraph
    deps.update()
    objs = [o for o in (objects or scene.objects) if o.type == "MESH" and not o.hide_render
            and o.users_collection and o.users_collection[0].name != COLLECTION]
    if not objs:
        raise InputError(f"scene '{scene.name}' has no mesh objects")
    meshes, used = [], []
    for o in objs:
        ev = o.evaluated_get(deps)
        me = ev.to_mesh()
        try:
            mw = np.array(ev.matrix_world)
            v = np.empty(len(me.vertices) * 3)
            me.vertices.foreach_get("co", v)
            v = v.reshape(-1, 3) @ mw[:3, :3].T + mw[:3, 3]
            faces = [tuple(p.vertices) for p in me.polygons]
            mats = [material_rho_emission(o.material_slots[p.material_index].material
                                          if o.material_slots else None) for p in me.polygons]
        finally:
            ev.to_mesh_clear()
        if not faces:
            continue
        meshes.append({"name": o.name, "vertices": v, "faces": faces,
                       "rho": np.array([m[0] for m in mats]), "emission": np.array([m[1] for m in mats])})
        used.append(o)
    return meshes, used


def visibility_bvh(patches, offset=1e-4):
    """Centre-to-centre visibility (N, N) by Blender's BVHTree over the patches: a ray per candidate pair."""
    from mathutils import Vector
    from mathutils.bvhtree import BVHTree
    n = len(patches)
    corners = patches.corners.reshape(-1, 3)
    polys = [list(range(4 * k, 4 * k + (3 if patches.is_tri[k] else 4))) for k in range(n)]
    bvh = BVHTree.FromPolygons([tuple(c) for c in corners], polys, all_triangles=False, epsilon=0.0)
    i, j = core.candidate_pairs(patches)
    o = patches.center[i] + offset * patches.normal[i]
    t = patches.center[j] + offset * patches.normal[j]
    d = t - o
    dist = np.linalg.norm(d, axis=1)
    d = d / dist[:, None]
    lim = dist - 2 * offset
    cast = bvh.ray_cast
    vis = np.fromiter((cast(Vector(a), Vector(b), L)[0] is None for a, b, L in zip(o.tolist(), d.tolist(), lim.tolist())),
                      bool, count=len(i))
    V = np.zeros((n, n))
    V[i, j] = V[j, i] = vis
    return V


# ----------------------------------------------------------------------------- the solve


def solve_scene(meshes, max_edge=0.25, solver="jacobi", tol=1e-5, adaptive=0, threshold=0.25, progress=None):
    """Patches -> visibility -> form factors -> solution, with ``adaptive`` refinement rounds.

    Returns a dict: patches, F, solution, H (irradiance), timings.
    """
    t = {}
    t0 = time.perf_counter()
    patches = core.subdivide_to_size(core.patches_from_meshes(meshes), max_edge)
    for round_ in range(adaptive + 1):
        if progress:
            progress(f"visibility and form factors of {len(patches)} patches")
        tv = time.perf_counter()
        V = visibility_bvh(patches)
        t["visibility"] = t.get("visibility", 0) + time.perf_counter() - tv
        tf = time.perf_counter()
        F = core.form_factors(patches, V)
        t["form_factors"] = t.get("form_factors", 0) + time.perf_counter() - tf
        sol = core.solve(F, patches.rho, patches.emission, patches.area, solver, tol)
        t["solve"] = t.get("solve", 0) + sol.seconds
        H = core.irradiance(F, sol.B)
        if round_ == adaptive:
            break
        mask = core.refine_mask(patches, H, threshold, min_area=(max_edge / 16) ** 2)
        if not mask.any():
            break
        patches, _ = core.split(patches, mask)
    t["total"] = time.perf_counter() - t0
    return {"patches": patches, "F": F, "V": V, "solution": sol, "H": H, "timings": t}


def convergence(F, patches, tol=1e-6):
    """Every solver on the same system: {solver: Solution} (for the convergence chart)."""
    return {s: core.solve(F, patches.rho, patches.emission, patches.area, s, tol) for s in core.SOLVERS}


def convergence_chart(path, solutions, n):
    """Residual against work (sweeps; a progressive shot counts 1/N of a sweep), log scale."""
    series = {}
    for s, sol in solutions.items():
        res = np.maximum(np.asarray(sol.residuals), 1e-16)
        if s == "progressive":
            step = max(1, n // 10)
            x = (np.arange(1, len(res) + 1) * step) / n
            x[-1] = sol.iterations / n
        else:
            x = np.arange(1, len(res) + 1)
        series[f"{s} ({sol.seconds * 1e3:.0f} ms)"] = (x, res)
    return charts.line_chart(path, series, "Radiosity convergence per solver",
                             "work (sweeps of N patches)", "relative residual |E + ρFB − B| / |E|", logy=True)


# ----------------------------------------------------------------------------- outputs


def result_objects(scene, patches, H, meshes, cell=4, gutter=2):
    """One new object per input mesh, built from its patches, in collection "IL Radiosity": colour attribute
    "IL Radiosity E" (irradiance, smoothed per vertex) and UV layer "IL Radiosity Atlas" (one cell per patch).

    Returns {name: (object, patch indices, atlas)}.
    """
    coll = bpy.data.collections.get(COLLECTION)
    if coll is None:
        coll = bpy.data.collections.new(COLLECTION)
    if coll.name not in scene.collection.children:
        scene.collection.children.link(coll)
    corner_vals, pos, idx = core.vertex_average(patches, H)
    out = {}
    for k, name in enumerate(patches.names):
        sel = np.flatnonzero(patches.owner == k)
        if not len(sel):
            continue
        verts_global = np.unique(idx[sel])
        remap = {g: i for i, g in enumerate(verts_global)}
        faces = [[remap[g] for g in (idx[p][:3] if patches.is_tri[p] else idx[p])] for p in sel]
        me = bpy.data.meshes.new(f"{name} radiosity")
        me.from_pydata([tuple(p) for p in pos[verts_global]], [], faces)
        me.update()
        atlas = core.make_atlas(len(sel), cell, gutter)
        atlas_uvs = core.atlas_uvs(atlas, patches.is_tri[sel])
        layer = me.uv_layers.new(name=UV)
        loop_uv = np.concatenate([atlas_uvs[i, :3] if patches.is_tri[p] else atlas_uvs[i]
                                  for i, p in enumerate(sel)])
        layer.data.foreach_set("uv", loop_uv.ravel().astype(np.float32))
        col = me.color_attributes.new(ATTRIBUTE, "FLOAT_COLOR", "CORNER")
        cv = np.concatenate([corner_vals[p, :3] if patches.is_tri[p] else corner_vals[p] for p in sel])
        rgba = np.ones((len(cv), 4), np.float32)
        rgba[:, :3] = cv
        col.data.foreach_set("color", rgba.ravel())
        me.color_attributes.active_color_name = ATTRIBUTE
        obj = coll.objects.get(f"{name} radiosity")
        if obj is not None:      # the result of an earlier run; an object of the user's with that name stays
            bpy.data.objects.remove(obj)
        obj = bpy.data.objects.new(f"{name} radiosity", me)
        coll.objects.link(obj)
        src = scene.objects.get(name)
        if src is not None and src.material_slots:
            for slot in src.material_slots:
                me.materials.append(slot.material)
            me.polygons.foreach_set("material_index", [0] * len(me.polygons))
        out[name] = (obj, sel, atlas)
    return out


def write_lightmaps(out, results, patches, H):
    """``<out>/<object>_radiosity.exr``: R, G, B = irradiance H in W/m² per patch cell, A = covered."""
    files = {}
    for name, (obj, sel, atlas) in results.items():
        img = core.paint_atlas(atlas, H[sel], patches.is_tri[sel])
        path = os.path.join(out, f"{bpy.path.clean_name(name)}_radiosity.exr")
        exr.write_exr(path, {"R": img[..., 0], "G": img[..., 1], "B": img[..., 2], "A": img[..., 3]},
                      {"il:quantity": "irradiance E (radiosity solution)", "il:units": "W/m^2",
                       "il:uv_layer": UV, "il:patches": len(sel), "il:blender_version": bpy.app.version_string})
        files[name] = path
    return files


def cycles_patch_irradiance(scene, results, patches, out, samples=64, bounces=32, seed=0):
    """The light-map pipeline's Cycles irradiance bake (addon.bake, E = π × DIFFUSE bake, white only at the
    baked point so emitters and every albedo bake right) of every result object into its own patch atlas
    (``sizes``), written to ``out``; returns per-patch means (N, 3) and the seconds it took.

    The result objects carry the scene's materials, so the bounces are the real ones; the originals they
    were built from are hidden from rendering during the bake.
    """
    from ..bake import BakeOptions, bake_lightmaps
    t0 = time.perf_counter()
    originals = [scene.objects[n] for n in results if n in scene.objects]
    hidden = [o.hide_render for o in originals]
    objs = [obj for obj, _, _ in results.values()]
    options = BakeOptions(samples=int(samples), bounces=int(bounces), seed=int(seed), margin=0, uv_layer=UV,
                          sizes={obj.name: atlas.size for obj, _, atlas in results.values()},
                          overwrite=True, keep_products=False)
    try:
        for o in originals:
            o.hide_render = True
        report = bake_lightmaps(objs, ["irradiance"], out, options, scene=scene)
    finally:
        for o, hr in zip(originals, hidden):
            o.hide_render = hr
    H = np.full((len(patches), 3), np.nan)
    for obj, sel, atlas in results.values():
        ch, _ = exr.read_exr(report["objects"][obj.name]["irradiance"]["file"])      # row 0 = top
        img = np.stack([ch[c] for c in "RGB"], -1)
        H[sel] = core.atlas_means(atlas, img, patches.is_tri[sel])
    return H, time.perf_counter() - t0


def rms(a, b):
    """RMS difference over the rows where both are finite."""
    ok = np.isfinite(a).all(axis=1) & np.isfinite(b).all(axis=1)
    return float(np.sqrt(np.mean((a[ok] - b[ok]) ** 2))) if ok.any() else float("nan")


def run(out, scene=None, cornell=False, solver="jacobi", max_edge=0.25, adaptive=0, samples=64,
        compare=True, tol=1e-5, chart=True):
    """The whole job of scripts/radiosity.py; returns the report dict (also written to ``out``).

    ``chart=False`` skips the convergence chart (the UI passes ``charts.available()``: no matplotlib
    inside Blender); the report's "chart" is then None, the CSV table is written either way.
    """
    if solver not in core.SOLVERS:
        raise InputError(f"unknown solver {solver!r}; choose from {', '.join(core.SOLVERS)}")
    if max_edge <= 0:
        raise InputError(f"--max-edge must be positive, got {max_edge}")
    if samples < 1:
        raise InputError(f"--samples must be at least 1, got {samples}")
    if not 0 < tol < 1:
        raise InputError(f"--tol must be between 0 and 1, got {tol}")
    if adaptive < 0:
        raise InputError(f"--adaptive must be 0 or more, got {adaptive}")
    os.makedirs(out, exist_ok=True)
    steps = 5 if compare else 4
    with Progress("radiosity", steps) as p:
        p.step("scene")
        if cornell:
            scene = build_cornell_scene()
        scene = scene or bpy.context.scene
        meshes, _ = meshes_from_scene(scene)
        if not any(np.any(m["emission"] > 0) for m in meshes):     # before the costly visibility and solve
            raise InputError(f"nothing in scene '{scene.name}' emits light: radiosity counts only emissive surfaces "
                             "(an Emission shader or Principled emission), not lamps; give a mesh an emissive "
                             "material or build the Cornell box")
        p.step("patches, visibility, form factors, solve")
        r = solve_scene(meshes, max_edge, solver, tol, adaptive)
        patches, F, sol, H = r["patches"], r["F"], r["solution"], r["H"]
        p.step("all solvers for the convergence chart")
        sols = convergence(F, patches, tol)
        if chart:
            chart = convergence_chart(os.path.join(out, "radiosity_convergence.png"), sols, len(patches))
        else:
            chart = None
        charts.write_csv(os.path.join(out, "radiosity_convergence.csv"),
                         [{"solver": s, "iteration": k + 1, "residual": v}
                          for s, so in sols.items() for k, v in enumerate(so.residuals)])
        p.step("vertex colours and light maps")
        results = result_objects(scene, patches, H, meshes)
        files = write_lightmaps(out, results, patches, H)
        report = {"patches": len(patches), "solver": solver, "iterations": sol.iterations,
                  "seconds": round(r["timings"]["total"], 4),
                  "timings": {k: round(v, 4) for k, v in r["timings"].items()},
                  "rms_vs_cycles": None, "scene": scene.name, "chart": chart,
                  "solvers": {s: {"iterations": so.iterations, "seconds": round(so.seconds, 5),
                                  "converged": so.converged} for s, so in sols.items()},
                  "objects": {n: {"lightmap": f, "object": results[n][0].name, "patches": int(len(results[n][1]))}
                              for n, f in files.items()},
                  "units": "irradiance W/m^2"}
        if compare:
            p.step(f"Cycles irradiance bake ({samples} samples)")
            Hc, secs = cycles_patch_irradiance(scene, results, patches, os.path.join(out, "cycles_bake"), samples)
            ok = np.isfinite(Hc).all(axis=1)
            report["rms_vs_cycles"] = rms(H, Hc)
            report["relative_rms_vs_cycles"] = report["rms_vs_cycles"] / float(np.mean(Hc[ok]))
            report["mean_irradiance"] = {"radiosity": float(np.mean(H[ok])), "cycles": float(np.mean(Hc[ok]))}
            report["cycles_seconds"] = round(secs, 4)
            report["cycles_samples"] = int(samples)
            report["cycles_maps"] = os.path.join(out, "cycles_bake")
            r["cycles"] = Hc
    write_json(os.path.join(out, REPORT), report)
    r["report"] = report
    return r
