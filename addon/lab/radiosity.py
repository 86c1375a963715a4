"""Radiosity in Blender: patches from the scene, visibility rays, solution as vertex colours and light maps,
and the Cycles irradiance bake of the same scene for comparison (seed 004; core in addon.core.radiosity and the scene in addon.core.analytic).

Units: B radiosity (exitance) and H irradiance in W/m²; an Emission shader's Strength is the emitted
radiance L_e (E_i = π L_e). The comparison is the light-map pipeline's irradiance bake (addon.bake) of the
result objects: the scene's own materials drive the bounces, emitters included.
"""
import os
import time

import bpy
import numpy as np

from ..core import charts
from ..core import budget
from ..core.budget import memory_budget
from ..core.io import exr
from ..core import analytic
from ..core.radiosity import atlas as rad_atlas
from ..core.radiosity import cost as rad_cost
from ..core.radiosity import form_factors as rad_form_factors
from ..core.radiosity import gather as rad_gather
from ..core.radiosity import patches as rad_patches
from ..core.radiosity import solvers as rad_solvers
from ..core.radiosity import subdivision as rad_subdivision
from ..core.radiosity import visibility as rad_visibility
from ..core.errors import ILError, InputError, warn
from ..core.io.files import check_output_dir, write_json
from ..core.io.names import file_stems
from ..blender import interrupt
from ..blender.progress import Progress
from ..blender import compat, materials, scene as scn
from ..blender.state import SavedState, world_settings
from .options import RadiosityOptions
from ..core.result import JobResult

COLLECTION = "IL Radiosity"
ATTRIBUTE = "IL Radiosity E"
UV = "IL Radiosity Atlas"
REPORT = "radiosity_report.json"


# ----------------------------------------------------------------------------- scene in, scene out


def build_cornell_scene(name="IL Cornell", light_radiance=15.0):
    """The built-in Cornell-box-like room (analytic.cornell_box) as a new Cycles scene with a black world."""
    sc = scn.new_scene(name, (128, 128))
    scn.world(sc, 0.0)
    for m in analytic.cornell_box(light_radiance):
        me = bpy.data.meshes.new(m["name"])
        me.from_pydata([tuple(v) for v in m["vertices"]], [], [tuple(f) for f in m["faces"]])
        me.update()
        obj = scn.link(sc, bpy.data.objects.new(m["name"], me))
        obj.data.materials.append(_material(f"IL {m['name']}", m["rho"], m["emission"]))
    scn.camera(sc, "Camera", (0.0, -0.98, 1.0), target=(0.0, 1.0, 1.0), lens=14.0)
    return sc


def _material(name, rho, emission):
    mat = materials.empty_material(name)
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


NOTES = {
    "metallic": "metallic reflection treated as diffuse of the same colour",
    "glossy": "glossy BSDFs treated as diffuse of the same colour",
    "specular": "the specular layer of Principled BSDFs ignored (diffuse base colour only)",
    "transmission": "transmission and transparency not modelled (that light is lost)",
    "layers": "coat, sheen and subsurface treated as the diffuse base",
    "texture": "image textures replaced by their mean colour",
}
GEOMETRY = {"CURVE", "SURFACE", "META", "FONT", "CURVES", "POINTCLOUD", "VOLUME", "GPENCIL", "GREASEPENCIL"}


class _Unsupported(InputError):
    pass


def material_rho_emission(mat, notes=None):
    """(ρ RGB, L_e RGB) of a material as Cycles shades its surface, read from the active output's Surface
    link: Emission (Color × Strength; ρ 0), Diffuse BSDF (Color), Principled BSDF (ρ = Base Color × (1 −
    Transmission), L_e = Emission Color × Emission Strength), Add and Mix Shader (constant factor).

    Both sides of a Cycles surface reflect and emit alike (see core.radiosity.patches.back_side_needed). Radiosity is diffuse
    only: what it approximates is added to ``notes`` {kind: {material names}} (see NOTES); what it cannot
    evaluate at all (a factor or colour driven by nodes other than an image texture, node groups, unknown
    shaders) raises InputError naming the material and the socket.
    """
    notes = {} if notes is None else notes
    if mat is None:
        return np.full(3, 0.8), np.zeros(3)          # Cycles' default surface: diffuse grey 0.8
    tree = mat.node_tree if compat.uses_nodes(mat) else None
    if tree is None:
        return np.clip(np.array(mat.diffuse_color[:3], np.float64), 0.0, 0.999), np.zeros(3)
    out = tree.get_output_node("CYCLES")
    if out is None or not out.inputs["Surface"].is_linked:
        return np.zeros(3), np.zeros(3)              # no surface shader: Cycles renders it black
    rho, le = _shader(_source(out.inputs["Surface"]), mat, notes)
    return np.clip(rho, 0.0, 0.999), np.maximum(le, 0.0)


def _source(socket):
    """The node feeding ``socket``, through reroutes (None when not linked)."""
    node = socket.links[0].from_node if socket.is_linked else None
    while node is not None and node.bl_idname == "NodeReroute":
        node = node.inputs[0].links[0].from_node if node.inputs[0].is_linked else None
    return node


def _note(notes, kind, mat):
    notes.setdefault(kind, set()).add(mat.name)


