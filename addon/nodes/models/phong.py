"""Phong (seed 004, eq. 1): L = k_a I_a + I (k_d (n.l) + k_s N (r.v)^n) + I_e, N = 1 or ((n+2)/2)(n.l)."""
from ...core import brdf
from . import _phong_family as family
from ._common import Model


def _twin(n, l, v, I, p):
    """brdf.phong with the group's inputs."""
    return brdf.phong(n, l, v, I, **family.twin_args(p))


MODEL = Model(
    id="PHONG", label="Phong", description="k_a I_a + I (k_d n.l + k_s (r.v)^n) + I_e",
    group="IL Phong", group_description="Phong (seed 004): k_a I_a + I (k_d n.l + k_s N (r.v)^n) + I_e",
    order=10, params=family.PARAMS,
    surface=lambda g, i: family.surface(g, i, False), light=lambda g, i, s: family.light(g, i, s, False),
    twin=_twin, switches=family.SWITCHES, once=family.ONCE,
    sweep=(dict(Shininess=20.0, Ks=0.6), dict(Shininess=5.0, Ks=0.4, Normalized=1.0)))
