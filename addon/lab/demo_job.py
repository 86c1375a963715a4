"""The demo end to end (the README's main job): one step per tool, each timed, one report."""
import os
import time

import bpy
import numpy as np

from ..core.io import png as imageio
from ..core.io import exr
from ..core.errors import InputError
from ..core.io.files import write_json
from ..progress import Progress
from . import demo, render


def _render(scene, out, quick, samples):
    render.cycles_cpu(scene, samples=8 if quick else samples)
    passes = render.render_layers(scene)
    rgb = passes["Combined"][..., :3]
    path = os.path.join(out, "demo_render.exr")
    exr.write_exr(path, {"R": rgb[..., 0], "G": rgb[..., 1], "B": rgb[..., 2]},
                  {"il:quantity": "radiance", "il:units": "W/(m^2 sr)",
                   "il:samples": scene.cycles.samples, "il:blender_version": bpy.app.version_string})
    imageio.write_png(os.path.join(out, "demo_render.png"), imageio.to_uint8(imageio.tonemap(rgb)))
    return {"samples": scene.cycles.samples, "mean_radiance": float(np.mean(rgb)),
            "files": [path, os.path.join(out, "demo_render.png")]}


def _shading(scene, out, quick):
    from .shading_bench import demo_step
    return demo_step(scene, out, quick)


def _lightmaps(scene, out, quick):
    from ..bake.bench import demo_step
    return demo_step(scene, os.path.join(out, "lightmaps"), quick)


def _shadows(out, quick):
    from .shadows import demo_step
    result = demo_step(out, quick)
    result["files"] = [result["report"]]
    return result


def _ssao(out, quick):
    from .ssao_sweeps import demo_step
    result = demo_step(os.path.join(out, "ssao"), quick)
    result["files"] = [result["report"]]
    return result


def _report(out, quick):
    from . import bench
    result = bench.run(os.path.join(out, "report"), quick=True)
    return {"report": result["report"], "files": [result["report"]],
            "stability_rows": len(result["stability"])}


def run(out, quick=False, samples=32):
    """Build the demo scene, run every tool on it, write ``out/demo_report.json``; return a summary."""
    if samples <= 0:
        raise InputError(f"--samples must be positive, got {samples}")
    os.makedirs(out, exist_ok=True)
    steps = [
        ("shading", "assign Phong, Oren-Nayar and Cook-Torrance", lambda s: _shading(s, out, quick)),
        ("render", "render the shaded scene", lambda s: _render(s, out, quick, samples)),
        ("lightmaps", "bake AO and irradiance maps", lambda s: _lightmaps(s, out, quick)),
        ("shadows", "compare shadow methods with ray-traced shadows", lambda s: _shadows(out, quick)),
        ("ssao", "compare screen-space AO with ray-traced AO", lambda s: _ssao(out, quick)),
    ]
    if not quick:
        steps.append(("report", "measure speed against accuracy (quick report)", lambda s: _report(out, quick)))
    report = {"quick": quick, "blender": bpy.app.version_string, "steps": {}}
    lines = []
    with Progress("demo", len(steps) + 1) as progress:
        progress.step("build the demo scene")
        t = time.perf_counter()
        scene = demo.build_demo_scene(new_scene=True, resolution=(160, 120) if quick else (320, 240))
        report["steps"]["scene"] = {"seconds": time.perf_counter() - t, "objects": len(scene.objects)}
        for key, label, step in steps:
            progress.step(label)
            t = time.perf_counter()
            result = step(scene)
            result["seconds"] = time.perf_counter() - t
            report["steps"][key] = result
            lines.append(f"{key}: {len(result.get('files', []))} files, {result['seconds']:.1f} s")
    path = os.path.join(out, "demo_report.json")
    write_json(path, report)
    lines.append(f"demo report: {path}")
    if "report" in report["steps"]:
        lines.append(f"speed-against-accuracy report: {report['steps']['report']['report']}")
    return {"out": out, "lines": lines}
