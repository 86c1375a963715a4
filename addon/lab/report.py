"""The speed-versus-accuracy report: every area's benchmark, their charts and CSV tables, one report.md.

Used by scripts/bench.py and the demo (lab/demo/job.py); it sits beside bench/ and demo/ so that both
import it and the demo does not reach into bench/. Each area's module (the registry :data:`AREAS`) has ``KEY``, ``TITLE`` and
``run(output_dir, quick=False) -> BenchResult``; this module runs them, adds what needs more
than one area (the stability table, the shading twins at their edge inputs) and writes the report.
"""
import math
import os
import platform
import time

import bpy
import numpy as np

from ..core import brdf, charts
from ..core.errors import InputError
from ..core.io.files import atomic_path, write_json
from ..blender.progress import Progress
from .bench import envmap, lightmaps, shading, shadows, ssao
from .bench import raytrace as raytrace_bench
from .bench import reflections as reflections_bench

#: The registry, in report order (radiosity is part of the envmap section).
AREAS = (shading, lightmaps, shadows, ssao, envmap, reflections_bench, raytrace_bench)
SSAO_REMEDY = {
    "plane": "normal-oriented methods (hemisphere, HBAO, GTAO) read 1 on open surfaces",
    "edge": "reported, not hidden: render a guard band beyond the frame to avoid it",
    "discontinuity": "range check (samples past the radius ignored); crytek + range check shown",
    "thin": "reported: a depth buffer cannot see thickness",
}


def shading_edges():
    """Each shading twin at the inputs where the models break down: max |output| and finiteness."""
    n = np.array([0.0, 0.0, 1.0])
    grazing = brdf.direction(np.radians(89.999), 0.0)
    behind = brdf.direction(np.radians(120.0), 0.0)
    cases = {
        "grazing light (n.l = 2e-5)": (grazing, brdf.direction(0.3, np.pi), {}),
        "back-facing light (n.l < 0)": (behind, brdf.direction(0.3, np.pi), {}),
        "grazing view (n.v = 2e-5)": (brdf.direction(0.3, 0.0), grazing * [-1, 1, 1], {}),
        "roughness 0": (brdf.direction(0.3, 0.0), brdf.direction(0.3, np.pi), {"roughness": 0.0}),
        "shininess 0": (brdf.direction(0.3, 0.0), brdf.direction(0.3, np.pi), {"shininess": 0.0}),
        "shininess 1e4": (brdf.direction(0.3, 0.0), brdf.direction(0.3, np.pi), {"shininess": 1e4}),
        "sigma = pi/2 (very rough)": (brdf.direction(1.5, 0.0), brdf.direction(1.5, np.pi), {"sigma": np.pi / 2}),
    }
    models = {
        "Phong": lambda l, v, k: brdf.phong(n, l, v, 1.0, shininess=k.get("shininess", 32.0)),
        "Blinn-Phong (normalised)": lambda l, v, k: brdf.blinn_phong(n, l, v, 1.0, shininess=k.get("shininess", 32.0),
                                                                     normalized=1.0),
        "Oren-Nayar": lambda l, v, k: brdf.oren_nayar(n, l, v, 1.0, sigma=k.get("sigma", 0.3)),
        "Cook-Torrance GGX": lambda l, v, k: brdf.cook_torrance(n, l, v, 1.0, roughness=k.get("roughness", 0.3)),
    }
    rows = []
    for case, (l, v, kw) in cases.items():
        for model, f in models.items():
            if ("shininess" in kw and "Phong" not in model) or ("roughness" in kw and "Cook" not in model) \
                    or ("sigma" in kw and "Oren" not in model):
                continue
            out = np.asarray(f(l, v, kw), float)
            rows.append({"model": model, "input": case, "max_output": float(np.max(np.abs(out))),
                         "finite": bool(np.all(np.isfinite(out)))})
    return rows


def _blinn_albedo_max():
    """Largest directional albedo of the normalised Blinn-Phong lobe (k_s = 1) over exponents and incidences."""
    n = np.array([0.0, 0.0, 1.0])
    worst = 0.0
    for e in (0.0, 1.0, 9.0, 100.0, 1e4):
        for t in (0.0, 45.0, 89.9):
            worst = max(worst, brdf.directional_albedo(
                lambda l, v: brdf.blinn_phong(n, l, v, 1.0, kd=(0, 0, 0), ks=1.0, shininess=e, normalized=1.0)[..., 0],
                np.radians(t), brdf.lobe_width(e), 256, 128))
    return worst


def _oren_nayar_horizon_ratio():
    """Twin over the 1994 angles form (cos theta_i (A + B sin alpha tan beta), dphi = 0) 1e-7 rad above the horizon."""
    t = np.pi / 2 - 1e-7
    A, B = brdf.oren_nayar_A(0.5), brdf.oren_nayar_B(0.5)
    paper = np.cos(t) * (A + B * np.sin(t) * np.tan(t))
    twin = brdf.oren_nayar([0, 0, 1], brdf.direction(t), brdf.direction(t), 1.0, 1.0, 0.5)[0]
    return float(twin / paper)


