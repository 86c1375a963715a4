"""What Phong and Blinn-Phong share (seed 004; REFERENCE.md §2): inputs, twin mapping and both node halves.

L = k_a I_a + I (k_d (n.l) + k_s N lobe) + I_e, lobe (r.v)^n (Phong) or (n.h)^n (Blinn-Phong); ``blinn``
selects the lobe and its energy factor.
"""
from ...core import brdf
from ._common import BLACK, C, F, Input, half_vector_cosines, light_common, surface_common

PARAMS = (
    Input("Ka", F, 0.1, (0.0, 1.0), "Ambient reflection coefficient k_a"),
    Input("Ambient Light", C, (0.2, 0.2, 0.2, 1.0), None, "Ambient intensity I_a"),
    Input("Kd", C, (0.8, 0.8, 0.8, 1.0), None, "Diffuse reflection coefficient k_d"),
    Input("Ks", F, 0.5, (0.0, 1.0), "Specular reflection coefficient k_s"),
    Input("Shininess", F, 32.0, (0.0, 1e5), "Specular exponent n"),
    Input("Emission Color", C, BLACK, None, "Emitted radiance I_e"),
    Input("Normalized", F, 0.0, (0.0, 1.0), "0 classic, 1 energy-normalised lobe"))
SWITCHES = ("Normalized",)
ONCE = "k_a I_a + I_e"


def twin_args(p):
    """Keyword arguments of brdf.phong / brdf.blinn_phong from the group inputs ``p``."""
    return dict(ka=p["Ka"], ambient_light=p["Ambient Light"], kd=p["Kd"], ks=p["Ks"], shininess=p["Shininess"],
                emission=p["Emission Color"], normalized=p["Normalized"])


def surface(g, i, blinn):
    """Surface half: n (exponent), the lobe's energy factor, k_d, k_s, k_a I_a + I_e (and 2 n.v, -v for Phong)."""
    s = surface_common(g)
    R = g.reg
    s["n (exponent)"] = R(i["Shininess"], "n")
    if blinn:
        s[f"{brdf.TINY:g}"] = R(brdf.TINY)
        with g.block("Surface: (n+2)(n+4) / (8 (2^(-n/2) + n))"):
            n0 = g.max(i["Shininess"], 0.0, label="max(n, 0)")
            num = g.mul(g.add(n0, 2.0), g.add(n0, 4.0), label="(n+2)(n+4)")
            den = g.mul(g.add(g.pow(2.0, g.mul(n0, -0.5)), n0), 8.0, label="8 (2^(-n/2) + n)")
            s["energy factor"] = R(g.div(num, den), "energy factor")
    else:
        with g.block("Surface: (n+2)/2, 2 n.v, -v"):
            s["energy factor"] = R(g.div(g.add(i["Shininess"], 2.0), 2.0), "energy factor")
            s["2 n.v"] = g.add(s["n.v"], s["n.v"], label="2 n.v")
            s["-v"] = g.scale(s["v"], -1.0, label="-v")
    with g.block("Surface: k_d, k_s, k_a I_a + I_e"):
        s["k_d"] = g.vreg(i["Kd"], "k_d")
        s["k_s"] = g.vreg(i["Ks"], "k_s")
        s["k_a I_a + I_e"] = g.vadd(g.scale(i["Ambient Light"], i["Ka"], label="k_a I_a"), i["Emission Color"],
                                    label="+ I_e")
    return s


def light(g, i, s, blinn):
    """Light half: k_d max(n.l, 0) + k_s N lobe, lobe (r.v)^n (Phong) or (n.h)^n (Blinn-Phong), N = lit or
    factor max(n.l, 0) by Normalized."""
    l, n_l = light_common(g, i, s)
    zero, shin = s["0"], s["n (exponent)"]
    with g.block("lit: n.l > 0"):
        lit = g.gt(n_l, zero, label="lit")
        a = g.mul(n_l, lit, label="max(n.l, 0)")
    if blinn:
        with g.block("Lobe: (n.h)^n"):
            n_h = half_vector_cosines(g, s, l)[0]
            lobe = g.pow(g.max(n_h, zero), shin, label="(n.h)^n")
    else:
        with g.block("Lobe: (r.v)^n, r.v = 2 (n.l)(n.v) - l.v"):
            r_v = g.madd(n_l, s["2 n.v"], g.dot(l, s["-v"], label="-l.v"), label="r.v")
            lobe = g.pow(g.max(r_v, zero), shin, label="(r.v)^n")
    with g.block("N lit: lit (classic) or factor max(n.l, 0) (energy-normalised)"):
        norm = g.lerp(lit, g.mul(a, s["energy factor"], label="factor max(n.l, 0)"), i["Normalized"], label="N lit")
    with g.block("k_d n.l + k_s N lobe"):
        diff = g.scale(s["k_d"], a, label="k_d n.l")
        return g.add_scaled(diff, s["k_s"], g.mul(lobe, norm, label="N lobe"), label="k_d n.l + k_s N lobe")
