"""Reflection lab (seed 002 "Reflection mapping"; issue 29): lat-long, cube and sphere maps against Cycles'
ray-traced mirror on the same pixels.

The map methods are computed in numpy from the reference render's passes, not by rendering the assigned
material: per mirror pixel, r = 2 (n·v) n − v from the camera ray (core.camera.pixel_rays, v = −ray) and
Cycles' shading normal (Normal pass), looked up bilinearly (core.envmap.maps.sample) in the map of that
type. The maps come from one capture at the capture point (default: the mirror's centre): a panoramic
equirectangular Cycles render of 2H x 4H texel centres without the mirror, box-filtered to the H x 2H
lat-long map and converted to a cube strip and a sphere map of as many texels (core.envmap.maps.convert).
The same lookup is what "IL Environment Map" does in a material (tests/nodes/test_environment_mapping.py:
equal to Cycles' mirror to float precision on a convex object under a world image).

Error over the mirror's pixels (Object Index pass): RMSE of the RGB radiance, and relative RMSE = RMSE /
mean reference radiance there.
"""
import os
import time

import bpy
import numpy as np

from ...core.envmap import latlong, maps
from ...core.errors import InputError
from ...core.io import exr
from ...core.io.files import check_output_dir, write_json
from ...core.result import JobResult
from ...blender.progress import Progress
from ..options import ReflectionOptions
from .frame import BOUNCES, ReflectionFrame
from . import scenes

REPORT = "reflections_report.json"
MAP_OF = {"latlong": "LATLONG", "cube": "CUBE", "sphere": "SPHERE"}


def _mirror(scene, name):
    name = name or "Mirror"
    obj = scene.objects.get(name)
    if obj is None:
        meshes = [o.name for o in scene.objects if o.type == "MESH"][:8]
        raise InputError(f"no object '{name}' in scene '{scene.name}': name the mirror mesh with --object "
                         f"(meshes: {', '.join(meshes) or 'none'})")
    return obj


def _errors(img, ref, mask):
    diff = (img - ref)[mask]
    rmse = float(np.sqrt(np.mean(diff ** 2))) if diff.size else 0.0
    mean = float(np.mean(ref[mask])) if mask.any() else 0.0
    return rmse, (rmse / mean if mean > 0 else 0.0)


def _contrast(img, ref, mask):
    """Standard deviation of the radiance over the mirror against the reference's (1: as varied; a flat
    mirror of "almost one colour" reads well below 1)."""
    sd = float(np.std(ref[mask].mean(-1)))
    return round(float(np.std(img[mask].mean(-1))) / sd, 6) if sd > 0 else 1.0


def _write(path, img, method):
    exr.write_exr(path, {c: img[..., k].astype(np.float32) for k, c in enumerate("RGB")},
                  {"il:quantity": "radiance", "il:method": method, "il:blender_version": bpy.app.version_string})


