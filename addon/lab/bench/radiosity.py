"""Radiosity on the Cornell box: cost against patches (visibility, form factors, solve) and the solvers'
convergence. The report shows it in the environment-map section (:mod:`.envmap` runs it)."""
import os

from ...core import charts as ch
from ...core import analytic
from .. import radiosity as lrad
from .result import BenchResult

KEY = "radiosity"
TITLE = "Radiosity: cost and convergence"


def run(output_dir, quick=False):
    """Tables radiosity_cost and radiosity_solvers, their charts, figures radiosity_patches and _seconds."""
    os.makedirs(output_dir, exist_ok=True)
    tables, figs, pngs = {}, {}, []
    rows, last = [], None
    meshes = analytic.cornell_box()
    for edge in ((0.5, 0.25) if quick else (0.5, 0.25, 0.125)):
        r = lrad.solve_scene(meshes, edge, "gauss_seidel", 1e-6)
        t = r["timings"]
        rows.append({"max_edge": edge, "patches": len(r["patches"]), "visibility_s": t["visibility"],
                     "form_factors_s": t["form_factors"], "solve_s": t["solve"], "total_s": t["total"]})
        last = r
    tables["radiosity_cost"] = rows
    pngs.append(ch.line_chart(os.path.join(output_dir, "radiosity_cost.png"),
                              {k: ([r["patches"] for r in rows], [r[k] for r in rows])
                               for k in ("visibility_s", "form_factors_s", "solve_s", "total_s")},
                              "Radiosity cost (Cornell box)", "patches", "seconds", logx=True, logy=True))
    big = rows[-1]
    figs["radiosity_patches"] = big["patches"]
    figs["radiosity_seconds"] = big["total_s"]
    sols = lrad.convergence(last["F"], last["patches"], 1e-6)
    pngs.append(lrad.convergence_chart(os.path.join(output_dir, "radiosity_convergence.png"), sols, len(last["patches"])))
    tables["radiosity_solvers"] = [{"solver": s, "patches": len(last["patches"]), "iterations": so.iterations,
                                    "seconds": so.seconds, "final_residual": so.residuals[-1]} for s, so in sols.items()]
    return BenchResult(tables, pngs, figs)


# ----------------------------------------------------------------------------- speed, before and after

PATHS = {"before": {"visibility": "bvh", "reciprocal": False},     # BVH ray per pair, every ordered pair's F
         "after": {"visibility": "auto", "reciprocal": True}}      # face test, visible pairs once


def _timed_solve(meshes, edge, path):
    import time
    from ...core.radiosity import gather
    c0 = time.process_time()
    r = lrad.solve_scene(meshes, edge, "jacobi", 1e-5, **PATHS[path])
    t0 = time.perf_counter()
    g = gather.near_field_gather(r["patches"], r["F"], r["solution"].B, r["near_field"])
    t = dict(r["timings"])
    t["texel_gather"] = time.perf_counter() - t0
    t["total"] += t["texel_gather"]
    return r, g, t, time.process_time() - c0


def speed(scenes, paths=("before", "after"), repeat=1, report=None):
    """Rows {scene, path, method, patches, visibility_s, form_factors_s, near_field_s, near_emitters_s, solve_s,
    texel_gather_s, total_s, cpu_s} (best total of ``repeat`` runs) and, per scene, the largest differences of
    the paths' irradiance (the same patches): {scene: {"H_rel_max", "texel_rel_rms"}}. ``scenes``: {name:
    (meshes, max_edge[, paths])}; ``report(row)`` is called as each row is measured."""
    import numpy as np
    rows, diffs = [], {}
    for name, (meshes, edge, *own) in scenes.items():
        out = {}
        for path in (own[0] if own else paths):
            best = None
            for _ in range(repeat):
                r, g, t, cpu = _timed_solve(meshes, edge, path)
                if best is None or t["total"] < best[2]["total"]:
                    best = (r, g, t, cpu)
            r, g, t, cpu = best
            out[path] = (r["H"], g.H)
            rows.append({"scene": name, "path": path, "method": r["visibility"], "patches": len(r["patches"]),
                         **{f"{k}_s": round(t.get(k, 0.0), 2) for k in ("visibility", "form_factors", "near_field",
                                                                       "near_emitters", "solve", "texel_gather",
                                                                       "total")},
                         "cpu_s": round(cpu, 1)})
            if report:
                report(rows[-1])
            del r, g
        if len(out) == 2:
            (h0, g0), (h1, g1) = out.values()
            diffs[name] = {"H_rel_max": float(np.abs(h1 - h0).max() / np.abs(h0).max()),
                           "texel_rel_rms": float(np.sqrt(np.nanmean((g1 - g0) ** 2)) / np.nanmean(g0))}
    return rows, diffs
