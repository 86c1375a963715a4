"""The demo end to end (the README's main job): one step per tool, each timed, one report."""
import os
import time

import bpy
import numpy as np

from ...bake.options import BakeOptions
from ...bake.pipeline import bake_lightmaps
from ...core.io import exr
from ...core.io import png as io_png
from ...core.ssao import methods as ssao_methods
from ...core.errors import InputError
from ...core.io.files import write_json
from ...core.result import JobResult
from ...nodes import groups, material
from ...blender.progress import Progress
from ...blender import render
from .. import shadows, ssao as ssao_lab
from ..options import RaytraceOptions, ReflectionOptions, ShadowOptions, SSAOOptions
from .. import report as lab_report
from . import scene as demo


def _render(scene, out, quick, samples):
    render.cycles_cpu(scene, samples=8 if quick else samples)
    passes = render.render_layers(scene)
    rgb = passes["Combined"][..., :3]
    path = os.path.join(out, "demo_render.exr")
    exr.write_exr(path, {"R": rgb[..., 0], "G": rgb[..., 1], "B": rgb[..., 2]},
                  {"il:quantity": "radiance", "il:units": "W/(m^2 sr)",
                   "il:samples": scene.cycles.samples, "il:blender_version": bpy.app.version_string})
    io_png.write_png(os.path.join(out, "demo_render.png"), io_png.to_uint8(io_png.tonemap(rgb)))
    return {"samples": scene.cycles.samples, "mean_radiance": float(np.mean(rgb)),
            "files": [path, os.path.join(out, "demo_render.png")]}


DEMO_MODELS = {"Box": ("PHONG", {"Kd": (0.8, 0.3, 0.2), "Ks": 0.5, "Shininess": 40.0}),
               "Torus": ("OREN_NAYAR", {"Albedo": (0.3, 0.6, 0.8), "Sigma": 0.6}),
               "Sphere": ("COOK_TORRANCE", {"Kd": (0.1, 0.1, 0.1), "F0": 0.9, "Roughness": 0.25})}
LIGHTMAP_OBJECTS = ("Floor", "Box", "Sphere", "Torus")


def shading_step(scene):
    """Shade the demo scene: Phong on "Box", Oren-Nayar on "Torus", Cook-Torrance on "Sphere".

    Returns figures for the demo report: {"seconds", "materials": {object: material}, "lights", "warnings"}.
    """
    t = time.perf_counter()
    groups.add_node_groups()
    mats, warnings = {}, []
    for obj_name, (model, params) in DEMO_MODELS.items():
        obj = demo.get(scene, obj_name)
        mat, w = material.assign_shading_model(scene, [obj], model, params=params,
                                               name=f"IL {material.MODEL_LABELS[model]} ({obj.name})")
        mats[obj.name] = mat.name
        warnings += w
    lights = [o.name for o in material.scene_lights(scene)]
    return {"seconds": time.perf_counter() - t, "materials": mats, "lights": lights, "warnings": warnings,
            "models": {k: v[0] for k, v in DEMO_MODELS.items()}}


def lightmaps_step(scene, output_dir, quick=False):
    """Bake AO and irradiance maps of Floor, Box, Sphere and Torus of the demo ``scene`` into ``output_dir``.

    Returns figures for the demo report: {"seconds", "resolution", "samples", "maps":
    {object: {map: {file, seconds, estimated_error, mean}}}, "files": [...]}.
    """
    objects = [demo.get(scene, n) for n in LIGHTMAP_OBJECTS]
    res, samples = (32, 8) if quick else (256, 64)
    t = time.perf_counter()
    report = bake_lightmaps(objects, ["ao", "irradiance"], output_dir,
                            BakeOptions(resolution=res, samples=samples, bounces=2, overwrite=True), scene=scene)
    maps, files = {}, []
    for name, entries in report["objects"].items():
        for kind, e in entries.items():
            ch, _ = exr.read_exr(e["file"])
            cov = ch["A"] > 0
            v = ch["Y"] if kind == "ao" else (ch["R"] + ch["G"] + ch["B"]) / 3.0
            maps.setdefault(name, {})[kind] = {
                "file": e["file"], "seconds": e["seconds"], "estimated_error": e["estimated_error"],
                "mean": float(v[cov].mean()) if cov.any() else None,
                "units": "1" if kind == "ao" else "W/m^2"}
            files += [e["file"], e["preview"]]
    files.append(report.path)
    return {"seconds": time.perf_counter() - t, "resolution": res, "samples": samples, "maps": maps, "files": files}


def shadows_step(output_dir, quick=True):
    """The shadow step: the sphere scene under a sun, a few methods; returns figures for the demo report."""
    methods = ["raytraced", "planar", "shadowmap", "volume_zpass", "volume_zfail"]
    rep = shadows.compare_builtin("sphere", "sun", os.path.join(output_dir, "shadows"), ShadowOptions(
        methods=methods, resolution=96 if quick else 256, shadowmap_size=512 if quick else 2048))
    return {"report": rep.path, "files": [rep.path],
            "methods": {m: {"error": e["error"], "seconds": e["seconds"]} for m, e in rep["methods"].items()}}


