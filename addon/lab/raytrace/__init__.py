"""Ray-tracing lab: ray casting and Whitted ray tracing (core.raytrace) of the scene camera, pixel-aligned with
Cycles, and what Whitted leaves out.

``run(scene, out, options)`` writes ``<out>/<method>.exr`` (RGB radiance, the scene camera at the options'
resolution, pixel centres as Cycles renders them with a 0.01-pixel filter) and ``<out>/raytrace_report.json``.
With ``compare`` it renders the same camera with Cycles twice (two seeds) with the light paths Whitted
computes -- diffuse bounces 0, glossy and transmission bounces = max_depth (0 for ray casting) -- and once with
the scene's own bounces: ``rmse_vs_cycles`` is against the first (their seed difference gives Cycles' noise),
``missing`` against the second (``missing.exr`` = Cycles - Whitted: interreflection, area lights, sky light).
The user's settings are put back (blender.state.SavedState); nothing is written outside ``out``.
"""
import os
import time

import numpy as np

from ...blender import render
from ...blender.progress import Progress
from ...blender.state import SavedState
from ...core import camera as cam
from ...core.errors import InputError
from ...core.io import exr
from ...core.io.files import write_json
from ...core.raytrace import trace
from ...core.result import JobResult
from ..options import RaytraceOptions
from . import engines, read as reader, scenes

#: Pixel filter width of the Cycles renders: every sample through the pixel centre, like the primary rays.
FILTER_WIDTH = 0.01
BOUNCES = ("max_bounces", "diffuse_bounces", "glossy_bounces", "transmission_bounces", "transparent_max_bounces",
           "volume_bounces", "blur_glossy")


def _settings(scene):
    r = scene.render
    return (render.settings(scene) + [(r, "resolution_x"), (r, "resolution_y"), (r, "resolution_percentage"),
                                      (r, "film_transparent"), (scene.cycles, "film_exposure")]
            + [(scene.cycles, k) for k in BOUNCES if hasattr(scene.cycles, k)])


def _write(out, name, rgb):
    path = os.path.join(out, name)
    exr.write_exr(path, {"R": rgb[..., 0].astype(np.float32), "G": rgb[..., 1].astype(np.float32),
                         "B": rgb[..., 2].astype(np.float32)})
    return path


def _cycles(scene, samples, seed, depth=None):
    """Cycles' Combined RGB (H, W, 3) and seconds; ``depth`` None keeps the scene's bounces, else Whitted's paths."""
    render.cycles_cpu(scene, samples, seed=seed, pixel_filter=FILTER_WIDTH, clamp=0.0)
    cy = scene.cycles
    if depth is not None:
        cy.max_bounces = cy.glossy_bounces = cy.transmission_bounces = cy.transparent_max_bounces = depth
        cy.diffuse_bounces = cy.volume_bounces = 0
        cy.blur_glossy = 0.0
    t = time.perf_counter()
    p = render.render_layers(scene)
    return np.asarray(p["Combined"][..., :3], np.float64), time.perf_counter() - t


#: Share of pixels left out of ``rmse_vs_cycles_99``: silhouettes and shadow edges of faceted meshes, where a
#: pixel-centre hit or shadow ray lands a few micrometres apart in the two tracers.
EDGE_FRACTION = 0.01


def _rmse(a, b):
    return float(np.sqrt(np.mean((a - b) ** 2)))


def trimmed_rmse(a, b, fraction=EDGE_FRACTION):
    """RMSE over all but the ``fraction`` of pixels with the largest squared error (RGB mean per pixel)."""
    e = np.sort(((a - b) ** 2).mean(-1).ravel())
    return float(np.sqrt(e[:len(e) - int(np.ceil(fraction * len(e)))].mean()))


