"""Speed against accuracy for every method the project offers: charts, CSV tables and report.md.

    python scripts/bench.py --out out/bench --quick
    blender -b -P scripts/bench.py -- --out out/bench
"""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import _cli  # noqa: E402


def main(args):
    from addon.lab import report
    result = report.run(os.path.abspath(args.out), quick=args.quick, areas=args.areas)
    print(f"bench: {result['report']} ({result['seconds']:.0f} s)")


def build_parser():
    p = _cli.bench_parser("bench.py", "Run the sweeps of all labs and write report.md with charts and CSV tables.",
                          "out/bench", "small sizes and sample counts (under a minute)")
    p.add_argument("--areas", nargs="+", metavar="KEY",
                   help="only these areas, by key (default: all; the keys are those of addon.lab.report.AREAS: "
                        "an unknown one is refused with the list)")
    return p


if __name__ == "__main__":
    _cli.run(build_parser(), main)