def _shader(node, mat, notes):
    zero = np.zeros(3)
    if node is None:
        return zero, zero
    kind = node.bl_idname
    if kind == "ShaderNodeEmission":
        return zero, _color(node, "Color", mat, notes) * _float(node, "Strength", mat)
    if kind == "ShaderNodeBsdfDiffuse":
        return _color(node, "Color", mat, notes), zero
    if kind == "ShaderNodeBsdfPrincipled":
        return _principled(node, mat, notes)
    if kind == "ShaderNodeAddShader":
        (r1, e1), (r2, e2) = (_shader(_source(node.inputs[i]), mat, notes) for i in (0, 1))
        return r1 + r2, e1 + e2
    if kind == "ShaderNodeMixShader":
        f = _float(node, "Fac", mat)
        (r1, e1), (r2, e2) = (_shader(_source(node.inputs[i]), mat, notes) for i in (1, 2))
        return (1 - f) * r1 + f * r2, (1 - f) * e1 + f * e2
    if kind in ("ShaderNodeBsdfGlossy", "ShaderNodeBsdfAnisotropic", "ShaderNodeBsdfMetallic",
                "ShaderNodeBsdfToon", "ShaderNodeBsdfSheen"):
        _note(notes, "glossy", mat)
        name = "Base Color" if "Base Color" in node.inputs else "Color"
        return _color(node, name, mat, notes), zero
    if kind in ("ShaderNodeBsdfGlass", "ShaderNodeBsdfRefraction", "ShaderNodeBsdfTransparent",
                "ShaderNodeBsdfTranslucent", "ShaderNodeHoldout"):
        _note(notes, "transmission", mat)
        return zero, zero
    if kind == "ShaderNodeSubsurfaceScattering":
        _note(notes, "layers", mat)
        return _color(node, "Color", mat, notes), zero
    raise _Unsupported(f"material '{mat.name}': its surface uses a {node.bl_label} node, which radiosity "
                       f"cannot evaluate (it reads Emission, Diffuse, Principled, Add and Mix Shader)")


def _principled(node, mat, notes):
    def get(name, default=0.0):
        return _float(node, name, mat) if name in node.inputs else default
    base = _color(node, "Base Color", mat, notes)
    metallic, transmission = get("Metallic"), get("Transmission Weight", get("Transmission"))
    if metallic > 0:
        _note(notes, "metallic", mat)
    if transmission > 0 or get("Alpha", 1.0) < 1:
        _note(notes, "transmission", mat)
    ior, level = get("IOR", 1.5), get("Specular IOR Level", 0.5)
    f0 = ((ior - 1) / (ior + 1)) ** 2 * 2 * level
    if f0 > 1e-3 and metallic < 1 and transmission < 1:
        _note(notes, "specular", mat)
    if get("Coat Weight") > 0 or get("Sheen Weight") > 0 or get("Subsurface Weight") > 0:
        _note(notes, "layers", mat)
    rho = base * (1 - transmission) * get("Alpha", 1.0)
    le = np.zeros(3)
    strength = get("Emission Strength")
    if strength > 0:
        le = _color(node, "Emission Color", mat, notes) * strength
    return rho, le


def _float(node, name, mat):
    sock = node.inputs[name]
    src = _source(sock)
    if src is None:
        return float(sock.default_value)
    if src.bl_idname == "ShaderNodeValue":
        return float(src.outputs[0].default_value)
    raise _Unsupported(f"material '{mat.name}': {node.name}.{name} is driven by a {src.bl_label} node, which "
                       f"radiosity cannot evaluate; give it a plain value")


def _color(node, name, mat, notes):
    sock = node.inputs[name]
    src = _source(sock)
    if src is None:
        return np.array(sock.default_value[:3], np.float64)
    if src.bl_idname == "ShaderNodeRGB":
        return np.array(src.outputs[0].default_value[:3], np.float64)
    if src.bl_idname == "ShaderNodeTexImage" and src.image is not None:
        mean = _image_mean(src.image)
        if mean is not None:
            _note(notes, "texture", mat)
            return mean
    raise _Unsupported(f"material '{mat.name}': {node.name}.{name} is driven by a {src.bl_label} node, which "
                       f"radiosity cannot evaluate; give it a plain colour or an image texture")


def _image_mean(image):
    """Mean linear RGB of an image (None when it has no pixels)."""
    try:
        w, h = image.size
        if not w or not h:
            return None
        px = np.empty(w * h * image.channels, np.float32)
        image.pixels.foreach_get(px)
    except (RuntimeError, ValueError):
        return None
    px = px.reshape(-1, image.channels)[:, :3].astype(np.float64)
    if px.shape[1] < 3:
        px = np.repeat(px[:, :1], 3, axis=1)
    if not image.is_float and image.colorspace_settings.name in ("sRGB", "sRGB OETF"):
        px = np.where(px <= 0.04045, px / 12.92, ((px + 0.055) / 1.055) ** 2.4)
    m = px.mean(axis=0)
    return m if np.all(np.isfinite(m)) else None


def approximation_warning(notes):
    """One line for what the materials made approximate ('' when nothing)."""
    parts = [f"{NOTES[k]} ({', '.join(sorted(notes[k]))})" for k in NOTES if notes.get(k)]
    return "radiosity is diffuse only, the result is approximate: " + "; ".join(parts) if parts else ""


def _world_is_black(world):
    if world is None:
        return True
    if world.node_tree is not None and compat.uses_nodes(world):
        out = world.node_tree.get_output_node("CYCLES")
        src = _source(out.inputs["Surface"]) if out is not None else None
        if src is None:
            return True
        if src.bl_idname == "ShaderNodeBackground":
            col, strength = src.inputs["Color"], src.inputs["Strength"]
            if not strength.is_linked and strength.default_value == 0:
                return True
            return not col.is_linked and max(col.default_value[:3]) == 0
        return False
    return max(world.color[:3]) == 0


