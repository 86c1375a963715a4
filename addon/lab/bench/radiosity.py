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
