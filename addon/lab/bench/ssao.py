"""SSAO sweeps: error against seconds (Pareto front), samples, radius, and the failure cases side by side.

``run(output_dir, quick)`` is used by ``scripts/ssao.py --sweeps`` and by the
project-wide bench; ``speed(...)`` times the methods on one frame (scripts/bench_ssao.py).
Errors are RMSE against Cycles' AO pass over geometry pixels (core.ssao.metrics.error_metrics).
"""
import os
import time
import tracemalloc

import numpy as np

from ...core import charts
from ...core.ssao import figures as ssao_figures
from ...core.ssao import gbuffer as gbuffer_mod
from ...core.ssao import methods as ssao
from ...core.ssao import limits as ssao_limits
from ...core.ssao import metrics
from ...core.errors import InputError
from ...core.io.files import write_json
from ...blender.progress import Progress
from .. import ssao as lab
from ...blender import scene as sc
from ..ssao import scenes as ssao_scenes
from ..options import SSAOOptions
from .result import BenchResult

KEY = "ssao"
#: The radius of every sweep = the reference's AO distance: the built-in scenes' own (SSAOOptions).
RADIUS = SSAOOptions.BUILTIN_RADIUS
TITLE = "Screen-space AO against ray-traced AO"

#: Per failure scene: the methods shown and the one whose failure the scene is about.
FAILURES = (("plane", "crytek", "flat plane grey under the sphere kernel"),
            ("edge", "gtao", "occluders cut by the screen edge are lost"),
            ("discontinuity", "crytek", "halos on the wall behind a floating ball"),
            ("thin", "gtao", "thin occluders treated as infinitely thick"))


def _settings(quick):
    if quick:
        return dict(resolution=64, reference_samples=256, counts=(4, 16, 64), radii=(0.25, 0.5, 1.0, 2.0),
                    blender=("workbench",))
    return dict(resolution=128, reference_samples=1024, counts=(2, 4, 8, 16, 32, 64, 128),
                radii=(0.125, 0.25, 0.5, 1.0, 2.0, 4.0), blender=("workbench", "eevee"))


