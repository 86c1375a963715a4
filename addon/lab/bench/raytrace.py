"""Ray casting and Whitted against Cycles: error and cost against recursion depth, every built-in scene at one
depth (what Whitted leaves out), and the stability rows (grazing views, total internal reflection, IOR 1, depth 0
and large depths)."""
import os

from ...core import charts as ch
from .. import raytrace
from ..options import RaytraceOptions
from .result import BenchResult

KEY = "raytrace"
TITLE = "Ray casting and Whitted ray tracing against Cycles"
SCENES = ("diffuse", "mirror", "glass", "walls", "area", "grazing", "ior1", "tir")


def _row(scene, r):
    return {"scene": scene, "method": r["method"], "max_depth": r["max_depth"], "rays": r["rays"],
            "seconds": r["seconds"], "rays_per_second": r["rays_per_second"], "rmse_vs_cycles": r["rmse_vs_cycles"],
            "rmse_vs_cycles_99": r["rmse_vs_cycles_99"], "cycles_noise": r["cycles"]["noise_rmse"],
            "missing_fraction": r["missing"]["fraction"], "cycles_paths_per_second": r["cycles"]["paths_per_second"],
            "cut_weight_mean": r["ray_counts"]["cut_weight_mean"], "cut_weight_max": r["ray_counts"]["cut_weight_max"],
            "dropped_weight_max": r["ray_counts"]["dropped_weight_max"],
            "numpy_bvh_rays_per_second": r["engines"]["numpy_bvh"]["rays_per_second"],
            "bvhtree_rays_per_second": r["engines"]["mathutils_bvhtree"]["rays_per_second"]}


def run(output_dir, quick=False):
    """Tables raytrace_depth (glass and TIR spheres, depth 0..64) and raytrace_scenes (every built-in scene, ray
    casting and Whitted depth 4), the depth chart, figures at depth 4."""
    os.makedirs(output_dir, exist_ok=True)
    res, samples = (24, 4) if quick else (64, 64)
    depths = (0, 1, 2, 4, 64) if quick else (0, 1, 2, 3, 4, 8, 16, 32, 64)
    work = os.path.join(output_dir, "renders")
    depth_rows = []
    for scene in ("glass", "tir"):
        for depth in depths:
            r = raytrace.run_builtin(scene, os.path.join(work, f"{scene}_depth{depth}"),
                                     RaytraceOptions(resolution=res, samples=samples, max_depth=depth))
            depth_rows.append(_row(scene, r))
    scene_rows = []
    for scene in (("mirror", "grazing", "ior1", "walls") if quick else SCENES):
        for method in ("raycast", "whitted"):
            r = raytrace.run_builtin(scene, os.path.join(work, f"{scene}_{method}"),
                                     RaytraceOptions(method=method, resolution=res, samples=samples, max_depth=4))
            scene_rows.append(_row(scene, r))
    pngs = []
    if ch.available():
        series = {f"{s} RMSE": ([r["max_depth"] for r in depth_rows if r["scene"] == s],
                                [max(r["rmse_vs_cycles"], 1e-9) for r in depth_rows if r["scene"] == s])
                  for s in ("glass", "tir")}
        series.update({f"{s} missing (fraction)": ([r["max_depth"] for r in depth_rows if r["scene"] == s],
                                                   [max(r["missing_fraction"], 1e-9) for r in depth_rows
                                                    if r["scene"] == s]) for s in ("glass", "tir")})
        pngs.append(ch.line_chart(os.path.join(output_dir, "raytrace_depth.png"), series,
                                  f"Whitted depth against error ({res} px, Cycles {samples} spp)", "max depth",
                                  "RMSE vs Cycles / missing fraction", logy=True))
    at4 = {r["scene"]: r for r in depth_rows if r["max_depth"] == 4}
    figs = {"glass_depth4_rmse": at4["glass"]["rmse_vs_cycles"], "glass_depth4_noise": at4["glass"]["cycles_noise"],
            "tir_depth4_rmse": at4["tir"]["rmse_vs_cycles"],
            "whitted_rays_per_second": at4["glass"]["rays_per_second"],
            "cycles_paths_per_second": at4["glass"]["cycles_paths_per_second"]}
    return BenchResult({"raytrace_depth": depth_rows, "raytrace_scenes": scene_rows}, pngs, figs)


def stability_rows(result):
    """Rows of the report's stability table from :func:`run`'s tables (empty when the area did not run)."""
    if result is None:
        return []
    depth = {(r["scene"], r["max_depth"]): r for r in result.tables.get("raytrace_depth", [])}
    scenes = {(r["scene"], r["method"]): r for r in result.tables.get("raytrace_scenes", [])}

    def err(r):
        return (f"RMSE {r['rmse_vs_cycles']:.3g} (Cycles noise {r['cycles_noise']:.2g}), "
                f"{100 * r['missing_fraction']:.1f} % of Cycles' light missing") if r else "—"
    deepest = max((d for s, d in depth if s == "tir"), default=None)

    def _deep(r, r4):
        if not r or not r4:
            return "—"
        return (f"{r['rays']} rays ({r['rays'] / r4['rays']:.1f} x depth 4), {r['seconds']:.2f} s; weight still "
                f"travelling: mean {r['cut_weight_mean']:.2g}, worst pixel {r['cut_weight_max']:.2f} (light caught "
                f"between facets by total internal reflection); dropped <= {r['dropped_weight_max']:.2g}; " + err(r))
    return [
        {"method": "Whitted", "fails at": "depth 0 (= ray casting): mirrors and glass black",
         "measured": err(depth.get(("glass", 0))), "what the project does": "--max-depth; 4 is within noise here"},
        {"method": "Whitted", "fails at": f"large depths ({deepest}): rays split at every glass hit",
         "measured": _deep(depth.get(("tir", deepest)), depth.get(("tir", 4))),
         "what the project does": "rays below weight 1e-4 dropped and counted (dropped_weight_max in the report)"},
        {"method": "Whitted", "fails at": "total internal reflection (IOR 2.4 sphere)",
         "measured": err(depth.get(("tir", 4))), "what the project does": "k_s = 1, no refracted ray (Snell)"},
        {"method": "Whitted", "fails at": "grazing views of a mirror floor",
         "measured": err(scenes.get(("grazing", "whitted"))),
         "what the project does": "Schlick F of the metal -> 1 at grazing, as Cycles' Principled metal"},
        {"method": "Whitted", "fails at": "glass of IOR 1 (should be invisible)",
         "measured": err(scenes.get(("ior1", "whitted"))),
         "what the project does": "F = 0, t = d; its shadow stays (Whitted's and Cycles' shadow rays stop at glass)"},
        {"method": "Whitted", "fails at": "two diffuse walls facing each other (interreflection)",
         "measured": err(scenes.get(("walls", "whitted"))), "what the project does": "reported as missing.exr"},
    ]
