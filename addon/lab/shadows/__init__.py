"""The shadow lab: every method's mask on the ray-traced reference's pixel grid, scored and written.

    report = compare(scene, "Light", out, ShadowOptions(methods=["raytraced", "shadowmap", "volume_zfail"]))

writes ``<out>/<method>_mask.png`` (white lit, black shadow), ``<out>/<method>_error.png`` (greys
agree, red false shadow, blue false light; see core.shadow.metrics.COLOURS) and
``<out>/shadows_report.json`` (DESIGN.md). The bench (lab/bench/shadows.py) and the demo
(lab/demo/job.py) call it.
"""
import dataclasses
import os
import time

import numpy as np

from ...core import choices
from ...core.io import png
from ...core.shadow import metrics
from ...core.shadow import volume as shadow_volume
from ...core.shadow import depth_map
from ...core.shadow import planar as shadow_planar
from ...core.errors import ILError, InputError, warn
from ...core.io.files import write_json
from ...core.result import JobResult
from ...blender.progress import Progress
from ...blender import scene as sc
from ..options import SHADOW_METHOD_CHOICES, ShadowOptions
from . import scenes
from .frame import ShadowFrame

METHODS = tuple(m[0] for m in SHADOW_METHOD_CHOICES)
#: The shadow map's depth by default: "raster" (numpy, the casters' triangles) or "cycles" (Depth pass).
DEPTH_SOURCE = "raster"


def parse_methods(methods):
    """"a,b" or ["a", "b"] -> validated list of shadow methods in the given order (duplicates dropped)."""
    return choices.parse_choices(methods, METHODS, "shadow method")


def check_params(params):
    """``params`` (None: the default) over lab.options.ShadowOptions, validated; returned as a dict."""
    o = ShadowOptions(**{k: v for k, v in params.items() if v is not None and k != "methods"}).validate()
    return dataclasses.asdict(o)


def _validated(options):
    """A validated copy of ``options`` (lab.options.ShadowOptions; None: its defaults)."""
    return (ShadowOptions() if options is None else options.replace()).validate()


def check_cost(frame, methods, p):
    """core.shadow.depth_map.check_cost for the frame's size and, with "shadowmap", its maps from
    ``p["depth_source"]``."""
    faces = 6 if frame.light.kind == "POINT" else 1
    depth_map.check_cost(frame.width, frame.height, p["shadowmap_size"] if "shadowmap" in methods else None,
                          faces, p["depth_source"])


class MethodSkipped(InputError):
    """A method that cannot run on this scene (e.g. shadow volumes without a closed caster): the comparison
    goes on without it and reports why under "skipped"."""


def _drawn_instances(scene):
    """Yield the depsgraph instances of every mesh the view layer draws, objects and instances alike (collection
    instances of collections outside the scene, geometry-nodes instances); objects or instancers hidden for
    render are left out."""
    if not scene.view_layers:
        return
    depsgraph = scene.view_layers[0].depsgraph
    depsgraph.update()
    for inst in depsgraph.object_instances:
        ob = inst.object
        if ob.type != "MESH" or not inst.show_self or ob.original.hide_render:
            continue
        if inst.is_instance and inst.parent and inst.parent.original.hide_render:
            continue
        yield inst


def _drawn_meshes(scene):
    """Yield (original object's name, world vertices, evaluated mesh, matrix) of each of _drawn_instances."""
    for inst in _drawn_instances(scene):
        ob = inst.object
        me = ob.data
        if len(me.polygons) == 0:
            continue
        m = np.array(inst.matrix_world, np.float64)
        if abs(np.linalg.det(m[:3, :3])) < 1e-30:
            continue
        co = np.empty(len(me.vertices) * 3)
        me.vertices.foreach_get("co", co)
        yield ob.original.name, co.reshape(-1, 3) @ m[:3, :3].T + m[:3, 3], me, m


