"""Sweeps of the shadow lab: each failure pushed along one parameter, as tables and charts.

run(output_dir, quick) -> BenchResult: the sweeps, then every method on the sphere scene (error
against seconds); speed() prints beside the targets (scripts/bench_shadows.py).
"""
import contextlib
import os
import tempfile
import time

import numpy as np

from ...core import charts
from ...core.camera import SKY_DEPTH
from ...core.shadow import depth_map as shadow_map
from ...core.shadow import metrics as shadow_metrics
from ...core.io.files import write_json
from ...blender.progress import Progress
from ...blender import scene as sc
from .. import shadows as lab
from ..options import ShadowOptions
from ..shadows import scenes as shadow_scenes
from ..shadows.frame import ShadowFrame
from .result import BenchResult

KEY = "shadows"
TITLE = "Shadows: methods against ray-traced shadows"


def _score(s, mask):
    return shadow_metrics.confusion(mask, s.reference, s.receiver)


@contextlib.contextmanager
def _reference(name, res, **kw):
    """A built-in scene under a sun, an open :class:`ShadowFrame` with its reference rendered; the scene
    is removed afterwards."""
    scene = shadow_scenes.build(name, "sun", (res, res), **kw)
    try:
        with ShadowFrame(scene, scene["il_shadow_light"], res) as s:
            s.render_reference()
            yield s
    finally:
        sc.remove_scene(scene)


