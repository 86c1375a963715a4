"""Cycles render cost of the IL shading models against a Principled BSDF, side by side in one run.

    python scripts/bench_shading.py                       # 256² at 64 spp and 64² at 8 spp, 1 and 4 lights
    python scripts/bench_shading.py --repeats 5 --configs 128x16
    blender -b -P scripts/bench_shading.py -- --repeats 3

The same scene (floor, ball, dim world; one point light, or point + sun + spot + point) is rendered with
each material in turn, F12 as a user does (sync, shader compile, path tracing), best of --repeats with the
materials alternating in each repeat. Prints seconds, the ratio over the Principled BSDF of the same row
set, the same for CPU seconds (all threads; steadier than wall time when other jobs share the cores),
nanoseconds per camera sample, the cost of each extra light, the node count of each group, and the
machine's load average (the machine is shared: ratios from one run are what count). "nodes/light" is what
Blender converts for each light at every render (a point light's group and the model's light half, the variants
the material's switch values select), "nodes once" the model's surface half.
"""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import _cli  # noqa: E402


def _config(text):
    try:
        size, samples = (int(x) for x in text.lower().split("x"))
    except ValueError:
        raise _cli.argparse.ArgumentTypeError(f"expected SIZExSAMPLES such as 256x64, got {text!r}") from None
    if not (8 <= size <= 2048 and 1 <= samples <= 4096):
        raise _cli.argparse.ArgumentTypeError(f"size must be 8..2048 and samples 1..4096, got {text!r}")
    return size, samples


def main(args):
    from addon.lab.bench import shading
    load = os.getloadavg()
    counts = shading.node_counts()
    rows = shading.render_cost(configs=args.configs, light_counts=args.lights, repeats=args.repeats)
    print(f"Cycles CPU render, best of {args.repeats}; load average before {load[0]:.2f} {load[1]:.2f} "
          f"{load[2]:.2f}, after {' '.join(f'{x:.2f}' for x in os.getloadavg())} ({os.cpu_count()} cores)")
    print("nodes per group: " + ", ".join(f"{k} {v}" for k, v in counts.items()))
    print(f"{'lights':>6} {'size':>5} {'spp':>4}  {'material':<24}{'seconds':>9}{'ratio':>7}{'ns/sample':>11}"
          f"{'CPU s':>8}{'CPU ratio':>10}{'nodes/light':>12}{'nodes once':>11}")
    for r in rows:
        print(f"{r['lights']:>6} {r['size']:>5} {r['samples']:>4}  {r['model']:<24}{r['seconds']:>9.3f}"
              f"{r['ratio']:>7.2f}{r['ns_per_sample']:>11.0f}{r['cpu_seconds']:>8.3f}{r['cpu_ratio']:>10.2f}"
              f"{r['nodes_per_light'] or '':>12}{r['nodes_once'] or '':>11}")
    per = shading.per_light_cost(rows)
    if per:
        print("cost of each extra light (from the two light counts):")
        for (model, size, samples), (sec, ns) in per.items():
            print(f"  {size:>4}² {samples:>3} spp  {model:<24}{sec:>8.3f} s{ns:>8.0f} ns/sample")


def build_parser():
    p = _cli.parser("bench_shading.py", "Time Cycles renders of the IL shading models beside a Principled BSDF.",
                    blend_file=False)
    p.add_argument("--repeats", type=_cli.number(int, 1, 50), default=3, help="best of N renders (default 3)")
    p.add_argument("--configs", type=_config, nargs="+", default=[(256, 64), (64, 8)], metavar="SIZExSPP",
                   help="resolutions and samples per pixel (default 256x64 64x8)")
    p.add_argument("--lights", type=_cli.number(int, 1, 4), nargs="+", default=[1, 4],
                   help="light counts (default 1 4)")
    return p


if __name__ == "__main__":
    _cli.run(build_parser(), main)
