"""The contract of a shading model (:class:`Model`) and the node-building steps several models share.

A model file in this package defines one ``MODEL = Model(...)``. Its two builders follow one contract:
``surface(g, i)`` returns {term: socket} of what depends only on the shading point and the parameters (n,
v, n.v and the model's registers, computed once per material), and ``light(g, i, s)`` the factor of one
light's I from those terms, so that radiance = sum over lights of I factor (+ the ``once`` term). ``g`` is a
:class:`..builder.Graph`, ``i`` the group inputs by name. No bpy here: builders only call ``g``.
"""
import dataclasses
from typing import Callable, NamedTuple

from ...core import brdf

F, V, C = "NodeSocketFloat", "NodeSocketVector", "NodeSocketColor"
WHITE, BLACK = (1.0, 1.0, 1.0, 1.0), (0.0, 0.0, 0.0, 1.0)


class Input(NamedTuple):
    """One group input: socket name, socket type, default, (min, max) or None, description."""
    name: str
    socket: str
    default: object
    range: object
    description: str


#: The two inputs every model group starts with (the light, REFERENCE.md §1).
LIGHT_IN = (Input("Light Vector", V, (0.0, 0.0, 1.0), None, "World-space vector from the surface toward the light"),
            Input("Light Color", C, WHITE, None, "Incident intensity I = E_perp / pi"))


@dataclasses.dataclass(frozen=True)
class Model:
    """One shading model: what the options, the node groups, the materials and the bench read.

    ``twin(n, l, v, I, p)`` is the numpy twin (``addon/core/brdf.py``) with ``p`` = {input name: value} of
    every input (colours as RGB); ``switches``: inputs the light half reads that select a branch (0 or 1);
    ``once``: the surface term added once per material (ambient, emission), or None; ``sweep``: parameter
    sets the node-vs-twin sweep renders (crossed with its light vectors).
    """
    id: str
    label: str
    description: str
    group: str
    group_description: str
    order: int
    params: tuple
    surface: Callable
    light: Callable
    twin: Callable
    switches: tuple = ()
    once: object = None
    sweep: tuple = ()

    @property
    def inputs(self):
        """Every input of the public group: the light's two, then the model's parameters."""
        return LIGHT_IN + tuple(self.params)

    @property
    def surface_group(self):
        return f".{self.group} Surface"

    @property
    def light_group(self):
        return f".{self.group} Light"


# -- steps several models share ----------------------------------------------------------------------

def surface_common(g):
    """n and v (unit vectors as Cycles and EEVEE give them), n.v and the constant registers: what every light
    shares (computed once)."""
    with g.block("Surface: n, v, n.v, constants (computed once for all lights)"):
        geo = g.node("ShaderNodeNewGeometry")
        g.registers(geo)
        n, v = geo.outputs["Normal"], geo.outputs["Incoming"]
        n_v = g.dot(n, v, label="n.v")
    return {"n": n, "v": v, "n.v": n_v, "0": g.reg(0.0)}


def light_common(g, i, s):
    """l = normalize(Light Vector) and n.l."""
    with g.block("Light: l, n.l"):
        l = g.normalize(i["Light Vector"], label="l (toward light)")
        n_l = g.dot(s["n"], l, label="n.l")
    return l, n_l


def half_vector_cosines(g, s, l):
    """n.h = n.(l + v)/|l + v| and |l + v|^2 = (l + v).(l + v), kept above 1e-12 (l = -v gives 0), with
    1/|l + v|: v.h = |l + v|/2 in [0, 1] for unit l and v, without normalizing h."""
    with g.block("Half vector cosines: n.h = n.(l + v)/|l + v|, v.h = |l + v|/2"):
        l_v = g.vadd(l, s["v"], label="l + v")
        lv2 = g.max(g.dot(l_v, l_v), s[f"{brdf.TINY:g}"], label="|l + v|^2")
        inv_lv = g.math("INVERSE_SQRT", lv2, label="1/|l + v|")
        n_h = g.mul(g.dot(s["n"], l_v, label="n.(l + v)"), inv_lv, label="n.h")
    return n_h, lv2, inv_lv
