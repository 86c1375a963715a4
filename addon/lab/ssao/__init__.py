"""SSAO lab: screen-space AO methods against Cycles' ray-traced AO, on the same camera and pixels.

    from addon.lab import ssao
    from addon.lab.options import SSAOOptions
    report = ssao.compare(scene, "out/ssao", SSAOOptions(methods=["gtao", "hbao"], radius=0.5))
    report = ssao.run_builtin("corner", "out/ssao", SSAOOptions(resolution=64))

The comparison and its files are in comparison.py, the renders (G-buffer, cached Cycles AO reference,
EEVEE, Workbench) and the scene-state guard in renders.py, the built-in scenes in scenes.py.
"""
from . import scenes  # noqa: F401
from .comparison import (RADIUS_RULE, blender_method, check_cost, compare, frame, parse_methods,  # noqa: F401
                         run_builtin, run_methods, summary_lines, write_ao)
from .renders import (FILTER_WIDTH, REFERENCE_VERSION, frame_size, preserved, render_eevee,  # noqa: F401
                      render_gbuffer, render_reference, render_workbench, scene_key, set_resolution)
