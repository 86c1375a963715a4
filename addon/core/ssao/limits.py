"""Limits and cost estimates of the SSAO lab (shared by the script, the panel and the lab) and its scene names."""
from .. import budget
from ..errors import InputError


#: The lab's built-in scenes (built by addon/lab/ssao/scenes.py).
SCENES = ("plane", "corner", "thin", "edge", "discontinuity")

#: Limits shared by the script, the panel and the lab: frame width, samples per pixel of a
#: screen-space method, Cycles AO samples per pixel of the reference.
MAX_RESOLUTION = 8192
MAX_SAMPLES = 1024
MAX_REFERENCE_SAMPLES = 65536
#: Cost estimates (measured on 2 cores, rounded up, README "Limits"): peak bytes per frame pixel of
#: a comparison (Blender's render buffers, passes, G-buffer; 280 measured at 1024²), seconds per
#: pixel and sample of a numpy method (0.8-1.9e-7 measured before issue 14, 0.3-0.5e-7 after; the bound is
#: kept) and of Cycles' AO pass (1.2e-6).
BYTES_PER_PIXEL = 400
SECONDS_PER_SAMPLE = 2e-7
REFERENCE_SECONDS_PER_SAMPLE = 1.5e-6


def check_cost(width, height, samples, reference_samples, numpy_methods=1):
    """Refuse (InputError naming the largest value that fits) a comparison whose estimated memory
    (width x height x BYTES_PER_PIXEL) or time (pixels x samples x seconds per sample, for the reference
    and for the numpy methods) does not fit :mod:`budget`."""
    aspect = height / width
    budget.check("resolution", int(width), lambda w: (w * max(1, round(w * aspect)) * BYTES_PER_PIXEL, 0.0), 8)
    pixels, frame = int(width) * int(height), f"at {width}x{height} pixels"
    budget.check("reference samples", int(reference_samples),
                 lambda n: (0, pixels * n * REFERENCE_SECONDS_PER_SAMPLE), 1, frame)
    if numpy_methods:
        budget.check("samples", int(samples),
                     lambda n: (0, pixels * n * SECONDS_PER_SAMPLE * numpy_methods), 1,
                     f"{frame} and {numpy_methods} method{'s' if numpy_methods > 1 else ''}")


def check_scene(name):
    """``name`` if it is one of :data:`SCENES`, else InputError (checked before Blender is needed)."""
    if name not in SCENES:
        raise InputError(f"unknown SSAO scene '{name}' (choose from {', '.join(SCENES)})")
    return name