def flat_meshes(scene):
    """[(name, area)] of the meshes the render draws, instances included, whose vertices lie on one plane
    (core.shadow.planar's PLANAR_TOLERANCE of their size), largest area first: the receivers planar shadows can
    be drawn on. An object drawn several times is named once, with its largest copy."""
    found = {}
    for name, v, me, m in _drawn_meshes(scene):
        areas = np.empty(len(me.polygons))
        me.polygons.foreach_get("area", areas)
        normals = np.empty(len(me.polygons) * 3)
        me.polygons.foreach_get("normal", normals)
        big = int(np.argmax(areas))
        centers = np.empty(len(me.polygons) * 3)
        me.polygons.foreach_get("center", centers)
        point = m[:3, :3] @ centers.reshape(-1, 3)[big] + m[:3, 3]
        normal = np.linalg.inv(m[:3, :3]).T @ normals.reshape(-1, 3)[big]
        if not np.any(normal):
            continue
        plane = shadow_planar.plane_from_point_normal(point, normal)
        distance, extent = shadow_planar.off_plane(v, plane)
        if distance <= shadow_planar.PLANAR_TOLERANCE * extent:
            area = float(areas.sum() * abs(np.linalg.det(m[:3, :3])) ** (2 / 3))
            found[name] = max(area, found.get(name, 0.0))
    return sorted(found.items(), key=lambda f: -f[1])


def resolve_receiver(scene, receiver=None):
    """The planar receiver's name, checked before any render: ``receiver`` when given (InputError naming the
    flat meshes when the render draws no mesh of that name), else the scene's "il_shadow_receiver", else
    "Floor", else the largest flat mesh (with a warning); InputError when the scene has none. A mesh drawn only
    through a collection or geometry-nodes instance counts."""
    named = receiver or scene.get("il_shadow_receiver")
    name = named or "Floor"
    if name in scene.objects and scene.objects[name].type == "MESH":
        return name
    if any(inst.object.original.name == name for inst in _drawn_instances(scene)):
        return name
    flats = flat_meshes(scene)
    if named or not flats:
        listed = ", ".join(f"'{n}'" for n, _ in flats[:8]) or "none in this scene"
        raise InputError(f"no mesh named '{name}' to receive planar shadows: name a flat receiver with the "
                         f"Receiver field or --receiver (flat meshes: {listed})")
    warn(f"no receiver named: planar shadows use '{flats[0][0]}', the largest flat mesh"
         + (f" (others: {', '.join(n for n, _ in flats[1:4])})" if len(flats) > 1 else ""))
    return flats[0][0]


# -- methods ------------------------------------------------------------------------------------
def _planar(s, p):
    """Each drawn copy of the receiver (the object, or its instances) is a plane; the shadows of every caster
    triangle not lying on that plane are drawn on it, and the copies' masks are joined."""
    name = resolve_receiver(s.user_scene, p["receiver"])
    copies = s.surfaces_named(name)
    if not copies:
        raise InputError(f"the receiver '{name}' has no faces the render sees (hidden for render, or no faces)")
    cover = np.zeros(s.reach.shape, bool)
    planes, off = [], 0.0
    for surface in copies:
        tri = surface.verts[surface.tris]
        n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        big = int(np.argmax(np.linalg.norm(n, axis=1)))
        plane = shadow_planar.plane_from_point_normal(tri[big, 0], n[big])
        distance, extent = shadow_planar.off_plane(surface.verts, plane)
        if distance > shadow_planar.PLANAR_TOLERANCE * extent:
            warn(f"the receiver '{surface.name}' is not planar: its vertices lie up to {distance:.3g} m off the "
                 f"plane of its largest face (size {extent:.3g} m); planar shadows are drawn on that plane only")
        tris = s.caster_triangles(exclude=surface)
        on_plane = np.abs(tris @ plane[:3] + plane[3]).max(axis=1) <= shadow_planar.PLANAR_TOLERANCE * max(extent, 1e-9)
        cover |= shadow_planar.planar_shadow_mask(tris[~on_plane], plane, s.light.h, s.world_to_view, s.proj,
                                                  s.width, s.height, s.depth, offset=p["offset"])
        planes.append([round(float(x), 6) for x in plane])
        off = max(off, distance)
    return s.reach & ~cover, {"receiver": name, "offset": p["offset"], "plane": planes[0],
                              "copies": len(copies), "off_plane": round(off, 6)}


