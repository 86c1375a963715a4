"""What every batch script shares: run two ways, parse, exit 0 / 2 / 1 with one error line.

    blender -b [FILE.blend] -P scripts/x.py -- ARGS
    python scripts/x.py [FILE.blend] ARGS          (the pip bpy module)

Each script builds an ``argparse`` parser (its job's options from the job's options class, see
``add_options``) and calls ``run(parser, main)``; ``main(args)`` returns nothing on success and
raises ``ILError`` (exit 1) or ``InputError`` (exit 2) with a readable message. Numeric options use ``number``
(finite, in range, else exit 2 at parse time); an ``--out`` folder is checked
before anything runs (exit 2, nothing created); Ctrl-C stops at the next safe
point with exit 130 (``addon.blender.interrupt``); a full disk or out-of-memory is one
line with exit 1; only a genuine bug shows its type name.
"""
import argparse
import contextlib
import math
import os
import sys
import traceback
import warnings

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
if ROOT not in sys.path:
    sys.path.insert(0, ROOT)

from addon.blender import chatter, interrupt  # noqa: E402  (no bpy)

if "bpy" not in sys.modules:                   # Blender logs while it starts (e.g. the OCIO config in use)
    with chatter.captured(always=True), contextlib.suppress(ImportError):
        import bpy  # noqa: E402,F401
from addon.core.errors import OUT_OF_MEMORY, ILError, ILWarning, InputError, os_error_message  # noqa: E402
from addon.core.io import blend, files  # noqa: E402
from addon.core.io.files import check_output_dir  # noqa: E402
from addon.core import options as core_options  # noqa: E402
from addon.core.choices import parse_choices  # noqa: E402

INTERRUPTED = 130


class ArgumentParser(argparse.ArgumentParser):
    """argparse that fails with one line on stderr and exit code 2."""

    def error(self, message):
        print(f"{self.prog}: error: {message}", file=sys.stderr)
        sys.exit(2)


def parser(prog, description, blend_file=True):
    """A parser for ``prog``; with ``blend_file`` it takes an optional FILE.blend first."""
    p = ArgumentParser(prog=prog, description=description)
    if blend_file:
        p.add_argument("blend", nargs="?", metavar="FILE.blend",
                       help="open this file first (inside Blender: give it before -P instead)")
    return p


def bench_parser(prog, description, output_dir, quick_help="small sizes and sample counts"):
    """A parser for a benchmark or the demo: ``--out`` (default ``output_dir``) and ``--quick``; no .blend."""
    p = parser(prog, description, blend_file=False)
    p.add_argument("--out", default=output_dir, help=f"output folder (default {output_dir})")
    p.add_argument("--quick", action="store_true", help=quick_help)
    return p


def number(kind=float, minimum=None, maximum=None, above=None):
    """An argparse ``type``: a finite ``kind`` (int or float) with ``minimum <= x <= maximum`` and
    ``x > above`` where given; anything else is a parse error (exit 2) that names the range."""
    def parse(text):
        try:
            value = kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"not a{'n integer' if kind is int else ' number'}: {text!r}") from None
        if isinstance(value, float) and not math.isfinite(value):
            raise argparse.ArgumentTypeError(f"must be a finite number, got {text}")
        if above is not None and not value > above:
            raise argparse.ArgumentTypeError(f"must be greater than {above}, got {text}")
        if minimum is not None and value < minimum or maximum is not None and value > maximum:
            lo = "" if minimum is None else f"{minimum} <= "
            hi = "" if maximum is None else f" <= {maximum}"
            raise argparse.ArgumentTypeError(f"must be {lo}value{hi}, got {text}")
        return value
    parse.__name__ = kind.__name__
    return parse


def joined(choices, separator, what):
    """An argparse ``type``: ``a,b,c`` -> ["a", "b", "c"], each one of ``choices`` (a parse error names the
    unknown one and the choices)."""
    def parse(text):
        try:
            return parse_choices(text.split(separator), choices, what)
        except InputError as e:
            raise argparse.ArgumentTypeError(str(e)) from None
    parse.__name__ = what
    return parse


