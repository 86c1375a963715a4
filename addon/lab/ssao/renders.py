"""SSAO lab, the renders: G-buffer, Cycles' AO reference (cached), EEVEE's AO pass, Workbench's cavity.

1. G-buffer: Cycles at 1 sample with a pixel filter of 0.01 px (no jitter):
   Depth, Normal, Position passes + alpha -> core.ssao.GBuffer via
   render.camera_matrices.
2. Reference: Cycles' AO pass (cosine-weighted rays of length = World AO
   distance = radius) at ``reference_samples`` per pixel, same filter; cached
   under ``cache_dir`` by a key of the scene's content and the parameters.
3. EEVEE's AO pass; Workbench's world-space cavity (flat white, so the image is the cavity factor).

Every render changes the scene's settings: run them inside :func:`preserved`, which puts them back
(also after an error).
"""
import contextlib
import hashlib
import os
import time

import bpy
import numpy as np

from ...blender import compat
from ...core import camera as core_camera
from ...core.ssao import gbuffer as ssao_gbuffer
from ...core.errors import ILError
from ...core.io.files import atomic_path
from ...blender.state import SavedState, world_settings
from ...blender import materials, render

#: Bumped when the reference render changes meaning (invalidates caches).
REFERENCE_VERSION = 1
#: Pixel filter width of every lab render (pixels): effectively no jitter.
FILTER_WIDTH = 0.01