def shadowmap_mask(s, maps, p):
    """Lit mask from depth maps with the bias and PCF of ``p``; returns (mask, lookup seconds)."""
    t = time.perf_counter()
    r = s.receiver
    lit = np.zeros(r.shape)
    lit[r] = depth_map.lit_fraction(maps, s.position[r], s.normal[r], s.to_light[r],
                                     p["bias"], p["slope_bias"], p["pcf"])
    return s.reach & (lit >= 0.5), time.perf_counter() - t


def _shadowmap(s, p):
    source = p.get("depth_source", DEPTH_SOURCE)
    maps, render_s = s.depth_maps(p["shadowmap_size"], source)
    mask, lookup_s = shadowmap_mask(s, maps, p)
    kind = {"SUN": "orthographic", "SPOT": "perspective", "POINT": "cube (6 faces)"}[s.light.kind]
    return mask, {"size": p["shadowmap_size"], "bias": p["bias"], "slope_bias": p["slope_bias"], "pcf": p["pcf"],
                  "projection": kind, "depth_source": source, "render_seconds": render_s, "lookup_seconds": lookup_s}


def volume_inputs(s):
    """Closed surfaces' volume triangles (every object and instance that casts, ShadowFrame.surfaces); open meshes
    are skipped (documented fallback) and listed once by name."""
    vols, skipped, tris, sil = [], [], 0, 0
    _, radius = s._scene_radius()
    distance = 1e3 * max(1.0, radius)
    for x in s.surfaces:
        if not x.casts:
            continue
        if not shadow_volume.is_closed(x.tris):
            skipped.append(x.name)
            continue
        vt, ns = shadow_volume.volume_triangles(x.verts, x.tris, s.light.h, distance, x.name)
        vols.append(vt)
        tris += len(x.tris)
        sil += ns
    skipped = list(dict.fromkeys(skipped))
    if not vols:
        raise MethodSkipped("shadow volumes need at least one closed mesh; open meshes found: " + ", ".join(skipped))
    return np.concatenate(vols), {"occluder_triangles": tris, "silhouette_edges": sil,
                                  "volume_triangles": int(sum(len(x) for x in vols)), "skipped_open_meshes": skipped}


def volume_mask(s, volume, mode):
    """Lit mask from the stencil count of ``volume`` along the camera rays: lit where count = 0
    (and the light reaches the surface at all); ``mode`` "zpass" or "zfail" (core.shadow.volume)."""
    tau = shadow_volume.surface_distance(s.position, s.origins, s.dirs)
    count = shadow_volume.stencil(volume, s.origins, s.dirs, tau, s.world_to_view, s.proj,
                                  s.width, s.height, s.near, s.receiver, mode)
    return s.reach & (count == 0)


def _volume(mode):
    def run(s, p):
        volume, info = volume_inputs(s)
        return volume_mask(s, volume, mode), dict(info, mode=mode)
    return run


def _engine(name):
    def run(s, p):
        mask, _ = s.engine_mask(name)
        return mask, {"engine": name}
    return run


_RUN = {"planar": _planar, "shadowmap": _shadowmap, "volume_zpass": _volume("zpass"),
        "volume_zfail": _volume("zfail"), "eevee": _engine("eevee"), "workbench": _engine("workbench")}


def run_method(s, method, p):
    """(mask, seconds, params) of one method in an open :class:`ShadowFrame` with its reference rendered."""
    if method == "raytraced":
        return s.reference, s.reference_seconds, {"samples": s.samples, "engine": "cycles", "light_radius": 0.0}
    t = time.perf_counter()
    mask, info = _RUN[method](s, p)
    return mask, time.perf_counter() - t, info