def meshes_from_scene(scene, objects=None):
    """World-space mesh arrays of the render-visible mesh objects (or ``objects``): evaluated meshes
    (modifiers applied), faces wound as Blender's normals point (mirrored objects included), per-face
    ρ, L_e and material slot. Returns (meshes, objects used).

    What radiosity cannot use is skipped with one warning naming it: curves, text, metaballs and other
    non-mesh geometry, meshes without faces, lamps and the world's light (radiosity counts emissive
    surfaces only; the comparison bake leaves them out too), collection instances. Materials it reads
    approximately give one warning (see :func:`material_rho_emission`); nothing usable left is an InputError.
    """
    vl = scene.view_layers[0]
    deps = vl.depsgraph
    deps.update()
    in_layer = set(vl.objects)
    pool = list(objects) if objects is not None else [o for o in scene.objects if o in in_layer]
    pool = [o for o in pool if not o.hide_render and not any(c.name == COLLECTION for c in o.users_collection)]
    skipped = {"not meshes": [], "no faces": [], "lamps (radiosity counts emissive surfaces only)": [],
               "collection instances (not expanded)": []}
    meshes, used, notes = [], [], {}
    for o in pool:
        if o.type == "LIGHT":
            skipped["lamps (radiosity counts emissive surfaces only)"].append(o.name)
            continue
        if o.type == "EMPTY" and o.instance_type == "COLLECTION" and o.instance_collection is not None:
            skipped["collection instances (not expanded)"].append(o.name)
            continue
        if o.type in GEOMETRY:
            skipped["not meshes"].append(o.name)
            continue
        if o.type != "MESH":
            continue
        ev = o.evaluated_get(deps)
        me = ev.to_mesh()
        try:
            mw = np.array(ev.matrix_world)
            v = np.empty(len(me.vertices) * 3)
            me.vertices.foreach_get("co", v)
            v = v.reshape(-1, 3) @ mw[:3, :3].T + mw[:3, 3]
            mirrored = np.linalg.det(mw[:3, :3]) < 0
            faces = [tuple(p.vertices)[::-1] if mirrored else tuple(p.vertices) for p in me.polygons]
            mi = np.zeros(len(me.polygons), int)
            if len(mi):
                me.polygons.foreach_get("material_index", mi)
        finally:
            ev.to_mesh_clear()
        if not faces:
            skipped["no faces"].append(o.name)
            continue
        slots = [s.material for s in o.material_slots] or [None]
        mi = np.clip(mi, 0, len(slots) - 1)
        try:
            table = [material_rho_emission(m, notes) for m in slots]
        except _Unsupported as e:
            raise InputError(f"{o.name}: {e}") from None
        meshes.append({"name": o.name, "vertices": v, "faces": faces, "material_index": mi,
                       "rho": np.array([table[k][0] for k in mi]), "emission": np.array([table[k][1] for k in mi])})
        used.append(o)
    lost = "; ".join(f"{what}: {', '.join(names)}" for what, names in skipped.items() if names)
    if not meshes:
        raise InputError(f"scene '{scene.name}' has no mesh objects with faces to solve"
                         + (f" (skipped {lost})" if lost else ""))
    if lost:
        warn(f"radiosity skipped {lost}")
    if not _world_is_black(scene.world):
        warn("the world's light is ignored: radiosity counts emissive surfaces only (the comparison bake uses a "
             "black world)")
    line = approximation_warning(notes)
    if line:
        warn(line)
    return meshes, used


def _bvh(patches):
    from mathutils.bvhtree import BVHTree
    corners = patches.corners.reshape(-1, 3)
    polys = [list(range(4 * k, 4 * k + (3 if patches.is_tri[k] else 4))) for k in range(len(patches))]
    return BVHTree.FromPolygons([tuple(c) for c in corners], polys, all_triangles=False, epsilon=0.0)


def _cast(bvh, o, t, offset):
    """True where the segment o -> t (M, 3) is free, ``offset`` short of t."""
    from mathutils import Vector
    d = t - o
    dist = np.linalg.norm(d, axis=1)
    d = d / np.maximum(dist, 1e-300)[:, None]
    lim = dist - offset
    cast = bvh.ray_cast
    return np.fromiter((cast(Vector(a), Vector(b), L)[0] is None
                        for a, b, L in zip(o.tolist(), d.tolist(), lim.tolist())), bool, count=len(o))


def visibility_bvh(patches, offset=1e-4, bvh=None, progress=None):
    """Centre-to-centre visibility (N, N) bool by Blender's BVHTree over the patches: a ray per candidate
    pair, cast a block of rows at a time (bounded memory; Ctrl-C stops between blocks; ``progress(rays cast)``
    before each block)."""
    n = len(patches)
    bvh = bvh or _bvh(patches)
    V = np.zeros((n, n), bool)
    cast = 0
    for i, j in rad_visibility.candidate_pair_blocks(patches):
        if not len(i):
            continue
        interrupt.checkpoint()
        if progress:
            progress(cast)
        cast += len(i)
        vis = _cast(bvh, patches.center[i] + offset * patches.normal[i],
                    patches.center[j] + offset * patches.normal[j], 2 * offset)
        V[i, j] = vis
        V[j, i] = vis
    return V


def visible_bvh(patches, offset=1e-4, bvh=None):
    """The ``visible(points, normals, src)`` callback of core.radiosity.form_factors.seen_form_factors: 1 where the ray from
    the point (lifted ``offset`` along its normal) to the source patch's centre is free."""
    bvh = bvh or _bvh(patches)

    def visible(points, normals, src):
        interrupt.checkpoint()
        return _cast(bvh, points + offset * normals, patches.center[src] + offset * patches.normal[src],
                     2 * offset).astype(float)
    return visible


# ----------------------------------------------------------------------------- the solve


def scene_patches(meshes):
    """Unsplit patches of ``meshes`` with the back sides Cycles would light (core.radiosity.patches.back_side_needed);
    zero-area faces are dropped with a warning."""
    base = rad_patches.patches_from_meshes(meshes, drop_degenerate=True)
    if base.dropped:
        warn(f"radiosity skipped {base.dropped} zero-area faces")
    return rad_patches.with_back_sides(base, rad_patches.back_side_needed(base, rad_patches.open_meshes(meshes)))


# The numpy face test (core.radiosity.visibility.visibility_faces) costs about a pair of patches times the
# faces its cluster bounds leave undecided; a BVH ray about 2-5 µs a pair. Measured on the imported Cornell box
# (its warped red wall blocks as its patches' triangles): 8,479 patches with 523 blocking faces, 2.7 s on two
# threads (16 CPU s before the slab culling) against 100 s of BVH rays. Past this many blocking faces the BVH is
# used.
MAX_OCCLUDERS = 4096
VISIBILITY = ("auto", "faces", "bvh")


def visibility_method(base, patches, method="auto"):
    """("faces", Occluders) or ("bvh", None): how :func:`solve_scene` casts its rays (``method`` "auto" takes the
    faces when at most MAX_OCCLUDERS of them can block a ray between ``patches``)."""
    if method not in VISIBILITY:
        raise InputError(f"visibility must be one of {', '.join(VISIBILITY)}, got {method!r}")
    if method == "bvh":
        return "bvh", None
    occ = rad_visibility.blocking(rad_visibility.occluders(base, patches), patches.center + 1e-4 * patches.normal)
    if method == "auto" and len(occ) > MAX_OCCLUDERS:
        return "bvh", None
    return "faces", occ


