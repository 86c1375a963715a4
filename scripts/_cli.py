"""What every batch script shares: run two ways, parse, exit 0 / 2 / 1 with one error line.

    blender -b [FILE.blend] -P scripts/x.py -- ARGS
    python scripts/x.py [FILE.blend] ARGS          (the pip bpy module)

Each script builds an ``argparse`` parser and calls ``run(parser, main)``;
``main(args)`` returns nothing on success and raises ``ILError`` (exit 1) or
``InputError`` (exit 2) with a readable message.
"""
import argparse
import os
import sys
import traceback

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
if ROOT not in sys.path:
    sys.path.insert(0, ROOT)

from addon.core.errors import ILError, InputError  # noqa: E402


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
    bpy.ops.wm.open_mainfile(filepath=os.path.abspath(path), load_ui=False)


def run(p, main, argv=None):
    """Parse the script arguments, open the .blend if one is given, call ``main``, exit."""
    args = p.parse_args(script_argv(argv))
    code = 0
    try:
        if getattr(args, "blend", None):
            open_blend(args.blend)
        main(args)
    except InputError as e:
        print(f"{p.prog}: error: {e}", file=sys.stderr)
        code = 2
    except ILError as e:
        print(f"{p.prog}: error: {e}", file=sys.stderr)
        code = 1
    except KeyboardInterrupt:
        print(f"{p.prog}: error: interrupted", file=sys.stderr)
        code = 130
    except Exception as e:  # noqa: BLE001 - the one readable line, details only on request
        if os.environ.get("IL_DEBUG"):
            traceback.print_exc()
        print(f"{p.prog}: error: {type(e).__name__}: {e}", file=sys.stderr)
        code = 1
    sys.stdout.flush()
    sys.stderr.flush()
    if code:
        sys.exit(code)
