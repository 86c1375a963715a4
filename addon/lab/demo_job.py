"""The demo end to end (the README's main job). Each finished tool adds its step here."""
import os
import time

import bpy
import numpy as np

from ..core import exr, imageio
from ..core.errors import InputError
from ..core.fileio import write_json
from ..progress import Progress
from . import demo, render


def run(out, quick=False, samples=32):
    """Build the demo scene, render a preview, write ``out/demo_report.json``; return a summary."""
    if samples <= 0:
        raise InputError(f"--samples must be positive, got {samples}")
    os.makedirs(out, exist_ok=True)
    steps = ["build the demo scene", "render the preview"]
    lines, report = [], {"steps": {}}
    with Progress("demo", len(steps)) as progress:
        progress.step(steps[0])
        t = time.perf_counter()
        scene = demo.build_demo_scene(new_scene=True, resolution=(160, 120) if quick else (320, 240))
        report["steps"]["scene"] = {"seconds": time.perf_counter() - t, "objects": len(scene.objects)}

        progress.step(steps[1])
        t = time.perf_counter()
        render.cycles_cpu(scene, samples=8 if quick else samples)
        passes = render.render_layers(scene)
        rgb = passes["Combined"][..., :3]
        exr.write_exr(os.path.join(out, "demo_render.exr"),
                      {"R": rgb[..., 0], "G": rgb[..., 1], "B": rgb[..., 2]},
                      {"il:quantity": "radiance", "il:units": "W/(m^2 sr)",
                       "il:samples": scene.cycles.samples, "il:blender_version": bpy.app.version_string})
        imageio.write_png(os.path.join(out, "demo_render.png"), imageio.to_uint8(imageio.tonemap(rgb)))
        report["steps"]["render"] = {"seconds": time.perf_counter() - t, "samples": scene.cycles.samples,
                                     "mean_radiance": float(np.mean(rgb))}
        lines.append(f"render: {os.path.join(out, 'demo_render.exr')} (+ .png)")
    write_json(os.path.join(out, "demo_report.json"), report)
    lines.append(f"report: {os.path.join(out, 'demo_report.json')}")
    return {"out": out, "lines": lines}
