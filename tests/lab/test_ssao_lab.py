"""SSAO lab under bpy: Cycles' AO reference against closed forms, methods against the reference, UI."""
import json

import bpy
import numpy as np
import pytest

from addon.blender import compat
from addon.core.ssao import limits
from addon.core.io import exr
from addon.core.errors import ILError, InputError
from addon.lab import ssao as lab
from addon.lab.options import SSAOOptions
from addon.lab.ssao import renders as ssao_renders
from addon.lab.ssao import scenes as ssao_scenes
from addon.blender.scene import remove_scene


@pytest.mark.both_versions
def test_reference_matches_closed_forms_on_plane_and_corner(tmp_path):
    n = 256
    scene = ssao_scenes.build_scene("plane", 48, 1.0)
    gb, world, ref = lab.frame(scene, 1.0, n, 48)
    assert 0 < (~gb.mask).sum() and gb.mask.sum() > 1000          # sky is in the frame, and excluded
    np.testing.assert_array_equal(ref["k"][gb.mask], 1.0)        # open plane: k_A = 1 exactly

    scene = ssao_scenes.build_scene("corner", 64, 1.0)
    gb, world, ref = lab.frame(scene, 1.0, n, 64, cache_dir=str(tmp_path))
    # REFERENCE.md §3 with AO distance R (core.analytic.corner_k_a, checked by Monte Carlo in tests/core/ssao)
    closed = ssao_scenes.corner_closed_form(np.nan_to_num(world, nan=1e9), 1.0)
    ok = np.isfinite(closed) & gb.mask
    occluded = ok & (closed < 0.97)
    assert occluded.sum() > 200 and ok.sum() > 1000
    sigma = np.sqrt(closed[ok] * (1 - closed[ok]) / n)
    diff = ref["k"][ok] - closed[ok]
    # per pixel within 5 standard errors (+ the pixel footprint), and no mean shift beyond 4 SE of the mean
    assert np.all(np.abs(diff) <= 5 * sigma + 0.02)
    assert abs(diff.mean()) < 4 * np.sqrt(np.sum(sigma ** 2)) / ok.sum() + 2e-3
    # the wall through a floor point at its foot: k_A -> 1/2; the corner itself: 1/4
    foot = ok & (closed < 0.56)
    assert foot.any() and np.all(np.abs(ref["k"][foot] - closed[foot]) < 5 * 0.5 / np.sqrt(n) + 0.02)
    # cached: the second call reads the same array back
    again = lab.render_reference(scene, 1.0, n, str(tmp_path))
    assert again["cached"] and np.array_equal(again["k"], ref["k"])


def test_reference_without_closures_is_the_same_bit_for_bit_and_leaves_no_override(monkeypatch):
    # scenes without materials render their reference with a no-closure override: same AO and alpha as
    # Cycles' default surface; a scene with a material renders as it is
    import contextlib
    from addon.blender import materials
    scene = ssao_scenes.build_scene("discontinuity", 48, 1.0)
    try:
        def reference():
            with lab.preserved(scene):
                lab.set_resolution(scene, 48)
                return lab.render_reference(scene, 1.0, 64)
        fast = reference()
        assert scene.view_layers[0].material_override is None
        assert not [m for m in bpy.data.materials if m.name.startswith("IL SSAO geometry only")]
        with monkeypatch.context() as m:
            m.setattr(ssao_renders, "_geometry_only", lambda s: contextlib.nullcontext())
            plain = reference()
        assert 0.2 < fast["k"][fast["alpha"] > 0].mean() < 0.99
        np.testing.assert_array_equal(fast["k"], plain["k"])
        np.testing.assert_array_equal(fast["alpha"], plain["alpha"])
        mat = materials.white_lambert("T SSAO material")
        scene.objects["Ball"].data.materials.append(mat)
        seen = []
        real_render = ssao_renders.render.render_layers
        monkeypatch.setattr(ssao_renders.render, "render_layers",
                            lambda sc_: seen.append(sc_.view_layers[0].material_override) or real_render(sc_))
        reference()
        assert seen == [None]
    finally:
        remove_scene(scene)
        for m in [m for m in bpy.data.materials if m.name.startswith("T SSAO material")]:
            bpy.data.materials.remove(m)