def frame_size(scene, resolution=None):
    """(width, height) the lab renders ``scene`` at: ``resolution`` wide keeping the aspect, else the scene's."""
    r = scene.render
    if resolution is None:
        return (max(1, r.resolution_x * r.resolution_percentage // 100),
                max(1, r.resolution_y * r.resolution_percentage // 100))
    return int(resolution), max(1, int(round(resolution * r.resolution_y / r.resolution_x)))


# ---------------------------------------------------------------- scene state

def _state_items(scene):
    """(owner, attribute) of every render, pass, display and world setting the lab changes."""
    r, vl, d = scene.render, scene.view_layers[0], scene.display
    items = render.settings(scene) + [(r, "resolution_x"), (r, "resolution_y"), (r, "resolution_percentage"),
                                      (r, "film_transparent"), (scene.cycles, "max_bounces")]
    items += render.output_settings(scene)
    items += [(vl, a) for a in ("use_pass_z", "use_pass_normal", "use_pass_position",
                                "use_pass_ambient_occlusion")]
    items.append(compat.eevee_ao_distance_owner(scene, vl))
    items += [(d.shading, a) for a in ("light", "color_type", "single_color", "show_cavity", "cavity_type",
                                       "cavity_valley_factor", "cavity_ridge_factor")]
    items += [(d, a) for a in ("matcap_ssao_distance", "matcap_ssao_samples", "matcap_ssao_attenuation",
                               "render_aa")]
    return items + world_settings(scene)


@contextlib.contextmanager
def preserved(scene):
    """Every setting the lab touches put back on exit (blender.state.SavedState); a world while it runs when
    the scene has none, removed afterwards."""
    with SavedState(scene, settings=_state_items(scene)) as state:
        state.world(lambda: bpy.data.worlds.new(f"{scene.name} SSAO World"))
        yield scene


def set_resolution(scene, resolution):
    """Width = ``resolution`` (height keeps the scene's aspect ratio), 100 %."""
    if resolution is None:
        return
    r = scene.render
    aspect = r.resolution_y / r.resolution_x
    r.resolution_x = int(resolution)
    r.resolution_y = max(1, int(round(resolution * aspect)))
    r.resolution_percentage = 100


def _cycles(scene, samples):
    """Cycles on the CPU, ``samples`` per pixel, seed 0, every sample through the pixel centre, no sky."""
    render.cycles_cpu(scene, samples, seed=0, pixel_filter=FILTER_WIDTH)
    scene.render.film_transparent = True


def _passes(scene, z=False, normal=False, position=False, ao=False):
    vl = scene.view_layers[0]
    vl.use_pass_z, vl.use_pass_normal, vl.use_pass_position, vl.use_pass_ambient_occlusion = z, normal, position, ao


# ---------------------------------------------------------------- renders

def render_gbuffer(scene):
    """Depth, normal, position at 1 sample, no jitter -> ``(GBuffer, world positions (H, W, 3), seconds)``."""
    t0 = time.perf_counter()
    _cycles(scene, 1)
    scene.cycles.max_bounces = 0
    _passes(scene, z=True, normal=True, position=True)
    w2v, proj, _, _ = render.camera_matrices(scene)
    p = render.render_layers(scene)
    mask = (p["Combined"][..., 3] > 0.5) & (p["Depth"] < 0.5 * core_camera.SKY_DEPTH)
    gb = ssao_gbuffer.gbuffer_from_passes(p["Position"][..., :3], p["Normal"][..., :3], mask, w2v, proj)
    world = np.where(gb.mask[..., None], p["Position"][..., :3], np.nan)
    return gb, world, time.perf_counter() - t0


def scene_key(scene, radius, samples):
    """Cache key of the reference: the geometry Cycles would render (each visible object's name, type,
    evaluated transform, every modifier setting and the evaluated mesh), the camera, the resolution,
    AO distance, samples, Blender version and REFERENCE_VERSION.

    The evaluated mesh is the viewport's; the modifier settings add what differs in a render
    (render levels, show_render)."""
    h = hashlib.sha256()
    h.update(repr((REFERENCE_VERSION, bpy.app.version, float(radius), int(samples), FILTER_WIDTH,
                   scene.render.resolution_x, scene.render.resolution_y,
                   scene.render.resolution_percentage)).encode())
    view_layer = scene.view_layers[0]
    view_layer.update()
    depsgraph = view_layer.depsgraph
    for obj in sorted(scene.objects, key=lambda o: o.name):
        if obj.hide_render:
            continue
        ev = obj.evaluated_get(depsgraph)
        h.update(repr((obj.name, obj.type, [tuple(r) for r in ev.matrix_world],
                       [_settings(m) for m in getattr(obj, "modifiers", ())])).encode())
        if obj.type in {"MESH", "CURVE", "SURFACE", "META", "FONT"}:
            h.update(_mesh_bytes(ev))
    cam = scene.camera
    data = cam.data
    h.update(repr((cam.name, [tuple(r) for r in cam.matrix_world], data.type, data.lens, data.sensor_width,
                   data.sensor_fit, data.ortho_scale, data.shift_x, data.shift_y,
                   data.clip_start, data.clip_end)).encode())
    return h.hexdigest()[:20]


def _settings(struct):
    """Every plain RNA property of ``struct`` (a modifier) as a tuple; ID pointers by name."""
    values = []
    for prop in struct.bl_rna.properties:
        if prop.identifier == "rna_type" or prop.type == "COLLECTION":
            continue
        value = getattr(struct, prop.identifier, None)
        if prop.type == "POINTER":
            value = getattr(value, "name", None)
        elif hasattr(value, "__len__") and not isinstance(value, str):
            value = tuple(value)
        values.append((prop.identifier, value))
    return tuple(values)


def _mesh_bytes(evaluated):
    """Vertex positions and face corners of an evaluated object's mesh (b"" when it has none)."""
    me = evaluated.to_mesh()
    try:
        if me is None:
            return b""
        co = np.empty(len(me.vertices) * 3, np.float32)
        me.vertices.foreach_get("co", co)
        idx = np.empty(len(me.loops), np.int32)
        me.loops.foreach_get("vertex_index", idx)
        return co.tobytes() + idx.tobytes()
    finally:
        evaluated.to_mesh_clear()


def render_reference(scene, radius, samples, cache_dir=None, progress=None):
    """Cycles AO pass with AO distance = ``radius`` -> dict(k, alpha, samples, seconds, cached, key).

    The pass is the cosine-weighted fraction of unblocked rays (REFERENCE.md §1),
    one AO ray per sample at the first hit; noise per pixel √(k(1-k)/N).
    """
    key = scene_key(scene, radius, samples)
    path = os.path.join(cache_dir, f"ssao_reference_{key}.npz") if cache_dir else None
    cached = _read_cache(path) if path else None
    if cached is not None:
        return dict(cached, cached=True, key=key)
    t0 = time.perf_counter()
    _cycles(scene, samples)
    scene.cycles.max_bounces = 0
    scene.world.light_settings.distance = radius
    _passes(scene, ao=True)
    with _geometry_only(scene):
        p = render.render_layers(scene)
    if compat.AO_PASS not in p:
        raise ILError("Cycles returned no ambient occlusion pass")
    k = p[compat.AO_PASS][..., 0].astype(np.float32)
    alpha = p["Combined"][..., 3].astype(np.float32)
    seconds = time.perf_counter() - t0
    if path:
        with atomic_path(path) as tmp:
            with open(tmp, "wb") as f:
                np.savez_compressed(f, k=k, alpha=alpha, samples=samples, seconds=seconds)
    return {"k": k, "alpha": alpha, "samples": int(samples), "seconds": seconds, "cached": False, "key": key}


@contextlib.contextmanager
def _geometry_only(scene):
    """While the reference renders: when no object Cycles renders has a material (every surface is Cycles'
    default one, as in the built-in scenes), a view-layer override with no closure (materials.no_closure), so
    that no BSDF or light is sampled. The AO pass and alpha are the same bit for bit (measured on every
    built-in scene, 64² at 256 samples and the corner at 128² and 1024) in about half the time; a scene with
    materials (displacement, transparency, bump) renders as it is."""
    vl = scene.view_layers[0]
    if vl.material_override is not None or any(
            slot.material is not None for obj in scene.objects if not obj.hide_render
            for slot in getattr(obj, "material_slots", ())):
        yield
        return
    mat = materials.no_closure("IL SSAO geometry only")
    vl.material_override = mat
    try:
        yield
    finally:
        vl.material_override = None
        bpy.data.materials.remove(mat)


def _read_cache(path):
    """A cached reference, or None when the entry is missing or unreadable (a damaged entry is a miss
    and is replaced by the next write)."""
    if not os.path.exists(path):
        return None
    try:
        with np.load(path) as f:
            k, alpha = np.asarray(f["k"], np.float32), np.asarray(f["alpha"], np.float32)
            entry = {"k": k, "alpha": alpha, "samples": int(f["samples"]), "seconds": float(f["seconds"])}
    except Exception:  # noqa: BLE001 - a truncated zip, a missing key, garbage: all mean "not cached"
        return None
    if k.ndim != 2 or k.shape != alpha.shape or not np.isfinite(k).all():
        return None
    return entry


def render_eevee(scene, radius, samples=16):
    """EEVEE's AO pass (horizon scan, distance = radius) -> (k_A image, seconds, params)."""
    t0 = time.perf_counter()
    render.eevee(scene, samples, pixel_filter=0.0)
    scene.render.film_transparent = True
    compat.set_eevee_ao_distance(scene, scene.view_layers[0], radius)
    _passes(scene, ao=True)
    p = render.render_layers(scene)
    if compat.AO_PASS not in p:
        raise ILError("EEVEE returned no ambient occlusion pass")
    k = np.clip(p[compat.AO_PASS][..., 0], 0.0, 1.0).astype(np.float32)
    return k, time.perf_counter() - t0, {"radius": float(radius), "taa_render_samples": int(samples)}


def render_workbench(scene, radius, samples=16):
    """Workbench world-space cavity (Alchemy-style SSAO) on flat white: Combined = cavity factor."""
    t0 = time.perf_counter()
    r, d = scene.render, scene.display
    r.engine = compat.WORKBENCH
    r.film_transparent = True
    sh = d.shading
    sh.light, sh.color_type, sh.single_color = "FLAT", "SINGLE", (1.0, 1.0, 1.0)
    sh.show_cavity, sh.cavity_type = True, "WORLD"
    sh.cavity_valley_factor, sh.cavity_ridge_factor = 1.0, 0.0
    d.matcap_ssao_distance, d.matcap_ssao_samples, d.matcap_ssao_attenuation = radius, int(samples), 1.0
    d.render_aa = "OFF"
    _passes(scene)
    p = render.render_layers(scene)
    k = np.clip(p["Combined"][..., 0], 0.0, 1.0).astype(np.float32)
    return k, time.perf_counter() - t0, {"radius": float(radius), "samples": int(samples),
                                         "cavity_type": "WORLD", "valley": 1.0, "ridge": 0.0}
