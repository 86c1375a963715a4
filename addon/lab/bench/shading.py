"""Shading models measured: node groups against their numpy twins, against Blender's closures, and their cost.

- :func:`render_group_sweep` renders spheres shaded by one node group with fixed inputs
  (orthographic camera, 1 sample, Normal pass): every pixel is one (n, l, v) triple.
- :func:`run` is the benchmark (``scripts/brdf_compare.py`` and the project-wide bench call it).
"""
import os
import time

import bpy
import numpy as np

from ...blender import compat
from ...core import brdf, charts
from ...core.errors import InputError
from ...nodes import groups, material
from ...nodes.models import BY_GROUP, MODELS
from ...blender.progress import Progress
from ...blender import materials, scene as sc
from ...blender import render
from .result import BenchResult

KEY = "shading"
TITLE = "Shading models against Blender's closures"

V_ORTHO = np.array([0.0, -1.0, 0.0])  # toward the viewer of the sweep camera (which looks along +Y)


# -- scenes -----------------------------------------------------------------------------------------

def sphere_grid(name, count, size=96, segments=64, rings=32):
    """A scene with ``count`` unit spheres in a grid, an orthographic camera looking along +Y, black world."""
    cols = int(np.ceil(np.sqrt(count)))
    rows = int(np.ceil(count / cols))
    scene = sc.new_scene(name, (size * cols // max(cols, rows), size * rows // max(cols, rows)))
    spheres = []
    for k in range(count):
        r, c = divmod(k, cols)
        obj = sc.sphere(scene, f"{name} S{k}", 1.0, location=(2.2 * c, 0.0, -2.2 * r), segments=segments,
                        rings=rings)
        obj.pass_index = k + 1
        spheres.append(obj)
    center = (2.2 * (cols - 1) / 2, -10.0, -2.2 * (rows - 1) / 2)
    sc.camera(scene, f"{name} Cam", center, target=(center[0], 0.0, center[2]),
              ortho_scale=2.2 * max(cols, rows))
    sc.world(scene, strength=0.0)
    vl = scene.view_layers[0]
    vl.use_pass_normal = True
    vl.use_pass_object_index = True
    vl.use_pass_position = True
    return scene, spheres


def group_material(name, group_name, inputs, output="Emission"):
    """A material whose surface is the node group's ``output`` with constant ``inputs``."""
    mat = materials.empty_material(name)
    nt = mat.node_tree
    node = nt.nodes.new("ShaderNodeGroup")
    node.node_tree = groups.ensure_group(group_name)
    set_inputs(node, inputs)
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    nt.links.new(node.outputs[output], out.inputs["Surface"])
    return mat


def set_inputs(node, inputs):
    """Set a group node's inputs from {name: value}; an RGB triple fills a colour socket with alpha 1."""
    for key, value in inputs.items():
        socket = node.inputs[key]
        if isinstance(value, (tuple, list)) and len(socket.default_value) == 4 and len(value) == 3:
            value = (*value, 1.0)
        socket.default_value = value


def closure_material(name, kind, color=(1.0, 1.0, 1.0), roughness=0.0, distribution="GGX"):
    """A material with one of Blender's BSDFs: 'DIFFUSE', 'GLOSSY' or 'PRINCIPLED'."""
    mat = materials.empty_material(name)
    nt = mat.node_tree
    node = nt.nodes.new({"DIFFUSE": "ShaderNodeBsdfDiffuse", "GLOSSY": "ShaderNodeBsdfGlossy",
                         "PRINCIPLED": "ShaderNodeBsdfPrincipled"}[kind])
    node.inputs["Color" if kind != "PRINCIPLED" else "Base Color"].default_value = (*color, 1.0)
    node.inputs["Roughness"].default_value = roughness
    if kind == "GLOSSY":
        node.distribution = distribution
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    nt.links.new(node.outputs[0], out.inputs["Surface"])
    return mat


def assign(obj, mat):
    """Make ``mat`` the mesh's only material."""
    obj.data.materials.clear()
    obj.data.materials.append(mat)


def render_pixels(scene, samples=1, seed=0, bounces=0):
    """Render (direct light only by default: the models are local); return per-object pixel data
    {pass_index: {"n", "p", "L"}} (background dropped)."""
    render.cycles_cpu(scene, samples, seed=seed, pixel_filter=0.01)
    scene.cycles.max_bounces = bounces
    # drivers of a scene that is not the window's scene are not evaluated by the render itself
    scene.view_layers[0].update()
    passes = render.render_layers(scene)
    index = np.rint(passes[compat.OBJECT_INDEX_PASS]).astype(int)
    out = {}
    for k in np.unique(index):
        if k <= 0:
            continue
        m = index == k
        out[int(k)] = {"n": passes["Normal"][..., :3][m].astype(float),
                       "p": passes["Position"][..., :3][m].astype(float),
                       "L": passes["Combined"][..., :3][m].astype(float)}
    return out


def render_group_sweep(group_name, cases, size=96):
    """Render one sphere per case (dict of group inputs); return [{"n", "v", "L", "inputs"}] per case."""
    scene, spheres = sphere_grid("IL sweep", len(cases), size)
    mats = []
    try:
        for k, (obj, inputs) in enumerate(zip(spheres, cases)):
            mats.append(group_material(f"IL sweep {k}", group_name, inputs))
            assign(obj, mats[-1])
        pix = render_pixels(scene)
    finally:
        sc.remove_scene(scene, mats)
    return [dict(pix.get(k + 1, {"n": np.zeros((0, 3)), "p": np.zeros((0, 3)), "L": np.zeros((0, 3))}),
                 v=V_ORTHO, inputs=inputs) for k, inputs in enumerate(cases)]


# -- twins of the group inputs ----------------------------------------------------------------------

def _rgb(x):
    return np.asarray(x, float)[:3] if np.ndim(x) else float(x)


def _model(group_name):
    if group_name not in BY_GROUP:
        raise InputError(f"no twin for '{group_name}'")
    return BY_GROUP[group_name]


def twin_inputs(group_name, inputs):
    """{input name: value} of every input of the model group: ``inputs`` over the defaults, colours as RGB."""
    spec = {name: default for name, _, default, *_ in _model(group_name).inputs}
    spec.update(inputs)
    return {k: _rgb(val) for k, val in spec.items()}


def twin(group_name, n, v, inputs):
    """The numpy twin of ``group_name`` (its record's ``twin``, nodes/models) evaluated with the group's
    ``inputs`` (missing ones at defaults)."""
    p = twin_inputs(group_name, inputs)
    return _model(group_name).twin(n, p["Light Vector"], v, p["Light Color"], p)


#: Light vectors of the sweep: frontal, oblique, grazing (l perpendicular to v), behind the sphere.
SWEEP_LIGHTS = [(0.0, -1.0, 0.0), (2.0, -1.0, 1.5), (1.0, 0.0, 0.0), (-0.3, 1.0, 0.4)]

#: {model group: parameter sets of its sweep} (each record's ``sweep``, nodes/models).
SWEEP_CASES = {m.group: [dict(case) for case in m.sweep] for m in MODELS}


def sweep_cases(group_name):
    """Every parameter set of SWEEP_CASES crossed with every SWEEP_LIGHTS vector (colour 0.9, 0.7, 0.5)."""
    return [dict(case, **{"Light Vector": l, "Light Color": (0.9, 0.7, 0.5)})
            for case in SWEEP_CASES[group_name] for l in SWEEP_LIGHTS]


def node_vs_twin(group_name, size=96):
    """Max |node - twin| over every pixel of every case, and the peak twin value."""
    results = render_group_sweep(group_name, sweep_cases(group_name), size)
    err, peak, count = 0.0, 0.0, 0
    for r in results:
        ref = twin(group_name, r["n"], r["v"], r["inputs"])
        err = max(err, float(np.max(np.abs(r["L"] - ref), initial=0.0)))
        peak = max(peak, float(np.max(ref, initial=0.0)))
        count += len(ref)
    return {"group": group_name, "pixels": count, "max_abs_error": err, "peak": peak,
            "relative_error": err / peak if peak else 0.0}


# -- directional albedo of the node groups, rendered -------------------------------------------------

#: (group, inputs, incidence in degrees) of the rendered albedo check: the energy-normalised lobes at
#: exponents where the old (n+8)/8 factor gained up to 7.5 %, Lambert (sigma 0) and Oren-Nayar.
ALBEDO_CASES = (
    [("IL Blinn-Phong", {"Shininess": e}, t) for e in (0.0, 1.0, 9.0, 100.0) for t in (0.0, 60.0, 89.9)]
    + [("IL Phong", {"Shininess": e}, t) for e in (1.0, 9.0, 100.0) for t in (0.0, 60.0, 89.9)]
    + [("IL Oren-Nayar", {"Sigma": s}, t) for s in (0.0, 0.2, 1.0) for t in (0.0, 60.0, 89.9)])
#: Inputs that leave only the lobe under test: k_s = 1 (or rho = 1), no diffuse, ambient or emission, I = 1.
ALBEDO_BASE = {"IL Phong": {"Ka": 0.0, "Kd": (0, 0, 0), "Ks": 1.0, "Normalized": 1.0, "Emission Color": (0, 0, 0)},
               "IL Oren-Nayar": {"Albedo": (1, 1, 1)}}
ALBEDO_BASE["IL Blinn-Phong"] = ALBEDO_BASE["IL Phong"]


def _albedo_width(inputs):
    return brdf.lobe_width(inputs["Shininess"]) if "Shininess" in inputs else 1.0


def _albedo_frame(theta_v):
    """World (e1, e2, n) of a plane seen along +Y (v = (0, -1, 0)) whose shading normal is theta_v from v,
    with v in the (e1, n) plane on the + side: v = sin(theta_v) e1 + cos(theta_v) n."""
    t = np.radians(theta_v)
    return (np.array([-np.cos(t), -np.sin(t), 0.0]), np.array([0.0, 0.0, 1.0]),
            np.array([np.sin(t), -np.cos(t), 0.0]))


def albedo_material(name, group_name, inputs, theta_v):
    """A material that feeds the group, at each point (x, y) of the unit square (Object coordinates of a
    [-1, 1]^2 plane in XZ), the light direction brdf.half_vector_map(x, y) in the plane's normal frame."""
    from ...nodes.builder import Graph
    mat = materials.empty_material(name)
    g = Graph(mat.node_tree)
    e1, e2, nrm = _albedo_frame(theta_v)
    width = _albedo_width(inputs)
    xyz = g.node("ShaderNodeSeparateXYZ")
    g.feed(g.node("ShaderNodeTexCoord").outputs["Object"], xyz.inputs[0])
    x = g.mul(g.add(xyz.outputs["X"], 1.0), 0.5, label="x")
    y = g.mul(g.add(xyz.outputs["Z"], 1.0), 0.5, label="y")
    theta = g.math("ARCTANGENT", g.mul(g.math("TANGENT", g.mul(x, np.pi / 2)), width), label="theta_h")
    phi = g.mul(y, np.pi, label="phi_h")
    st = g.math("SINE", theta)
    h = g.vadd(g.vadd(g.scale(tuple(e1), g.mul(st, g.math("COSINE", phi))),
                      g.scale(tuple(e2), g.mul(st, g.math("SINE", phi)))),
               g.scale(tuple(nrm), g.math("COSINE", theta)), label="h")
    v = g.node("ShaderNodeNewGeometry").outputs["Incoming"]
    v_h = g.max(g.dot(v, h), 0.0, label="max(v.h, 0)")
    l = g.vmath("SUBTRACT", g.scale(h, g.mul(v_h, 2.0)), v, label="l = 2 (v.h) h - v")
    node = g.node("ShaderNodeGroup")
    node.node_tree = groups.ensure_group(group_name)
    set_inputs(node, dict(ALBEDO_BASE[group_name], **inputs, **{"Light Color": (1.0, 1.0, 1.0)}))
    g.feed(l, node.inputs["Light Vector"])
    out = g.node("ShaderNodeOutputMaterial")
    g.feed(node.outputs["Emission"], out.inputs["Surface"])
    return mat


def _custom_normal_plane(scene, name, location, normal):
    """A 2 x 2 plane in XZ facing -Y (the camera) whose shading normal is ``normal`` everywhere."""
    me = bpy.data.meshes.new(name)
    me.from_pydata([(-1, 0, -1), (1, 0, -1), (1, 0, 1), (-1, 0, 1)], [], [(0, 1, 2, 3)])
    me.shade_smooth()
    me.normals_split_custom_set([tuple(normal)] * len(me.loops))
    obj = bpy.data.objects.new(name, me)
    obj.location = location
    return sc.link(scene, obj)


def _albedo_twin(group_name, inputs, l, v, n=(0.0, 0.0, 1.0)):
    """The twin of an ALBEDO_BASE case for arrays of light directions l (I = 1), in the plane's frame
    (e1, e2, n) of :func:`_albedo_frame`: n = +z, or per-pixel shading normals (N, 3) in that frame."""
    p = twin_inputs(group_name, dict(ALBEDO_BASE[group_name], **inputs))
    return _model(group_name).twin(np.asarray(n, float), l, v, 1.0, p)


def render_group_albedo(cases=None, size=64):
    """Directional albedo of node groups from one Cycles render: one plane per (group, inputs, incidence),
    size x size pixels each, every pixel one light direction of brdf.half_vector_map.

    Returns [{"group", "inputs", "theta_v", "albedo" (render), "twin" (the numpy twin on the same
    directions and the same shading normal: the Normal pass, which is the plane's normal only to within
    compat.CYCLES_NORMAL_ERROR), "pixels"}]: albedo = (1/pi) sum of L J / size^2 (white light, I = 1).
    """
    cases = list(ALBEDO_CASES if cases is None else cases)
    cols = int(np.ceil(np.sqrt(len(cases))))
    rows = int(np.ceil(len(cases) / cols))
    scene = sc.new_scene("IL albedo", (size * cols, size * rows))
    mats = []
    try:
        for k, (group_name, inputs, theta_v) in enumerate(cases):
            r, c = divmod(k, cols)
            obj = _custom_normal_plane(scene, f"IL albedo P{k}", (2.0 * c, 0.0, -2.0 * r), _albedo_frame(theta_v)[2])
            obj.pass_index = k + 1
            mats.append(albedo_material(f"IL albedo {k}", group_name, inputs, theta_v))
            assign(obj, mats[-1])
        center = (cols - 1.0, -10.0, -(rows - 1.0))
        sc.camera(scene, "IL albedo Cam", center, target=(center[0], 0.0, center[2]), ortho_scale=2.0 * max(cols, rows))
        sc.world(scene, strength=0.0)
        vl = scene.view_layers[0]
        vl.use_pass_normal = vl.use_pass_object_index = vl.use_pass_position = True
        pix = render_pixels(scene)
    finally:
        sc.remove_scene(scene, mats)
    out = []
    for k, (group_name, inputs, theta_v) in enumerate(cases):
        p = pix.get(k + 1, {"n": np.zeros((0, 3)), "p": np.zeros((0, 3)), "L": np.zeros((0, 3))})
        r, c = divmod(k, cols)
        x = (p["p"][:, 0] - 2.0 * c + 1.0) / 2.0
        y = (p["p"][:, 2] + 2.0 * r + 1.0) / 2.0
        _, l, v, J = brdf.half_vector_map(x, y, np.radians(theta_v), _albedo_width(inputs))
        n = p["n"] @ np.stack(_albedo_frame(theta_v), axis=1)     # the normal Cycles shaded with, plane frame
        ref = _albedo_twin(group_name, inputs, l, v, n)
        w = J / (np.pi * size * size)
        out.append({"group": group_name, "inputs": dict(inputs), "theta_v": theta_v, "pixels": int(len(x)),
                    "albedo": float(np.sum(p["L"][:, 0] * w)), "twin": float(np.sum(ref[:, 0] * w))})
    return out


# -- against Blender's closures ---------------------------------------------------------------------

def _lit_sphere_scene(name, count, size, sun_rotation):
    scene, spheres = sphere_grid(name, count, size, segments=96, rings=48)
    sun = sc.light(scene, f"{name} Sun", "SUN", np.pi, rotation=sun_rotation)
    if hasattr(sun.data, "use_shadow"):
        sun.data.use_shadow = False  # IL materials do not shadow: compare shading, not the terminator
    return scene, spheres, sun


def closure_comparison(kind, values, size=64, samples=16):
    """Render spheres with Blender's Diffuse ('OREN_NAYAR') or Glossy GGX ('COOK_TORRANCE') BSDF at roughness
    ``values`` and the IL group (assigned with the same sun, physical units) at the matching parameter.

    IL Oren-Nayar uses sigma = roughness (radians); IL Cook-Torrance uses F0 = 1, k_d = 0, alpha = roughness^2.
    Returns rows and per-value pixel data for charts.
    """
    # sun from the upper left front: l = (-0.5, -0.5, 0.707); v = (0, -1, 0)
    rot = sc.deg(45, 0, 225)
    scene, spheres, sun = _lit_sphere_scene(f"IL closures {kind}", len(values), size, rot)
    blender, il = [], []
    try:
        for k, val in enumerate(values):
            if kind == "OREN_NAYAR":
                blender.append(closure_material(f"B{k}", "DIFFUSE", roughness=val))
                params = {"Albedo": (1.0, 1.0, 1.0), "Sigma": float(val)}
            else:
                blender.append(closure_material(f"B{k}", "GLOSSY", roughness=val, distribution="GGX"))
                params = {"Kd": (0.0, 0.0, 0.0), "Ks": 1.0, "F0": 1.0, "Roughness": float(val) ** 2,
                          "Distribution": 1.0, "Geometry": 1.0}
            il.append(material.assign_shading_model(scene, [spheres[k], sun], kind, lights="SELECTED",
                                                    params=params, name=f"IL{k}")[0])
        pix_il = render_pixels(scene, samples=samples)
        for obj, mat in zip(spheres, blender):
            assign(obj, mat)
        pix_b = render_pixels(scene, samples=samples)  # same seed and pixels: only the shading differs
    finally:
        sc.remove_scene(scene, blender + il)
    l = -np.array(_sun_direction(rot))
    rows, data = [], []
    for k, val in enumerate(values):
        b, i = pix_b[k + 1], pix_il[k + 1]
        lb, li = b["L"].mean(-1), i["L"].mean(-1)
        diff = lb - li
        peak = float(max(lb.max(initial=0), li.max(initial=0), 1e-12))
        rms = float(np.sqrt(np.mean(diff ** 2)))
        rows.append({"model": kind, "blender_roughness": float(val), "pixels": int(len(lb)),
                     "rms_difference": rms, "peak": peak, "relative_rms": rms / peak,
                     "mean_blender": float(lb.mean()), "mean_il": float(li.mean())})
        data.append({"value": val, "n_blender": b["n"], "L_blender": lb, "n_il": i["n"], "L_il": li})
    return rows, data, l


def _sun_direction(rot):
    from mathutils import Euler, Vector
    return tuple(Euler(rot, "XYZ").to_matrix() @ Vector((0, 0, -1)))


def best_sigma(n, L, l, v=V_ORTHO):
    """The IL Oren-Nayar sigma whose twin best fits radiance ``L`` (white albedo, I = 1) in least squares."""
    sigmas = np.linspace(0.0, 3.0, 301)
    errs = [np.mean((brdf.oren_nayar(n, l, v, np.ones(3), np.ones(3), s)[:, 0] - L) ** 2) for s in sigmas]
    k = int(np.argmin(errs))
    return float(sigmas[k]), float(np.sqrt(errs[k]))


# -- cost ---------------------------------------------------------------------------------------------

#: Materials of the cost benchmark: Blender's Principled BSDF, then each IL model (assigned with the scene's lights).
COST_MODELS = ("PRINCIPLED", "PHONG", "BLINN_PHONG", "OREN_NAYAR", "COOK_TORRANCE", "COOK_TORRANCE_BECKMANN")
COST_PARAMS = {"COOK_TORRANCE": {"Roughness": 0.3, "Kd": (0.5, 0.5, 0.5)},
               "COOK_TORRANCE_BECKMANN": {"Roughness": 0.3, "Kd": (0.5, 0.5, 0.5), "Distribution": 0.0,
                                          "Geometry": 0.0}}
#: (resolution, samples per pixel) of the cost benchmark.
COST_CONFIGS = ((256, 64), (64, 8))


def cost_scene(light_count):
    """Floor, ball, camera, a dim world and 1 (a point) or up to 4 lights (+ sun, spot, second point)."""
    scene = sc.new_scene(f"IL cost {light_count}", (64, 64))
    sc.plane(scene, "Cost Floor", 8.0)
    sc.sphere(scene, "Cost Ball", 0.8, location=(0, 0, 0.8))
    sc.light(scene, "Cost Key", "POINT", 300.0, location=(2.0, -3.0, 3.5))
    if light_count > 1:
        sc.light(scene, "Cost Sun", "SUN", 3.0, rotation=sc.deg(40, 0, 30))
    if light_count > 2:
        spot = sc.light(scene, "Cost Spot", "SPOT", 400.0, location=(-2.5, -2.0, 3.0))
        sc.look_at(spot, (0, 0, 0.5))
    if light_count > 3:
        sc.light(scene, "Cost Fill", "POINT", 100.0, location=(-3.0, 2.0, 1.5), color=(0.6, 0.7, 1.0))
    sc.camera(scene, "Cost Cam", (0.0, -5.0, 3.0), target=(0, 0, 0.6))
    sc.world(scene, strength=0.2)
    return scene


def _nodes(tree):
    return sum(n.bl_idname not in ("NodeFrame", "NodeGroupInput", "NodeGroupOutput", "NodeReroute")
               for n in tree.nodes)


def node_counts():
    """{group name: nodes in it (frames, group input and output not counted)} of every IL group, public and
    internal (the per-type light groups and the surface and light halves that materials use, with the switches
    left free: a material links the variant its switch values select, see :func:`material_node_counts`)."""
    return {name: _nodes(groups.ensure_group(name)) for name in list(groups.BUILDERS) + list(groups.INTERNAL)}


def material_node_counts(mat, light_name):
    """(nodes of the groups ``mat`` links for the light ``light_name``: its type's light group and the model's
    light half, as the material's switches select them; nodes of the surface half)."""
    nodes = mat.node_tree.nodes
    per_light = sum(_nodes(n.node_tree) for n in nodes if n.bl_idname == "ShaderNodeGroup"
                    and n.name.endswith(f": {light_name}"))
    once = sum(_nodes(n.node_tree) for n in nodes if n.bl_idname == "ShaderNodeGroup"
               and n.name.endswith("surface (shared by every light)"))
    return per_light, once


def _timed_render(scene):
    """(wall seconds, CPU seconds of every thread of this process) of one F12 render."""
    scene.view_layers[0].update()  # drivers of a scene that is not the window's are stale otherwise
    t, c = time.perf_counter(), time.process_time()
    bpy.ops.render.render(scene=scene.name)
    return time.perf_counter() - t, time.process_time() - c


def render_cost(configs=COST_CONFIGS, light_counts=(1, 4), repeats=3, models=COST_MODELS):
    """Seconds of one Cycles render (F12: sync, shader compile, path tracing) of the same scene with each material
    of ``models`` and each light count, best of ``repeats``; every (light count, material) pair is rendered once
    per repeat, in turn, so that a change of load on the machine hits them alike.

    Rows {"model", "lights", "size", "samples", "seconds", "ratio" (over Principled's with the same lights and
    settings), "cpu_seconds" and "cpu_ratio" (CPU time of all the process' threads, best of the repeats: less
    sensitive than wall time to other jobs on a shared machine), "nodes_per_light" (nodes of the groups the
    material links for a point light: its light group and the model's light half, the variants its switches
    select; what Blender converts for every light at every render), "nodes_once" (the model's surface half), "ns_per_sample" (seconds per camera sample)}.
    """
    counts = {}
    scenes, mats = {}, {}
    try:
        for light_count in light_counts:
            scene = scenes[light_count] = cost_scene(light_count)
            objs = [o for o in scene.objects if o.type == "MESH"]
            for model in models:
                if model == "PRINCIPLED":
                    mat = closure_material("Cost Principled", "PRINCIPLED", (0.5, 0.5, 0.5), 0.5)
                else:
                    kind = "COOK_TORRANCE" if model.startswith("COOK_TORRANCE") else model
                    mat = material.assign_shading_model(scene, objs, kind, params=COST_PARAMS.get(model),
                                                        name=f"Cost {model}")[0]
                mat.use_fake_user = True    # the next model assigned to these meshes would free it (unused)
                mats[(light_count, model)] = mat
                if model != "PRINCIPLED":
                    key = next(o.name for o in scene.objects if o.type == "LIGHT" and o.data.type == "POINT")
                    counts[model] = material_node_counts(mat, key)
        best = {}
        for size, samples in configs:
            for light_count, scene in scenes.items():
                scene.render.resolution_x = scene.render.resolution_y = size
                render.cycles_cpu(scene, samples=samples)
            for rep in range(repeats + 1):  # the first pass warms up and is not counted
                for light_count, scene in scenes.items():
                    objs = [o for o in scene.objects if o.type == "MESH"]
                    for model in models:
                        for o in objs:
                            assign(o, mats[(light_count, model)])
                        sec = _timed_render(scene)
                        if rep:
                            key = (light_count, size, samples, model)
                            best[key] = tuple(min(a, b) for a, b in zip(best.get(key, sec), sec))
        rows = []
        for size, samples in configs:
            for light_count in light_counts:
                base, cpu_base = best.get((light_count, size, samples, "PRINCIPLED"), (None, None))
                for model in models:
                    sec, cpu = best[(light_count, size, samples, model)]
                    per_light, once = counts.get(model, (None, None))
                    rows.append({"model": model, "lights": light_count, "size": size, "samples": samples,
                                 "seconds": sec, "ratio": sec / base if base else None,
                                 "cpu_seconds": cpu, "cpu_ratio": cpu / cpu_base if cpu_base else None,
                                 "nodes_per_light": per_light,
                                 "nodes_once": once,
                                 "ns_per_sample": sec / (size * size * samples) * 1e9})
    finally:
        for m in mats.values():
            m.use_fake_user = False
        for scene in scenes.values():
            sc.remove_scene(scene, [m for (lc, _), m in mats.items() if scenes.get(lc) is scene])
    return rows


def per_light_cost(rows):
    """Per-light cost from rows of two light counts: (seconds(k) - seconds(j)) / (k - j) per (model, size,
    samples), as {(model, size, samples): (seconds per light, ns per sample per light)}."""
    out = {}
    by = {}
    for r in rows:
        by.setdefault((r["model"], r["size"], r["samples"]), {})[r["lights"]] = r["seconds"]
    for key, secs in by.items():
        if len(secs) >= 2:
            lo, hi = min(secs), max(secs)
            per = (secs[hi] - secs[lo]) / (hi - lo)
            out[key] = (per, per / (key[1] * key[1] * key[2]) * 1e9)
    return out


# -- charts of the twins ------------------------------------------------------------------------------

def twin_charts(output_dir):
    """Radiance of each model in the plane of incidence against the view angle, for several incidence angles."""
    paths = []
    tv = np.radians(np.linspace(-89, 89, 179))
    v = np.stack([np.sin(tv), np.zeros_like(tv), np.cos(tv)], -1)
    N = np.array([0.0, 0.0, 1.0])
    one = np.ones(3)
    models = {
        "phong": lambda l: brdf.phong(N, l, v, one, kd=(0.5,) * 3, ks=0.5, shininess=20.0),
        "phong_normalized": lambda l: brdf.phong(N, l, v, one, kd=(0.5,) * 3, ks=0.5, shininess=20.0,
                                                 normalized=1.0),
        "blinn_phong": lambda l: brdf.blinn_phong(N, l, v, one, kd=(0.5,) * 3, ks=0.5, shininess=20.0),
        "blinn_phong_normalized": lambda l: brdf.blinn_phong(N, l, v, one, kd=(0.5,) * 3, ks=0.5, shininess=20.0,
                                                             normalized=1.0),
        "oren_nayar_sigma0.5": lambda l: brdf.oren_nayar(N, l, v, one, one, 0.5),
        "cook_torrance_ggx": lambda l: brdf.cook_torrance(N, l, v, one, kd=(0.2,) * 3, ks=1.0, F0=0.04,
                                                          roughness=0.3),
        "cook_torrance_beckmann": lambda l: brdf.cook_torrance(N, l, v, one, kd=(0.2,) * 3, ks=1.0, F0=0.04,
                                                               roughness=0.3, distribution=0.0, geometry=0.0),
    }
    for name, fn in models.items():
        series = {}
        for ti in (0, 30, 60, 80):
            l = brdf.direction(np.radians(ti), np.pi)
            series[f"incidence {ti} deg"] = (np.degrees(tv), fn(l)[:, 0])
        paths.append(charts.line_chart(os.path.join(output_dir, f"brdf_{name}.png"), series,
                                       f"{name}: radiance in the plane of incidence (I = 1)",
                                       "view angle (deg, + = mirror side)", "radiance L / I"))
    paths.append(albedo_chart(os.path.join(output_dir, "brdf_albedo.png")))
    return paths


def albedo_chart(path):
    """Directional albedo (k_s = 1, rho = 1) against incidence: the energy-normalised lobes, the old
    (n+8)/8 Blinn-Phong factor, Lambert and Oren-Nayar (whose qualitative model exceeds 1 at grazing
    incidence for 0 < sigma < 0.33 rad)."""
    N = np.array([0.0, 0.0, 1.0])
    deg = np.array([0.0, 10, 20, 30, 40, 50, 60, 70, 80, 85, 89, 89.9])

    def curve(fn, width):
        return deg, np.array([brdf.directional_albedo(fn, np.radians(t), width, 192, 96) for t in deg])

    def blinn(e, normalised=True):
        scale = 1.0 if normalised else (e + 8) / 8 / brdf.blinn_energy_factor(e)
        return curve(lambda l, v: scale * brdf.blinn_phong(N, l, v, 1.0, kd=(0, 0, 0), ks=1.0, shininess=e,
                                                           normalized=1.0)[..., 0], brdf.lobe_width(e))

    series = {f"Blinn-Phong normalised n={e:g}": blinn(e) for e in (1.0, 9.0, 100.0)}
    series["Blinn-Phong (n+8)/8, before, n=9"] = blinn(9.0, normalised=False)
    series["Phong normalised n=9"] = curve(lambda l, v: brdf.phong(N, l, v, 1.0, kd=(0, 0, 0), ks=1.0, shininess=9.0,
                                                                   normalized=1.0)[..., 0], brdf.lobe_width(9.0))
    for sigma in (0.0, 0.2, 1.0):
        series[f"Oren-Nayar sigma={sigma:g}" + (" (Lambert)" if sigma == 0 else "")] = curve(
            lambda l, v: brdf.oren_nayar(N, l, v, 1.0, 1.0, sigma)[..., 0], 1.0)
    return charts.line_chart(path, series, "Directional albedo (k_s = 1, rho = 1; 1 = all energy reflected)",
                             "incidence (deg)", "albedo")


def _profile_chart(path, data, l, title, label_fn):
    """Mean radiance over the sphere's pixels binned by the angle between n and l (3 degree bins)."""
    series = {}
    edges = np.arange(0.0, 93.0, 3.0)
    for d in data:
        for who in ("blender", "il"):
            n, L = d[f"n_{who}"], d[f"L_{who}"]
            ang = np.degrees(np.arccos(np.clip(n @ np.asarray(l), -1.0, 1.0)))
            k = np.digitize(ang, edges) - 1
            mids, means = [], []
            for b in range(len(edges) - 1):
                m = k == b
                if np.any(m):
                    mids.append((edges[b] + edges[b + 1]) / 2)
                    means.append(float(np.mean(L[m])))
            series[label_fn(d["value"], who)] = (np.array(mids), np.array(means))
    return charts.line_chart(path, series, title, "angle between n and l (deg)",
                             "mean radiance over the bin (W m^-2 sr^-1)")


def run(output_dir, quick=False):
    """The shading benchmark: node-vs-twin errors, node-vs-Blender-closure differences, render cost.

    Returns {"tables": {name: [rows]}, "charts": [png paths], "figures": {...}}.
    """
    os.makedirs(output_dir, exist_ok=True)
    groups.add_node_groups()
    size = 64 if quick else 128
    steps = ["twin charts", "node groups vs twins", "Oren-Nayar vs Diffuse BSDF",
             "Cook-Torrance vs Glossy BSDF", "render cost"]
    tables, chart_paths, figures = {}, [], {}
    with Progress("shading", len(steps)) as progress:
        progress.step(steps[0])
        chart_paths += twin_charts(output_dir)

        progress.step(steps[1])
        rows = []
        for name in (m.group for m in MODELS):
            t = time.perf_counter()
            row = node_vs_twin(name, size=48 if quick else 96)
            row["seconds"] = time.perf_counter() - t
            rows.append(row)
        tables["shading_node_vs_twin"] = rows
        figures["node_vs_twin_max_relative_error"] = max(r["relative_error"] for r in rows)

        t = time.perf_counter()
        albedo_rows = render_group_albedo(size=64)
        for row in albedo_rows:
            row["inputs"] = ", ".join(f"{k} {v:g}" for k, v in row["inputs"].items())
            row["seconds"] = time.perf_counter() - t
        tables["shading_group_albedo"] = albedo_rows
        figures["group_albedo_max_abs_vs_twin"] = max(abs(r["albedo"] - r["twin"]) for r in albedo_rows)

        progress.step(steps[2])
        values = (0.0, 0.5, 1.0) if quick else (0.0, 0.25, 0.5, 0.75, 1.0)
        on_rows, on_data, l = closure_comparison("OREN_NAYAR", values, size=size, samples=8 if quick else 32)
        for row, d in zip(on_rows, on_data):
            sigma, rms = best_sigma(d["n_blender"], d["L_blender"], l)
            row["best_fit_sigma"], row["best_fit_rms"] = sigma, rms
        tables["shading_oren_nayar_vs_diffuse"] = on_rows
        chart_paths.append(_profile_chart(os.path.join(output_dir, "oren_nayar_vs_diffuse.png"), on_data, l,
                                          "IL Oren-Nayar (sigma = r) vs Diffuse BSDF (roughness r)",
                                          lambda r, who: f"{'Blender' if who == 'blender' else 'IL'} r={r:g}"))
        figures["oren_nayar_sigma0_relative_rms"] = on_rows[0]["relative_rms"]

        progress.step(steps[3])
        values = (0.2, 0.5) if quick else (0.1, 0.2, 0.3, 0.5, 0.7)
        ct_rows, ct_data, l = closure_comparison("COOK_TORRANCE", values, size=size, samples=8 if quick else 32)
        tables["shading_cook_torrance_vs_glossy"] = ct_rows
        chart_paths.append(_profile_chart(os.path.join(output_dir, "cook_torrance_vs_glossy.png"), ct_data, l,
                                          "IL Cook-Torrance (GGX, Smith, F=1, alpha=r^2) vs Glossy GGX (r)",
                                          lambda r, who: f"{'Blender' if who == 'blender' else 'IL'} r={r:g}"))
        figures["cook_torrance_vs_glossy_max_relative_rms"] = max(r["relative_rms"] for r in ct_rows)

        progress.step(steps[4])
        cost = render_cost(configs=((64, 8),) if quick else ((256, 64),), repeats=1,
                           models=("PRINCIPLED", "COOK_TORRANCE"))
        tables["shading_render_cost"] = cost
        figures["render_time_ratio_il_ct_over_principled"] = max(
            r["ratio"] for r in cost if r["model"] == "COOK_TORRANCE")
    for name, rows in tables.items():
        charts.write_csv(os.path.join(output_dir, f"{name}.csv"), rows)
    return BenchResult(tables, chart_paths, figures)
