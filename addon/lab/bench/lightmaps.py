"""Light-map benchmark.

- :func:`run` -- pipeline overhead over the bare Cycles bake call, and time to reach
  RMS 0.01 against the analytic k_A of the demo floor for plain sampling, target-error
  (pilot variance) and Blender's denoiser; tables, charts, figures.
- :func:`monte_carlo_slope` -- the error's exponent in the sample count (-1/2 for plain Monte Carlo).
"""
import math
import os
import time

import bpy
import numpy as np

from ...core import charts
from ...core.io import exr
from ...core import lightmap as lm
from ..demo import scene as demo
from ...blender import chatter, render
from ...blender.materials import no_closure
from ...blender.state import SavedState
from ...blender.scene import remove_scene
from ...bake.options import BakeOptions
from ...bake.pipeline import bake_lightmaps
from .result import BenchResult

KEY = "lightmaps"
TITLE = "Light maps: bake error against seconds"

PLANAR = "IL planar"


# ------------------------------------------------------------------ the demo floor and its analytic k_A

def _demo_floor_scene():
    """The demo scene with the Torus hidden (no closed form) and a planar UV layer on the Floor."""
    scene = demo.build_demo_scene(new_scene=True, resolution=(32, 32))
    demo.get(scene, "Torus").hide_render = True
    floor = demo.get(scene, "Floor")
    me = floor.data
    layer = me.uv_layers.new(name=PLANAR)
    co = np.zeros(len(me.vertices) * 3)
    me.vertices.foreach_get("co", co)
    vi = np.zeros(len(me.loops), int)
    me.loops.foreach_get("vertex_index", vi)
    layer.data.foreach_set("uv", (co.reshape(-1, 3)[vi, :2] / 8.0 + 0.5).ravel())
    return scene, floor


def _world_faces(obj):
    mw = np.array(obj.matrix_world, float)
    co = np.array([mw[:3, :3] @ np.array(v.co) + mw[:3, 3] for v in obj.data.vertices])
    return [co[list(p.vertices)] for p in obj.data.polygons], co


def analytic_floor_ao(scene, n):
    """(reference k_A, mask) on an n × n planar map of the 8 m demo floor, rows bottom-first.

    k_A = 1 - F_box - F_sphere: Lambert's polygon formula over the box faces facing the
    texel and F = (R/D)² cos θ for the sphere (REFERENCE.md §3). The mask keeps texels
    whose two occluders' cones do not overlap and that lie 0.25 m or more away from them.
    """
    box, sphere = demo.get(scene, "Box"), demo.get(scene, "Sphere")
    faces, corners = _world_faces(box)
    centre_s = np.array(sphere.matrix_world.translation)
    radius = max(np.linalg.norm(np.array(v.co)) for v in sphere.data.vertices)
    # polygonal sphere: use the radius of the sphere of equal volume-ish (mean of in- and circumradius)
    radius *= 0.5 * (1 + math.cos(math.pi / 48))
    c = (np.arange(n) + 0.5) / n * 8.0 - 4.0
    y, x = np.meshgrid(c, c, indexing="ij")
    p = np.stack([x.ravel(), y.ravel(), np.zeros(n * n)], axis=1)
    centre_b = corners.mean(axis=0)
    db = centre_b - p
    ab = np.max([_angles(db, q - p) for q in corners], axis=0)
    ds = centre_s - p
    dist = np.linalg.norm(ds, axis=1)
    as_ = np.arcsin(np.minimum(radius / dist, 1.0))
    local = np.c_[p, np.ones(len(p))] @ np.linalg.inv(np.array(box.matrix_world))[:2].T
    near_box = np.all(np.abs(local) < 0.75, axis=1)
    ok = (_angles(db, ds) > ab + as_) & (dist > radius + 0.25) & ~near_box
    f = lm.view_factors_convex(p, (0, 0, 1), faces) + lm.view_factor_sphere(dist, ds[:, 2] / dist, radius)
    return (1.0 - f).reshape(n, n), ok.reshape(n, n)


def _angles(a, b):
    """Angles between the rows of ``a`` and ``b``."""
    cos = np.einsum("ij,ij->i", a, b) / (np.linalg.norm(a, axis=1) * np.linalg.norm(b, axis=1))
    return np.arccos(np.clip(cos, -1.0, 1.0))


