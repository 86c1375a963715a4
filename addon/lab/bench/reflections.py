"""Reflection mapping: every map type against Cycles' mirror on the built-in scenes (error against seconds),
the map types at equal texel count (lookup error against an analytic sky, texel solid-angle and shape
distortion), the capture-distance sweep, and the stability rows (grazing views, total internal reflection,
IOR 1)."""
import os

import numpy as np

from ...core import charts as ch
from ...core.envmap import maps, reflection
from .. import reflections
from ..options import ReflectionOptions
from ..reflections import scenes
from .result import BenchResult

KEY = "reflections"
TITLE = "Reflection and refraction mapping against Cycles' mirror"
METHODS = ("latlong", "cube", "sphere", "raytraced")


def smooth_sky(d):
    """A smooth analytic environment (no horizon step, whose alignment with lat-long rows would favour that
    map): a sun lobe exp(10 (d·s − 1)), a vertical gradient, six azimuthal stripes fading at the poles."""
    d = np.asarray(d, np.float64)
    sun = np.exp(10 * (d @ np.array([0.48, -0.6, 0.64]) - 1))[..., None] * np.array([3.0, 2.5, 1.8])
    stripes = 0.1 * (1 + np.cos(6 * np.arctan2(d[..., 1], d[..., 0])))[..., None] * np.sqrt(1 - d[..., 2:3] ** 2)
    return sun + 0.3 * (1 + d[..., 2:3]) + stripes


def map_type_rows(heights=(16, 32, 64, 128), n=20000, seed=3):
    """Per map type and lat-long height H (equal texel count 2H²): texels, solid angle max/min, largest
    anisotropy, RMSE and max error of the bilinear lookup of :func:`smooth_sky` against the sky itself."""
    d = np.random.default_rng(seed).normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    rows = []
    for h in heights:
        for p in maps.PROJECTIONS:
            size = maps.equal_texel_size(p, h)
            dist = maps.distortion(p, size)
            rmse, worst = maps.lookup_error(smooth_sky, p, size, d)
            rows.append({"map": p.lower(), "height": h, "size": size, "texels": dist["texels"],
                         "solid_angle_max_over_min": dist["max_over_min"], "anisotropy_max": dist["anisotropy_max"],
                         "lookup_rmse": rmse, "lookup_max": worst})
    return rows


def edge_figures():
    """The lookup at its edges: grazing view, total internal reflection, IOR 1 (numpy twin of the node group)."""
    n = np.array([0.0, 0.0, 1.0])
    grazing = np.array([np.sqrt(1 - 1e-14), 0.0, 1e-7])
    r, fr = reflection.lookup(grazing, n, "REFLECT", 1.5, True)
    _, tir = reflection.lookup(np.array([0.9, 0.0, np.sqrt(1 - 0.81)]), n, "REFRACT", 1.5, True, inside=True)
    v = np.random.default_rng(0).normal(size=(1000, 3))
    v /= np.linalg.norm(v, axis=-1, keepdims=True)
    v[:, 2] = np.abs(v[:, 2])
    t1, w1 = reflection.lookup(v, np.broadcast_to(n, v.shape), "REFRACT", 1.0, True)
    return {"grazing_weight": float(fr), "grazing_finite": bool(np.all(np.isfinite(r))),
            "tir_weight": float(tir), "ior1_max_direction_change": float(np.abs(t1 + v).max()),
            "ior1_min_weight": float(w1.min())}


def run(output_dir, quick=False):
    """Tables reflections_methods (scene x method), reflections_distance (capture offset), reflections_map_types
    (equal texel count); charts error against seconds and map type against texels."""
    os.makedirs(output_dir, exist_ok=True)
    res, size = (32, 32) if quick else (96, 64)
    work = os.path.join(output_dir, "reflections")
    method_rows, distance_rows = [], []
    for name in scenes.SCENES:
        r = reflections.run_builtin(name, os.path.join(work, name), ReflectionOptions(resolution=res, map_size=size))
        for m, e in r["methods"].items():
            method_rows.append({"scene": name, "method": m, "rmse": e["rmse"], "relative_rmse": e["relative_rmse"],
                                "seconds": e["seconds"], "texels": e["params"].get("texels", 0),
                                "contrast": e["params"].get("contrast", 1.0)})
        for row in r.get("distance_sweep", []):
            distance_rows.append(dict(row))
    type_rows = map_type_rows((16, 32) if quick else (16, 32, 64, 128))
    pngs = []
    if ch.available():
        pts = {f"{r['scene']} {r['method']}": (max(r["seconds"], 1e-6), max(r["relative_rmse"], 1e-6))
               for r in method_rows if r["method"] != "raytraced"}
        pngs.append(ch.scatter_chart(os.path.join(output_dir, "reflections_error_seconds.png"), pts,
                                     f"Reflection maps vs Cycles' mirror ({res} px, H = {size})", "seconds",
                                     "relative RMSE", logx=True, logy=True, front=False))
        series = {p: ([r["texels"] for r in type_rows if r["map"] == p],
                      [r["lookup_rmse"] for r in type_rows if r["map"] == p]) for p in ("latlong", "cube", "sphere")}
        pngs.append(ch.line_chart(os.path.join(output_dir, "reflections_map_types.png"), series,
                                  "Map type against texels: lookup RMSE of a smooth analytic sky", "texels", "RMSE",
                                  logx=True, logy=True))
    figs = {f"{r['scene']}_{r['method']}_relative_rmse": r["relative_rmse"] for r in method_rows
            if r["method"] == "latlong"}
    figs.update(edge_figures())
    return BenchResult({"reflections_methods": method_rows, "reflections_distance": distance_rows,
                        "reflections_map_types": type_rows}, pngs, figs)


def stability_rows(result):
    """Rows of the report's stability table (empty when the area did not run)."""
    if result is None:
        return []
    f = result.figures
    rel = {(r["scene"], r["method"]): r["relative_rmse"] for r in result.tables.get("reflections_methods", [])}
    return [
        {"method": "reflection mapping", "fails at": "grazing view (n.v = 1e-7)",
         "measured": f"F = {f['grazing_weight']:.4f}, direction finite: {f['grazing_finite']}",
         "what the project does": "n.v clamped at 0; Schlick's F -> 1 (all reflected)"},
        {"method": "refraction mapping", "fails at": "total internal reflection (leaving IOR 1.5 at 64 deg)",
         "measured": f"transmitted weight {f['tir_weight']:g}",
         "what the project does": "no transmitted light (weight 0); the reflected lookup gets F = 1"},
        {"method": "refraction mapping", "fails at": "IOR 1 (no interface)",
         "measured": f"direction change {f['ior1_max_direction_change']:.1e}, weight >= {f['ior1_min_weight']:.4f}",
         "what the project does": "t = -v and F = 0 (Schlick's grazing term dropped at IOR 1): the world behind"},
        {"method": "reflection maps", "fails at": "concave mirror (self-reflection)",
         "measured": f"relative RMSE {rel.get(('concave', 'latlong'), float('nan')):.3f} "
                     f"(sky alone {rel.get(('sphere', 'latlong'), float('nan')):.3f})",
         "what the project does": "reported: a map cannot hold the object itself; use the ray-traced mirror"},
    ]
