"""Level benchmark: a generated level of 200+ objects baked AO + irradiance per object and as an atlas; pipeline
wall time against Blender's bare bake calls, peak RSS, texels per second, atlas utilisation against uv.pack_islands;
time outside Cycles over time inside at --samples and at 64 (production) samples, first runs and reruns with a
light changed (layouts from the UV cache; --reruns of them at 64 samples, each in a new process: the median one's
row, with the range).

    python scripts/bench_level.py --out out/bench_level [--quick] [--props N] [--texel-density T] [--samples N]
                                  [--reruns N]
"""
import json
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import _cli  # noqa: E402


def main(args):
    from addon.lab.bench import level
    from addon.core import charts
    out = os.path.abspath(args.out)
    result = level.run(out, quick=args.quick, props=args.props, texel_density=args.texel_density,
                       samples=args.samples, reruns=args.reruns)
    for name, rows in result.tables.items():
        charts.write_csv(os.path.join(out, f"{name}.csv"), rows)
        for row in rows:
            print("  ".join(f"{k}={v}" for k, v in row.items()))
    print("figures:", json.dumps(result.figures, indent=1, default=str))


def build_parser():
    p = _cli.bench_parser("bench_level.py", "Benchmark light maps of a generated level.", "out/bench_level",
                          "24 props, small maps (about a minute)")
    p.add_argument("--props", type=_cli.number(int, 1, 5000), help="props in the level (default 200, quick 24)")
    p.add_argument("--texel-density", type=_cli.number(float, above=0), help="texels per metre (default 10)")
    p.add_argument("--samples", type=_cli.number(int, 1, 4096), help="Cycles samples (default 8, quick 4)")
    p.add_argument("--reruns", type=_cli.number(int, 1, 99),
                   help="reruns at 64 samples with a light changed, each in a new process (default 3)")
    return p


if __name__ == "__main__":
    _cli.run(build_parser(), main)
