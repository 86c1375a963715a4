"""Benchmark: radiosity of about 10,000 patches including visibility (target <= 30 s), the old path (a BVH ray
per pair, every ordered pair's form factor) and the new one (rays against the scene's faces in numpy, the
visible pairs' form factors once) side by side, and the relative RMS against a Cycles bake of each; with
--versus, radiosity against Cycles' path-traced bake, error against seconds (radiosity_vs_cycles.png).

    python scripts/bench_radiosity.py [--out DIR] [--quick] [--no-before] [--samples 32] [--versus 512]
    python scripts/bench_radiosity.py --versus-only [--versus 512]

Scenes: the published Cornell box through Blender's OBJ importer (addon.lab.bench.cornell_obj: light 1 mm under
the ceiling, red wall 6 mm out of plane) at 0.1 m, before and after, at 0.04 m (8,479 patches) and 0.03 m
(13,630) after, and the built-in Cornell box (analytic.cornell_box) at 0.075 m (15,331 patches with the split
near the light), after only unless --big-before. Every solve by Jacobi sweeps (scripts/radiosity.py's default).
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
    from addon.lab.bench.cornell_obj import import_cornell
    bpy.ops.wm.read_factory_settings(use_empty=True)
    return import_cornell(folder)


def main(args):
    from addon.core import analytic
    from addon.lab import radiosity as L
    from addon.lab.bench import radiosity as B
    from addon.lab.options import RadiosityOptions
    out = os.path.abspath(args.out)
    os.makedirs(out, exist_ok=True)
    print(f"load average {os.getloadavg()[0]:.2f} {os.getloadavg()[1]:.2f} on {os.cpu_count()} cores")
    if args.versus_only:
        versus(out, args.versus or 512)
        print(f"load average {os.getloadavg()[0]:.2f}")
        return
    paths = ("after",) if args.no_before else ("before", "after")
    sc = _imported_cornell(os.path.join(out, "obj"))
    meshes, _ = L.meshes_from_scene(sc)
    scenes = {"imported 0.1": (meshes, 0.1)}
    if not args.quick:
        scenes["imported 0.04"] = (meshes, 0.04, ("after",))
        scenes["imported 0.03"] = (meshes, 0.03, ("after",))
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
            res = L.run(os.path.join(out, f"rad_{path}"), RadiosityOptions(max_edge=0.1, samples=args.samples),
                        scene=sc, chart=False, **B.PATHS[path])
            rep = res.report
            print(f"imported 0.1 {path}: {rep['patches']} patches, solve {rep['seconds']:.1f} s, Cycles "
                  f"{rep['cycles_samples']} samples {rep['cycles_seconds']:.1f} s, relative RMS vs Cycles "
                  f"{100 * rep['relative_rms_vs_cycles']:.2f} % (run {time.perf_counter() - t0:.0f} s)")
    if args.versus:
        versus(out, args.versus)
    print(f"load average {os.getloadavg()[0]:.2f}")


def _raw2(H, ref, area):
    """Squared relative RMS of H against ``ref`` (N, 3) over the patches where both are finite: per patch
    unweighted (the report's "patch" comparison) and area-weighted (∫ (H − H_ref)² dA over the surfaces,
    independent of how finely they are cut), each over the reference's mean weighted alike."""
    import numpy as np
    ok = np.isfinite(H).all(axis=1) & np.isfinite(ref).all(axis=1)
    d2 = ((H[ok] - ref[ok]) ** 2).mean(axis=1)
    out = {}
    for kind, w in (("patch", np.ones(int(ok.sum()))), ("area", np.asarray(area, float)[ok])):
        norm = float((ref[ok].mean(axis=1) * w).sum() / w.sum())
        out[kind] = float((d2 * w).sum() / w.sum()) / norm ** 2
    return out


def _reference_noise2(raw, ref_samples):
    """The reference bake's own squared relative noise per kind, from a Cycles bake of the same atlas with
    another seed: a bake of s samples differs from the reference by noise of variance σ²₁ (1/s + 1/S) (both
    1/√samples, independent), so σ²_ref = σ²₁ / S = RMS²_s / (S / s + 1); from the bake with the most samples in
    ``raw`` {s: _raw2} (the nearest the reference's own regime: the light trapped in the 1 mm gap gives the
    few-sample bakes heavier tails than 1/s)."""
    s = max(raw)
    return {kind: raw[s][kind] / (ref_samples / s + 1) for kind in ("patch", "area")}