# -- the comparison ---------------------------------------------------------------------------------
def compare(scene, light, out, options=None, depth_source=DEPTH_SOURCE):
    """Run ``options`` (lab.options.ShadowOptions: the methods and their settings; None: its defaults) on
    ``scene`` lit by the light named ``light``; write images and the report to ``out``; return it (a
    core.result.JobResult). ``depth_source`` is where the shadow map's depth comes from
    (core.shadow.depth_map.DEPTH_SOURCES).

    Everything is computed before the first file is written (an error or Ctrl-C leaves no partial set);
    the output folder is made only then. A reference with no lit or no shadowed receiver pixel scores
    nothing: it is reported with ``"meaningful": false`` and a warning.
    """
    o = _validated(options)
    methods, p = o.methods, dataclasses.asdict(o)
    p["depth_source"] = depth_map.check_source(depth_source)
    report = {"scene": scene.name, "light": light, "reference": {}, "methods": {}}
    images = {}
    frame = ShadowFrame(scene, light, p["resolution"], p["samples"])
    check_cost(frame, methods, p)
    if "planar" in methods:
        p["receiver"] = resolve_receiver(scene, p["receiver"])
    with Progress("shadows", len(methods) + 1) as progress, frame as s:
        progress.step("ray-traced reference (Cycles, radius-0 light)")
        s.reference_seconds = s.render_reference()
        if not s.receiver.any():
            raise ILError(f"the camera of scene '{scene.name}' sees no geometry")
        lit = int(s.reference[s.receiver].sum())
        shadowed = int(s.receiver.sum()) - lit
        report["reference"] = {"engine": "cycles", "samples": s.samples, "seconds": s.reference_seconds,
                               "resolution": [s.width, s.height], "light_type": s.light.kind.lower(),
                               "receiver_pixels": int(s.receiver.sum()), "lit_pixels": lit,
                               "shadowed_fraction": float(1 - s.reference[s.receiver].mean()),
                               "mask": os.path.join(out, "raytraced_mask.png")}
        report["meaningful"] = bool(lit and shadowed)
        if not report["meaningful"]:
            warn(f"the reference is {'all shadow' if not lit else 'all lit'} on the {s.receiver.sum()} pixels the "
                 f"camera sees: every method's score is meaningless (aim '{light}' at the objects, or move them)")
        if s.skipped:
            warn(f"not triangulated for the planar, volume and shadow-map methods: {', '.join(s.skipped)} (Cycles "
                 "still renders them in the reference, and in the shadow map with depth source cycles)")
        images["raytraced_mask.png"] = metrics.mask_image(s.reference)
        for m in methods:
            progress.step(m)
            try:
                mask, seconds, info = run_method(s, m, p)
            except MethodSkipped as e:
                warn(f"{m} skipped: {e}")
                report.setdefault("skipped", {})[m] = str(e)
                continue
            entry = metrics.confusion(mask, s.reference, s.receiver)
            entry.update(seconds=seconds, params=info,
                         mask=os.path.join(out, f"{m}_mask.png"), error_image=os.path.join(out, f"{m}_error.png"))
            images[f"{m}_mask.png"] = metrics.mask_image(mask)
            images[f"{m}_error.png"] = metrics.error_image(mask, s.reference, s.receiver)
            report["methods"][m] = entry
    if report.get("skipped") and not set(report["methods"]) - {"raytraced"}:
        raise InputError("; ".join(report["skipped"].values()))
    report["report"] = os.path.join(out, "shadows_report.json")
    os.makedirs(out, exist_ok=True)
    for name, pixels in images.items():
        png.write_png(os.path.join(out, name), pixels)
    write_json(report["report"], report)
    return JobResult(report, report["report"], "  ".join(
        f"{m} {e['error']:.2%}" for m, e in report["methods"].items() if m != "raytraced"))


def compare_builtin(name, light_kind, out, options=None, keep=False, depth_source=DEPTH_SOURCE):
    """Build the built-in scene ``name`` with a ``light_kind`` light (square frame of ``options.resolution``),
    :func:`compare` with ``options``, remove the scene unless ``keep``."""
    o = _validated(options)
    depth_map.check_cost(o.resolution, o.resolution, o.shadowmap_size if "shadowmap" in o.methods else None,
                          6 if light_kind == "point" else 1, depth_source)
    scene = scenes.build(name, light_kind, (o.resolution, o.resolution))
    try:
        return compare(scene, scene["il_shadow_light"], out, o, depth_source)
    finally:
        if not keep:
            sc.remove_scene(scene)
