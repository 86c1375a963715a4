"""Blinn-Phong: L = k_a I_a + I (k_d (n.l) + k_s N (n.h)^n) + I_e, N = 1 or (n+2)(n+4)/(8 (2^(-n/2) + n)) (n.l)."""
from ...core import brdf
from . import _phong_family as family
from ._common import Model


def _twin(n, l, v, I, p):
    """brdf.blinn_phong with the group's inputs."""
    return brdf.blinn_phong(n, l, v, I, **family.twin_args(p))


MODEL = Model(
    id="BLINN_PHONG", label="Blinn-Phong", description="Phong with (n.h)^n",
    group="IL Blinn-Phong", group_description="Blinn-Phong: k_a I_a + I (k_d n.l + k_s N (n.h)^n) + I_e",
    order=20, params=family.PARAMS,
    surface=lambda g, i: family.surface(g, i, True), light=lambda g, i, s: family.light(g, i, s, True),
    twin=_twin, switches=family.SWITCHES, once=family.ONCE,
    sweep=(dict(Shininess=40.0, Ks=0.6), dict(Shininess=10.0, Ks=0.4, Normalized=1.0)))