def run(output_dir, quick=False, radius=RADIUS, samples=SSAOOptions.samples):
    """Run every sweep; write charts (PNG) and tables (CSV) to ``output_dir``.

    Returns {"tables": {name: [row dicts]}, "charts": [png paths], "figures": {...}}.
    """
    cfg = _settings(quick)
    os.makedirs(output_dir, exist_ok=True)
    cache = os.path.join(output_dir, "cache")
    tables, chart_paths, figures = {}, [], {}
    steps = 3 + len(FAILURES)
    with Progress("ssao sweeps", steps) as progress:
        progress.step("corner scene: G-buffer and reference")
        scene = ssao_scenes.build_scene("corner", cfg["resolution"], radius)
        try:
            gb, _, ref = lab.frame(scene, radius, cfg["reference_samples"], cfg["resolution"], cache)
            mask = gb.mask

            progress.step("error against seconds, samples")
            rows = []
            for m in ssao.METHODS:
                for n in cfg["counts"]:
                    for blur in (False, True) if n == samples else (False,):
                        k, sec, _ = ssao.run_method(m, gb, radius, n, blur=blur)
                        e = metrics.error_metrics(k, ref["k"], mask)
                        rows.append({"method": m + (" + blur" if blur else ""), "samples": n, "rmse": e["rmse"],
                                     "bias": e["bias"], "seconds": sec})
            for m in cfg["blender"]:
                k, sec, _ = lab.blender_method(scene, m, radius, samples, cfg["resolution"])
                e = metrics.error_metrics(k, ref["k"], mask)
                rows.append({"method": m, "samples": samples, "rmse": e["rmse"], "bias": e["bias"], "seconds": sec})
            tables["ssao_error_vs_seconds"] = rows
            points = {f"{r['method']} {r['samples']}": (r["seconds"], r["rmse"]) for r in rows}
            chart_paths.append(charts.scatter_chart(
                os.path.join(output_dir, "ssao_pareto.png"), points,
                f"SSAO on the corner scene, {gb.width}x{gb.height}: error against time",
                "seconds per frame (log)", "RMSE of k_A against Cycles AO", logx=True))
            front = charts.pareto_front([p[0] for p in points.values()], [p[1] for p in points.values()])
            figures["pareto_front"] = [list(points)[i] for i in front]
            series = {m: ([r["samples"] for r in rows if r["method"] == m],
                          [r["rmse"] for r in rows if r["method"] == m]) for m in ssao.METHODS}
            chart_paths.append(charts.line_chart(
                os.path.join(output_dir, "ssao_samples.png"), series,
                "SSAO error against samples per pixel (corner scene)", "samples per pixel (log)",
                "RMSE of k_A (log)", logx=True, logy=True))

            progress.step("radius (reference AO distance fixed)")
            rrows = []
            for m in ssao.METHODS:
                for r in cfg["radii"]:
                    k, sec, _ = ssao.run_method(m, gb, r * radius, samples)
                    e = metrics.error_metrics(k, ref["k"], mask)
                    rrows.append({"method": m, "radius_over_ao_distance": r, "rmse": e["rmse"], "bias": e["bias"],
                                  "seconds": sec})
            tables["ssao_radius"] = rrows
            chart_paths.append(charts.line_chart(
                os.path.join(output_dir, "ssao_radius.png"),
                {m: ([r["radius_over_ao_distance"] for r in rrows if r["method"] == m],
                     [r["rmse"] for r in rrows if r["method"] == m]) for m in ssao.METHODS},
                f"SSAO radius against the reference's AO distance ({radius} m), {samples} samples",
                "SSAO radius / AO distance (log)", "RMSE of k_A", logx=True))
            figures["reference"] = {"samples": ref["samples"], "seconds": ref["seconds"],
                                    "noise_rms": metrics.reference_noise(ref["k"], ref["samples"], mask)}
        finally:
            sc.remove_scene(scene)

        frows, ao_rows, err_rows = [], [], []
        for name, focus, what in FAILURES:
            progress.step(f"failure: {name} ({what})")
            scene = ssao_scenes.build_scene(name, cfg["resolution"], radius)
            try:
                gb, world, ref = lab.frame(scene, radius, cfg["reference_samples"], cfg["resolution"], cache)
            finally:
                sc.remove_scene(scene)
            label, region_of, control_of = ssao_scenes.REGIONS[name]
            wpos = np.nan_to_num(world, nan=1e9)
            region = region_of(wpos, gb, radius) & gb.mask
            control = control_of(wpos, gb, radius) & gb.mask if control_of else None
            variants = [(m, m, {}) for m in ssao.METHODS]
            if name == "discontinuity":
                variants.append(("crytek + range check", "crytek", {"range_check": True}))
            ao_cols = [("reference (Cycles)", ssao_figures.ao_grey(ref["k"], gb.mask))]
            err_cols = []
            for label_m, m, params in variants:
                k, sec, _ = ssao.run_method(m, gb, radius, samples, **params)
                e = metrics.error_metrics(k, ref["k"], gb.mask)
                er = metrics.error_metrics(k, ref["k"], region)
                ec = metrics.error_metrics(k, ref["k"], control if control is not None else np.zeros_like(region))
                frows.append({"scene": name, "failure": what, "region": label, "method": label_m,
                              "rmse": e["rmse"], "bias": e["bias"], "region_pixels": er["pixels"],
                              "region_rmse": er["rmse"], "region_bias": er["bias"],
                              "region_reference_mean": float(np.mean(ref["k"][region])) if region.any() else float("nan"),
                              "region_mean": er["mean"], "control_pixels": ec["pixels"],
                              "control_rmse": ec["rmse"], "control_bias": ec["bias"]})
                ao_cols.append((label_m, ssao_figures.ao_grey(k, gb.mask)))
                err_cols.append((f"{label_m} error", ssao_figures.error_rgb(k, ref["k"], gb.mask)))
            ao_rows.append((name, ao_cols))
            err_rows.append((name, err_cols))
            figures.setdefault("failures", {})[name] = {
                r["method"]: round(r["region_bias"], 4) for r in frows if r["scene"] == name}
        tables["ssao_failures"] = frows
        chart_paths.append(ssao_figures.failure_grid(
            os.path.join(output_dir, "ssao_failures.png"), ao_rows,
            f"k_A side by side (white = open), radius = AO distance = {radius} m, {samples} samples"))
        chart_paths.append(ssao_figures.failure_grid(
            os.path.join(output_dir, "ssao_failures_error.png"), err_rows,
            "signed error (blue = too dark, red = too bright, saturated at 0.5)"))
    for name, rows in tables.items():
        charts.write_csv(os.path.join(output_dir, f"{name}.csv"), rows)
    write_json(os.path.join(output_dir, "ssao_sweeps.json"), {"figures": figures, "charts": chart_paths})
    return BenchResult(tables, chart_paths, figures)


