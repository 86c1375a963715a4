"""Light-map pipeline on Cycles (bpy side): UVs, temporary materials, bakes, restore.

Public API (used by the operator, scripts/bake.py, the demo and other labs)::

    from addon.bake import BakeOptions, bake_lightmaps
    report = bake_lightmaps([obj], ["ao", "irradiance"], "out/maps",
                            BakeOptions(resolution=256, samples=64), scene=scene)
    report["objects"]["Floor"]["irradiance"]["file"]   # -> out/maps/Floor_irradiance.exr

Files: ``<out>/<object>_ao.exr`` (channels Y = k_A, A = covered) and
``<out>/<object>_irradiance.exr`` (R, G, B = E in W/m², A), each with a PNG preview,
and ``<out>/bake_report.json`` (see DESIGN.md). Read a map back with
``addon.core.io.exr.read_exr`` (row 0 = top = v 1).
"""
from .options import MAPS, BakeOptions  # noqa: F401
from .passes import BakeResult  # noqa: F401
from .pipeline import bake_lightmaps  # noqa: F401
from .plan import output_files, validate  # noqa: F401
from .report import REPORT, summary  # noqa: F401