def test_corner_against_cycles_gtao_beats_hemisphere_beats_sphere_kernel(tmp_path):
    report = lab.run_builtin("corner", str(tmp_path), SSAOOptions(
        methods=["crytek", "hemisphere", "gtao", "hbao"], resolution=64, samples=32, radius=1.0, reference_samples=256))
    r = {m: v["rmse"] for m, v in report["methods"].items()}
    noise = report["reference"]["noise_rms"]
    assert noise < 0.03
    assert r["gtao"] < r["hemisphere"] < r["crytek"], r
    # the crytek gap is the theory's: open floor reads ~0.5
    assert report["methods"]["crytek"]["bias"] < -0.25
    # files: pixel-aligned EXRs with Y and A, A = the geometry mask, sky never NaN
    data = json.load(open(tmp_path / "ssao_report.json"))
    assert set(data["methods"]) == {"crytek", "hemisphere", "gtao", "hbao"}
    assert {"samples", "seconds"} <= set(data["reference"])
    ref, _ = exr.read_exr(tmp_path / "reference_ao.exr")
    for m in data["methods"]:
        ch, hdr = exr.read_exr(tmp_path / f"{m}_ao.exr")
        assert set(ch) == {"Y", "A"} and ch["Y"].shape == ref["Y"].shape == (64, 64)
        np.testing.assert_array_equal(ch["A"], ref["A"])
        assert np.isfinite(ch["Y"]).all()
        assert 0 < ch["A"].mean() < 1
        mask = ch["A"] > 0.5
        d = ch["Y"][mask].astype(float) - ref["Y"][mask]
        assert np.sqrt(np.mean(d * d)) == pytest.approx(data["methods"][m]["rmse"], rel=1e-4)
        assert (tmp_path / f"{m}_error.png").stat().st_size > 100
    assert report["reference"]["closed_form"]["rmse"] < 2 * noise


@pytest.mark.both_versions
def test_workbench_cavity_and_settings_restored(tmp_path):
    scene = ssao_scenes.build_scene("corner", 48, 1.0)
    scene.render.engine = compat.CYCLES
    scene.cycles.samples = 7
    scene.render.resolution_x = scene.render.resolution_y = 200
    scene.view_layers[0].use_pass_z = False
    scene.world.light_settings.distance = 3.5
    report = lab.compare(scene, str(tmp_path), SSAOOptions(methods=["workbench", "crytek"], samples=16, radius=1.0,
                                                           reference_samples=64, resolution=48))
    wb = report["methods"]["workbench"]
    assert wb["rmse"] < report["methods"]["crytek"]["rmse"]
    assert 0.5 < wb["mean"] <= 1.0
    # the user's settings came back
    assert scene.render.engine == compat.CYCLES and scene.cycles.samples == 7
    assert scene.render.resolution_x == 200 and not scene.view_layers[0].use_pass_z
    assert scene.world.light_settings.distance == pytest.approx(3.5)
    assert scene.cycles.filter_width == pytest.approx(1.5)