def load_baseline(checkout):
    """The numpy SSAO methods of another checkout of this project (e.g. the main branch's worktree), to
    time beside this one in the same run: ``checkout``/addon imported as package ``il_baseline``
    (core modules only, no bpy; no bytecode written there). Returns (methods module, gbuffer module);
    InputError if it has none."""
    import importlib
    import importlib.util
    import sys
    root = os.path.join(os.path.abspath(checkout), "addon")
    if not os.path.isfile(os.path.join(root, "core", "ssao", "methods.py")):
        raise InputError(f"--baseline {checkout}: no addon/core/ssao/methods.py there")
    name = "il_baseline"
    write_bytecode, sys.dont_write_bytecode = sys.dont_write_bytecode, True
    try:
        if name not in sys.modules:
            spec = importlib.util.spec_from_file_location(name, os.path.join(root, "__init__.py"),
                                                          submodule_search_locations=[root])
            module = importlib.util.module_from_spec(spec)
            sys.modules[name] = module
            spec.loader.exec_module(module)
        return (importlib.import_module(name + ".core.ssao.methods"),
                importlib.import_module(name + ".core.ssao.gbuffer"))
    finally:
        sys.dont_write_bytecode = write_bytecode


def _timed(func, *args, **kwargs):
    """(result, wall seconds, CPU seconds of this process) of one call."""
    t0, c0 = time.perf_counter(), time.process_time()
    result = func(*args, **kwargs)
    return result, time.perf_counter() - t0, time.process_time() - c0


def _peak_bytes(func, *args, **kwargs):
    """Peak bytes allocated (numpy arrays included, tracemalloc) during one call, above what was held before."""
    tracemalloc.start()
    try:
        func(*args, **kwargs)
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


