"""Job options declared once: a dataclass whose fields carry their label, help, limits and choices.

Every job (bake, shadows, SSAO, environment map, radiosity) has one options class built with
:func:`option`. The batch script's argparse parser (scripts/_cli.add_options), the operator's
properties and the panel (ui/props.py) are generated from it, and :meth:`Options.validate` is the one
range and choice check all of them go through (an out-of-range value is an InputError).
"""
import dataclasses
import math

from . import choices
from .errors import InputError


@dataclasses.dataclass(frozen=True)
class Spec:
    """What a field means: label and help for people, limits and choices for validation and widgets.

    minimum/maximum inclusive, ``above`` exclusive lower bound, ``soft_max`` only for UI sliders;
    ``choices`` is a tuple of (id, label, description); ``multiple`` makes the value a list of choice ids
    (given on the command line as separate words, or joined by ``separator`` when one is set; ``item`` names
    one of them in messages);
    ``cli``/``ui`` say whether the field appears in the script / the panel; ``flag`` overrides the
    ``--name-with-dashes`` spelling; ``group`` puts fields in a mutually exclusive argparse group;
    ``ui_default`` is the widget's value for a field whose default is None (its panel has a mode switch);
    ``unit`` and ``subtype`` are Blender property unit/subtype.
    """
    label: str
    help: str
    minimum: float = None
    maximum: float = None
    above: float = None
    soft_max: float = None
    choices: tuple = None
    multiple: bool = False
    separator: str = None
    item: str = None
    cli: bool = True
    ui: bool = True
    flag: str = None
    metavar: str = None
    group: str = None
    ui_default: object = None
    unit: str = None
    subtype: str = None


def option(default, label, help, kind=None, **spec):
    """A dataclass field with its :class:`Spec`; ``kind`` (int, float, str, bool) when the default is None
    or a list."""
    meta = {"spec": Spec(label, help, **spec), "kind": kind or type(default)}
    if isinstance(default, (list, dict, set)):
        return dataclasses.field(default_factory=lambda: type(default)(default), metadata=meta)
    return dataclasses.field(default=default, metadata=meta)


def specs(cls):
    """[(name, kind, default, Spec)] of the declared fields of an options class, in order."""
    out = []
    for f in dataclasses.fields(cls):
        if "spec" not in f.metadata:
            continue
        default = f.default if f.default is not dataclasses.MISSING else f.default_factory()
        out.append((f.name, f.metadata["kind"], default, f.metadata["spec"]))
    return out


def choice_ids(spec):
    return tuple(c[0] for c in spec.choices) if spec.choices else ()


def check_value(name, kind, spec, value):
    """``value`` converted to ``kind`` and checked against ``spec``; InputError naming the label otherwise."""
    if value is None:
        return None
    if spec.multiple:                       # a list, or one string joined by commas
        return choices.parse_choices(value if isinstance(value, str) else list(value), choice_ids(spec),
                                     spec.item or spec.label.lower())
    if kind is bool:
        return bool(value)
    if kind in (int, float):
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise InputError(f"{spec.label.lower()} must be a number, got {value!r}")
        if not math.isfinite(value):
            raise InputError(f"{spec.label.lower()} must be a finite number, got {value}")
        if kind is int and value != int(value):
            raise InputError(f"{spec.label.lower()} must be a whole number, got {value}")
        value = kind(value)
        if spec.above is not None and not value > spec.above:
            raise InputError(f"{spec.label.lower()} must be greater than {spec.above:g}, got {value:g}")
        lo, hi = spec.minimum, spec.maximum
        if (lo is not None and value < lo) or (hi is not None and value > hi):
            rng = (f"between {lo:g} and {hi:g}" if lo is not None and hi is not None
                   else f"at least {lo:g}" if lo is not None else f"at most {hi:g}")
            raise InputError(f"{spec.label.lower()} must be {rng}, got {value:g}")
        return value
    value = str(value)
    if spec.choices and value not in choice_ids(spec):
        raise InputError(f"unknown {spec.label.lower()} {value!r}: choose from {', '.join(choice_ids(spec))}")
    return value


@dataclasses.dataclass
class Options:
    """Base of the job options classes: :meth:`validate` checks every declared field, then :meth:`check`."""

    def validate(self):
        """Raise InputError for any value out of range or not among the choices (before anything is
        touched); return self with values converted to their kinds."""
        for name, kind, _, spec in specs(type(self)):
            setattr(self, name, check_value(name, kind, spec, getattr(self, name)))
        self.check()
        return self

    def check(self):
        """Rules between fields (a subclass overrides it)."""

    def replace(self, **changes):
        return dataclasses.replace(self, **changes)
