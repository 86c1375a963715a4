"""The shading models, one file per model (as rigify's ``rigs/``, listed like its ``rig_lists.py``).

Each module here whose name does not start with "_" defines ``MODEL``, a :class:`._common.Model`: id,
label, description, group name, inputs, the surface-half and light-half node builders, switches and
the numpy twin (a function of ``addon/core/brdf.py``). They are discovered at import and kept in the
fixed order of ``Model.order``; the options, node groups, materials and bench read :data:`MODELS`, so
adding a model is adding one file (and its tests).

Each model is two halves: ``surface(g, i)`` returns the named terms that depend only on the shading
point and the parameters (n, v, n.v, roughness terms, registers), ``light(g, i, s)`` the factor of one
light's I from them (radiance = I factor, summed over the lights by one multiply-add each). The public
group holds both; a material holds the surface half once (internal group ".IL <model> Surface") and the
light half per light (".IL <model> Light"), so Blender converts only the light half for every light at
every render (it converts every node reachable from the output, about 13 us each; Cycles folds the
switches' unused branches only after that, so materials link the variants built with the switches fixed,
``groups.variant``).

Cost (Cycles SVM): a switch input left constant (Distribution, Geometry, Normalized, Physical, Type)
keeps one branch only, so switches are Mix nodes, never math that evaluates both branches; and the
per-light nodes take no constant operands (a constant is loaded before every node that takes it, as
costly as the operation): they read "registers" (g.reg), nodes computed once per shading point.
"""
import importlib
import pkgutil

from ._common import Input, Model  # noqa: F401


def _discover():
    """MODEL of every public module of this package, by ``order``; ids, groups and orders unique."""
    found = []
    for info in pkgutil.iter_modules(__path__):
        if info.name.startswith("_"):
            continue
        module = importlib.import_module(f".{info.name}", __name__)
        model = getattr(module, "MODEL", None)
        if not isinstance(model, Model):
            raise TypeError(f"shading model module '{info.name}' defines no MODEL = Model(...)")
        found.append(model)
    found.sort(key=lambda m: m.order)
    for field in ("id", "group", "order"):
        values = [getattr(m, field) for m in found]
        if len(set(values)) != len(values):
            raise ValueError(f"shading models share a {field}: {values}")
    return tuple(found)


#: Every shading model, in menu order.
MODELS = _discover()
#: {model id: Model} and {public group name: Model}.
BY_ID = {m.id: m for m in MODELS}
BY_GROUP = {m.group: m for m in MODELS}
