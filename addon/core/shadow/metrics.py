"""Shadow masks against the ray-traced reference: thresholds, misclassification, images.

Masks are boolean (H, W) arrays, True = lit by the light under test, on the reference's
pixel grid. Only receiver pixels (geometry, not sky) are scored:
  false shadow = method dark where the reference is lit,
  false light  = method lit where the reference is dark,
  error = false shadow + false light, each a fraction of the receiver pixels.
"""
import numpy as np

from ..errors import InputError

#: Error image colours (8-bit sRGB): agreement in greys, the two failures in two hues, and the
#: pixels that are not scored (sky: no receiver) in dark green so they never read as shadow.
COLOURS = {
    "background": (30, 80, 50),
    "lit": (200, 200, 200),
    "shadow": (70, 70, 70),
    "false_shadow": (230, 30, 30),
    "false_light": (30, 120, 255),
}

#: A pixel counts as lit when its direct light reaches this fraction of the unshadowed value.
LIT_FRACTION = 0.5


def unshadowed_diffuse(normals, to_light, irradiance_normal):
    """Direct diffuse pass value without shadow: E⊥ (n·l)⁺ / π (REFERENCE.md §1: passes hold E/π)."""
    cos = np.clip(np.einsum("...i,...i->...", normals, to_light), 0.0, None)
    return irradiance_normal * cos / np.pi


def lit_from_pass(diffuse_direct, unshadowed, receiver, fraction=LIT_FRACTION):
    """Binary mask from a rendered direct-diffuse pass: lit where pass >= fraction × unshadowed value.

    With a radius-0 light each pixel's shadow ray is deterministic, so a lit pixel carries the
    full unshadowed value and a shadowed one carries 0; any fraction in (0, 1) separates them.
    Pixels whose unshadowed value is 0 (facing away, outside a spot cone) are dark.
    """
    d = np.asarray(diffuse_direct, np.float64)
    if d.ndim == 3:
        d = d[..., :3].mean(-1)
    u = np.asarray(unshadowed, np.float64)
    return receiver & (u > 0) & (d >= fraction * u)


def confusion(mask, reference, receiver):
    """Fractions of receiver pixels: {"error", "false_shadow", "false_light", "receiver_pixels"}."""
    mask, reference, receiver = (np.asarray(a, bool) for a in (mask, reference, receiver))
    if mask.shape != reference.shape or receiver.shape != reference.shape:
        raise InputError(f"mask {mask.shape} is not on the reference's pixel grid {reference.shape}")
    n = int(receiver.sum())
    if n == 0:
        raise InputError("no receiver pixels: the camera sees no geometry")
    fs = int((receiver & ~mask & reference).sum()) / n
    fl = int((receiver & mask & ~reference).sum()) / n
    return {"error": fs + fl, "false_shadow": fs, "false_light": fl, "receiver_pixels": n}


def mask_image(mask):
    """8-bit grey image: 255 lit, 0 in shadow -- and 0 where there is no receiver (sky), which the
    light under test does not light either; :func:`error_image` marks those pixels apart."""
    return np.where(np.asarray(mask, bool), 255, 0).astype(np.uint8)


def error_image(mask, reference, receiver):
    """(H, W, 3) uint8: greys where method and reference agree, red false shadow, blue false light,
    dark green where there is no receiver (not scored)."""
    mask, reference, receiver = (np.asarray(a, bool) for a in (mask, reference, receiver))
    img = np.empty(mask.shape + (3,), np.uint8)
    img[:] = COLOURS["background"]
    for name, sel in (("lit", mask & reference), ("shadow", ~mask & ~reference),
                      ("false_shadow", ~mask & reference), ("false_light", mask & ~reference)):
        img[receiver & sel] = COLOURS[name]
    return img
