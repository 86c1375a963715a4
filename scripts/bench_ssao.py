"""SSAO speed: every numpy method on a 512² frame at 16 samples per pixel, beside EEVEE's AO pass.

    python scripts/bench_ssao.py                  # 512², 16 spp, corner scene
    python scripts/bench_ssao.py --resolution 256 --samples 32 --no-eevee
    python scripts/bench_ssao.py --no-eevee --baseline /work/main     # before and after, same run

Times are the best of --repeats runs (wall and CPU seconds of this process); the
numpy methods start from the G-buffer (rendered once). ns per pixel-sample =
seconds / (geometry pixels x samples): the Pareto chart's time axis divided by
the work. "passes" and "B/px-s" are the numpy passes (ufunc calls' elements) and
bytes touched per pixel-sample, counted (addon.lab.bench.ssao.count_passes);
"floor" is what they would cost at this machine's plainest rates (every pass as
fast as c = a·b in cache, plus the method's random draws and four gathers), and
"x floor" the measured CPU cost over it.
Peak memory is tracemalloc's peak during one more run (numpy's arrays included).
With --baseline DIR the numpy methods of that checkout (e.g. the main branch)
run interleaved with these on the same G-buffer, and max |Δk| compares the images.
EEVEE's figure is the whole render call (scene sync, AO pass, writing the
passes), after a warm-up render that compiles its shaders. RMSE is against
Cycles' AO pass (256 samples by default, noise stated).
"""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import _cli  # noqa: E402

from addon.core.ssao import limits as core_ssao


def _mib(n):
    return f"{n / 2 ** 20:.0f}"


def main(args):
    import numpy as np
    from addon.core.ssao import metrics
    from addon.lab.bench import ssao as bench_ssao
    load = os.getloadavg()
    result = bench_ssao.speed(args.out, resolution=args.resolution, samples=args.samples, repeats=args.repeats,
                              reference_samples=args.reference_samples, eevee=not args.no_eevee,
                              baseline=args.baseline)
    rows, gb, ref, mc = result["rows"], result["gbuffer"], result["reference"], result["machine"]
    pixels = int(gb.mask.sum())
    print(f"SSAO on the corner scene, {gb.width}x{gb.height} ({pixels} geometry pixels), "
          f"{args.samples} samples per pixel, radius = AO distance = 1 m; best of {args.repeats} runs")
    print(f"reference: Cycles AO pass, {ref['samples']} samples, {ref['seconds']:.1f} s"
          f"{' (cached)' if ref['cached'] else ''}, noise "
          f"{metrics.reference_noise(ref['k'], ref['samples'], gb.mask):.4f} rms")
    print(f"machine: numpy {np.__version__}, {os.cpu_count()} CPUs, load average {load[0]:.2f} {load[1]:.2f} "
          f"{load[2]:.2f} (1, 5, 15 min) at start, {os.getloadavg()[0]:.2f} at the end")
    print(f"  float32 pass c = a·b (12 B/element): {mc['pass_ns']:.2f} ns/element in cache "
          f"({mc['cache_gb_per_s']:.0f} GB/s), {mc['stream_ns']:.2f} ns from memory ({mc['stream_gb_per_s']:.0f} GB/s); "
          f"uniform float32 draw {mc['random_ns']:.2f} ns; gather {mc['gather_ns']:.2f} ns")
    head = (f"{'method':<20}{'seconds':>9}{'cpu s':>8}{'ns/px-s':>9}{'passes':>7}{'B/px-s':>7}{'floor':>6}"
            f"{'x floor':>8}{'peak MiB':>9}{'RMSE':>8}")
    if args.baseline:
        head += f"  |{'before':>8}{'cpu s':>8}{'RMSE':>8}{'peak MiB':>9}{'speed-up':>9}{'max|dk|':>9}"
    print(head + f"{'load':>6}")
    for r in rows:
        if "cpu_seconds" not in r:
            print(f"{r['method']:<20}{r['seconds']:>9.3f}{'':>54}{r['rmse']:>8.4f}"
                  + ("  |" + " " * 51 if args.baseline else "") + f"{r['load']:>6.1f}")
            continue
        name = r["method"].split(" ")[0]
        work = ["", "", "", ""]
        if "passes" in r:
            floor = (r["passes"] * mc["pass_ns"] + bench_ssao.DRAWS_PER_SAMPLE[name] * mc["random_ns"]
                     + bench_ssao.GATHERS_PER_SAMPLE * mc["gather_ns"])
            work = [f"{r['passes']:.0f}", f"{r['bytes']:.0f}", f"{floor:.0f}",
                    f"{r['cpu_ns_per_pixel_sample'] / floor:.1f}"]
        line = (f"{r['method']:<20}{r['seconds']:>9.3f}{r['cpu_seconds']:>8.3f}{r['ns_per_pixel_sample']:>9.1f}"
                f"{work[0]:>7}{work[1]:>7}{work[2]:>6}{work[3]:>8}{_mib(r['peak_bytes']):>9}{r['rmse']:>8.4f}")
        if args.baseline:
            line += (f"  |{r['baseline_seconds']:>8.3f}{r['baseline_cpu_seconds']:>8.3f}{r['baseline_rmse']:>8.4f}"
                     f"{_mib(r['baseline_peak_bytes']):>9}{r['baseline_seconds'] / r['seconds']:>8.2f}x"
                     f"{r['max_difference']:>9.1e}")
        print(line + f"{r['load']:>6.1f}")


def build_parser():
    p = _cli.parser("bench_ssao.py", "Time the SSAO methods on one frame, beside EEVEE's AO pass.",
                    blend_file=False)
    p.add_argument("--resolution", type=_cli.number(int, 8, core_ssao.MAX_RESOLUTION), default=512)
    p.add_argument("--samples", type=_cli.number(int, 1, core_ssao.MAX_SAMPLES), default=16)
    p.add_argument("--repeats", type=_cli.number(int, 1, 100), default=3)
    p.add_argument("--reference-samples", type=_cli.number(int, 1, core_ssao.MAX_REFERENCE_SAMPLES), default=256)
    p.add_argument("--no-eevee", action="store_true", help="skip EEVEE (its first render compiles shaders)")
    p.add_argument("--baseline", metavar="DIR", help="another checkout of this project (e.g. the main branch's "
                   "worktree): time its numpy methods beside these, interleaved, on the same G-buffer")
    p.add_argument("--out", default="out/bench_ssao", help="folder of the reference cache")
    return p


if __name__ == "__main__":
    _cli.run(build_parser(), main)
