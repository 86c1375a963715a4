"""The main job: build the embedded demo scene and write its outputs to --out.

    python scripts/demo.py --out out/demo
    blender -b -P scripts/demo.py -- --out out/demo
"""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import _cli  # noqa: E402


def main(args):
    from addon.lab.demo import job
    result = job.run(os.path.abspath(args.out), quick=args.quick, samples=args.samples)
    print(f"demo: outputs in {os.path.dirname(result.path)}")
    for line in result.summary.splitlines():
        print(f"  {line}")


def build_parser():
    p = _cli.bench_parser("demo.py", "Build the demo scene and run the project's tools on it.",
                          "out/demo", "smallest sizes, for tests")
    p.add_argument("--samples", type=_cli.number(int, 1, 4096), default=32,
                   help="Cycles samples of the preview render, 1..4096 (default 32)")
    return p


if __name__ == "__main__":
    _cli.run(build_parser(), main)