def ssao_step(output_dir, quick=False):
    """The SSAO step: corner scene, the numpy methods against the reference, files in ``output_dir``.

    Returns {"report": path of ssao_report.json, "figures": {method: {"rmse", "bias", "seconds"}},
    "reference": {...}, "lines": [summary lines]}.
    """
    options = SSAOOptions(methods=list(ssao_methods.METHODS), resolution=64 if quick else 128,
                          radius=SSAOOptions.BUILTIN_RADIUS, reference_samples=256 if quick else 1024)
    report = ssao_lab.run_builtin("corner", output_dir, options)
    path = report.path
    return {"report": path, "files": [path],
            "figures": {m: {k: r[k] for k in ("rmse", "bias", "seconds")} for m, r in report["methods"].items()},
            "reference": {k: report["reference"][k] for k in ("samples", "seconds", "noise_rms")},
            "lines": ssao_lab.summary_lines(report)}


def reflections_step(output_dir, quick=False):
    """The reflection step: the "nearby" scene's mirror sphere, lat-long, cube and sphere maps against Cycles'
    mirror, the capture point moved away; returns figures for the demo report."""
    from .. import reflections
    rep = reflections.run_builtin("nearby", output_dir, ReflectionOptions(
        resolution=48 if quick else 128, map_size=16 if quick else 64))
    return {"report": rep.path, "files": [rep.path],
            "methods": {m: {"relative_rmse": e["relative_rmse"], "seconds": e["seconds"]}
                        for m, e in rep["methods"].items()},
            "distance_sweep": rep["distance_sweep"]}


def raytrace_step(output_dir, quick=False):
    """The ray-tracing step: Whitted on the glass sphere against Cycles on the same light paths; returns
    figures for the demo report."""
    from .. import raytrace
    rep = raytrace.run_builtin("glass", output_dir, RaytraceOptions(
        method="whitted", max_depth=4, resolution=32 if quick else 96, samples=4 if quick else 16))
    return {"report": rep.path, "files": [rep.path],
            **{k: rep[k] for k in ("rays", "seconds", "rays_per_second", "relative_rmse_vs_cycles")},
            "cycles_noise_rmse": rep["cycles"]["noise_rmse"], "rmse_vs_cycles": rep["rmse_vs_cycles"]}


def _report(output_dir):
    result = lab_report.run(os.path.join(output_dir, "report"), quick=True)
    return {"report": result["report"], "files": [result["report"]],
            "stability_rows": len(result["stability"])}


def run(out, quick=False, samples=32):
    """Build the demo scene, run every tool on it, write ``out/demo_report.json`` (per step its figures, wall
    ``seconds`` and ``cpu_seconds`` of every thread of this process; the load average at the end); return a
    core.result.JobResult whose summary is one line per step."""
    if samples <= 0:
        raise InputError(f"--samples must be positive, got {samples}")
    os.makedirs(out, exist_ok=True)
    steps = [
        ("shading", "assign Phong, Oren-Nayar and Cook-Torrance", shading_step),
        ("render", "render the shaded scene", lambda s: _render(s, out, quick, samples)),
        ("lightmaps", "bake AO and irradiance maps", lambda s: lightmaps_step(s, os.path.join(out, "lightmaps"), quick)),
        ("shadows", "compare shadow methods with ray-traced shadows", lambda s: shadows_step(out, quick)),
        ("ssao", "compare screen-space AO with ray-traced AO", lambda s: ssao_step(os.path.join(out, "ssao"), quick)),
        ("reflections", "compare reflection maps with Cycles' mirror",
         lambda s: reflections_step(os.path.join(out, "reflections"), quick)),
        ("raytrace", "Whitted ray tracing against Cycles", lambda s: raytrace_step(os.path.join(out, "raytrace"), quick)),
    ]
    if not quick:
        steps.append(("report", "measure speed against accuracy (quick report)", lambda s: _report(out)))
    report = {"quick": quick, "blender": bpy.app.version_string, "steps": {}}
    lines = []
    with Progress("demo", len(steps) + 1) as progress:
        progress.step("build the demo scene")
        t, cpu = time.perf_counter(), time.process_time()
        scene = demo.build_demo_scene(new_scene=True, resolution=(160, 120) if quick else (320, 240))
        report["steps"]["scene"] = {"seconds": time.perf_counter() - t, "cpu_seconds": time.process_time() - cpu,
                                    "objects": len(scene.objects)}
        for key, label, step in steps:
            progress.step(label)
            t, cpu = time.perf_counter(), time.process_time()
            result = step(scene)
            result["seconds"] = time.perf_counter() - t
            result["cpu_seconds"] = time.process_time() - cpu
            report["steps"][key] = result
            lines.append(f"{key}: {len(result.get('files', []))} files, {result['seconds']:.1f} s "
                         f"(CPU {result['cpu_seconds']:.1f} s)")
    report["load_average"] = os.getloadavg()[0] if hasattr(os, "getloadavg") else None
    path = os.path.join(out, "demo_report.json")
    write_json(path, report)
    lines.append(f"demo report: {path}")
    if "report" in report["steps"]:
        lines.append(f"speed-against-accuracy report: {report['steps']['report']['report']}")
    return JobResult(report, path, "\n".join(lines))
