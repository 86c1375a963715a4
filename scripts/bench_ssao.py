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

from addon.core import ssao as core_ssao  # noqa: E402  (numpy only)


def main(args):
    from addon.core import ssao
    ssao.check_cost(args.resolution, args.resolution, args.samples, args.reference_samples,
                    len(ssao.METHODS) * 2 * args.repeats)          # each method with and without blur, repeated
    from addon.lab import ssao as lab
    from addon.lab import ssao_scenes
    from addon.blender.scene import remove_scene
    scene = ssao_scenes.build_scene("corner", args.resolution, 1.0)
    cache = os.path.abspath(os.path.join(args.out, "cache"))
    gb, _, ref = lab.frame(scene, 1.0, args.reference_samples, args.resolution, cache)
    rows = []
    for m in ssao.METHODS:
        for blur in (False, True):
            best, k = float("inf"), None
            for _ in range(args.repeats):
                k, sec, _ = ssao.run_method(m, gb, 1.0, args.samples, blur=blur)
                best = min(best, sec)
            rows.append((m + (" + blur" if blur else ""), best, ssao.error_metrics(k, ref["k"], gb.mask)["rmse"]))
    for m in ("workbench",) + (() if args.no_eevee else ("eevee",)):
        if m == "eevee":
            lab.blender_method(scene, "eevee", 1.0, 1, 32)           # compile shaders first
        for spp in sorted({1, args.samples}):
            best, k = float("inf"), None
            for _ in range(args.repeats):
                k, sec, _ = lab.blender_method(scene, m, 1.0, spp, args.resolution)
                best = min(best, sec)
            rows.append((f"{m} ({spp} spp)", best, ssao.error_metrics(k, ref["k"], gb.mask)["rmse"]))
    remove_scene(scene)
    print(f"SSAO on the corner scene, {gb.width}x{gb.height} ({int(gb.mask.sum())} geometry pixels), "
          f"{args.samples} samples per pixel, radius = AO distance = 1 m")
    print(f"reference: Cycles AO pass, {ref['samples']} samples, {ref['seconds']:.1f} s"
          f"{' (cached)' if ref['cached'] else ''}, noise "
          f"{ssao.reference_noise(ref['k'], ref['samples'], gb.mask):.4f} rms")
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