def machine_rates(elements=1 << 22, chunk=ssao.CHUNK, repeats=5):
    """What numpy does per element on this machine, best of ``repeats`` (ns): one float32 pass c = a·b
    over chunk-sized arrays (12 bytes, cache-resident as the methods' chunks are) and over arrays too
    large for any cache (so GB/s of memory), a float32 uniform draw, and a gather (np.take) from a
    512² float32 table at positions scattered ±64 px around consecutive pixels."""
    rng = np.random.default_rng(0)

    def best(func, n):
        t = min(_timed(func)[1] for _ in range(repeats))
        return t / n * 1e9

    a, b = rng.random(chunk, dtype=np.float32), rng.random(chunk, dtype=np.float32)
    c = np.empty_like(a)
    rounds = max(1, elements // chunk)

    def cached():
        for _ in range(rounds):
            np.multiply(a, b, out=c)
    big_a, big_b = rng.random(elements, dtype=np.float32), rng.random(elements, dtype=np.float32)
    big_c = np.empty_like(big_a)
    table = rng.random(512 * 512, dtype=np.float32)
    base = np.arange(chunk) * (512 * 512 // chunk)
    index = np.clip(base + rng.integers(-64, 65, chunk) * 512 + rng.integers(-64, 65, chunk), 0, 512 * 512 - 1)
    index = index.astype(np.int32)

    def gathers():
        for _ in range(rounds):
            np.take(table, index, out=c)
    pass_ns = best(cached, rounds * chunk)
    stream_ns = best(lambda: np.multiply(big_a, big_b, out=big_c), elements)
    return {"pass_ns": pass_ns, "stream_ns": stream_ns, "stream_gb_per_s": 12.0 / stream_ns,
            "cache_gb_per_s": 12.0 / pass_ns,
            "random_ns": best(lambda: rng.random(elements, dtype=np.float32), elements),
            "gather_ns": best(gathers, rounds * chunk)}


class _Counted(np.ndarray):
    """An ndarray whose ufunc passes, and those of every array computed from it, are tallied in
    :attr:`tally`: passes (elements written) and bytes read and written by full-size operands."""
    tally = None

    def __array_ufunc__(self, ufunc, method, *inputs, **kwargs):
        plain = [x.view(np.ndarray) if isinstance(x, _Counted) else x for x in inputs]
        if "out" in kwargs:
            kwargs["out"] = tuple(o.view(np.ndarray) if isinstance(o, _Counted) else o for o in kwargs["out"])
        result = getattr(ufunc, method)(*plain, **kwargs)
        outs = result if isinstance(result, tuple) else (result,)
        n = max(np.size(o) for o in outs)
        if _Counted.tally is not None:
            _Counted.tally["elements"] += n
            _Counted.tally["bytes"] += (sum(x.nbytes for x in plain if isinstance(x, np.ndarray) and x.size == n)
                                        + sum(np.asarray(o).nbytes for o in outs))
        wrap = (lambda o: o.view(_Counted) if isinstance(o, np.ndarray) else o)
        return tuple(wrap(o) for o in outs) if isinstance(result, tuple) else wrap(result)


def count_passes(gb, method, samples):
    """Numpy passes and bytes touched per pixel-sample of one method on ``gb``: every ufunc call's
    elements and full-size operands' bytes (the G-buffer and the random numbers tracked through an
    ndarray subclass), plus the four gathers of each lookup (index, value, result: 12 bytes each).
    Copies, np.where and reductions are not counted. Returns {"passes", "bytes"} per pixel-sample."""
    tracked = ssao.__dict__["_sample_major"]
    counted = gbuffer_mod.GBuffer(*(a.view(_Counted) for a in (gb.position, gb.normal, gb.depth)),
                                  gb.mask, gb.proj)
    _Counted.tally = {"elements": 0, "bytes": 0}
    ssao._sample_major = lambda u: tracked(u).view(_Counted)
    try:
        ssao.run_method(method, counted, RADIUS, samples)
        tally = dict(_Counted.tally)
    finally:
        ssao._sample_major = tracked
        _Counted.tally = None
    n = int(gb.mask.sum()) * samples
    return {"passes": tally["elements"] / n, "bytes": tally["bytes"] / n + 12 * GATHERS_PER_SAMPLE}


#: Per pixel-sample of each numpy method: uniform draws and depth-buffer gathers (4 per bilinear lookup).
#: The horizon methods draw 2 numbers per pixel, not per sample.
DRAWS_PER_SAMPLE = {"crytek": 3, "hemisphere": 3, "hbao": 0, "gtao": 0}
GATHERS_PER_SAMPLE = 4


def speed(output_dir, resolution=512, samples=16, repeats=3, reference_samples=256, eevee=True, baseline=None):
    """Every numpy method (with and without blur) and Blender's AO on the corner scene, best of ``repeats``.

    With ``baseline`` (another checkout, :func:`load_baseline`) its numpy methods run on the same
    G-buffer, interleaved with this checkout's, so both sets of figures share the machine's load.
    Returns {"rows": [{"method", "seconds", "cpu_seconds", "rmse", "ns_per_pixel_sample", "peak_bytes",
    "load", "passes" and "bytes" per pixel-sample (:func:`count_passes`, without blur), and with a baseline "baseline_seconds", "baseline_cpu_seconds", "baseline_rmse",
    "baseline_peak_bytes", "max_difference"}], "gbuffer", "reference", "machine"}; the reference is
    cached in ``output_dir``/cache.
    """
    base_methods, base_gbuffer = load_baseline(baseline) if baseline else (None, None)
    ssao_limits.check_cost(resolution, resolution, samples, reference_samples,
                           len(ssao.METHODS) * 2 * (repeats + 1) * (2 if baseline else 1))
    scene = ssao_scenes.build_scene("corner", resolution, RADIUS)
    cache = os.path.abspath(os.path.join(output_dir, "cache"))
    try:
        gb, _, ref = lab.frame(scene, RADIUS, reference_samples, resolution, cache)
        base_gb = (base_gbuffer.GBuffer(gb.position, gb.normal, gb.depth, gb.mask, gb.proj)
                   if baseline else None)
        pixel_samples = int(gb.mask.sum()) * samples
        machine = machine_rates()
        rows = []
        for m in ssao.METHODS:
            for blur in (False, True):
                row = {"method": m + (" + blur" if blur else "")}
                runs = [("", ssao, gb)] + ([("baseline_", base_methods, base_gb)] if baseline else [])
                best = {prefix: (float("inf"), float("inf")) for prefix, _, _ in runs}
                images = {}
                for _ in range(repeats):
                    for prefix, module, frame_gb in runs:
                        (k, _, _), wall, cpu = _timed(module.run_method, m, frame_gb, RADIUS, samples, blur=blur)
                        best[prefix] = (min(best[prefix][0], wall), min(best[prefix][1], cpu))
                        images[prefix] = k
                for prefix, module, frame_gb in runs:
                    row[prefix + "seconds"], row[prefix + "cpu_seconds"] = best[prefix]
                    row[prefix + "rmse"] = metrics.error_metrics(images[prefix], ref["k"], gb.mask)["rmse"]
                    row[prefix + "peak_bytes"] = _peak_bytes(module.run_method, m, frame_gb, RADIUS, samples,
                                                             blur=blur)
                if not blur:
                    row.update(count_passes(gb, m, samples))
                row["ns_per_pixel_sample"] = row["seconds"] / pixel_samples * 1e9
                row["cpu_ns_per_pixel_sample"] = row["cpu_seconds"] / pixel_samples * 1e9
                if baseline:
                    row["max_difference"] = float(np.max(np.abs(images[""].astype(np.float64) - images["baseline_"])))
                row["load"] = os.getloadavg()[0]
                rows.append(row)
        for m in ("workbench",) + (("eevee",) if eevee else ()):
            if m == "eevee":
                lab.blender_method(scene, "eevee", RADIUS, 1, 32)           # compile shaders first
            for spp in sorted({1, samples}):
                best, k = float("inf"), None
                for _ in range(repeats):
                    k, sec, _ = lab.blender_method(scene, m, RADIUS, spp, resolution)
                    best = min(best, sec)
                rows.append({"method": f"{m} ({spp} spp)", "seconds": best,
                             "rmse": metrics.error_metrics(k, ref["k"], gb.mask)["rmse"],
                             "load": os.getloadavg()[0]})
    finally:
        sc.remove_scene(scene)
    return {"rows": rows, "gbuffer": gb, "reference": ref, "machine": machine}
