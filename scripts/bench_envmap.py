"""Benchmark: SH irradiance of a 1024x512 environment (target <= 0.2 s) and radiosity of about 2000 patches
including visibility (target <= 30 s), figures side by side.

    python scripts/bench_envmap.py [--out DIR] [--quick]
"""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import _cli  # noqa: E402


def main(args):
    from addon.lab.bench import envmap
    res = envmap.run(os.path.abspath(args.out), quick=args.quick)
    print(f"{'measure':44s} {'value':>12s} {'target':>10s}")
    for row in res.tables["targets"]:
        print(f"{row['measure']:44s} {row['value']:12.4g} {row['target']:>10}")
    for c in res.charts:
        print(f"  chart: {c}")


def build_parser():
    p = _cli.bench_parser("bench_envmap.py", "Speed and accuracy of irradiance maps and radiosity.",
                          "out/bench_envmap", "small sizes (seconds)")
    return p


if __name__ == "__main__":
    _cli.run(build_parser(), main)
