"""Shadow-lab performance figures, side by side with the issue's targets.

    python scripts/bench_shadows.py

1. numpy shadow-map lookup with 3x3 PCF: a 512x512 frame against a 2048x2048 map (target <= 0.5 s);
2. the 2048x2048 depth map of the 10k-triangle sphere scene: Cycles' Depth pass beside the numpy
   rasteriser (target <= 0.3 s), their ratio, depth and mask differences, the limits;
3. shadow volumes (silhouette, extrusion, z-fail stencil) for a 10k-triangle occluder in a
   512x512 frame (target <= 5 s);
4. per-method seconds of one comparison on the sphere scene at 256x256.
"""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import _cli  # noqa: E402


def main(args):
    from addon.lab.bench import shadows
    load = os.getloadavg()
    rows = shadows.speed(resolution=args.resolution, map_size=args.map_size, repeats=args.repeats)
    print(f"load average (1, 5, 15 min) before {load[0]:.2f} {load[1]:.2f} {load[2]:.2f}, after "
          + " ".join(f"{x:.2f}" for x in os.getloadavg()) + f" on {os.cpu_count()} cores")
    print(f"{'figure':100s} {'seconds':>9s} {'target':>8s}")
    for name, sec, target in rows:
        tgt = f"<= {target:g}" if target else ""
        flag = "" if target is None else ("  ok" if sec <= target else "  SLOW")
        print(f"{name:100s} {'' if sec is None else f'{sec:9.3f}':>9s} {tgt:>8s}{flag}")


def build_parser():
    p = _cli.parser("bench_shadows.py", "Print the shadow lab's performance figures.", blend_file=False)
    p.add_argument("--resolution", type=_cli.number(int, 8, 8192), default=512, help="frame size (default 512)")
    p.add_argument("--map-size", type=_cli.number(int, 2, 16384), default=2048, help="shadow-map size (default 2048)")
    p.add_argument("--repeats", type=_cli.number(int, 1, 100), default=3,
                   help="Cycles depth renders timed, best taken (the raster: at least 5; default 3)")
    return p


if __name__ == "__main__":
    _cli.run(build_parser(), main)
