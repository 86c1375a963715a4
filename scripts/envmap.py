"""Irradiance environment map: the world's environment texture (or a lat-long file) -> E(n) as EXR.

    python scripts/envmap.py [FILE.blend | --env FILE.exr] --out DIR [--method sh9|brute] [--width W]
    blender -b FILE.blend -P scripts/envmap.py -- --out DIR
"""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import _cli  # noqa: E402


def main(args):
    from addon.core.errors import InputError
    from addon.lab import envmap
    from addon.lab.options import EnvmapOptions
    if args.env and args.blend:
        raise InputError("give either FILE.blend or --env FILE, not both")
    o = _cli.options_from(EnvmapOptions, args)
    result = envmap.run(os.path.abspath(args.out), o, env_file=args.env)
    print(f"envmap: {result['file']} ({o.method}, {result['seconds'] * 1e3:.1f} ms)")
    print(f"  report: {result.path}")


def build_parser():
    from addon.lab.options import EnvmapOptions
    p = _cli.parser("envmap.py", "Irradiance environment map E(n) of a lat-long environment (seed 002).")
    p.add_argument("--env", metavar="FILE", help="lat-long environment (.exr or .hdr) instead of the world's")
    p.add_argument("--out", required=True, help="output folder")
    return _cli.add_options(p, EnvmapOptions)


if __name__ == "__main__":
    _cli.run(build_parser(), main)