def seconds_per_pair(base, max_edge, visibility="auto"):
    """The cost estimate's seconds a patch pair (core.radiosity.cost) for the visibility :func:`visibility_method`
    will pick: the BVH's when the faces that could block (planar faces whole, the others' planned patches as
    two triangles each, an upper bound) exceed MAX_OCCLUDERS."""
    if visibility == "bvh":
        return rad_cost.SECONDS_PER_PAIR_BVH
    whole = rad_visibility.whole_faces(base)
    rest = ~whole & ~base.back
    n = int(whole.sum()) + (2 * int(rad_subdivision.planned_patches(base.take(rest), max_edge)) if rest.any() else 0)
    return rad_cost.SECONDS_PER_PAIR_BVH if visibility == "auto" and n > MAX_OCCLUDERS else rad_cost.SECONDS_PER_PAIR


def _visible(patches, how, bvh=None):
    return rad_visibility.visible_faces(patches, how[1]) if how[0] == "faces" else visible_bvh(patches, bvh=bvh)


class _Notes:
    """Progress lines of one phase (``note``: blender.progress.Progress.note or None): a line when the phase has
    run NOTE_SECONDS and then at most every NOTE_SECONDS; ``always`` lines (a solver's first and last sweep)
    regardless."""

    def __init__(self, note, every=None):
        self.note, self.every = note, NOTE_SECONDS if every is None else every
        self.last = time.perf_counter()

    def __call__(self, message, always=False):
        now = time.perf_counter()
        if self.note is not None and (always or now - self.last >= self.every):
            self.last = now
            self.note(message() if callable(message) else message)
        elif self.note is None:
            interrupt.checkpoint()


NOTE_SECONDS = 2.0
# The face test's cost a pair depends on how well its cluster bounds decide (2.5e-7 s on the boxes, 1.1e-5 s on
# the corpus' public_like.blend with 486 blocking faces round small open meshes); the BVH's varies less: 1.4e-6 s
# a pair on the imported box (8,479 patches, 100 s), 7e-7 s on public_like (1,723 patches, 2.1 s). "auto" times
# the face test's first PROBE_SECONDS and casts with the BVH when the face test would take longer than
# SWITCH_FACTOR times the BVH at BVH_SECONDS_PER_PAIR.
PROBE_SECONDS = 1.5
BVH_SECONDS_PER_PAIR = 1.5e-6
SWITCH_FACTOR = 1.5


class _UseBVH(Exception):
    def __init__(self, faces, bvh):
        super().__init__(faces, bvh)
        self.faces, self.bvh = faces, bvh


class _FaceProbe:
    """``progress(k, m, share)`` of core.radiosity.visibility.visibility_faces: progress lines with the time left,
    and ``projected`` (seconds of the whole face test: its set-up until the first row, then the rows' rate over the
    share of pairs they hold, the rows running in a shuffled order) once the rows have run PROBE_SECONDS. With
    ``switch``, raises :class:`_UseBVH` then when the BVH would be faster (SWITCH_FACTOR)."""

    def __init__(self, n, notes, switch):
        self.n, self.notes, self.switch = n, notes, switch
        self.t0 = time.perf_counter()
        self.first = None
        self.projected = None

    def __call__(self, k, m, done):
        elapsed = time.perf_counter() - self.t0
        if self.first is None:
            self.first = (elapsed, done)
        e1, d1 = self.first
        rate = (elapsed - e1) / (done - d1) if done > d1 else None
        if self.projected is None and rate is not None and (elapsed - e1 >= PROBE_SECONDS or k == m):
            self.projected = e1 + rate * (1.0 - d1)
            bvh = BVH_SECONDS_PER_PAIR * self.n ** 2
            if self.switch and k < m and self.projected - elapsed > SWITCH_FACTOR * bvh:
                raise _UseBVH(self.projected, bvh)
        left = f", about {budget.format_seconds(rate * (1.0 - done))} left" if rate and k < m else ""
        self.notes(f"visibility: {k}/{m} rows of patch clusters, {elapsed:.0f} s{left}")