def run(output_dir, quick=False):
    """Run every shadow sweep; write CSV tables and PNG charts into ``output_dir``; return what was made."""
    os.makedirs(output_dir, exist_ok=True)
    res = 64 if quick else 256
    sizes = [32, 64, 128, 256, 512, 1024] if quick else [128, 256, 512, 1024, 2048, 4096]
    biases = [0.0, 1e-3, 0.01, 0.03, 0.1, 0.3, 1.0, 3.0] if quick else \
        [0.0, 3e-4, 1e-3, 3e-3, 0.01, 0.03, 0.05, 0.1, 0.2, 0.3, 0.5, 1.0, 2.0, 3.0]
    pcfs = [1, 3, 5] if quick else [1, 3, 5, 7, 9]
    segs = [(16, 8), (32, 16), (64, 32)] if quick else [(16, 8), (32, 16), (64, 32), (128, 64), (256, 128)]
    tables, chart_paths, figures = {}, [], {}
    base = lab.check_params({})
    with Progress("shadow sweeps", 6) as progress:
        progress.step("shadow-map resolution")
        rows, pcf_rows = [], []
        with _reference("sphere", res) as s:
            for n in sizes:
                maps, render_s = s.depth_maps(n)
                mask, lookup_s = lab.shadowmap_mask(s, maps, base)
                cycles_maps, cycles_s = s.depth_maps(n, "cycles")
                cycles_mask, _ = lab.shadowmap_mask(s, cycles_maps, base)
                rows.append(dict(size=n, **_score(s, mask), render_seconds=render_s, cycles_seconds=cycles_s,
                                 mask_pixels_unlike_cycles=int((mask != cycles_mask)[s.receiver].sum()),
                                 lookup_seconds=lookup_s))
            progress.step("PCF kernel size")
            maps, _ = s.depth_maps(256 if quick else 512)
            for k in pcfs:
                mask, lookup_s = lab.shadowmap_mask(s, maps, dict(base, pcf=k))
                pcf_rows.append(dict(pcf=k, map_size=maps[0].size, **_score(s, mask), lookup_seconds=lookup_s))
        tables["shadowmap_resolution"] = rows
        tables["shadowmap_pcf"] = pcf_rows
        x = [r["size"] for r in rows]
        chart_paths.append(charts.line_chart(
            os.path.join(output_dir, "shadowmap_resolution_error.png"),
            {"error": (x, [r["error"] for r in rows]), "false shadow": (x, [r["false_shadow"] for r in rows]),
             "false light": (x, [r["false_light"] for r in rows])},
            "Shadow map: error against resolution (sphere, sun)", "shadow-map size N (N x N texels)",
            "misclassified fraction of receiver pixels", logx=True))
        chart_paths.append(charts.line_chart(
            os.path.join(output_dir, "shadowmap_resolution_time.png"),
            {"depth map (numpy raster)": (x, [r["render_seconds"] for r in rows]),
             "depth map (Cycles Depth pass)": (x, [r["cycles_seconds"] for r in rows]),
             "numpy lookup": (x, [r["lookup_seconds"] for r in rows])},
            "Shadow map: time against resolution", "shadow-map size N", "seconds", logx=True, logy=True))
        chart_paths.append(charts.line_chart(
            os.path.join(output_dir, "shadowmap_pcf.png"),
            {"error": ([r["pcf"] for r in pcf_rows], [r["error"] for r in pcf_rows])},
            "Shadow map: PCF kernel size", "PCF kernel K (K x K texels)", "misclassified fraction"))
        figures["shadowmap_error_by_size"] = {r["size"]: r["error"] for r in rows}

        progress.step("bias sweep (acne to peter-panning)")
        rows = []
        with _reference("acne", res) as s:
            maps, _ = s.depth_maps(256 if quick else 1024)
            for b in biases:
                mask, _ = lab.shadowmap_mask(s, maps, dict(base, bias=b, slope_bias=0.0))
                rows.append(dict(bias=b, slope_bias=0.0, map_size=maps[0].size, **_score(s, mask)))
        tables["shadowmap_bias"] = rows
        best = min(rows, key=lambda r: r["error"])
        xb = [max(r["bias"], 1e-4) for r in rows]
        chart_paths.append(charts.line_chart(
            os.path.join(output_dir, "shadowmap_bias.png"),
            {"false shadow (acne)": (xb, [r["false_shadow"] for r in rows]),
             "false light (peter-panning)": (xb, [r["false_light"] for r in rows]),
             "error": (xb, [r["error"] for r in rows])},
            "Shadow map: constant bias (box, grazing sun; bias 0 drawn at 1e-4)", "constant bias (m)",
            "fraction of receiver pixels", logx=True,
            marks={f"best bias {best['bias']:g} m": (max(best["bias"], 1e-4), best["error"])}))
        figures["best_bias"] = best["bias"]
        figures["bias_ends"] = {"acne_false_shadow": rows[0]["false_shadow"], "panning_false_light": rows[-1]["false_light"]}

        progress.step("shadow-volume cost against triangle count")
        rows = []
        for u, v in segs:
            with _reference("sphere", res, segments=u, rings=v) as s:
                t = time.perf_counter()
                volume, info = lab.volume_inputs(s)
                mask = lab.volume_mask(s, volume, "zfail")
                rows.append(dict(**info, seconds=time.perf_counter() - t, **_score(s, mask)))
        for r in rows:
            r.pop("skipped_open_meshes", None)
        tables["volume_cost"] = rows
        chart_paths.append(charts.line_chart(
            os.path.join(output_dir, "volume_cost.png"),
            {"z-fail stencil (numpy)": ([r["occluder_triangles"] for r in rows], [r["seconds"] for r in rows])},
            f"Shadow volumes: cost against occluder triangles ({res}x{res} frame)", "occluder triangles",
            "seconds", logx=True, logy=True))

        progress.step("planar shadows on planar and stepped receivers")
        rows = []
        for name in ("sphere", "stairs"):
            with _reference(name, res) as s:
                mask, _, _ = lab.run_method(s, "planar", base)
                rows.append(dict(scene=name, receiver="planar" if name == "sphere" else "stairs", **_score(s, mask)))
        tables["planar_receivers"] = rows
        chart_paths.append(_bar(os.path.join(output_dir, "planar_receivers.png"), rows, "scene",
                                "Planar shadows: planar floor vs stairs"))

        progress.step("z-pass against z-fail, camera outside and inside a volume")
        rows = []
        for name in ("sphere", "inside"):
            with _reference(name, res) as s:
                volume, _ = lab.volume_inputs(s)
                for mode in ("zpass", "zfail"):
                    rows.append(dict(scene=name, camera="inside" if name == "inside" else "outside", mode=mode,
                                     **_score(s, lab.volume_mask(s, volume, mode))))
        tables["zpass_zfail"] = rows
        chart_paths.append(_bar(os.path.join(output_dir, "zpass_zfail.png"), rows, ("camera", "mode"),
                                "Shadow volumes: z-pass vs z-fail"))
    for name, t in tables.items():
        charts.write_csv(os.path.join(output_dir, f"{name}.csv"), t)
    write_json(os.path.join(output_dir, "shadow_sweeps.json"), {"tables": tables, "figures": figures})
    tables["shadow_methods"], pareto = methods_pareto(output_dir, quick)
    chart_paths.append(pareto)
    return BenchResult(tables, chart_paths, figures)


