"""Light sources of seed 004 as numpy twins of the "IL Light" node group (REFERENCE.md §1-2).

Every function returns what the node group outputs for surface points ``p`` (..., 3)
with normals ``n``: the "Light Vector" (world space, from the surface toward the
light, not normalised) and the "Light Color" I = E_perp / pi, the intensity of the
seed's formulas in the unit convention of REFERENCE.md §1. Blender's radiometry:
a point or spot light of power P has intensity P/(4 pi) W/sr, so at distance d
E_perp = P/(4 pi d^2) and I = P/(4 pi^2 d^2); a sun of strength S gives E_perp = S.
"""
import numpy as np

from .brdf import TINY, dot, normalize

POINT, SPOT, SUN, HEMI = 0, 1, 2, 3
TYPES = {"POINT": POINT, "SPOT": SPOT, "SUN": SUN, "HEMI": HEMI}


def attenuation_physical(d):
    """f_att = 1/d^2 (inverse-square law), guarded at d -> 0."""
    return 1.0 / np.maximum(np.square(d), TINY)


def attenuation_empirical(d, c1, c2, c3):
    """f_att = min(1/(c1 + c2 d + c3 d^2), 1) (seed 004)."""
    return np.minimum(1.0 / np.maximum(c1 + c2 * d + c3 * np.square(d), TINY), 1.0)


def attenuation(d, physical=1.0, c1=1.0, c2=0.0, c3=1.0):
    """Blend of the two: ``physical`` 1 -> 1/d^2, 0 -> the empirical f_att."""
    return physical * attenuation_physical(d) + (1.0 - physical) * attenuation_empirical(d, c1, c2, c3)


def point_intensity(power):
    """I at unit attenuation: P/(4 pi) W/sr over pi, i.e. P/(4 pi^2)."""
    return np.asarray(power, float) / (4.0 * np.pi ** 2)


def spot_falloff(spot_dir, to_surface, cutoff, exponent):
    """(s.s')^k inside the cone (s.s' > cos(cutoff)), 0 outside (seed 004).

    ``spot_dir`` s is where the spot points, ``to_surface`` s' the unit direction from light to surface.
    """
    c = dot(normalize(spot_dir), normalize(to_surface))
    inside = (c > np.cos(cutoff)).astype(float)
    return inside * np.power(np.maximum(c, 0.0), exponent)


def hemi_blend(n, up):
    """Weight of the sky colour (1 + n.u)/2; the ground gets the rest (seed 004)."""
    return (1.0 + dot(normalize(n), normalize(up))) / 2.0


def point_light(p, position, color, power, physical=1.0, c1=1.0, c2=0.0, c3=1.0):
    """(Light Vector, Light Color) of a point light."""
    lvec = np.asarray(position, float) - np.asarray(p, float)
    d = np.linalg.norm(lvec, axis=-1)
    I = np.asarray(color, float) * (point_intensity(power) * attenuation(d, physical, c1, c2, c3))[..., None]
    return lvec, I


def spot_light(p, position, direction, color, power, cutoff, exponent=0.0, physical=1.0, c1=1.0, c2=0.0,
               c3=1.0):
    """A point light times the spot falloff; ``cutoff`` is the half angle of the cone (radians)."""
    lvec, I = point_light(p, position, color, power, physical, c1, c2, c3)
    return lvec, I * spot_falloff(direction, -lvec, cutoff, exponent)[..., None]


def area_light(p, position, direction, color, power, physical=1.0, c1=1.0, c2=0.0, c3=1.0):
    """An area light of power P as a Lambertian point emitter at its centre: I(theta) = (P/pi) cos theta for
    theta < 90 deg from ``direction`` (its -Z), i.e. a spot of power 4P (P/(4 pi) W/sr times 4), cutoff 90 deg,
    exponent 1. Exact in the far field; near it the relative error is ~ (size/distance)^2."""
    return spot_light(p, position, direction, color, 4.0 * np.asarray(power, float), np.pi / 2, 1.0, physical,
                      c1, c2, c3)


def sun_light(p, direction, color, strength):
    """Distant light: Light Vector = -direction, I = S/pi (Blender's sun strength is E_perp in W/m^2)."""
    shape = np.shape(p)[:-1]
    lvec = np.broadcast_to(-np.asarray(direction, float), shape + (3,))
    I = np.broadcast_to(np.asarray(color, float) * float(strength) / np.pi, shape + (3,))
    return lvec, I


def hemi_light(n, direction, sky, ground, strength):
    """Hemispherical sky/ground light: Light Vector = n (so n.l = 1), I = mix(ground, sky, (1 + n.u)/2) S/pi.

    ``direction`` is where the light points (like a sun); up u = -direction.
    """
    w = hemi_blend(n, -np.asarray(direction, float))[..., None]
    I = (np.asarray(ground, float) * (1 - w) + np.asarray(sky, float) * w) * float(strength) / np.pi
    return np.array(n, float), I


def light(kind, p, n, position=(0, 0, 0), direction=(0, 0, -1), color=(1, 1, 1), power=1.0, physical=1.0,
          c1=1.0, c2=0.0, c3=1.0, cutoff=np.pi / 4, exponent=0.0, ground=(0, 0, 0)):
    """Dispatch on ``kind`` (POINT, SPOT, SUN, HEMI or their names) like the node group's "Type" input."""
    kind = TYPES.get(kind, kind)
    p = np.asarray(p, float)
    if kind == POINT:
        return point_light(p, position, color, power, physical, c1, c2, c3)
    if kind == SPOT:
        return spot_light(p, position, direction, color, power, cutoff, exponent, physical, c1, c2, c3)
    if kind == SUN:
        return sun_light(p, direction, color, power)
    if kind == HEMI:
        return hemi_light(n, direction, color, ground, power)
    raise ValueError(f"unknown light type {kind!r}")
