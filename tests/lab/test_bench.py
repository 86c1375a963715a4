"""The speed-against-accuracy report: bench.py --quick writes every chart and table, all numbers finite."""
import csv
import math
import os

import numpy as np
import pytest

from addon.lab import shadows
from addon.lab import report
from addon.lab.bench import lightmaps

CHARTS = {
    "lightmaps": ["bake_error_vs_seconds.png", "bake_irradiance_error_vs_seconds.png"],
    "ssao": ["ssao_pareto.png", "ssao_samples.png", "ssao_radius.png", "ssao_failures.png"],
    "shadows": ["shadow_pareto.png", "shadowmap_resolution_error.png", "shadowmap_bias.png", "shadowmap_pcf.png",
                "volume_cost.png", "planar_receivers.png", "zpass_zfail.png"],
    "shading": ["oren_nayar_vs_diffuse.png", "cook_torrance_vs_glossy.png"],
    "envmap": ["envmap_sh9_accuracy.png", "radiosity_convergence.png"],
    "reflections": ["reflections_error_seconds.png", "reflections_map_types.png"],
}
TABLES = {
    "lightmaps": ["bake_time_to_error", "bake_irradiance_time_to_error", "bake_overhead"],
    "ssao": ["ssao_error_vs_seconds", "ssao_failures"],
    "shadows": ["shadow_methods", "shadowmap_resolution", "shadowmap_bias"],
    "shading": ["shading_node_vs_twin", "shading_oren_nayar_vs_diffuse", "shading_cook_torrance_vs_glossy"],
    "envmap": ["radiosity_solvers"],
    "reflections": ["reflections_methods", "reflections_distance", "reflections_map_types"],
}


def test_monte_carlo_slope_recovers_known_exponents():
    n = np.array([4, 16, 64, 256])
    assert lightmaps.monte_carlo_slope(n, 0.3 * n ** -0.5) == pytest.approx(-0.5, abs=1e-12)
    assert lightmaps.monte_carlo_slope(n, 2.0 / n) == pytest.approx(-1.0, abs=1e-12)
    assert math.isnan(lightmaps.monte_carlo_slope([8], [0.1]))


def test_shading_edges_are_finite_and_bounded():
    rows = report.shading_edges()
    assert len(rows) >= 18
    assert all(r["finite"] for r in rows)
    back = [r for r in rows if r["input"].startswith("back-facing")]
    assert back and all(r["max_output"] == 0.0 for r in back)


def _floats(path):
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    assert rows, path
    values = []
    for row in rows:
        for v in row.values():
            try:
                values.append(float(v))
            except (TypeError, ValueError):
                pass
    return rows, values


def test_quick_bench_writes_every_chart_and_table(script, tmp_path):
    proc = script("bench.py", "--quick", "--out", tmp_path, timeout=900)
    assert proc.returncode == 0, proc.stderr[-3000:]
    report = (tmp_path / "report.md").read_text()
    for area, names in CHARTS.items():
        for name in names:
            assert (tmp_path / area / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n", name
            assert f"]({area}/{name})" in report, name
    for area, names in TABLES.items():
        for name in names:
            rows, values = _floats(tmp_path / area / f"{name}.csv")
            assert values and all(math.isfinite(v) for v in values if v == v), name
            assert f"{area}/{name}.csv" in report
    stability, _ = _floats(tmp_path / "stability.csv")
    methods = {r["method"] for r in stability}
    assert {"shadow map", "shadow volume z-pass", "planar projection", "shading models", "SSAO"} <= methods
    failures = " ".join(r["fails at"] for r in stability)
    for word in ("acne", "peter-panning", "screen edge", "thin", "grazing", "roughness 0"):
        assert word in failures, word
    # The timings that let a user choose: every shadow method has finite seconds and error.
    shadow_rows, _ = _floats(tmp_path / "shadows" / "shadow_methods.csv")
    assert {r["method"] for r in shadow_rows} == set(shadows.METHODS)
    assert all(float(r["seconds"]) > 0 and 0 <= float(r["error"]) <= 1 for r in shadow_rows)
    assert os.path.exists(tmp_path / "report.json")
    # The bakes converge on the closed forms: per-texel noise is at most 0.5/sqrt(N) (REFERENCE.md §3),
    # plus 0.01 for the texel footprint and the polygonal sphere of the analytic k_A.
    for table, column in (("bake_time_to_error", "rms"), ("bake_irradiance_time_to_error", "relative_rms")):
        plain, _ = _floats(tmp_path / "lightmaps" / f"{table}.csv")
        plain = [r for r in plain if r["method"] == "plain"]
        errors = [float(r[column]) for r in plain]
        assert errors == sorted(errors, reverse=True), table
        for r in plain:
            assert float(r[column]) <= 0.5 / math.sqrt(int(r["samples"])) + 0.01, (table, r)


def test_the_level_benchmarks_evaluation_figure_evaluates_the_modifiers_and_leaves_the_uv_layers(tmp_path):
    """lab.bench.level.evaluation_seconds: after it, every mesh has the UV layers it had, and the evaluated meshes
    are the modifiers' result (a Subdivision's vertices, not the base mesh's)."""
    import bpy
    from addon.blender.scene import remove_scene
    from addon.lab.bench import level
    scene = bpy.data.scenes.new("IL evaluation test")
    try:
        me = bpy.data.meshes.new("IL evaluation cube")
        me.from_pydata([(x, y, z) for x in (0, 1) for y in (0, 1) for z in (0, 1)], [],
                       [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)])
        me.uv_layers.new(name="UVMap")
        obj = bpy.data.objects.new("IL evaluation cube", me)
        scene.collection.objects.link(obj)
        obj.modifiers.new("Subdivision", "SUBSURF").levels = 2
        seconds = level.evaluation_seconds(scene, [obj])
        assert math.isfinite(seconds) and seconds > 0
        assert [l.name for l in me.uv_layers] == ["UVMap"]
        evaluated = obj.evaluated_get(scene.view_layers[0].depsgraph).data
        assert len(evaluated.vertices) == 98 and [l.name for l in evaluated.uv_layers] == ["UVMap"]
    finally:
        remove_scene(scene)
        if "IL evaluation cube" in bpy.data.meshes:
            bpy.data.meshes.remove(bpy.data.meshes["IL evaluation cube"])