def add_options(p, cls, skip=()):
    """Add one argument per field of the options class ``cls`` (core.options): ``--name-with-dashes``,
    its type with the field's limits (``number``), its choices, ``store_true`` for a bool that defaults to
    False and ``--no-name`` for one that defaults to True, ``nargs="+"`` for a list. argparse defaults
    are None so :func:`options_from` keeps the class default (shown in the help)."""
    groups = {}
    for name, kind, default, spec in core_options.specs(cls):
        if not spec.cli or name in skip:
            continue
        target = p
        if spec.group:
            if spec.group not in groups:
                groups[spec.group] = p.add_mutually_exclusive_group()
            target = groups[spec.group]
        flag = spec.flag or "--" + name.replace("_", "-")
        shown = (spec.separator or " ").join(map(str, default)) if isinstance(default, (list, tuple)) else default
        notes = []
        if kind in (int, float) and spec.minimum is not None and spec.maximum is not None:
            notes.append(f"{spec.minimum}..{spec.maximum}")
        if default is not None and default is not False and kind is not bool:
            notes.append(f"default {shown}")
        help_ = spec.help + (f" ({'; '.join(notes)})" if notes else "")
        kw = {"dest": name, "default": None, "help": help_}
        if kind is bool:
            if default:
                flag = spec.flag or "--no-" + name.replace("_", "-")
                kw.update(action="store_false", help="do not " + help_)
            else:
                kw.update(action="store_true")
            kw.pop("default")
            target.add_argument(flag, **kw)
            continue
        if spec.multiple and spec.separator:
            kw["type"] = joined(core_options.choice_ids(spec), spec.separator, spec.item or spec.label.lower())
        elif spec.choices:
            kw["choices"] = core_options.choice_ids(spec)
        elif kind in (int, float):
            kw["type"] = number(kind, spec.minimum, spec.maximum, spec.above)
        if spec.multiple and not spec.separator:
            kw["nargs"] = "+"
        kw["metavar"] = spec.metavar or ("N" if kind is int else "X" if kind is float else
                                         "M[,M...]" if spec.separator else None)
        if kw["metavar"] is None:
            del kw["metavar"]
        target.add_argument(flag, **kw)
    for name, kind, default, spec in core_options.specs(cls):
        if kind is bool and spec.cli and name not in skip:
            p.set_defaults(**{name: default})
    return p


def options_from(cls, args, **extra):
    """An instance of the options class ``cls`` from parsed ``args`` (class defaults where an argument was
    not given), validated."""
    values = {name: getattr(args, name) for name, _, _, spec in core_options.specs(cls)
              if spec.cli and getattr(args, name, None) is not None}
    return cls(**values, **extra).validate()


def script_argv(argv=None):
    """The script's own arguments: after ``--`` inside Blender, else everything after the script."""
    argv = list(sys.argv if argv is None else argv)
    if "--" in argv:
        return argv[argv.index("--") + 1:]
    if _inside_blender():
        return []
    return argv[1:]


def _inside_blender():
    import bpy
    return bool(bpy.app.binary_path) and not bpy.app.binary_path.endswith(("python", "python3"))


def open_blend(path):
    """Open ``path`` (bpy module runs) -- the file on disk is never written by the scripts."""
    import bpy
    if not os.path.isfile(path):
        raise InputError(f"no such .blend file: {path}")
    if not path.lower().endswith(".blend"):
        raise InputError(f"not a .blend file: {path}")
    blend.blend_version(path)              # a damaged header crashes Blender's loader: refuse it first
    try:
        with interrupt.blender_call():
            bpy.ops.wm.open_mainfile(filepath=os.path.abspath(path), load_ui=False)
    except RuntimeError as e:
        reason = str(e).strip().splitlines()[-1] if str(e).strip() else "unreadable"
        raise InputError(f"cannot open {path}: damaged or not a Blender file ({reason})") from None


def run(p, main, argv=None):
    """Parse the script arguments, check the output folder, open the .blend if one is given, call
    ``main``, exit 0 / 1 / 2 / 130 with one line on stderr."""
    args = p.parse_args(script_argv(argv))
    interrupt.install()
    chatter.enable()
    warnings.simplefilter("always", ILWarning)
    warnings.showwarning = lambda message, category, *rest: print(
        f"{p.prog}: {'warning: ' if issubclass(category, ILWarning) else ''}{message}", file=sys.stderr)
    code = 0
    try:
        if getattr(args, "out", None) is not None:
            check_output_dir(args.out)
        if getattr(args, "blend", None):
            open_blend(args.blend)
        main(args)
        interrupt.checkpoint()
    except InputError as e:
        print(f"{p.prog}: error: {e}", file=sys.stderr)
        code = 2
    except ILError as e:
        print(f"{p.prog}: error: {e}", file=sys.stderr)
        code = 1
    except KeyboardInterrupt:
        print(f"{p.prog}: interrupted: stopped, the file and finished outputs are as they were", file=sys.stderr)
        code = INTERRUPTED
    except MemoryError:
        print(f"{p.prog}: error: {OUT_OF_MEMORY}", file=sys.stderr)
        code = 1
    except OSError as e:
        print(f"{p.prog}: error: {os_error_message(e)}", file=sys.stderr)
        code = 1
    except Exception as e:  # noqa: BLE001 - a bug: one line, the traceback on request
        if os.environ.get("IL_DEBUG"):
            traceback.print_exc()
        print(f"{p.prog}: internal error (please report, IL_DEBUG=1 shows the traceback and Blender's output): "
              f"{type(e).__name__}: {e}", file=sys.stderr)
        code = 1
    if code:
        files.remove_own_temporaries()
    if code and os.environ.get("IL_DEBUG") and chatter.tail():
        print(f"{p.prog}: Blender's own output, last lines:\n  " + "\n  ".join(chatter.tail()), file=sys.stderr)
    sys.stdout.flush()
    sys.stderr.flush()
    if not _inside_blender():            # the pip bpy module: nothing of the user's runs after the script
        chatter.silence_rest()
    if code:
        sys.exit(code)