def methods_pareto(output_dir, quick):
    """All shadow methods on the sphere scene: error against seconds.

    The GL context is made first by a 32² Workbench comparison (0.15 s), outside the timings. EEVEE needs no
    warm-up of its own: each EEVEE render costs the same, first or not (llvmpipe, 2 cores: 4.75 s CPU for the
    96² EEVEE method after this warm-up, 4.79 s after a whole EEVEE comparison, which itself took 4.7 s)."""
    res = 96 if quick else 256
    with tempfile.TemporaryDirectory(prefix="il_warmup_") as tmp:
        lab.compare_builtin("sphere", "sun", tmp, ShadowOptions(methods=["raytraced", "workbench"], resolution=32))
    rep = lab.compare_builtin("sphere", "sun", os.path.join(output_dir, "methods"), ShadowOptions(
        methods=list(lab.METHODS), resolution=res, shadowmap_size=1024 if quick else 2048))
    rows = [{"method": m, "error": e["error"], "false_shadow": e["false_shadow"], "false_light": e["false_light"],
             "seconds": e["seconds"]} for m, e in rep["methods"].items()]
    points = {r["method"]: (max(r["seconds"], 1e-4), max(r["error"], 1e-5)) for r in rows if r["method"] != "raytraced"}
    chart = charts.scatter_chart(os.path.join(output_dir, "shadow_pareto.png"), points,
                                 f"Shadow methods, sphere scene {res}² (error floor 1e-5)", "seconds",
                                 "misclassified fraction of receiver pixels", logx=True, logy=True)
    return rows, chart


def speed(resolution=512, map_size=2048, repeats=3):
    """Performance figures beside the issue's targets: [(what, seconds or None, target seconds or None)].

    1. numpy shadow-map lookup with 3x3 PCF: a ``resolution``² frame against a ``map_size``² map (target 0.5 s);
    2. the ``map_size``² depth map of the 10k-triangle sphere scene, Cycles' Depth pass against the numpy
       rasteriser (target 0.3 s), best of ``repeats``: their ratio, the texels whose depths differ, the
       receiver pixels whose masks differ (default bias, and bias 0 where the two depths straddle d - b),
       and the limits: the triangles' extraction, one z-buffer minimum over the fragments;
    3. shadow volumes (silhouette, extrusion, z-fail stencil) for a 10k-triangle occluder (target 5 s);
    4. per-method seconds of one comparison on the sphere scene at 256x256.
    """
    rows = []
    res = resolution
    shadow_map.check_cost(res, res, map_size, 1, "cycles")      # both sources are rendered
    scene = shadow_scenes.build("sphere", "sun", (res, res), segments=102, rings=50)   # 10 000 triangles
    try:
        with ShadowFrame(scene, scene["il_shadow_light"], res) as s:
            s.render_reference()
            r = s.receiver
            pts, nrm, tl = s.position[r], s.normal[r], s.to_light[r]
            cycles_s, cycles_maps = _best(lambda: s.depth_maps(map_size, "cycles"), repeats)
            stats = {}
            s.depth_maps(map_size, "raster", stats)
            raster_s, raster_maps = _best(lambda: s.depth_maps(map_size, "raster"), max(repeats, 5))
            best = min(_timed(lambda: shadow_map.lit_fraction(raster_maps, pts, nrm, tl, 0.01, 2.0, 3))
                       for _ in range(3))
            rows.append((f"shadow-map lookup, 3x3 PCF, {res}^2 frame ({r.sum()} receiver px), {map_size}^2 map",
                         best, 0.5))
            rows.append((f"shadow-map depth {map_size}^2, Cycles Depth pass (best of {repeats})", cycles_s, None))
            rows.append((f"shadow-map depth {map_size}^2, numpy raster of {stats['triangles']} triangles "
                         f"(best of {max(repeats, 5)})", raster_s, 0.3))
            rows.append((f"  Cycles / raster = {cycles_s / raster_s:.0f}x", None, None))
            rows += _agreement(s, cycles_maps, raster_maps)
            tri_s = min(_timed(s.gather_surfaces) for _ in range(3))
            rows.append((f"  of which the casters' triangles from the depsgraph", tri_s, None))
            n, f = map_size * map_size, stats["fragments"]
            rows.append((f"  limit: one z-buffer minimum over the {f} fragments ({f / n:.2f} per texel, "
                         f"{stats['spans']} spans), np.minimum.at", _scatter_floor(n, f), None))
            t = time.perf_counter()
            volume, info = lab.volume_inputs(s)
            lab.volume_mask(s, volume, "zfail")
            rows.append((f"shadow volumes z-fail, {info['occluder_triangles']}-triangle occluder, {res}^2 frame",
                         time.perf_counter() - t, 5.0))
    finally:
        sc.remove_scene(scene)
    with tempfile.TemporaryDirectory() as tmp:
        rep = lab.compare_builtin("sphere", "sun", tmp, ShadowOptions(
            methods="raytraced,planar,shadowmap,volume_zpass,volume_zfail", resolution=256, shadowmap_size=2048))
    for m, e in rep["methods"].items():
        rows.append((f"comparison 256^2, {m} (error {e['error']:.4f})", e["seconds"], None))
    return rows


