"""SSAO lab, the comparison: the methods against Cycles' ray-traced AO on the same camera and pixels.

``compare(scene, out, options)`` (lab.options.SSAOOptions) renders the G-buffer and the reference
(lab/ssao/renders.py), runs the methods (the numpy ones of core.ssao on the G-buffer, EEVEE, Workbench)
and writes ``<method>_ao.exr`` / ``reference_ao.exr`` ("Y" = k_A, "A" = 1 on geometry),
``<method>_error.png`` and ``ssao_report.json``. The scene's settings come back afterwards, also after an error.
"""
import os

import bpy
import numpy as np

from ...core import choices
from ...core.ssao import figures
from ...core.ssao import gbuffer as ssao_gbuffer
from ...core.ssao import limits as ssao_limits
from ...core.ssao import methods as ssao_methods
from ...core.ssao import metrics
from ...core.io import png
from ...core.io import exr
from ...core.errors import ILError, InputError
from ...core.io.files import write_json
from ...core.result import JobResult
from ...blender.progress import Progress
from ...blender import scene as sc
from ..options import SSAOOptions
from . import scenes
from .renders import (FILTER_WIDTH, frame_size, preserved, render_eevee, render_gbuffer, render_reference,
                      render_workbench, set_resolution)

#: How a radius that was not given is chosen (the report's "radius_rule").
RADIUS_RULE = (f"default: {ssao_gbuffer.DEFAULT_RADIUS_FRACTION:g} x the frame width at the median depth "
               f"of the visible geometry")


def parse_methods(methods):
    """``"a,b"`` or a list -> validated list of SSAO methods, in the given order, no duplicates."""
    return choices.parse_choices(methods, ssao_methods.ALL_METHODS, "SSAO method")


def check_cost(scene, methods, samples, reference_samples, resolution=None):
    """core.ssao.check_cost for ``scene``'s frame: refused before anything is rendered."""
    w, h = frame_size(scene, resolution)
    ssao_limits.check_cost(w, h, samples, reference_samples, sum(m in ssao_methods.METHODS for m in methods))


# ---------------------------------------------------------------- files

def write_ao(path, k_a, mask, method, samples, radius):
    """``<method>_ao.exr``: "Y" = k_A (1 on sky), "A" = 1 on geometry pixels."""
    exr.write_exr(path, {"Y": np.where(mask, k_a, 1.0), "A": mask.astype(np.float32)},
                  {"il:quantity": "ambient occlusion k_A (1 = open)", "il:units": "1", "il:method": method,
                   "il:samples": samples, "il:ao_distance": radius,
                   "il:blender_version": bpy.app.version_string})


def _write_images(out, name, k_a, reference, mask):
    png.write_png(os.path.join(out, f"{name}_ao.png"), png.to_uint8(figures.ao_grey(k_a, mask)))
    if reference is not None:
        png.write_png(os.path.join(out, f"{name}_error.png"),
                          png.to_uint8(figures.error_rgb(k_a, reference, mask)))


# ---------------------------------------------------------------- the comparison

def run_methods(gb, methods, samples, radius, blur=False, seed=0, scene=None, params=None):
    """Run ``methods`` on one frame -> {method: (k_A image, seconds, params)}. EEVEE/Workbench need ``scene``."""
    out = {}
    for m in methods:
        if m in ssao_methods.METHODS:
            out[m] = ssao_methods.run_method(m, gb, radius, samples, blur=blur, seed=seed, **(params or {}).get(m, {}))
        elif m == "eevee":
            out[m] = render_eevee(scene, radius, samples)
        else:
            out[m] = render_workbench(scene, radius, samples)
    return out


