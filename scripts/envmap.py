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
    if args.env and args.blend:
        raise InputError("give either FILE.blend or --env FILE, not both")
    summary = envmap.run(os.path.abspath(args.out), env_file=args.env, method=args.method, width=args.width)
    print(f"envmap: {summary['file']} ({args.method}, {summary['seconds'] * 1e3:.1f} ms)")
    print(f"  report: {summary['report']}")


def build_parser():
    p = _cli.parser("envmap.py", "Irradiance environment map E(n) of a lat-long environment (seed 002).")
    p.add_argument("--env", metavar="FILE", help="lat-long environment (.exr or .hdr) instead of the world's")
    p.add_argument("--out", required=True, help="output folder")
    p.add_argument("--method", choices=("sh9", "brute"), default="sh9",
                   help="nine spherical harmonics (default) or brute-force convolution")
    p.add_argument("--width", type=_cli.number(int, 4), default=64,
                   help="width of the irradiance map, even (height = width/2; default 64; memory and time are "
                        "checked first)")
    return p


if __name__ == "__main__":
    _cli.run(build_parser(), main)
