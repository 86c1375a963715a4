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

from addon.core.ssao import limits
from addon.core.ssao import methods as ssao_methods
from addon.core.choices import parse_choices  # noqa: E402
from addon.core.errors import InputError  # noqa: E402


def _validate(args):
    """Every bad-input check that needs no Blender (fast exit 2): numbers are checked by the parser,
    the cost of a built-in scene's square frame here."""
    methods = parse_choices(args.methods, ssao_methods.ALL_METHODS, "SSAO method")
    if args.scene is not None:
        limits.check_scene(args.scene)
    if args.scene is not None and args.blend:
        raise InputError("give either FILE.blend or --scene, not both")
    if not args.blend and not args.sweeps:
        limits.check_cost(args.resolution, args.resolution, args.samples, args.reference_samples,
                             sum(m in ssao_methods.METHODS for m in methods))
    return methods


def main(args):
    methods = _validate(args)
    out = os.path.abspath(args.out)
    cache = os.path.abspath(args.cache) if args.cache else os.path.join(out, "cache")
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
    kwargs = dict(samples=args.samples, radius=args.radius, reference_samples=args.reference_samples,
                  cache_dir=cache, blur=args.blur, seed=args.seed)
    if args.blend:
        scene = bpy.context.scene
        report = lab.compare(scene, methods, out, resolution=args.resolution if args.resolution_given else None,
                             **kwargs)
    else:
        report = lab.run_builtin(args.scene or "corner", methods, out, resolution=args.resolution, **kwargs)
    print(f"ssao: {os.path.join(out, 'ssao_report.json')}")
    for line in lab.summary_lines(report):
        print(f"  {line}")


class _Resolution(_cli.argparse.Action):
    def __call__(self, parser, namespace, values, option_string=None):
        setattr(namespace, self.dest, values)
        namespace.resolution_given = True


def build_parser():
    p = _cli.parser("ssao.py", "Compare screen-space AO methods with Cycles' ray-traced AO.")
    p.add_argument("--scene", choices=None, metavar="NAME",
                   help=f"a built-in scene: {', '.join(limits.SCENES)} (default corner without FILE.blend)")
    p.add_argument("--methods", default="crytek,hemisphere,hbao,gtao",
                   help=f"comma-separated, from {','.join(ssao_methods.ALL_METHODS)} (default: the numpy ones)")
    p.add_argument("--out", default="out/ssao", help="output folder (default out/ssao)")
    p.add_argument("--resolution", type=_cli.number(int, 8, limits.MAX_RESOLUTION), default=128,
                   action=_Resolution, help=f"frame width in pixels, 8..{limits.MAX_RESOLUTION} (default 128; a "
                                            ".blend keeps its own unless given; memory and time are checked first)")
    p.add_argument("--samples", type=_cli.number(int, 1, limits.MAX_SAMPLES), default=16,
                   help=f"depth-buffer samples per pixel, 1..{limits.MAX_SAMPLES} (default 16)")
    p.add_argument("--radius", type=_cli.number(float, above=0), default=1.0,
                   help="SSAO radius in metres = the reference's AO distance (default 1.0)")
    p.add_argument("--reference-samples", type=_cli.number(int, 1, limits.MAX_REFERENCE_SAMPLES), default=1024,
                   help=f"Cycles AO samples per pixel of the reference, 1..{limits.MAX_REFERENCE_SAMPLES} "
                        "(default 1024: noise <= 0.016)")
    p.add_argument("--blur", action="store_true", help="depth-aware blur after each numpy method")
    p.add_argument("--seed", type=_cli.number(int, 0, 2 ** 32 - 1), default=0, help="random seed of the numpy methods")
    p.add_argument("--cache", metavar="DIR", help="reference cache folder (default <out>/cache)")
    p.add_argument("--sweeps", action="store_true", help="run the sweeps (charts, tables) instead")
    p.add_argument("--quick", action="store_true", help="with --sweeps: small frames, well under a minute")
    p.set_defaults(resolution_given=False)
    return p


if __name__ == "__main__":
    _cli.run(build_parser(), main)
