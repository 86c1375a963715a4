"""Radiosity of the built-in Cornell-like box or a .blend, compared with a Cycles irradiance bake.

    python scripts/radiosity.py [FILE.blend | --scene cornell] --out DIR [--solver jacobi|gauss_seidel|progressive]
                                [--compare-solvers]
    blender -b FILE.blend -P scripts/radiosity.py -- --out DIR
"""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import _cli  # noqa: E402


def main(args):
    from addon.core.errors import InputError
    from addon.lab import radiosity
    from addon.lab.options import RadiosityOptions
    if args.scene and args.blend:
        raise InputError("give either FILE.blend or --scene cornell, not both")
    o = _cli.options_from(RadiosityOptions, args)
    result = radiosity.run(os.path.abspath(args.out), o, cornell=args.scene == "cornell")
    rep = result.report
    print(f"radiosity: {rep['patches']} patches ({rep['back_patches']} of them back sides), {rep['solver']} "
          f"{rep['iterations']} iterations, {rep['seconds']:.2f} s (estimated at most {rep['estimate']['seconds']:.1f} s)"
          + (f"; solvers compared: {', '.join(rep['solvers'])}" if rep["solvers_compared"] else ""))
    if rep["rms_vs_cycles"] is not None:
        print(f"  vs Cycles ({rep['cycles_samples']} samples, {rep['cycles_seconds']:.2f} s): "
              f"RMS {rep['rms_vs_cycles']:.4g} W/m^2 ({100 * rep['relative_rms_vs_cycles']:.1f}% of the mean)")
    print(f"  report: {result.path}")


def build_parser():
    from addon.lab.options import RadiosityOptions
    p = _cli.parser("radiosity.py", "Radiosity solution as vertex colours and light maps, checked against Cycles.")
    p.add_argument("--scene", choices=("cornell",), help="the built-in Cornell-box-like scene")
    p.add_argument("--out", required=True, help="output folder")
    return _cli.add_options(p, RadiosityOptions)


if __name__ == "__main__":
    _cli.run(build_parser(), main)
