"""Radiosity of the built-in Cornell-like box or a .blend, compared with a Cycles irradiance bake.

    python scripts/radiosity.py [FILE.blend | --scene cornell] --out DIR [--solver jacobi|gauss_seidel|progressive]
    blender -b FILE.blend -P scripts/radiosity.py -- --out DIR
"""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import _cli  # noqa: E402

MAX_ADAPTIVE = 8           # addon.lab.radiosity.MAX_ADAPTIVE, MAX_SAMPLES (not imported: --help needs no bpy)
MAX_SAMPLES = 65536


def main(args):
    from addon.core.errors import InputError
    from addon.lab import radiosity
    if args.scene and args.blend:
        raise InputError("give either FILE.blend or --scene cornell, not both")
    r = radiosity.run(os.path.abspath(args.out), cornell=args.scene == "cornell", solver=args.solver,
                      max_edge=args.max_edge, adaptive=args.adaptive, samples=args.samples,
                      compare=not args.no_compare, tol=args.tol)
    rep = r["report"]
    print(f"radiosity: {rep['patches']} patches ({rep['back_patches']} of them back sides), {rep['solver']} "
          f"{rep['iterations']} iterations, {rep['seconds']:.2f} s")
    if rep["rms_vs_cycles"] is not None:
        print(f"  vs Cycles ({rep['cycles_samples']} samples, {rep['cycles_seconds']:.2f} s): "
              f"RMS {rep['rms_vs_cycles']:.4g} W/m^2 ({100 * rep['relative_rms_vs_cycles']:.1f}% of the mean)")
    print(f"  report: {os.path.join(os.path.abspath(args.out), radiosity.REPORT)}")


def build_parser():
    p = _cli.parser("radiosity.py", "Radiosity solution as vertex colours and light maps, checked against Cycles.")
    p.add_argument("--scene", choices=("cornell",), help="the built-in Cornell-box-like scene")
    p.add_argument("--out", required=True, help="output folder")
    p.add_argument("--solver", choices=("jacobi", "gauss_seidel", "progressive"), default="jacobi")
    p.add_argument("--max-edge", type=_cli.number(float, above=0), default=0.25,
                   help="longest patch edge in metres (default 0.25); refused up front when the N² solve would "
                        "not fit in the available memory or would take more than an hour")
    p.add_argument("--adaptive", type=_cli.number(int, 0, MAX_ADAPTIVE), default=0,
                   help="rounds of adaptive subdivision (default 0)")
    p.add_argument("--samples", type=_cli.number(int, 1, MAX_SAMPLES), default=64,
                   help="Cycles samples of the comparison bake (default 64)")
    p.add_argument("--tol", type=_cli.number(float, above=0, maximum=0.5), default=1e-5,
                   help="relative residual to stop at (default 1e-5)")
    p.add_argument("--no-compare", action="store_true", help="skip the Cycles bake")
    return p


if __name__ == "__main__":
    _cli.run(build_parser(), main)
