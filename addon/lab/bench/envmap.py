"""Irradiance environment maps: SH9 speed and accuracy against brute force (plus the radiosity bench, which
the report shows in the same section)."""
import os
import time

import numpy as np

from ...core import charts as ch
from ...core import analytic
from ...core.envmap import irradiance as env_irradiance
from ...core.envmap import latlong
from ...core.envmap import sh9 as env_sh9
from . import radiosity
from .result import BenchResult

KEY = "envmap"
TITLE = "Irradiance environment maps and radiosity"


def _sharp_env(h, w, radius_deg=10.0, power=40.0):
    d = latlong.latlong_directions(h, w)
    env = analytic.linear_sky(h, w, 0.5, 0.2)
    axis = np.array([0.5, 0.5, 0.7071]) / np.linalg.norm([0.5, 0.5, 0.7071])
    return env + power * (d @ axis > np.cos(np.radians(radius_deg)))[..., None] * np.array([1.0, 0.8, 0.6])


def run(output_dir, quick=False):
    """Speed and accuracy of the irradiance maps, then :func:`radiosity.run`, and the targets table."""
    os.makedirs(output_dir, exist_ok=True)
    tables, figs, pngs = {}, {}, []

    # SH9 timing on a 1024x512 environment (best of 3), brute force for scale
    env = _sharp_env(512, 1024)
    best = min(_timed(lambda: env_sh9.irradiance_map_sh9(env, 64))[1] for _ in range(3))
    figs["sh9_1024x512_seconds"] = best
    n64 = latlong.latlong_directions(32, 64)
    _, tb = _timed(lambda: env_irradiance.irradiance_brute(env, n64, max_width=256))
    figs["brute_1024x512_seconds"] = tb

    # accuracy of SH9 against brute force as the light gets sharper
    rows = []
    for r in ((5, 20, 60) if quick else (2, 5, 10, 20, 40, 60, 90)):
        e = _sharp_env(128, 256, r, 40.0)
        ref = env_irradiance.irradiance_brute(e, n64)
        sh, ts = _timed(lambda: env_sh9.irradiance_map_sh9(e, 64))
        rows.append({"light_radius_deg": r, "sh9_rel_rms": float(np.sqrt(np.mean((sh - ref) ** 2)) / np.mean(ref)),
                     "sh9_rel_max": float(np.max(np.abs(sh - ref)) / np.max(ref)), "sh9_seconds": ts})
    tables["envmap_sh9_accuracy"] = rows
    pngs.append(ch.line_chart(os.path.join(output_dir, "envmap_sh9_accuracy.png"),
                              {"relative RMS": ([r["light_radius_deg"] for r in rows], [r["sh9_rel_rms"] for r in rows]),
                               "max / max E": ([r["light_radius_deg"] for r in rows], [r["sh9_rel_max"] for r in rows])},
                              "Nine SH coefficients vs brute-force E(n)", "light radius (degrees)", "error", logy=True))

    # brute force: speed against accuracy as the environment is box-filtered
    rows = []
    ref = env_irradiance.irradiance_brute(env, n64, max_width=512)
    for mw in ((32, 64, 128) if quick else (16, 32, 64, 128, 256)):
        e, t = _timed(lambda: env_irradiance.irradiance_brute(env, n64, max_width=mw))
        rows.append({"max_width": mw, "seconds": t, "rel_rms": float(np.sqrt(np.mean((e - ref) ** 2)) / np.mean(ref))})
    tables["envmap_brute_speed"] = rows
    pngs.append(ch.scatter_chart(os.path.join(output_dir, "envmap_brute_speed.png"),
                                 {f"{r['max_width']} px": (r["seconds"], max(r["rel_rms"], 1e-9)) for r in rows},
                                 "Brute-force E(n): speed vs accuracy", "seconds", "relative RMS vs 512 px", logx=True,
                                 logy=True))

    result = BenchResult(tables, pngs, figs).merge(radiosity.run(output_dir, quick))
    big = result.tables["radiosity_cost"][-1]
    tables["targets"] = [
        {"measure": "SH9 irradiance of 1024x512, seconds", "value": figs["sh9_1024x512_seconds"], "target": "<= 0.2"},
        {"measure": "brute-force E of 1024x512 (64x32 map), seconds", "value": tb, "target": "-"},
        {"measure": f"radiosity of {big['patches']} patches incl. visibility, s", "value": big["total_s"],
         "target": "<= 30" if big["patches"] >= 2000 else "-"},
    ]
    for name, rows_ in tables.items():
        ch.write_csv(os.path.join(output_dir, f"{name}.csv"), rows_)
    return result


def _timed(fn):
    """(fn(), seconds it took)."""
    t = time.perf_counter()
    out = fn()
    return out, time.perf_counter() - t
