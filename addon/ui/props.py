"""Operator and panel properties built from a job's options class (core.options), and options read back.

``properties(BakeOptions)`` gives the annotations of a PropertyGroup: one Blender property per field that
has ``ui=True``, with the field's label, help, default, limits and choices. ``options(BakeOptions, group)``
reads them back into a validated options instance, so the panel, the operator and the script share one
declaration.
"""
from bpy.props import BoolProperty, EnumProperty, FloatProperty, IntProperty, StringProperty

from ..blender import compat
from ..core import options as core_options


def _limits(spec, kind):
    kw = {}
    lo = spec.minimum if spec.minimum is not None else spec.above
    if lo is not None:
        kw["min"] = kind(lo) if spec.above is None else (kind(lo) + (1 if kind is int else 1e-6))
    if spec.maximum is not None:
        kw["max"] = kind(min(spec.maximum, 2 ** 31 - 1))
    if spec.soft_max is not None:
        kw["soft_max"] = kind(spec.soft_max)
    if spec.unit:
        kw["unit"] = spec.unit
    if spec.subtype:
        kw["subtype"] = spec.subtype
    return kw


def _description(spec):
    return spec.help[:1].upper() + spec.help[1:]


def prop(kind, value, spec, **override):
    """The Blender property for one field whose default is ``value`` (``override`` replaces keyword arguments,
    e.g. a smaller max)."""
    default = override.pop("default", value)
    if default is None:
        default = spec.ui_default
    name, description = spec.label, _description(spec)
    if spec.choices:
        kw = {"name": name, "items": [tuple(c) for c in spec.choices], "description": description}
        if spec.multiple:
            kw.update(options={"ENUM_FLAG"}, default=set(default or ()))
        else:
            kw["default"] = default
        kw.update(override)
        return EnumProperty(**kw)
    if kind is bool:
        return BoolProperty(**{"name": name, "default": bool(default), "description": description, **override})
    if kind is int:
        return IntProperty(**{"name": name, "default": int(default), "description": description,
                              **_limits(spec, int), **override})
    if kind is float:
        return FloatProperty(**{"name": name, "default": float(default), "description": description,
                                **_limits(spec, float), **override})
    return StringProperty(**{"name": name, "default": default or "", "description": description, **override})


def properties(cls, skip=(), **overrides):
    """{field name: Blender property} for every UI field of the options class ``cls``; ``overrides`` maps a
    field name to keyword arguments that replace the generated ones."""
    return {name: prop(kind, default, spec, **overrides.get(name, {}))
            for name, kind, default, spec in core_options.specs(cls) if spec.ui and name not in skip}


def output_dir(default, description):
    """The output-folder property every job panel has (relative to the .blend)."""
    return StringProperty(name="Output", subtype="DIR_PATH", default=default,
                          options=compat.BLEND_RELATIVE_PATH, description=description)


def options(cls, group, **values):
    """An instance of ``cls`` from the property group ``group`` (fields with ``ui=True``; ``values`` for the
    rest or to replace one, e.g. a field the panel switches off), validated."""
    read = {}
    for name, kind, _, spec in core_options.specs(cls):
        if not spec.ui or name in values:
            continue
        value = getattr(group, name)
        if spec.multiple:
            order = core_options.choice_ids(spec)
            value = sorted(value, key=order.index)
        elif kind is str and not spec.choices and value == "":
            value = None
        read[name] = value
    return cls(**read, **values).validate()


def draw(layout, group, names):
    """One row per field, in order (a panel's plain column of options)."""
    for name in names:
        layout.prop(group, name)