def measure(scene, options=None, capture_point=None):
    """Reference, capture and every method's image on the mirror's pixels; returns (report dict, {method:
    image}). Nothing is written."""
    o = (options or ReflectionOptions()).validate()
    from ...nodes.environment import world_environment_node
    world_environment_node(scene)                     # refuse early, naming what is missing
    obj = _mirror(scene, o.object)
    h = int(o.map_size)
    images, methods = {}, {}
    captured = any(m in MAP_OF for m in o.methods)
    with Progress("reflections", 1 + captured + len(o.methods)) as prog, \
            ReflectionFrame(scene, obj, o.resolution, o.samples) as f:
        prog.step(f"Cycles' mirror on '{obj.name}', {o.samples} sample(s)")
        ref, ref_s = f.reference()
        if not f.mask.any():
            raise InputError(f"the camera of scene '{scene.name}' does not see '{obj.name}'")
        point = np.array(obj.matrix_world.translation if capture_point is None else capture_point, np.float64)
        if captured:
            prog.step(f"capture at {', '.join(f'{c:.2f}' for c in point)}, {4 * h}x{2 * h}")
        cap, cap_s = (f.capture(point, 2 * h) if captured else (None, 0.0))
        v = -f.dirs
        r = 2.0 * np.einsum("...i,...i->...", f.normal, v)[..., None] * f.normal - v
        for m in o.methods:
            prog.step(m)
            t = time.perf_counter()
            if m == "raytraced":
                img, params = ref, {"samples": o.samples, "bounces": BOUNCES}
                seconds = ref_s
            else:
                proj = MAP_OF[m]
                base = latlong.downsample_latlong(cap, 2)
                image = base if proj == "LATLONG" else maps.convert(cap, proj, maps.equal_texel_size(proj, h))
                img = ref.copy()
                img[f.mask] = maps.sample(image, proj, r[f.mask])
                size = h if proj == "LATLONG" else maps.equal_texel_size(proj, h)
                seconds = time.perf_counter() - t
                params = {"map": proj.lower(), "size": size, "texels": maps.texel_count(proj, size),
                          "contrast": _contrast(img, ref, f.mask),
                          "capture_point": [round(float(c), 6) for c in point], "capture_seconds": round(cap_s, 4)}
            rmse, rel = _errors(img, ref, f.mask)
            images[m] = img
            methods[m] = {"rmse": rmse, "relative_rmse": rel, "seconds": round(seconds, 6), "params": params}
        report = {"reference": {"method": "cycles glossy roughness 0", "samples": o.samples, "seconds": round(ref_s, 4),
                                "object": obj.name, "pixels": int(f.mask.sum()),
                                "resolution": [f.width, f.height],
                                "mean_radiance": float(np.mean(ref[f.mask]))},
                  "methods": methods}
    return report, images


def compare(scene, out, options=None, capture_point=None):
    """:func:`measure`, then ``<out>/<method>.exr`` and ``<out>/reflections_report.json``; a JobResult."""
    out = os.path.abspath(out)
    check_output_dir(out)
    report, images = measure(scene, options, capture_point)
    os.makedirs(out, exist_ok=True)
    for m, img in images.items():
        _write(os.path.join(out, f"{m}.exr"), img, m)
    path = os.path.join(out, REPORT)
    write_json(path, report)
    summary = ", ".join(f"{m} {e['relative_rmse']:.3f}" for m, e in report["methods"].items())
    return JobResult(report, path=path, summary=f"relative RMSE: {summary}")


def run_builtin(name, out, options=None, distances=(0.0, 0.15, 0.3, 0.6, 1.2)):
    """A built-in scene (scenes.SCENES) compared, then removed. "nearby" also moves the capture point up from
    the mirror's centre by each of ``distances`` (metres; same pixels, same reference) and adds
    "distance_sweep": [{"distance", METHOD: relative_rmse}]."""
    o = (options or ReflectionOptions()).validate()
    o = o.replace(object=o.object or "Mirror")
    sc = scenes.build(name, o.resolution)
    try:
        result = compare(sc, out, o, capture_point=scenes.CAPTURE)
        if name == "nearby":
            sweep = []
            maps_only = o.replace(methods=[m for m in o.methods if m in MAP_OF] or ["latlong"])
            for d in distances:
                rep, _ = measure(sc, maps_only, capture_point=np.add(scenes.CAPTURE, (0.0, 0.0, float(d))))
                sweep.append({"distance": float(d), **{m: e["relative_rmse"] for m, e in rep["methods"].items()}})
            result.report["distance_sweep"] = sweep
        result.report["scene"] = name
        write_json(result.path, result.report)
        return result
    finally:
        _remove(sc)


def _remove(sc):
    """Remove a built-in scene with its objects, materials, world and sky image."""
    from ...blender import scene as S
    mats = list({s.material for o in sc.objects for s in o.material_slots if s.material is not None})
    images = [n.image for n in sc.world.node_tree.nodes if getattr(n, "image", None) is not None] if sc.world else []
    S.remove_scene(sc, mats)
    for im in images:
        if im.users == 0:
            bpy.data.images.remove(im)
