"""SSAO speed: every numpy method on a 512² frame at 16 samples per pixel, beside EEVEE's AO pass.

    python scripts/bench_ssao.py                  # 512², 16 spp, corner scene
    python scripts/bench_ssao.py --resolution 256 --samples 32 --no-eevee

Times are the best of --repeats runs (seconds of wall time on this machine);
the numpy methods start from the G-buffer (rendered once); EEVEE's figure is the
whole render call (scene sync, AO pass, writing the passes), after a warm-up
render that compiles its shaders. RMSE is against Cycles' AO pass (256 samples by default, noise stated).
"""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import _cli  # noqa: E402

from addon.core.ssao import limits as core_ssao


def main(args):
    from addon.core.ssao import metrics
    from addon.lab.bench import ssao as bench_ssao
    result = bench_ssao.speed(args.out, resolution=args.resolution, samples=args.samples, repeats=args.repeats,
                              reference_samples=args.reference_samples, eevee=not args.no_eevee)
    rows, gb, ref = result["rows"], result["gbuffer"], result["reference"]
    print(f"SSAO on the corner scene, {gb.width}x{gb.height} ({int(gb.mask.sum())} geometry pixels), "
          f"{args.samples} samples per pixel, radius = AO distance = 1 m")
    print(f"reference: Cycles AO pass, {ref['samples']} samples, {ref['seconds']:.1f} s"
          f"{' (cached)' if ref['cached'] else ''}, noise "
          f"{metrics.reference_noise(ref['k'], ref['samples'], gb.mask):.4f} rms")
    print(f"{'method':<22}{'seconds':>10}{'RMSE':>10}")
    for name, sec, rmse in rows:
        print(f"{name:<22}{sec:>10.3f}{rmse:>10.4f}")


def build_parser():
    p = _cli.parser("bench_ssao.py", "Time the SSAO methods on one frame, beside EEVEE's AO pass.",
                    blend_file=False)
    p.add_argument("--resolution", type=_cli.number(int, 8, core_ssao.MAX_RESOLUTION), default=512)
    p.add_argument("--samples", type=_cli.number(int, 1, core_ssao.MAX_SAMPLES), default=16)
    p.add_argument("--repeats", type=_cli.number(int, 1, 100), default=3)
    p.add_argument("--reference-samples", type=_cli.number(int, 1, core_ssao.MAX_REFERENCE_SAMPLES), default=256)
    p.add_argument("--no-eevee", action="store_true", help="skip EEVEE (its first render compiles shaders)")
    p.add_argument("--out", default="out/bench_ssao", help="folder of the reference cache")
    return p


if __name__ == "__main__":
    _cli.run(build_parser(), main)
