"""SSAO lab: screen-space AO methods against Cycles' ray-traced AO on the same pixels.

    python scripts/ssao.py --scene corner --methods crytek,hemisphere,hbao,gtao --out out/ssao
    python scripts/ssao.py my.blend --methods gtao,eevee --radius 0.5 --out out/ssao
    blender -b my.blend -P scripts/ssao.py -- --methods gtao,workbench --out out/ssao
    python scripts/ssao.py --sweeps --quick --out out/ssao_sweeps

Writes <out>/<method>_ao.exr and <out>/reference_ao.exr ("Y" = k_A, "A" = 1 on
geometry), <method>_error.png, <out>/ssao_report.json; the reference is cached
in <out>/cache (or --cache DIR). With --sweeps: the charts and tables of
addon/lab/bench/ssao.py instead.
"""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import _cli  # noqa: E402

from addon.core.ssao import limits  # noqa: E402
from addon.core.ssao import methods as ssao_methods  # noqa: E402
from addon.core.errors import InputError  # noqa: E402
from addon.core.io.files import check_output_dir  # noqa: E402
from addon.lab.options import SSAOOptions  # noqa: E402  (no bpy)


def _validate(args):
    """Every bad-input check that needs no Blender (fast exit 2): numbers are checked by the parser,
    the cost of a built-in scene's square frame here. Returns the options."""
    options = _cli.options_from(SSAOOptions, args)
    if args.scene is not None:
        limits.check_scene(args.scene)
    if args.scene is not None and args.blend:
        raise InputError("give either FILE.blend or --scene, not both")
    if not args.blend and not args.sweeps:
        limits.check_cost(options.resolution, options.resolution, options.samples, options.reference_samples,
                          sum(m in ssao_methods.METHODS for m in options.methods))
    return options


def main(args):
    o = _validate(args)
    if args.blend:
        o.resolution = args.resolution      # None: the .blend keeps its own frame
    out = os.path.abspath(args.out)
    cache = check_output_dir(os.path.join(out, "cache") if args.cache is None else args.cache)
    if args.sweeps:
        from addon.lab.bench import ssao as bench_ssao
        result = bench_ssao.run(out, quick=args.quick)
        print(f"ssao sweeps: {out}")
        for path in result.charts:
            print(f"  chart {path}")
        for name in result.tables:
            print(f"  table {os.path.join(out, name + '.csv')}")
        return
    import bpy
    from addon.lab import ssao as lab
    if args.blend:
        result = lab.compare(bpy.context.scene, out, o, cache_dir=cache)
    else:
        result = lab.run_builtin(args.scene or "corner", out, o, cache_dir=cache)
    print(f"ssao: {result.path}")
    for line in lab.summary_lines(result):
        print(f"  {line}")


def build_parser():
    p = _cli.parser("ssao.py", "Compare screen-space AO methods with Cycles' ray-traced AO.")
    p.add_argument("--scene", choices=None, metavar="NAME",
                   help=f"a built-in scene: {', '.join(limits.SCENES)} (default corner without FILE.blend)")
    p.add_argument("--out", default="out/ssao", help="output folder (default out/ssao)")
    _cli.add_options(p, SSAOOptions)
    p.add_argument("--cache", metavar="DIR", help="reference cache folder (default <out>/cache)")
    p.add_argument("--sweeps", action="store_true", help="run the sweeps (charts, tables) instead")
    p.add_argument("--quick", action="store_true", help="with --sweeps: small frames, well under a minute")
    return p


if __name__ == "__main__":
    _cli.run(build_parser(), main)