def run(scene, out, options=None, label=None):
    """Render ``scene``'s camera with the options' method; compare with Cycles; JobResult of the report."""
    o = (options or RaytraceOptions()).validate()
    if scene.camera is None:
        raise InputError(f"scene '{scene.name}' has no camera")
    os.makedirs(out, exist_ok=True)
    steps = 2 + (4 if o.compare else 0)
    with Progress("Ray tracing", steps) as prog, SavedState(scene, settings=_settings(scene)):
        r = scene.render
        rx, ry = r.resolution_x * r.pixel_aspect_x, r.resolution_y * r.pixel_aspect_y
        r.resolution_x, r.resolution_y = o.resolution, max(1, round(o.resolution * ry / rx))
        r.resolution_percentage = 100
        r.film_transparent = False
        scene.cycles.film_exposure = 1.0
        prog.step("reading the scene")
        rt, notes = reader.read(scene, engines.ENGINES[o.engine])
        w2v, proj, width, height = render.camera_matrices(scene)
        origins, dirs = cam.pixel_rays(w2v, proj, width, height)
        prog.step(f"{o.method}, depth {o.max_depth}, {width}x{height}, {len(rt.tris)} triangles")
        image, stats = trace(rt, origins.reshape(-1, 3), dirs.reshape(-1, 3), o.method, o.max_depth,
                             progress=prog.note)
        image = image.reshape(height, width, 3)
        _write(out, f"{o.method}.exr", image)
        report = {"method": o.method, "max_depth": o.max_depth, "rays": stats.rays, "seconds": stats.seconds,
                  "rays_per_second": stats.rays / max(stats.seconds, 1e-9), "rmse_vs_cycles": None,
                  "relative_rmse_vs_cycles": None, "scene": label or scene.name, "resolution": [width, height],
                  "triangles": int(len(rt.tris)), "engine": o.engine, "ray_counts": stats.as_dict(), "left_out": notes}
        if o.compare:
            depth = 0 if o.method == "raycast" else o.max_depth
            prog.step("Cycles, the scene's own bounces")
            full, tf = _cycles(scene, o.samples, 0, None)
            prog.step(f"Cycles, Whitted's light paths (depth {depth}), seed 0")
            a, ta = _cycles(scene, o.samples, 0, depth)
            prog.step("Cycles, seed 1")
            b, _ = _cycles(scene, o.samples, 1, depth)
            prog.step("engines: numpy BVH and mathutils BVHTree")
            ref = (a + b) / 2
            noise = _rmse(a, b) / 2                     # RMS noise of the two-seed mean
            _write(out, "cycles.exr", ref)
            _write(out, "cycles_full.exr", full)
            _write(out, "missing.exr", full - image)
            mean = float(ref.mean())
            report["rmse_vs_cycles"] = _rmse(image, ref)
            report["relative_rmse_vs_cycles"] = report["rmse_vs_cycles"] / mean if mean > 0 else None
            report["rmse_vs_cycles_99"] = trimmed_rmse(image, ref)
            paths = width * height * o.samples
            report["cycles"] = {
                "samples": o.samples, "seconds": ta, "bounces": depth, "noise_rmse": noise,
                "paths_per_second": paths / ta,
                "rays_per_second_estimate": paths / ta * stats.rays / stats.primary,
                "note": "paths_per_second: camera samples per second; the estimate assumes Cycles traces as many "
                        "rays per camera sample as Whitted per primary ray"}
            total = float(full.sum())
            report["missing"] = {"image": "missing.exr", "rmse": _rmse(image, full),
                                 "fraction": float(1 - image.sum() / total) if total > 0 else 0.0,
                                 "cycles_seconds": tf}
            report["engines"] = engines.compare(rt, origins.reshape(-1, 3), dirs.reshape(-1, 3))
    path = os.path.join(out, "raytrace_report.json")
    write_json(path, report)
    summary = (f"{o.method} depth {o.max_depth}: {stats.rays} rays in {stats.seconds:.2f} s"
               + (f", RMSE vs Cycles {report['rmse_vs_cycles']:.4g}" if o.compare else ""))
    return JobResult(report, path, summary, {"image": image})


def run_builtin(name, out, options=None):
    """:func:`run` on a new built-in scene (options' resolution), removed afterwards."""
    o = (options or RaytraceOptions()).validate()
    scene = scenes.build(name, (o.resolution, o.resolution))
    try:
        return run(scene, out, o, label=name)
    finally:
        scenes.remove(scene)