def compare(scene, out=None, options=None, cache_dir=None, method_params=None):
    """Run the comparison ``options`` (lab.options.SSAOOptions; None: its defaults) on ``scene`` (its camera);
    write files to ``out`` (if given; the reference is cached in ``cache_dir``, default ``<out>/cache``);
    return a core.result.JobResult (reads as the report; ``path`` is ssao_report.json when ``out`` is given).
    ``options.resolution`` None keeps the scene's frame. ``options.radius`` None: SSAOOptions.BUILTIN_RADIUS
    on a built-in scene, else :func:`core.ssao.gbuffer.default_radius` of the G-buffer, said on stderr and
    in the report's "radius" and "radius_rule". ``method_params``: {method: extra keyword arguments}.

    Report (DESIGN.md): {"reference": {"samples", "seconds", ...}, "methods": {m: {"rmse", "bias",
    "mean", "seconds", "params"}}} over geometry pixels (G-buffer mask) only.
    """
    o = (SSAOOptions() if options is None else options.replace()).validate()
    methods, samples, radius, reference_samples = o.methods, o.samples, o.radius, o.reference_samples
    if scene.camera is None:
        raise InputError(f"scene '{scene.name}' has no camera")
    check_cost(scene, methods, samples, reference_samples, o.resolution)
    if out is not None and cache_dir is None:
        cache_dir = os.path.join(out, "cache")
    steps = 2 + len(methods)
    with Progress("ssao", steps) as progress, preserved(scene):
        set_resolution(scene, o.resolution)
        progress.step("G-buffer (depth, normal, position at 1 sample)")
        gb, world, gb_seconds = render_gbuffer(scene)
        if not gb.mask.any():
            raise ILError(f"the camera of scene '{scene.name}' sees no geometry")
        rule = "given"
        if radius is None and scene.get("il_ssao_scene"):
            radius = SSAOOptions.BUILTIN_RADIUS
            rule = f"default of the built-in scenes: {radius:g} m"
        elif radius is None:
            radius, rule = ssao_gbuffer.default_radius(gb), RADIUS_RULE
        if rule != "given":
            progress.note(f"radius {radius:.4g} m ({rule}; --radius to choose)")
        progress.step(f"reference: Cycles AO pass, {reference_samples} samples")
        ref = render_reference(scene, radius, reference_samples, cache_dir)
        mask = gb.mask
        results = {}
        for m in methods:
            progress.step(m)
            results.update(run_methods(gb, [m], samples, radius, o.blur, o.seed, scene, method_params))
    noise = metrics.reference_noise(ref["k"], ref["samples"], mask)
    report = {
        "scene": scene.get("il_ssao_scene", scene.name),
        "resolution": [gb.width, gb.height],
        "radius": float(radius), "radius_rule": rule, "samples": int(samples), "blur": bool(o.blur),
        "geometry_pixels": int(mask.sum()),
        "gbuffer": {"seconds": gb_seconds, "samples": 1, "filter_width": FILTER_WIDTH},
        "reference": {"samples": ref["samples"], "seconds": ref["seconds"], "cached": ref["cached"],
                      "ao_distance": float(radius), "noise_rms": noise,
                      "noise_max": 0.5 / float(np.sqrt(ref["samples"])), "cache_key": ref["key"],
                      "mean": float(np.mean(ref["k"][mask]))},
        "methods": {},
    }
    for m, (k, seconds, params) in results.items():
        e = metrics.error_metrics(k, ref["k"], mask)
        report["methods"][m] = {"rmse": e["rmse"], "bias": e["bias"], "mean": e["mean"], "seconds": seconds,
                                "params": params}
    if report["scene"] == "corner":
        closed = scenes.corner_closed_form(world, radius)
        ok = np.isfinite(closed) & mask
        if ok.any():
            report["reference"]["closed_form"] = metrics.error_metrics(ref["k"], closed, ok)
    if out is not None:
        os.makedirs(out, exist_ok=True)
        write_ao(os.path.join(out, "reference_ao.exr"), ref["k"], mask, "reference", ref["samples"], radius)
        _write_images(out, "reference", ref["k"], None, mask)
        for m, (k, _, _) in results.items():
            write_ao(os.path.join(out, f"{m}_ao.exr"), k, mask, m, samples, radius)
            _write_images(out, m, k, ref["k"], mask)
            report["methods"][m]["file"] = f"{m}_ao.exr"
            report["methods"][m]["error_image"] = f"{m}_error.png"
        report["reference"]["file"] = "reference_ao.exr"
        write_json(os.path.join(out, "ssao_report.json"), report)
    return JobResult(report, os.path.join(out, "ssao_report.json") if out is not None else None,
                     "; ".join(summary_lines(report)), arrays={m: r[0] for m, r in results.items()})


def frame(scene, radius, reference_samples, resolution=None, cache_dir=None):
    """G-buffer and reference of ``scene`` (settings restored) -> (GBuffer, world positions, reference dict)."""
    SSAOOptions(samples=1, radius=radius, reference_samples=reference_samples, resolution=resolution).validate()
    check_cost(scene, [], 1, reference_samples, resolution)
    with preserved(scene):
        set_resolution(scene, resolution)
        gb, world, _ = render_gbuffer(scene)
        ref = render_reference(scene, radius, reference_samples, cache_dir)
    return gb, world, ref


def blender_method(scene, method, radius, samples, resolution=None):
    """EEVEE or Workbench on ``scene`` (settings restored) -> (k_A image, seconds, params)."""
    with preserved(scene):
        set_resolution(scene, resolution)
        return (render_eevee if method == "eevee" else render_workbench)(scene, radius, samples)


def run_builtin(name, out=None, options=None, cache_dir=None):
    """Build the built-in scene ``name`` at ``options.resolution`` (SSAOOptions; None: its defaults; a
    resolution of None: the default one), :func:`compare`, remove the scene again; return the report."""
    ssao_limits.check_scene(name)
    o = (SSAOOptions() if options is None else options.replace()).validate()
    if o.resolution is None:
        o.resolution = SSAOOptions.resolution
    scene = scenes.build_scene(name, o.resolution, o.radius or SSAOOptions.BUILTIN_RADIUS)
    try:
        return compare(scene, out, o, cache_dir)
    finally:
        sc.remove_scene(scene)


def summary_lines(report):
    """One line for the reference (samples, noise, seconds) and one per method (RMSE, bias, seconds)."""
    ref = report["reference"]
    lines = [f"radius: {report['radius']:.4g} m ({report.get('radius_rule', 'given')})",
             f"reference: {ref['samples']} samples, noise {ref['noise_rms']:.4f} rms, "
             f"{ref['seconds']:.2f} s{' (cached)' if ref['cached'] else ''}"]
    for m, r in report["methods"].items():
        lines.append(f"{m:>10}: RMSE {r['rmse']:.4f}  bias {r['bias']:+.4f}  {r['seconds']:.3f} s")
    return lines