def _first_below(rows, method, level=0.05):
    """Seconds at which ``method``'s area-weighted error first reaches ``level`` (log-log interpolation between
    its points in order of seconds; None when it never does)."""
    import numpy as np
    pts = sorted((r["seconds"], r["relative_rms_area"]) for r in rows if r["method"] == method)
    for (t0, e0), (t1, e1) in zip([(None, None)] + pts, pts):
        if e1 <= level:
            if t0 is None or e0 <= level:
                return t1
            k = (np.log(level) - np.log(e0)) / (np.log(e1) - np.log(e0))
            return float(np.exp(np.log(t0) + k * (np.log(t1) - np.log(t0))))
    return None


def versus(out, ref_samples, edges=(0.25, 0.15, 0.1, 0.06), samples=(4, 8, 16, 32, 64, 128), cycles_edge=0.1,
           noise_samples=64):
    """Radiosity against Cycles' path-traced bake on the imported box: relative RMS per patch against the
    converged answer, and seconds. Each radiosity run (``edges``) is compared with a ``ref_samples`` Cycles
    bake of its own patch atlas; the Cycles bakes of ``samples`` (other seeds) are of the ``cycles_edge``
    atlas, against its reference. The reference's own noise (:func:`_reference_noise2`: from the largest of
    those bakes, or from one ``noise_samples`` bake on the other atlases) is taken out: RMS² − σ²_ref. Writes
    radiosity_vs_cycles.csv and .png (area-weighted relative RMS against seconds, log-log, the 5 % line) and
    returns the rows (:func:`chart`)."""
    import numpy as np
    from addon.lab import radiosity as L
    from addon.lab.options import RadiosityOptions
    rows = []
    for e in edges:
        sc = _imported_cornell(os.path.join(out, "obj"))
        res = L.run(os.path.join(out, f"versus_{e}"), RadiosityOptions(max_edge=e, samples=ref_samples), scene=sc,
                    chart=False)
        a, rep = res.arrays, res.report
        pf = a["patches"].take(a["front"])
        ref = a["cycles"]
        bakes = {}
        for s in (samples if e == cycles_edge else (noise_samples,)):
            Hc, _, secs = L.cycles_patch_irradiance(sc, a["results"], pf, os.path.join(out, f"versus_{e}_cycles_{s}"),
                                                    s, seed=1)
            bakes[s] = (_raw2(Hc, ref, pf.area), secs)
        noise2 = _reference_noise2({s: r for s, (r, _) in bakes.items()}, ref_samples)
        raw = _raw2(a["H_points"], ref, pf.area)
        err = {k: np.sqrt(max(raw[k] - noise2[k], 0.0)) for k in raw}
        secs = rep["timings"]["total"]
        rows.append({"method": "radiosity", "max_edge": e, "patches": rep["patches"], "samples": "",
                     "seconds": round(secs, 2), "cpu_seconds": round(rep["timings"]["cpu"], 2),
                     "relative_rms_area": round(err["area"], 5), "relative_rms_patch": round(err["patch"], 5),
                     "reference_noise_area": round(np.sqrt(noise2["area"]), 5),
                     "reference_noise_patch": round(np.sqrt(noise2["patch"]), 5)})
        print(f"radiosity {e} m: {rep['patches']} patches {secs:.1f} s ({rep['timings']['cpu']:.1f} CPU s), relative "
              f"RMS area-weighted {100 * err['area']:.2f} %, per patch {100 * err['patch']:.2f} % (reference "
              f"{ref_samples} samples {rep['cycles_seconds']:.0f} s, its noise {100 * np.sqrt(noise2['area']):.2f} % "
              f"area-weighted, {100 * np.sqrt(noise2['patch']):.2f} % per patch)", flush=True)
        if e != cycles_edge:
            continue
        for s, (r, secs) in bakes.items():
            ec = {k: np.sqrt(max(r[k] - noise2[k], 0.0)) for k in r}
            rows.append({"method": "cycles", "max_edge": e, "patches": rep["patches"], "samples": s,
                         "seconds": round(secs, 2), "cpu_seconds": "",
                         "relative_rms_area": round(ec["area"], 5), "relative_rms_patch": round(ec["patch"], 5),
                         "reference_noise_area": round(np.sqrt(noise2["area"]), 5),
                         "reference_noise_patch": round(np.sqrt(noise2["patch"]), 5)})
            print(f"Cycles bake {s} samples ({e} m atlas): {secs:.1f} s, relative RMS area-weighted "
                  f"{100 * ec['area']:.2f} %, per patch {100 * ec['patch']:.2f} %", flush=True)
    chart(out, rows, cycles_edge)
    return rows


