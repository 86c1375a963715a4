"""Light-map benchmark: pipeline overhead over the bare Cycles bake, and time to RMS 0.01 vs analytic k_A.

    python scripts/bench_bake.py --out out/bench_bake [--quick]
"""
import json
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import _cli  # noqa: E402


def main(args):
    from addon.lab.bench import lightmaps
    from addon.core import charts
    out = os.path.abspath(args.out)
    result = lightmaps.run(out, quick=args.quick)
    for name, rows in result.tables.items():
        charts.write_csv(os.path.join(out, f"{name}.csv"), rows)
        print(f"{name}:")
        for row in rows:
            print("  " + "  ".join(f"{k}={v:.4g}" if isinstance(v, float) else f"{k}={v}" for k, v in row.items()))
    print("figures:", json.dumps(result.figures, indent=1))
    for c in result.charts:
        print(f"chart: {c}")


def build_parser():
    p = _cli.bench_parser("bench_bake.py", "Benchmark the light-map bake.",
                          "out/bench_bake", "small sizes (well under a minute)")
    return p


if __name__ == "__main__":
    _cli.run(build_parser(), main)