def _bare_bake(scene, floor, res, samples):
    """Time of the bare Cycles AO bake call doing the pipeline's work: the same Cycles settings (CPU,
    samples, seed, no adaptive sampling, no bounces), the pipeline's no-closure material carrying the image
    node, and Blender's own 4-texel margin in place of the pipeline's dilation. Material, image and settings
    are prepared beforehand and put back afterwards."""
    cy = scene.cycles
    with SavedState(scene, [floor], render.settings(scene) + [(cy, "max_bounces"), (cy, "diffuse_bounces")]) as state:
        img = state.track(bpy.data.images, bpy.data.images.new("IL bench", res, res, float_buffer=True, alpha=True))
        mat = state.track(bpy.data.materials, no_closure("IL bench"))
        nt = mat.node_tree
        tex = nt.nodes.new("ShaderNodeTexImage")
        tex.image = img
        nt.nodes.active = tex
        floor.data.materials.append(mat)
        render.cycles_cpu(scene, samples)
        cy.max_bounces = cy.diffuse_bounces = 0
        scene.world.light_settings.distance = 10.0
        vl = scene.view_layers[0]
        for o in vl.objects:
            o.select_set(o == floor, view_layer=vl)
        vl.objects.active = floor
        with chatter.captured():
            t = time.perf_counter()
            with bpy.context.temp_override(scene=scene, view_layer=vl, active_object=floor, object=floor,
                                           selected_objects=[floor], selected_editable_objects=[floor]):
                bpy.ops.object.bake(type="AO", margin=4, target="IMAGE_TEXTURES", uv_layer=PLANAR,
                                    save_mode="INTERNAL")
            return time.perf_counter() - t


def _pipeline(scene, floor, out, kind="ao", **kw):
    """Bake one map of the floor; (seconds, values with rows bottom-first, report entry).

    Values are k_A for "ao" and the mean of R, G, B (W/m²) for "irradiance"."""
    kw.setdefault("uv_layer", PLANAR)
    kw.setdefault("overwrite", True)
    kw.setdefault("force", True)          # every call bakes: a repeat would otherwise be skipped as unchanged
    t = time.perf_counter()
    rep = bake_lightmaps([floor], [kind], out, BakeOptions(**kw), scene=scene)
    seconds = time.perf_counter() - t                    # the whole call, validation included
    e = rep["objects"][floor.name][kind]
    ch, _ = exr.read_exr(e["file"])
    values = ch["Y"] if kind == "ao" else (ch["R"] + ch["G"] + ch["B"]) / 3.0
    return seconds, np.flipud(values), e


def _uniform_sky(scene, radiance):
    """Lights off, a uniform white world of ``radiance``: then E = pi L k_A exactly (0 bounces)."""
    for o in scene.objects:
        if o.type == "LIGHT":
            o.hide_render = True
    bg = scene.world.node_tree.nodes["Background"]
    bg.inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
    bg.inputs["Strength"].default_value = radiance


def _time_to(seconds, errors, goal):
    """Seconds at which the error curve crosses ``goal`` (log-log interpolation), or None."""
    pts = sorted(zip(seconds, errors))
    for (t0, e0), (t1, e1) in zip(pts, pts[1:]):
        if e0 > goal >= e1:
            w = (math.log(e0) - math.log(goal)) / (math.log(e0) - math.log(e1))
            return math.exp(math.log(t0) + w * (math.log(t1) - math.log(t0)))
    if pts and pts[0][1] <= goal:
        return pts[0][0]
    return None


def run(output_dir, quick=False):
    """Run the light-map benchmarks; return {"tables", "charts", "figures"} (see module doc)."""
    os.makedirs(output_dir, exist_ok=True)
    work = os.path.join(output_dir, "bake_bench_maps")
    scene, floor = _demo_floor_scene()
    try:
        return _sweeps(scene, floor, output_dir, work, quick)
    finally:
        remove_scene(scene)