def chart(out, rows, cycles_edge=0.1):
    """radiosity_vs_cycles.csv and .png of :func:`versus`' rows: area-weighted relative RMS against seconds,
    log-log, each point labelled, the 5 % line; prints where each method first reaches 5 %."""
    from addon.core import charts
    charts.write_csv(os.path.join(out, "radiosity_vs_cycles.csv"), rows)
    for m in ("radiosity", "cycles"):
        t = _first_below(rows, m)
        print(f"{m}: 5 % area-weighted relative RMS " + (f"first at {t:.1f} s" if t else "not reached"))
    if not charts.available():
        return None
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(7.2, 4.6))
    for m, label, key in (("radiosity", "radiosity (incl. visibility), max edge", "max_edge"),
                          ("cycles", f"Cycles bake ({cycles_edge} m atlas), samples", "samples")):
        rs = sorted((r for r in rows if r["method"] == m), key=lambda r: r["seconds"])
        x, y = [r["seconds"] for r in rs], [100 * r["relative_rms_area"] for r in rs]
        ax.plot(x, y, marker="o", label=label)
        for r, xi, yi in zip(rs, x, y):
            ax.annotate(f"{r[key]:g}" + (" m" if m == "radiosity" else ""), (xi, yi), textcoords="offset points",
                        xytext=(4, 4), fontsize="x-small")
    ax.axhline(5, color="crimson", lw=1, ls="--", label="5 %")
    ax.set_xscale("log")
    ax.set_yscale("log")
    from matplotlib.ticker import NullFormatter, ScalarFormatter
    for axis, ticks in ((ax.xaxis, (1, 2, 5, 10, 20, 50, 100)), (ax.yaxis, (1, 2, 3, 5, 10, 20, 50))):
        axis.set_major_formatter(ScalarFormatter())
        axis.set_minor_formatter(NullFormatter())
        axis.set_ticks(ticks)
    ax.set_xlabel("seconds")
    ax.set_ylabel("relative RMS error, area-weighted (%)")
    ax.set_title("Imported Cornell box: radiosity vs Cycles bake, error against time", fontsize="medium")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize="small")
    fig.tight_layout()
    path = os.path.join(out, "radiosity_vs_cycles.png")
    fig.savefig(path, dpi=120)
    plt.close(fig)
    print(f"chart: {path}")
    return path


def build_parser():
    p = _cli.bench_parser("bench_radiosity.py", "Radiosity speed before/after and accuracy against Cycles.",
                          "out/bench_radiosity", "the imported box only")
    p.add_argument("--no-before", action="store_true", help="skip the old path (BVH rays, every ordered pair)")
    p.add_argument("--big-before", action="store_true", help="the old path on the 11k-patch box too (minutes)")
    p.add_argument("--versus", type=int, default=0, metavar="REF_SAMPLES",
                   help="also radiosity (0.25, 0.15, 0.1, 0.06 m) against Cycles bakes of 4 to 128 samples, relative "
                        "RMS against seconds (radiosity_vs_cycles.png), each against a REF_SAMPLES bake (0: skip)")
    p.add_argument("--versus-only", action="store_true", help="only the radiosity-against-Cycles chart (--versus, "
                   "default 512 reference samples)")
    p.add_argument("--samples", type=int, default=32, help="Cycles samples of the comparison (0: none)")
    return p


if __name__ == "__main__":
    _cli.run(build_parser(), main)