def _solver_notes(note, solver, n):
    """``progress(iteration, residual)`` of core.radiosity.solvers printing through :class:`_Notes`: the first
    sweep (or block of shots) at once, then at most every NOTE_SECONDS."""
    notes = _Notes(note)
    unit = "shot" if solver == "progressive" else "sweep"

    def progress(k, res):
        notes(lambda: f"{solver} {unit} {k}{f' ({k / max(n, 1):.1f} N)' if unit == 'shot' else ''}: "
                      f"residual {res:.2e}", always=(k == 1 or (unit == "shot" and k <= max(1, n // 10))))
    return progress


def refine_near_emitters(patches, max_edge, memory=None, timings=None, base=None, visibility="bvh"):
    """Split the patches whose direct light from a near emitter varies across them, and grade the patches
    facing a bright bounce (core.radiosity.subdivision.emitter_refine_mask), edges not below max_edge / 2**EMITTER_LEVELS, adding at
    most core.radiosity.subdivision.refine_budget patches (the share of the up-front estimate); past it the largest of the marked
    patches are split first and the rest stay, with a warning; a split that would not fit the memory or the
    time limit is skipped with a warning."""
    t0 = time.perf_counter()
    extra = int(rad_subdivision.refine_budget(patches, len(patches)))
    limit = len(patches) + extra
    for level in range(2 * rad_subdivision.EMITTER_LEVELS):       # edges >= min_edge bound it; grading lags a level
        interrupt.checkpoint()
        how = visibility_method(patches if base is None else base, patches, visibility)
        mask = rad_subdivision.emitter_refine_mask(patches, _visible(patches, how),
                                        min_edge=max_edge / 2 ** rad_subdivision.EMITTER_LEVELS * 1.0001)
        if not mask.any():
            break
        room = int(limit - len(patches)) // 3
        if room < mask.sum():
            marked = np.flatnonzero(mask)
            mask[:] = False
            mask[marked[np.argsort(-patches.area[marked], kind="stable")[:max(room, 0)]]] = True
            warn(f"subdivision near emitters stopped at its budget of {extra} more patches (the share of the "
                 f"up-front estimate; a smaller --max-edge gives it more)")
            if not mask.any():
                break
        n_next = len(patches) + 3 * int(mask.sum())
        mem = memory_budget() if memory is None else memory
        c = rad_cost.solve_cost(n_next)
        if (mem is not None and c.bytes > mem) or c.seconds > rad_cost.MAX_SECONDS:
            warn(f"subdivision near emitters stopped after {level} levels: {n_next} patches would need "
                 f"{budget.format_bytes(c.bytes)} and about {budget.format_seconds(c.seconds)}")
            break
        patches, _ = rad_subdivision.split(patches, mask)
        if room <= mask.sum():
            break
    if timings is not None:
        timings["near_emitters"] = time.perf_counter() - t0
    return patches


def solve_scene(meshes, max_edge=0.25, solver="jacobi", tol=1e-5, adaptive=0, threshold=0.25, progress=None,
                memory=None, visibility="auto", reciprocal=True, compare_solvers=False):
    """Patches -> visibility -> form factors -> solution, with ``adaptive`` refinement rounds.

    ``meshes`` may also be the patches of :func:`scene_patches`. The cost is checked before anything big is
    allocated (core.radiosity.cost.check_cost): a split that does not fit is refused, an adaptive round that would not fit
    is skipped with a warning. The near pairs' F_ij come from their texel-element exchange
    (core.radiosity.gather.NearField, returned as "near_field" for :func:`run`'s texel solution). Returns a dict:
    patches, F, V, solution, H (irradiance of the patch solution), timings, cost (the up-front bound),
    estimate (the same model at the patch count made, before the visibility: :func:`solve_estimate`), near,
    near_field, visibility. ``progress(message)`` (blender.progress.Progress.note) gets the estimate, the solver's
    sweeps and, when they run longer than NOTE_SECONDS, the visibility's and form factors' progress.

    ``visibility``: "faces" tests the rays against the scene's faces in numpy
    (core.radiosity.visibility.visibility_faces), "bvh" casts them with Blender's BVHTree, "auto" the faces
    unless more than MAX_OCCLUDERS can block (the same V either way). ``reciprocal``: the form factors of the
    visible pairs only, each pair once (core.radiosity.form_factors.visible_form_factors); False: every
    ordered pair (core.radiosity.form_factors.form_factors, as before).
    """
    t = {}
    t0, c0 = time.perf_counter(), time.process_time()
    base = meshes if isinstance(meshes, rad_patches.Patches) else scene_patches(meshes)
    per = seconds_per_pair(base, max_edge, visibility)
    cost = rad_cost.check_cost(base, max_edge, memory=memory, seconds_per_pair=per, adaptive=adaptive,
                               solver=solver, compare_solvers=compare_solvers)
    patches = rad_subdivision.subdivide_to_size(base, max_edge)
    if progress:
        progress(f"{len(patches)} patches; subdivision near emitters")
    patches = refine_near_emitters(patches, max_edge, memory, t, base, visibility)
    estimate = solve_estimate(base, max_edge, len(patches), per, solver, adaptive, compare_solvers,
                              time.perf_counter() - t0)
    if progress:
        progress(f"{len(patches)} patches: about {budget.format_seconds(estimate.seconds)} in all (estimate, "
                 f"an upper bound{'' if not compare_solvers else ', with the solver comparison'})")
    for round_ in range(adaptive + 1):
        if progress and round_:
            progress(f"adaptive round {round_}: visibility and form factors of {len(patches)} patches")
        interrupt.checkpoint()
        tv = time.perf_counter()
        how = visibility_method(base, patches, visibility)
        notes = _Notes(progress)
        probe = _FaceProbe(len(patches), notes, switch=visibility == "auto")
        try:
            V = (rad_visibility.visibility_faces(patches, how[1], progress=probe) if how[0] == "faces" else None)
        except _UseBVH as e:
            notes(f"visibility: the face test would take about {budget.format_seconds(e.faces)}, Blender's BVH "
                  f"about {budget.format_seconds(e.bvh)}: casting rays with the BVH", always=True)
            how = ("bvh", None)
            probe.projected = time.perf_counter() - tv + rad_cost.SECONDS_PER_PAIR_BVH * len(patches) ** 2
        if probe.projected is not None and not round_ and probe.projected > per * len(patches) ** 2:
            estimate = rad_cost.Cost(estimate.patches, estimate.bytes,
                                     estimate.seconds + probe.projected - per * len(patches) ** 2)
            if progress:
                progress(f"about {budget.format_seconds(estimate.seconds)} in all (estimate revised on the "
                         f"visibility's timed rows)")
        bvh = _bvh(patches) if how[0] == "bvh" else None
        if bvh is not None:
            V = visibility_bvh(patches, bvh=bvh, progress=lambda k: notes(
                f"visibility: {k:,} rays cast (BVH), {time.perf_counter() - tv:.0f} s"))
        t["visibility"] = t.get("visibility", 0) + time.perf_counter() - tv
        tf = time.perf_counter()
        notes = _Notes(progress)
        F = (rad_form_factors.visible_form_factors(patches, V, dtype=np.float32, progress=lambda k, m: notes(
                 f"form factors: {k}/{m} chunks of visible pairs, {time.perf_counter() - tf:.0f} s"))
             if reciprocal else rad_form_factors.form_factors(patches, V))
        del V
        t["form_factors"] = t.get("form_factors", 0) + time.perf_counter() - tf
        tn = time.perf_counter()
        near = rad_visibility.near_candidate_pairs(patches)
        visible = _visible(patches, how, bvh)
        nf = rad_gather.NearField(patches, *near, CELL, visible, fine=rad_gather.fine_patches(patches, *near, CELL))
        F[near] = nf.patch_form_factors()
        t["near_field"] = t.get("near_field", 0) + time.perf_counter() - tn
        sol = rad_solvers.solve(F, patches.rho, patches.emission, patches.area, solver, tol,
                                progress=_solver_notes(progress, solver, len(patches)))
        if progress:
            progress(f"{solver}: {sol.iterations} {'shots' if solver == 'progressive' else 'sweeps'}, residual "
                     f"{sol.residuals[-1]:.2e}, {sol.seconds:.2f} s")
        t["solve"] = t.get("solve", 0) + sol.seconds
        H = rad_solvers.irradiance(F, sol.B)
        if round_ == adaptive:
            break
        mask = rad_subdivision.refine_mask(patches, H, threshold, min_area=rad_subdivision.adaptive_min_area(max_edge))
        if not mask.any():
            break
        n_next = len(patches) + 3 * int(mask.sum())
        mem = memory_budget() if memory is None else memory
        c = rad_cost.solve_cost(n_next)
        if (mem is not None and c.bytes + rad_cost.BYTES_PER_PAIR * len(patches) ** 2 > mem) \
                or c.seconds > rad_cost.MAX_SECONDS:
            warn(f"adaptive refinement stopped after {round_} rounds: {n_next} patches would need "
                 f"{budget.format_bytes(c.bytes)} and about {budget.format_seconds(c.seconds)}")
            break
        del F
        patches, _ = rad_subdivision.split(patches, mask)
    t["total"] = time.perf_counter() - t0
    t["cpu"] = time.process_time() - c0
    return {"patches": patches, "F": F, "solution": sol, "H": H, "timings": t, "cost": cost, "estimate": estimate,
            "near": near, "near_evals": nf.evaluations, "visible": visible, "near_field": nf, "visibility": how[0]}


def solve_estimate(base, max_edge, n, seconds_per_pair, solver="jacobi", adaptive=0, compare_solvers=False,
                   elapsed=0.0):
    """:class:`core.radiosity.cost.Cost` of a solve made of ``n`` patches (after the subdivision near emitters,
    ``elapsed`` seconds so far) with ``adaptive`` rounds at their worst case (the planned rounds' growth applied
    to ``n``) and, with ``compare_solvers``, the convergence chart's other solvers: an upper bound (calibrated
    within about 2x of the measured time on the Cornell boxes, docs/envmap-radiosity.md)."""
    ns = rad_subdivision.planned_patches_per_round(base, max_edge, adaptive)
    rounds = [n * r / ns[0] for r in ns]
    costs = [rad_cost.solve_cost(m, seconds_per_pair, solver, compare_solvers and i == len(rounds) - 1)
             for i, m in enumerate(rounds)]
    return rad_cost.Cost(rounds[-1], max(c.bytes for c in costs), elapsed + sum(c.seconds for c in costs))


def convergence(F, patches, tol=1e-6, known=None, progress=None):
    """Every solver on the same system: {solver: Solution} (for the convergence chart); ``known`` solutions
    ({solver: Solution} on the same F and tol) are reused; ``progress(message)`` as in :func:`solve_scene`."""
    out = dict(known or {})
    for s in rad_solvers.SOLVERS:
        if s not in out:
            out[s] = rad_solvers.solve(F, patches.rho, patches.emission, patches.area, s, tol,
                                       progress=_solver_notes(progress, s, len(patches)))
    return {s: out[s] for s in rad_solvers.SOLVERS}


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


CELL = 4


def result_objects(scene, patches, H, meshes, cell=CELL, gutter=2, sources=None):
    """One new object per input mesh, built from its front-side patches, in collection "IL Radiosity", hidden
    from rendering (they lie exactly on the originals: renders and bakes of the user's file stay as they
    were; the viewport shows them, and the comparison bake unhides them while it runs): colour
    attribute "IL Radiosity E" (irradiance, smoothed per vertex) and UV layer "IL Radiosity Atlas" (one cell
    per patch), with the source object's materials on the faces they came from (``sources``: the objects
    ``meshes`` were read from, else looked up by name).

    Returns {name: (object, patch indices, atlas)}.
    """
    coll = bpy.data.collections.get(COLLECTION)
    if coll is None:
        coll = bpy.data.collections.new(COLLECTION)
    if coll.name not in scene.collection.children:
        scene.collection.children.link(coll)
    corner_vals, pos, idx = rad_atlas.vertex_average(patches, H)
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
        atlas = rad_atlas.make_atlas(len(sel), cell, gutter)
        atlas_uvs = rad_atlas.atlas_uvs(atlas, patches.is_tri[sel])
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
        obj.hide_render = True       # lying on the original, it would shadow later renders and bakes of it
        coll.objects.link(obj)
        src = sources[k] if sources is not None else scene.objects.get(name)
        if src is not None and src.material_slots:
            for slot in src.material_slots:
                me.materials.append(slot.material)
            mi = np.asarray(meshes[k].get("material_index", np.zeros(len(meshes[k]["faces"]), int)))
            me.polygons.foreach_set("material_index", mi[patches.source[sel]].astype(np.int32))
        out[name] = (obj, sel, atlas)
    return out


def _finite(what, values):
    """Refuse to write non-finite numbers (ILError naming ``what``)."""
    if not np.all(np.isfinite(values)):
        raise ILError(f"{what} is not finite: the solve diverged (check the albedos: they must be below 1)")


def write_lightmaps(out, results, patches, H):
    """``<out>/<object>_radiosity.exr``: R, G, B = irradiance H in W/m² per texel (H (N, cell², 3), the texel
    solution of core.radiosity.gather) or per patch cell (H (N, 3)), A = covered."""
    files = {}
    stems = file_stems(results)
    for name, (obj, sel, atlas) in results.items():
        img = rad_atlas.paint_atlas(atlas, H[sel], patches.is_tri[sel])
        _finite(f"the light map of {name}", img)
        path = os.path.join(out, f"{stems[name]}_radiosity.exr")
        exr.write_exr(path, {"R": img[..., 0], "G": img[..., 1], "B": img[..., 2], "A": img[..., 3]},
                      {"il:quantity": "irradiance E (radiosity solution)", "il:units": "W/m^2",
                       "il:uv_layer": UV, "il:patches": len(sel), "il:blender_version": bpy.app.version_string})
        files[name] = path
    return files


def cycles_patch_irradiance(scene, results, patches, out, samples=64, bounces=32, seed=0, sources=None):
    """The light-map pipeline's Cycles irradiance bake (addon.bake, E = π × DIFFUSE bake, white only at the
    baked point so emitters and every albedo bake right) of every result object into its own patch atlas
    (``sizes``), written to ``out``; returns per-patch means (N, 3) of the texels inside each cell, the texels
    themselves (N, cell², 3; NaN outside a triangle's half) and the seconds it took.

    The result objects carry the scene's materials, so the bounces are the real ones. The bake sees what
    the solve sees: every other renderable object (the originals, lamps, what was skipped) is hidden from
    rendering, the world is black and Cycles' sample clamping is off (Blender clamps indirect light at 10 by
    default, which cuts the light bouncing between a lamp and a ceiling just above it) while it runs; all of it
    is restored afterwards, also on errors and Ctrl-C.
    """
    from ..bake import BakeOptions, bake_lightmaps
    t0 = time.perf_counter()
    objs = [obj for obj, _, _ in results.values()]
    keep = set(objs)
    others = [o for o in scene.objects if o not in keep and not o.hide_render]
    options = BakeOptions(samples=int(samples), bounces=int(bounces), seed=int(seed), margin=0, uv_layer=UV,
                          sizes={obj.name: atlas.size for obj, _, atlas in results.values()},
                          force=True, keep_products=False,      # bake also where a former run's map is unchanged
                          seam_fix=False)      # every patch is a chart: a stitch would blend neighbouring patches
    settings = [(o, "hide_render") for o in others + objs] + world_settings(scene)
    with SavedState(scene, settings=settings) as state:
        for o in others:
            o.hide_render = True
        for o in objs:
            o.hide_render = False
        scene.world = state.track(bpy.data.worlds, scn.black_world("IL radiosity black world"))
        report = bake_lightmaps(objs, ["irradiance"], out, options, scene=scene)
    H = np.full((len(patches), 3), np.nan)
    texels = None
    for obj, sel, atlas in results.values():
        ch, _ = exr.read_exr(report["objects"][obj.name]["irradiance"]["file"])      # row 0 = top
        img = np.stack([ch[c] for c in "RGB"], -1)
        H[sel] = rad_atlas.atlas_means(atlas, img, patches.is_tri[sel])
        if texels is None:
            texels = np.full((len(patches), atlas.cell ** 2, 3), np.nan)
        texels[sel] = rad_atlas.atlas_texels(atlas, img, patches.is_tri[sel])
    return H, texels, time.perf_counter() - t0


def rms(a, b):
    """RMS difference over the rows where both are finite (rows of (..., 3) arrays)."""
    a, b = np.reshape(a, (-1, np.shape(a)[-1])), np.reshape(b, (-1, np.shape(b)[-1]))
    ok = np.isfinite(a).all(axis=1) & np.isfinite(b).all(axis=1)
    return float(np.sqrt(np.mean((a[ok] - b[ok]) ** 2))) if ok.any() else float("nan")


COMPARISONS = {
    "patch": "per patch: the mean over the patch's baked texel centres of the solution's irradiance there (the "
             "texel solution of core.radiosity.gather: the light map's texels) against the mean of Cycles' "
             "texels there: the same points on both sides",
    "texel": "per texel: the light map's texel against Cycles' texel (adds the bake's per-texel noise)",
    "lightmap": "per patch: the patch-average irradiance (area-weighted mean of the patch's texel elements; the "
                "vertex colours) against the mean of Cycles' texels in the patch's cell (differs from 'patch' "
                "where a triangle's diagonal half texels or unequal texel areas weigh in)",
}


def compare_with_cycles(patches, H_texels, Hf, Hc, Hc_texels):
    """The three comparisons of COMPARISONS as a report dict {kind: {"rms", "relative_rms", "meaning"}}
    (relative = RMS / Cycles' mean over the same items) of the front ``patches``' texel solution H_texels
    (N, cell², 3) and patch averages Hf (N, 3), plus the arrays: the solution at the baked texels (N, cell²,
    3, NaN elsewhere) and their per-patch means (N, 3)."""
    _, mask = rad_atlas.texel_points(patches, CELL)
    Hx = np.where(mask[..., None], H_texels, np.nan)
    Hx_mean = np.nanmean(Hx, axis=1)
    out = {}
    for kind, (a, b) in {"patch": (Hx_mean, Hc), "texel": (Hx, Hc_texels), "lightmap": (Hf, Hc)}.items():
        e = rms(a, b)
        bb = np.reshape(b, (-1, 3))
        ref = float(np.mean(bb[np.isfinite(bb).all(axis=1)]))
        out[kind] = {"rms": e, "relative_rms": e / max(ref, 1e-300), "meaning": COMPARISONS[kind]}
    return out, Hx, Hx_mean


def estimate(scene, max_edge, solver=RadiosityOptions.solver, compare_solvers=RadiosityOptions.compare_solvers):
    """(Cost, smallest max_edge that fits the available memory) of a solve of ``scene`` (the panel's
    figures: the same check as :func:`run`'s, at the planned patch count's upper bound). Warnings about the
    scene are not shown."""
    import warnings
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        meshes, _ = meshes_from_scene(scene)
    base = scene_patches(meshes)
    per = seconds_per_pair(base, max_edge)
    cost = rad_cost.solve_cost(rad_subdivision.planned_patches(base, max_edge), per, solver, compare_solvers)
    best = rad_cost.smallest_edge_that_fits(base, memory_budget(), seconds_per_pair=per)
    return cost, best


def run(out, options=None, scene=None, cornell=False, chart=True, memory=None, visibility="auto", reciprocal=True):
    """The whole job of scripts/radiosity.py with ``options`` (lab.options.RadiosityOptions; None: its
    defaults) on ``scene`` (default: the context's) or, with ``cornell``, on a new Cornell box; returns a
    core.result.JobResult (reads as the report written to ``out``; ``arrays`` holds the solve: patches, F,
    solution, H, front, H_front and the comparison's arrays).

    Order: options, output folder, scene, emitters and the cost estimate are all checked before the
    folder is created or anything big is allocated. Only ``solver`` runs unless ``compare_solvers``: then the
    other two run on the same F too (the convergence chart and CSV of all three; the report's "solvers" holds
    the solvers that ran, "solvers_compared" says which case it was). ``chart=False`` skips the convergence
    chart (the UI passes ``charts.available()``: no matplotlib inside Blender); the report's "chart" is then
    None, the CSV table is written either way. Progress lines (blender.progress) name the estimate at the patch
    count made and the solver's sweeps; the report's "estimate" is that estimate, "estimate_up_front" the
    bound checked before anything was allocated. Light maps and vertex colours hold the front side of every face
    (the side its normal points to, what a light-map bake of it measures). ``visibility`` and ``reciprocal``
    as in :func:`solve_scene` (the benchmark's before/after).
    """
    o = (RadiosityOptions() if options is None else options.replace()).validate()
    solver, max_edge, adaptive, samples, tol = o.solver, o.max_edge, o.adaptive, o.samples, o.tol
    compare, compare_solvers = o.compare, o.compare_solvers
    out = check_output_dir(out)
    steps = 4 + bool(compare) + bool(compare_solvers)
    with Progress("radiosity", steps) as p:
        p.step("scene")
        if cornell:
            scene = build_cornell_scene()
        scene = scene or bpy.context.scene
        meshes, used = meshes_from_scene(scene)
        if not any(np.any(m["emission"] > 0) for m in meshes):     # before the costly visibility and solve
            raise InputError(f"nothing in scene '{scene.name}' emits light: radiosity counts only emissive surfaces "
                             "(an Emission shader or Principled emission), not lamps; give a mesh an emissive "
                             "material or build the Cornell box")
        base = scene_patches(meshes)
        rad_cost.check_cost(base, max_edge, memory=memory, seconds_per_pair=seconds_per_pair(base, max_edge, visibility),
                            adaptive=adaptive, solver=solver, compare_solvers=compare_solvers)
        p.step("patches, visibility, form factors, solve")
        r = solve_scene(base, max_edge, solver, tol, adaptive, memory=memory, visibility=visibility,
                        reciprocal=reciprocal, compare_solvers=compare_solvers, progress=p.note)
        patches, F, sol, H = r["patches"], r["F"], r["solution"], r["H"]
        _finite("the radiosity solution", sol.B)
        tg = time.perf_counter()
        g = rad_gather.near_field_gather(patches, F, sol.B, r["near_field"], tol=tol)
        r["timings"]["texel_gather"] = time.perf_counter() - tg
        r["timings"]["total"] += r["timings"]["texel_gather"]
        r["gather"] = g
        H = g.patch_mean()
        _finite("the texel solution", g.B[g.mask])
        sols = {solver: sol}
        if compare_solvers:
            p.step("the other solvers for the convergence chart")
            tc = time.perf_counter()
            sols = convergence(F, patches, tol, known=sols, progress=p.note)
            r["timings"]["compare_solvers"] = time.perf_counter() - tc
        front = ~patches.back
        pf, Hf, Ht = patches.take(front), H[front], g.H[front]
        os.makedirs(out, exist_ok=True)
        if chart:
            chart = convergence_chart(os.path.join(out, "radiosity_convergence.png"), sols, len(patches))
        else:
            chart = None
        charts.write_csv(os.path.join(out, "radiosity_convergence.csv"),
                         [{"solver": s, "iteration": k + 1, "residual": v}
                          for s, so in sols.items() for k, v in enumerate(so.residuals)])
        p.step("vertex colours and light maps")
        results = result_objects(scene, pf, Hf, meshes, sources=used)
        files = write_lightmaps(out, results, pf, Ht)
        report = {"patches": len(patches), "front_patches": int(front.sum()), "back_patches": int((~front).sum()),
                  "solver": solver, "iterations": sol.iterations,
                  "seconds": round(r["timings"]["total"], 4),
                  "timings": {k: round(v, 4) for k, v in r["timings"].items()},
                  "estimate": {"patches": int(r["estimate"].patches), "bytes": int(r["estimate"].bytes),
                               "seconds": round(r["estimate"].seconds, 2),
                               "covers": "seconds + timings.compare_solvers" if compare_solvers else "seconds"},
                  "estimate_up_front": {"patches": int(r["cost"].patches), "bytes": int(r["cost"].bytes),
                                        "seconds": round(r["cost"].seconds, 2)},
                  "rms_vs_cycles": None, "scene": scene.name, "chart": chart,
                  "solvers": {s: {"iterations": so.iterations, "seconds": round(so.seconds, 5),
                                  "converged": so.converged} for s, so in sols.items()},
                  "solvers_compared": bool(compare_solvers), "visibility": r["visibility"],
                  "objects": {n: {"lightmap": f, "object": results[n][0].name, "patches": int(len(results[n][1]))}
                              for n, f in files.items()},
                  "units": "irradiance W/m^2"}
        if compare:
            p.step(f"Cycles irradiance bake ({samples} samples)")
            Hc, Hct, secs = cycles_patch_irradiance(scene, results, pf, os.path.join(out, "cycles_bake"), samples,
                                                    sources=used)
            ok = np.isfinite(Hc).all(axis=1)
            if not ok.any():
                raise ILError("the Cycles comparison bake covered no patch")
            cmp, Hx, Hx_mean = compare_with_cycles(pf, Ht, Hf, Hc, Hct)
            report["comparison"] = cmp
            report["rms_vs_cycles"] = cmp["patch"]["rms"]                # the "patch" comparison (like with like)
            report["relative_rms_vs_cycles"] = cmp["patch"]["relative_rms"]
            r["cycles_texels"], r["H_texels"], r["H_points"] = Hct, Hx, Hx_mean
            report["mean_irradiance"] = {"radiosity": float(np.mean(Hf[ok])), "cycles": float(np.mean(Hc[ok]))}
            report["near_field"] = {"pairs": int(len(r["near"][0])), "evaluations": int(r["near_evals"]),
                                    "fine_patches": int(r["near_field"].fine.sum()),
                                    "texel_iterations": int(g.iterations)}
            report["cycles_seconds"] = round(secs, 4)
            report["cycles_samples"] = int(samples)
            report["cycles_maps"] = os.path.join(out, "cycles_bake")
            _finite("the comparison with Cycles", [report["rms_vs_cycles"], report["relative_rms_vs_cycles"]])
            r["cycles"] = Hc
    write_json(os.path.join(out, REPORT), report)
    r["front"] = front
    r["H_front"] = Hf
    r["results"] = results
    extra = "" if report["rms_vs_cycles"] is None else \
        f", {100 * report['relative_rms_vs_cycles']:.1f} % relative RMS against Cycles"
    return JobResult(report, os.path.join(out, REPORT),
                     f"{report['patches']} patches, {report['iterations']} iterations{extra}", arrays=r)