def _sweeps(scene, floor, output_dir, work, quick):
    tables, figures = {}, {}
    # 1. overhead over the bare bake call: interleaved repetitions, the least time of each (the shared
    # machine's load only ever adds time); also the pipeline's own time outside its Cycles call, which the
    # load hardly touches
    res, samples = (128, 16) if quick else (512, 64)
    rows = []
    _bare_bake(scene, floor, 32, 1)                    # warm-up: kernels and scene sync once
    for rep in range(1 if quick else 3):
        bare = _bare_bake(scene, floor, res, samples)
        pipe, _, e = _pipeline(scene, floor, work, resolution=res, samples=samples, margin=4)
        rows.append({"resolution": res, "samples": samples, "bare_s": bare, "pipeline_s": pipe,
                     "pipeline_cycles_s": e["cycles_seconds"], "overhead": pipe / bare - 1.0,
                     "outside_cycles": pipe / e["cycles_seconds"] - 1.0})
    tables["bake_overhead"] = rows
    figures["bake_overhead"] = min(r["pipeline_s"] for r in rows) / min(r["bare_s"] for r in rows) - 1.0
    figures["bake_overhead_outside_cycles"] = min(r["outside_cycles"] for r in rows)
    figures["bake_overhead_at"] = f"{res}x{res}, {samples} samples"
    # 2. time to RMS 0.01 against the analytic k_A
    n = 64 if quick else 128
    ref, mask = analytic_floor_ao(scene, n)
    goal = 0.01
    plans = {
        "plain": [dict(samples=s) for s in ((4, 16, 64, 256) if quick else (4, 8, 16, 32, 64, 128, 256, 512))],
        "target error": [dict(target_error=e) for e in ((0.04, 0.01) if quick else (0.04, 0.02, 0.01, 0.007))],
        "denoised": [dict(samples=s, denoise=True) for s in ((4, 16) if quick else (2, 4, 8, 16, 32, 64))],
    }
    rows, series = [], {}
    for method, runs in plans.items():
        xs, ys = [], []
        for kw in runs:
            secs, k, e = _pipeline(scene, floor, work, resolution=n, margin=0, **kw)
            err = lm.rms(k, ref, mask)
            rows.append({"method": method, "samples": e["samples"], "seconds": secs, "rms": err,
                         "estimated_error": e["estimated_error"], "target": kw.get("target_error")})
            xs.append(secs)
            ys.append(err)
        series[method] = (xs, ys)
    tables["bake_time_to_error"] = rows
    # 3. irradiance under a uniform sky of radiance L, 0 bounces: E = pi L k_A; errors relative to pi L
    radiance = 1.0
    _uniform_sky(scene, radiance)
    e_open = math.pi * radiance
    irr_rows, irr_series = [], {}
    for method, runs in plans.items():
        xs, ys = [], []
        for kw in runs:
            kw = dict(kw, bounces=0)
            if "target_error" in kw:
                kw["target_error"] *= e_open
            secs, e_map, e = _pipeline(scene, floor, work, "irradiance", resolution=n, margin=0, **kw)
            err = lm.rms(e_map, e_open * ref, mask) / e_open
            irr_rows.append({"method": method, "samples": e["samples"], "seconds": secs, "relative_rms": err,
                             "estimated_error": e["estimated_error"] / e_open})
            xs.append(secs)
            ys.append(err)
        irr_series[f"irradiance {method}"] = (xs, ys)
    tables["bake_irradiance_time_to_error"] = irr_rows
    irr_times = {m: _time_to(*irr_series[m], goal) for m in irr_series}
    figures["irradiance_time_to_rel_rms_0.01_s"] = irr_times
    times = {m: _time_to(*series[m], goal) for m in series}
    figures["bake_time_to_rms_0.01_s"] = times
    figures["bake_texels_compared"] = int(mask.sum())
    plain = times.get("plain")
    best = min((t for m, t in times.items() if m != "plain" and t), default=None)
    figures["bake_speedup_best_vs_plain"] = (plain / best) if (plain and best) else None
    chart = charts.line_chart(os.path.join(output_dir, "bake_error_vs_seconds.png"), series,
                              f"AO light map of the demo floor ({n}x{n}): error against time",
                              "seconds (whole pipeline)", "RMS error vs analytic k_A", logx=True, logy=True,
                              marks={f"goal RMS {goal}": (plain or (min(series['plain'][0])), goal)})
    irr_chart = charts.line_chart(os.path.join(output_dir, "bake_irradiance_error_vs_seconds.png"), irr_series,
                                  f"Irradiance map of the demo floor ({n}x{n}) under a uniform sky: error "
                                  "against time", "seconds (whole pipeline)", "RMS error / (pi L)",
                                  logx=True, logy=True)
    for table, column, key in (("bake_time_to_error", "rms", "mc_slope"),
                               ("bake_irradiance_time_to_error", "relative_rms", "mc_slope_irradiance")):
        plain = [r for r in tables[table] if r["method"] == "plain"]
        figures[key] = monte_carlo_slope([r["samples"] for r in plain], [r[column] for r in plain])
    return BenchResult(tables, [chart, irr_chart], figures)


def monte_carlo_slope(samples, rms):
    """Least-squares slope of log(rms) against log(samples); -1/2 for an unbiased Monte Carlo estimate."""
    x, y = np.log(np.asarray(samples, float)), np.log(np.asarray(rms, float))
    if len(x) < 2 or np.ptp(x) == 0:
        return float("nan")
    return float(np.polyfit(x, y, 1)[0])
