"""Oren-Nayar qualitative model (Oren & Nayar 1994; REFERENCE.md §2, §6):
L = rho I (n.l) (A + B max(0, cos dphi) sin alpha tan beta), zero unless n.l > 0 and n.v > 0."""
from ...core import brdf
from ._common import C, F, Input, Model, light_common, surface_common


def _twin(n, l, v, I, p):
    """brdf.oren_nayar with the group's inputs."""
    return brdf.oren_nayar(n, l, v, I, albedo=p["Albedo"], sigma=p["Sigma"])


def _surface(g, i):
    """Surface half: A, B from sigma (brdf.oren_nayar_A, _B), -n.v, max(n.v, 1e-12), 2 (n.v > 0), rho."""
    s = surface_common(g)
    R = g.reg
    n_v = s["n.v"]
    with g.block("Surface: A, B from sigma; n.v terms"):
        s2 = g.mul(i["Sigma"], i["Sigma"], label="sigma^2")
        s["A"] = R(g.sub(1.0, g.div(g.mul(s2, 0.5), g.add(s2, 0.33))), "A = 1 - 0.5 s2/(s2+0.33)")
        s["B"] = R(g.div(g.mul(s2, 0.45), g.add(s2, 0.09)), "B = 0.45 s2/(s2+0.09)")
        s["-n.v"] = g.mul(n_v, -1.0, label="-n.v")
        s["max(n.v, 1e-12)"] = g.max(n_v, brdf.TINY, label="max(n.v, 1e-12)")
        s["2 (n.v > 0)"] = g.mul(g.gt(n_v, 0.0), 2.0, label="2 (n.v > 0)")
        s["rho"] = g.vreg(i["Albedo"], "rho")
    return s


def _light(g, i, s):
    """Light half: rho (n.l) (A + B max(0, l.v - (n.l)(n.v)) / max(n.l, n.v)) (brdf.oren_nayar_angular)."""
    l, n_l = light_common(g, i, s)
    with g.block("(n.l)(A + B max(0, cos dphi) sin(alpha) tan(beta)), bounded vector form"):
        t0 = g.max(g.madd(n_l, s["-n.v"], g.dot(l, s["v"], label="l.v")), s["0"], label="max(0, l.v - (n.l)(n.v))")
        t = g.div(t0, g.max(n_l, s["max(n.v, 1e-12)"]), label="s / max(n.l, n.v, 1e-12)")
        a = g.min(g.max(n_l, s["0"]), s["2 (n.v > 0)"], label="max(n.l, 0), 0 unless n.v > 0")
        factor = g.mul(a, g.madd(t, s["B"], s["A"]), label="n.l (A + B s / max(n.l, n.v))")
    with g.block("rho factor"):
        return g.scale(s["rho"], factor, label="rho factor")


MODEL = Model(
    id="OREN_NAYAR", label="Oren-Nayar", description="Rough diffuse, qualitative model",
    group="IL Oren-Nayar", group_description="Oren-Nayar qualitative model, bounded vector form",
    order=30,
    params=(Input("Albedo", C, (0.8, 0.8, 0.8, 1.0), None, "Diffuse albedo rho"),
            Input("Sigma", F, 0.3, (0.0, 10.0), "Standard deviation of the facet slopes, radians")),
    surface=_surface, light=_light, twin=_twin,
    sweep=(dict(Sigma=0.0), dict(Sigma=0.5), dict(Sigma=1.2)))
