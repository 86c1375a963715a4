"""Benchmark: radiosity of about 10,000 patches including visibility (target <= 30 s), the old path (a BVH ray
per pair, every ordered pair's form factor) and the new one (rays against the scene's faces in numpy, the
visible pairs' form factors once) side by side, and the relative RMS against a Cycles bake of each.

    python scripts/bench_radiosity.py [--out DIR] [--quick] [--no-before] [--samples 32]

Scenes: the published Cornell box through Blender's OBJ importer (light 1 mm under the ceiling, red wall 6 mm
out of plane) at 0.1 m, before and after, and the built-in Cornell box (analytic.cornell_box) at 0.075 m
(11,367 patches before the split near the light), after only unless --big-before.
"""
import os
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import _cli  # noqa: E402

COLS = ("patches", "method", "visibility_s", "form_factors_s", "near_field_s", "near_emitters_s", "solve_s",
        "texel_gather_s", "total_s", "cpu_s")


def _imported_cornell(folder):
    import bpy
    sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "tests"))
    from test_radiosity_imported import import_cornell
    bpy.ops.wm.read_factory_settings(use_empty=True)
    return import_cornell(folder)


def main(args):
    from addon.core import analytic
    from addon.lab import radiosity as L
    from addon.lab.bench import radiosity as B
    out = os.path.abspath(args.out)
    os.makedirs(out, exist_ok=True)
    print(f"load average {os.getloadavg()[0]:.2f} {os.getloadavg()[1]:.2f} on {os.cpu_count()} cores")
    paths = ("after",) if args.no_before else ("before", "after")
    sc = _imported_cornell(os.path.join(out, "obj"))
    meshes, _ = L.meshes_from_scene(sc)
    scenes = {"imported 0.1": (meshes, 0.1)}
    if not args.quick:
        scenes["built-in 0.075"] = (analytic.cornell_box(), 0.075, ("after",) if not args.big_before else paths)
    print(f"{'scene':16s} {'path':7s} " + " ".join(f"{c[:-2] if c.endswith('_s') else c:>14s}" for c in COLS))
    rows, diffs = B.speed(scenes, paths, report=lambda r: print(
        f"{r['scene']:16s} {r['path']:7s} " + " ".join(f"{str(r[c]):>14s}" for c in COLS), flush=True))
    for name, d in diffs.items():
        print(f"{name}: after vs before, patch irradiance max |dH| / max H {d['H_rel_max']:.2e}, texel "
              f"solution relative RMS difference {d['texel_rel_rms']:.2e}")
    if args.samples:
        for path in paths:
            sc = _imported_cornell(os.path.join(out, "obj"))
            t0 = time.perf_counter()
            res = L.run(os.path.join(out, f"rad_{path}"), scene=sc, max_edge=0.1, samples=args.samples, chart=False,
                        **B.PATHS[path])
            rep = res.report
            print(f"imported 0.1 {path}: {rep['patches']} patches, solve {rep['seconds']:.1f} s, Cycles "
                  f"{rep['cycles_samples']} samples {rep['cycles_seconds']:.1f} s, relative RMS vs Cycles "
                  f"{100 * rep['relative_rms_vs_cycles']:.2f} % (run {time.perf_counter() - t0:.0f} s)")
    if args.versus:
        versus(out, args.versus)
    print(f"load average {os.getloadavg()[0]:.2f}")


def versus(out, ref_samples, edge=0.25, samples=(4, 16, 64)):
    """Radiosity against Cycles' path-traced bake on the imported box, both against a ``ref_samples`` Cycles
    bake of the same patch atlas: relative RMS per patch (the report's "patch" comparison) and seconds."""
    import numpy as np
    from addon.lab import radiosity as L
    runs = {}
    for s in samples + (ref_samples,):
        sc = _imported_cornell(os.path.join(out, "obj"))
        res = L.run(os.path.join(out, f"versus_{s}"), scene=sc, max_edge=edge, samples=s, chart=False)
        runs[s] = (res.report, res.arrays["cycles"], res.arrays["H_points"])
    rep, ref, H = runs[ref_samples]
    norm = float(np.nanmean(ref))
    print(f"imported box {edge} m, {rep['patches']} patches; reference: Cycles {ref_samples} samples "
          f"({rep['cycles_seconds']:.1f} s)")
    print(f"{'method':30s} {'seconds':>8s} {'relative RMS vs reference':>26s}")
    print(f"{'radiosity (solve incl. near field)':30s} {rep['seconds']:8.1f} {100 * L.rms(H, ref) / norm:25.2f}%")
    for s in samples:
        r, hc, _ = runs[s]
        print(f"{f'Cycles bake, {s} samples':30s} {r['cycles_seconds']:8.1f} {100 * L.rms(hc, ref) / norm:25.2f}%")


def build_parser():
    p = _cli.bench_parser("bench_radiosity.py", "Radiosity speed before/after and accuracy against Cycles.",
                          "out/bench_radiosity", "the imported box only")
    p.add_argument("--no-before", action="store_true", help="skip the old path (BVH rays, every ordered pair)")
    p.add_argument("--big-before", action="store_true", help="the old path on the 11k-patch box too (minutes)")
    p.add_argument("--versus", type=int, default=0, metavar="REF_SAMPLES",
                   help="also radiosity against Cycles bakes of 4, 16, 64 samples, error against seconds, both "
                        "measured against a REF_SAMPLES bake (0: skip)")
    p.add_argument("--samples", type=int, default=32, help="Cycles samples of the comparison (0: none)")
    return p


if __name__ == "__main__":
    _cli.run(build_parser(), main)