def _get(d, *keys, default=None):
    for k in keys:
        if not isinstance(d, dict) or k not in d:
            return default
        d = d[k]
    return d


def _pct(x):
    return "—" if x is None or (isinstance(x, float) and math.isnan(x)) else f"{100 * x:.2f} %"


def stability_table(results, shading_rows):
    """One row per (method, input where it fails): what was measured and what the project does there."""
    sh, ss, bk, ev = (vars(results[k]) if k in results else {} for k in ("shadows", "ssao", "lightmaps", "envmap"))
    sht = sh.get("tables", {})
    zz = {(r["camera"], r["mode"]): r["error"] for r in sht.get("zpass_zfail", [])}
    planar = {r["scene"]: r["error"] for r in sht.get("planar_receivers", [])}
    worst_shading = max((r["max_output"] for r in shading_rows), default=float("nan"))
    all_finite = all(r["finite"] for r in shading_rows)
    rows = [
        {"method": "shadow map", "fails at": "bias 0 (acne)",
         "measured": f"false shadow {_pct(_get(sh, 'figures', 'bias_ends', 'acne_false_shadow'))}",
         "what the project does": f"constant + slope-scaled bias; best measured bias {_get(sh, 'figures', 'best_bias')} m"},
        {"method": "shadow map", "fails at": "bias too large (peter-panning)",
         "measured": f"false light {_pct(_get(sh, 'figures', 'bias_ends', 'panning_false_light'))}",
         "what the project does": "the bias sweep marks the best value; PCF softens aliasing"},
        {"method": "shadow volume z-pass", "fails at": "camera inside a shadow volume",
         "measured": f"error {_pct(zz.get(('inside', 'zpass')))} (z-fail {_pct(zz.get(('inside', 'zfail')))})",
         "what the project does": "z-fail with caps is the default; open meshes are receivers only"},
        {"method": "planar projection", "fails at": "non-planar receiver (stairs)",
         "measured": f"error {_pct(planar.get('stairs'))} (flat floor {_pct(planar.get('sphere'))})",
         "what the project does": "reports the error; use shadow volumes or maps on non-planar receivers"},
        {"method": "shading models", "fails at": "grazing / back-facing light, n.v -> 0, roughness 0, "
                                                 "shininess 0 and 1e4, sigma pi/2",
         "measured": f"all finite: {all_finite}; largest output {worst_shading:.3g} x I",
         "what the project does": "dot products clamped, roughness >= 1e-3, terms zero where n.l <= 0"},
        {"method": "Blinn-Phong, Normalized = 1", "fails at": "small and mid exponents (was (n+8)/8)",
         "measured": "was: albedo 1.024 / 1.075 / 1.018 at n = 1 / 9 / 100, normal incidence; now "
                     f"{_blinn_albedo_max():.4f} at most (n = 0, 1, 9, 100, 1e4; incidence 0, 45, 89.9 deg)",
         "what the project does": "exact (n+2)(n+4)/(8 (2^(-n/2) + n)): albedo k_s at normal incidence, "
                                  "less elsewhere"},
        {"method": "Oren-Nayar", "fails at": "viewer below the horizon (n.v <= 0)",
         "measured": "was: up to 0.794 I (sigma 0.5, l = (0.3, 0, 1), v = (0.5, 0, -1)); now "
                     f"{float(brdf.oren_nayar([0, 0, 1], [0.3, 0, 1], [0.5, 0, -1], 1.0, 1.0, 0.5)[0]):.3g} I",
         "what the project does": "zero unless n.l > 0 and n.v > 0 (twin and node group), as Cook-Torrance"},
        {"method": "Oren-Nayar", "fails at": "both directions within 0.006 deg of the horizon",
         "measured": "was: max(n.l, n.v, 1e-4) guard cut the model up to 400x; now "
                     f"{_oren_nayar_horizon_ratio():.6f} x the 1994 angles form at 1e-7 rad",
         "what the project does": "bounded form (n.l)/max(n.l, n.v, 1e-12) in [0, 1]: the model, always finite"},
        {"method": "AO / irradiance bake", "fails at": "few samples (noise)",
         "measured": f"AO error ~ N^{_get(bk, 'figures', 'mc_slope', default=float('nan')):.2f}, irradiance "
                     f"~ N^{_get(bk, 'figures', 'mc_slope_irradiance', default=float('nan')):.2f} "
                     "(plain Monte Carlo: -0.50; Cycles' quasi-random sequences may do better)",
         "what the project does": "--target-error picks samples from pilot variance; --denoise"},
        {"method": "SH9 irradiance", "fails at": "small bright lights (high frequency)",
         "measured": "; ".join(f"{r['light_radius_deg']} deg: {_pct(r['sh9_rel_max'])} max"
                               for r in _get(ev, "tables", "envmap_sh9_accuracy", default=[])) or "—",
         "what the project does": "--method brute for exact E(n)"},
    ]
    failures = {}
    for r in _get(ss, "tables", "ssao_failures", default=[]):
        failures.setdefault((r["scene"], r["failure"]), []).append(f"{r['method']} {r['region_bias']:+.3f}")
    for (scene, failure), biases in failures.items():
        rows.append({"method": "SSAO", "fails at": failure,
                     "measured": "mean error in the affected region: " + ", ".join(biases),
                     "what the project does": SSAO_REMEDY.get(scene, "reported")})
    rows += reflections_bench.stability_rows(results.get("reflections"))
    rows += raytrace_bench.stability_rows(results.get("raytrace"))
    return rows