@pytest.mark.both_versions
def test_reference_cache_key_follows_modifiers_and_their_settings():
    scene = ssao_scenes.build_scene("corner", 24, 1.0)
    keys = [lab.scene_key(scene, 1.0, 16)]
    bevel = scene.objects["Box"].modifiers.new("Bevel", "BEVEL")
    keys.append(lab.scene_key(scene, 1.0, 16))
    bevel.width = 0.2                                             # changes the evaluated mesh
    keys.append(lab.scene_key(scene, 1.0, 16))
    subsurf = scene.objects["Box"].modifiers.new("Subdivision", "SUBSURF")
    subsurf.levels = 0                                            # the viewport mesh stays as it was ...
    keys.append(lab.scene_key(scene, 1.0, 16))
    subsurf.render_levels = 3                                     # ... only the render differs
    keys.append(lab.scene_key(scene, 1.0, 16))
    assert len(set(keys)) == len(keys), keys
    assert lab.scene_key(scene, 1.0, 16) == keys[-1]             # and it is stable
    remove_scene(scene)


def test_failure_restores_settings_and_reports_clearly(tmp_path):
    scene = ssao_scenes.build_scene("plane", 32, 1.0)
    scene.camera.rotation_euler = (3.14159, 0.0, 0.0)        # looking straight up: nothing but sky
    scene.camera.location = (0.0, 0.0, 1.0)
    samples = scene.cycles.samples
    with pytest.raises(ILError, match="sees no geometry"):
        lab.compare(scene, str(tmp_path), SSAOOptions(methods=["gtao"], resolution=32, reference_samples=16))
    assert scene.cycles.samples == samples and scene.render.resolution_x == 32
    for bad in (dict(methods=["ssdo"]), dict(radius=0.0), dict(samples=0), dict(reference_samples=0)):
        kw = dict(methods=["gtao"], radius=1.0, samples=8, reference_samples=16)
        kw.update(bad)
        with pytest.raises(InputError):
            lab.compare(scene, None, SSAOOptions(**kw))
    with pytest.raises(InputError, match="unknown SSAO scene"):
        ssao_scenes.build_scene("attic")


@pytest.mark.both_versions
def test_operators_build_scene_and_run_comparison(tmp_path):
    s = bpy.context.scene.illumination.ssao
    s.scene_kind, s.resolution, s.samples, s.reference_samples = "plane", 32, 8, 16
    s.methods = {"hemisphere", "gtao"}
    s.output_dir = str(tmp_path)
    before = set(bpy.data.scenes)
    assert bpy.ops.illumination.ssao_build_scene() == {"FINISHED"}
    new = [sc for sc in bpy.data.scenes if sc not in before]
    assert len(new) == 1 and new[0]["il_ssao_scene"] == "plane"
    with bpy.context.temp_override(scene=new[0]):
        assert bpy.ops.illumination.ssao_compare() == {"FINISHED"}
        result = json.loads(new[0].illumination.ssao.last_report)
    assert set(result) == {"hemisphere", "gtao"} and result["gtao"][0] < 0.01
    assert (tmp_path / "ssao_report.json").exists()


def test_every_builtin_scene_renders_a_gbuffer():
    for name in limits.SCENES:
        scene = ssao_scenes.build_scene(name, 24, 1.0)
        gb, world, _ = lab.render_gbuffer(scene)
        assert gb.mask.any() and np.isfinite(gb.position).all() and np.isfinite(gb.normal).all()
        # normals face the camera and are unit
        n = gb.normal[gb.mask]
        np.testing.assert_allclose(np.linalg.norm(n, axis=-1), 1.0, atol=1e-3)
        assert np.all(np.sum(n * -gb.position[gb.mask], -1) >= -1e-4)
        remove_scene(scene)


@pytest.mark.eevee
def test_eevee_ao_pass_on_the_corner(tmp_path):
    report = lab.run_builtin("corner", str(tmp_path), SSAOOptions(methods=["eevee", "crytek"], resolution=48, samples=4,
                                                                 radius=1.0, reference_samples=128))
    ev = report["methods"]["eevee"]
    assert ev["rmse"] < report["methods"]["crytek"]["rmse"]
    assert ev["rmse"] < 0.2 and abs(ev["bias"]) < 0.1
    ch, _ = exr.read_exr(tmp_path / "eevee_ao.exr")
    assert np.isfinite(ch["Y"]).all()