def _agreement(s, cycles_maps, raster_maps):
    """Rows: how far the two depth maps are apart per texel and on how many receiver pixels the masks differ."""
    rows = []
    for a, b in zip(cycles_maps, raster_maps):
        sky_a, sky_b = a.depth >= 0.5 * SKY_DEPTH, b.depth >= 0.5 * SKY_DEPTH
        both = ~sky_a & ~sky_b
        diff = np.abs(a.depth - b.depth)[both]
        rows.append((f"  depth |Cycles - raster|: max {diff.max():.2g} m, {int((diff > 1e-4).sum())} texels > 0.1 mm, "
                     f"{int((sky_a != sky_b).sum())} texels sky in one only, of {a.depth.size}", None, None))
    base = lab.check_params({})
    for name, p in (("default bias 0.01 m, slope 2", base), ("bias 0, slope 0 (acne)", dict(base, bias=0.0, slope_bias=0.0))):
        ma, _ = lab.shadowmap_mask(s, cycles_maps, p)
        mb, _ = lab.shadowmap_mask(s, raster_maps, p)
        differ = (ma != mb) & s.receiver
        gap = ""
        if differ.any() and len(raster_maps) == 1:     # one nearest texel each: d - b lies between the two depths
            m = raster_maps[0]
            x, y, d = m.project(s.position[differ])
            b = shadow_map.bias(d, s.normal[differ], s.to_light[differ], m.proj, m.size, p["bias"], p["slope_bias"])
            tx = np.clip(np.rint(x).astype(int), 0, m.size - 1)
            ty = np.clip(np.rint(y).astype(int), 0, m.size - 1)
            gap = (f", |d - b - z| there <= {np.abs(d - b - m.depth[ty, tx]).max():.1g} m (d - b between the two "
                   "depths)")
        rows.append((f"  masks differ, {name}: {int(differ.sum())} of {int(s.receiver.sum())} "
                     f"receiver px (shadowed {int((~ma)[s.receiver].sum())}){gap}", None, None))
    return rows


def _scatter_floor(texels, fragments):
    """Seconds of np.minimum.at over ``fragments`` sequential indices into ``texels`` float64 (best of 3)."""
    idx = np.arange(fragments, dtype=np.int64) % texels
    val = np.random.default_rng(0).random(fragments)
    return min(_timed(lambda: np.minimum.at(np.full(texels, np.inf), idx, val)) for _ in range(3))


def _best(fn, repeats):
    """(fastest seconds, result) of ``repeats`` calls of ``fn`` returning (result, seconds)."""
    best, out = np.inf, None
    for _ in range(repeats):
        out, sec = fn()
        best = min(best, sec)
    return best, out


def _timed(fn):
    t = time.perf_counter()
    fn()
    return time.perf_counter() - t


def _bar(path, rows, key, title):
    """Grouped bars of false shadow / false light per row."""
    labels = [" ".join(str(r[k]) for k in key) if isinstance(key, tuple) else str(r[key]) for r in rows]
    return charts.bar_chart(path, labels, {"false shadow": [r["false_shadow"] for r in rows],
                                           "false light": [r["false_light"] for r in rows]},
                            title, "case", "fraction of receiver pixels")