def test_the_level_benchmarks_rerun_runs_in_a_new_process_and_puts_the_layers_back(tmp_path):
    """lab.bench.level._changed_light_rerun: another process opens the level saved and rebakes the irradiance the
    brighter light changed (the AO maps stay), the parent's light-map layers come back as they were, and the saved
    level and job file are gone."""
    import bpy
    from addon.bake import uv as uvmod
    from addon.bake.options import BakeOptions
    from addon.blender.scene import remove_scene
    from addon.lab.bench import level
    scene = bpy.data.scenes.new("IL rerun test")
    try:
        objects = []
        for name, verts in (("IL rerun floor", [(-2, -2, 0), (2, -2, 0), (2, 2, 0), (-2, 2, 0)]),
                            ("IL rerun wall", [(-2, 2, 0), (2, 2, 0), (2, 2, 2), (-2, 2, 2)])):
            me = bpy.data.meshes.new(name)
            me.from_pydata(verts, [], [(0, 1, 2, 3)])
            obj = bpy.data.objects.new(name, me)
            scene.collection.objects.link(obj)
            objects.append(obj)
        sun = bpy.data.objects.new("IL rerun sun", bpy.data.lights.new("IL rerun sun", "SUN"))
        scene.collection.objects.link(sun)
        out = tmp_path / "per_object"
        options = BakeOptions(resolution=16, samples=1, overwrite=True)
        level._timed(scene, objects, str(out), options)
        layers = {o.name: np.array([d.uv[:] for d in o.data.uv_layers[uvmod.LIGHTMAP].data]) for o in objects}
        row = level._changed_light_rerun(scene, objects, str(out), options)
        assert row["maps_baked"] == len(objects) and row["pipeline_seconds"] >= row["pipeline_cycles_seconds"] > 0
        for o in objects:
            assert np.array_equal(np.array([d.uv[:] for d in o.data.uv_layers[uvmod.LIGHTMAP].data]), layers[o.name])
        assert sorted(p.name for p in tmp_path.iterdir()) == ["per_object"]
    finally:
        remove_scene(scene)


def test_the_level_benchmarks_rerun_row_is_the_median_runs_with_the_range():
    """lab.bench.level.median_rerun: the row of the run with the median ratio (its seconds with it), the count and the
    ratio's range; with an even count, the lower middle run."""
    from addon.lab.bench import level
    rows = [{"pipeline_seconds": s, "outside_over_cycles": r} for s, r in ((2.4, 0.2), (2.1, 0.1), (2.2, 0.15))]
    assert level.median_rerun(rows) == {"pipeline_seconds": 2.2, "outside_over_cycles": 0.15, "reruns": 3,
                                        "outside_over_cycles_range": "0.100-0.200"}
    assert level.median_rerun(rows[:2])["pipeline_seconds"] == 2.1
    assert level.median_rerun(rows[:1])["outside_over_cycles_range"] == "0.200-0.200"