def _md_table(rows, limit=30):
    if not rows:
        return "_no rows_\n"
    keys = list(rows[0].keys())

    def fmt(v):
        if isinstance(v, float):
            return f"{v:.4g}"
        return str(v).replace("|", "\\|")
    lines = ["| " + " | ".join(keys) + " |", "|" + "---|" * len(keys)]
    lines += ["| " + " | ".join(fmt(r.get(k, "")) for k in keys) + " |" for r in rows[:limit]]
    if len(rows) > limit:
        lines.append(f"\n_{len(rows) - limit} more rows in the CSV_")
    return "\n".join(lines) + "\n"


def run(output_dir, quick=False, areas=None):
    """Run the benchmarks of ``areas`` (keys, default all) into ``output_dir``; write report.md, report.json,
    CSVs, charts. Returns {"report": path, "seconds", "results": {key: BenchResult}, "stability": rows}."""
    chosen = [a for a in AREAS if areas is None or a.KEY in areas]
    unknown = set(areas or ()) - {a.KEY for a in AREAS}
    if unknown:
        raise InputError(f"unknown area(s): {', '.join(sorted(unknown))}; choose from {', '.join(a.KEY for a in AREAS)}")
    os.makedirs(output_dir, exist_ok=True)
    t_all = time.perf_counter()
    results, seconds, cpu_seconds = {}, {}, {}
    with Progress("bench", len(chosen) + 1) as progress:
        for area in chosen:
            progress.step(area.TITLE)
            t, cpu = time.perf_counter(), time.process_time()
            results[area.KEY] = area.run(os.path.join(output_dir, area.KEY), quick)
            seconds[area.KEY] = time.perf_counter() - t
            cpu_seconds[area.KEY] = time.process_time() - cpu
        progress.step("cross-area tables and the report")
        shading_rows = shading_edges()
        stability = stability_table(results, shading_rows)
    for key, r in results.items():
        for name, rows in r.tables.items():
            charts.write_csv(os.path.join(output_dir, key, f"{name}.csv"), rows)
    charts.write_csv(os.path.join(output_dir, "stability.csv"), stability)
    charts.write_csv(os.path.join(output_dir, "shading_edges.csv"), shading_rows)
    total = time.perf_counter() - t_all
    path = os.path.join(output_dir, "report.md")
    with atomic_path(path) as tmp:
        with open(tmp, "w", encoding="utf-8") as f:
            f.write(_markdown(output_dir, results, seconds, stability, shading_rows, quick, total))
    write_json(os.path.join(output_dir, "report.json"),
               {"quick": quick, "seconds": total, "area_seconds": seconds, "area_cpu_seconds": cpu_seconds,
                "load_average": os.getloadavg()[0] if hasattr(os, "getloadavg") else None, "stability": stability,
                "figures": {k: r.figures for k, r in results.items()}})
    return {"report": path, "seconds": total, "results": results, "stability": stability}


def _markdown(out, results, seconds, stability, shading_rows, quick, total):
    md = ["# Illumination Lab: speed against accuracy\n\n",
          f"Blender {bpy.app.version_string}, {os.cpu_count()} cores ({platform.machine()}), "
          f"{'quick' if quick else 'full'} mode, {total:.0f} s in all. Every number below was measured in this run; "
          "each table is also a CSV beside this file.\n\n",
          "## Stability: where each method fails, and what the project does\n\n", _md_table(stability),
          "\nShading twins at their edge inputs ([shading_edges.csv](shading_edges.csv)):\n\n",
          _md_table(shading_rows)]
    titles = {a.KEY: a.TITLE for a in AREAS}
    for key, r in results.items():
        md.append(f"\n## {titles[key]} ({seconds[key]:.0f} s)\n\n")
        figs = {k: v for k, v in r.figures.items() if not isinstance(v, (list, dict)) or len(str(v)) < 300}
        if figs:
            md.append("".join(f"- **{k}**: {_fmt_fig(v)}\n" for k, v in figs.items()))
        for chart in r.charts:
            rel = os.path.relpath(chart, out)
            md.append(f"\n![{os.path.basename(chart)}]({rel})\n")
        for name, rows in r.tables.items():
            md.append(f"\n### {name} ([{key}/{name}.csv]({key}/{name}.csv))\n\n")
            md.append(_md_table(rows))
    return "".join(md)


def _fmt_fig(v):
    if isinstance(v, float):
        return f"{v:.4g}"
    if isinstance(v, dict):
        return ", ".join(f"{k}: {_fmt_fig(x)}" for k, x in v.items())
    return str(v)
