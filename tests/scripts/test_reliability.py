"""The labs on files users bring, and their boundary: bad input refused up front (exit 2, nothing
created), cost bounds, non-finite and meaningless results refused, Ctrl-C, leftovers, the cache."""
import json
import math
import os
import signal
import subprocess
import sys
import time

import bpy
import numpy as np
import pytest
from mathutils import Vector

from addon.core.io import hdr as io_hdr
from addon.core.io import png
from addon.core.io import exr
from addon.lab import ssao as ssao_lab
from addon.lab.options import ShadowOptions, SSAOOptions
from addon.lab.ssao import scenes as ssao_scenes
from addon.blender import compat
from addon.blender.scene import remove_scene

from conftest import ROOT

SCRIPTS = sorted(f for f in os.listdir(os.path.join(ROOT, "scripts")) if f.endswith(".py") and f != "_cli.py")
BLEND_SCRIPTS = ("ssao.py", "shadows.py", "envmap.py", "bake.py", "radiosity.py", "reflections.py", "raytrace.py",
                 "export_lightmaps.py")
NO_OUT = ("bench_shadows.py", "bench_shading.py")    # print only
REQUIRED = {"bake.py": ["--objects", "Cube"], "export_lightmaps.py": ["--lightmaps", ROOT]}
OUT_FILE = ("export_lightmaps.py",)                  # --out names the file written, not a folder


def _aim(obj, target=(0.0, 0.0, 0.3)):
    obj.rotation_euler = (Vector(target) - obj.location).to_track_quat("-Z", "Y").to_euler()


def user_file(path):
    """A .blend made only with Blender's operators: plane, cube, UV sphere, Suzanne with subdivision and
    bevel, a camera, point, sun, spot and area lights, a curve, a text and a metaball."""
    ops = bpy.ops
    ops.mesh.primitive_plane_add(size=8.0)
    ops.mesh.primitive_cube_add(size=1.0, location=(-1.5, 0.0, 0.5))
    ops.mesh.primitive_uv_sphere_add(radius=0.5, location=(0.0, 1.2, 0.6))
    ops.mesh.primitive_monkey_add(size=1.0, location=(1.5, 0.0, 0.7))
    monkey = bpy.context.object
    ops.object.modifier_add(type="SUBSURF")
    ops.object.modifier_add(type="BEVEL")
    monkey.modifiers["Subdivision"].levels = 1
    ops.curve.primitive_bezier_circle_add(radius=0.4, location=(0.0, -1.5, 0.3))
    bpy.context.object.data.bevel_depth = 0.05
    ops.object.text_add(location=(-1.0, -2.5, 0.01))
    ops.object.metaball_add(type="BALL", radius=0.4, location=(1.2, -1.5, 0.5))
    ops.object.camera_add(location=(0.0, -7.0, 5.0))
    cam = bpy.context.object
    _aim(cam)
    bpy.context.scene.camera = cam
    ops.object.light_add(type="POINT", location=(1.0, -1.0, 4.0))
    bpy.context.object.name, bpy.context.object.data.energy = "Light", 1000.0
    ops.object.light_add(type="SUN", rotation=(0.5, 0.2, 0.4))
    bpy.context.object.name = "Sun"
    ops.object.light_add(type="SPOT", location=(0.5, -2.0, 6.0))
    bpy.context.object.name, bpy.context.object.data.energy = "Spot", 3000.0
    bpy.context.object.data.spot_size = 1.4
    _aim(bpy.context.object)
    ops.object.light_add(type="AREA", location=(0.0, 2.0, 4.0))
    bpy.context.object.name = "Area"
    scene = bpy.context.scene
    scene.render.resolution_x, scene.render.resolution_y = 64, 48
    bpy.ops.wm.save_as_mainfile(filepath=str(path), copy=True)
    return path


@pytest.fixture
def user_blend(tmp_path):
    return user_file(tmp_path / "user.blend")


def _errors(stderr):
    """stderr without the progress lines."""
    return [line for line in stderr.strip().splitlines() if not line.startswith("[")]


# ------------------------------------------------------------------------------- real files (issue 15)

@pytest.mark.parametrize("light", ["Light", "Sun", "Spot"])
def test_shadows_on_a_file_made_with_blenders_operators(script, user_blend, tmp_path, light):
    out = tmp_path / "out"
    r = script("shadows.py", user_blend, "--light", light, "--receiver", "Plane", "--resolution", 64,
               "--shadowmap-size", 512, "--methods", "raytraced,planar,shadowmap,volume_zfail", "--out", out)
    assert r.returncode == 0, r.stderr
    rep = json.loads((out / "shadows_report.json").read_text())
    ref = rep["reference"]
    assert ref["resolution"] == [64, 48] and ref["receiver_pixels"] > 0.5 * 64 * 48     # the floor fills the frame
    assert rep["meaningful"] and 0 < ref["lit_pixels"] < ref["receiver_pixels"]          # lit and shadowed pixels
    assert 0.02 < ref["shadowed_fraction"] < 0.9
    assert rep["methods"]["shadowmap"]["error"] < 0.05                                    # same occluders as Cycles
    assert "Suzanne" in rep["methods"]["volume_zfail"]["params"]["skipped_open_meshes"]   # open: documented
    mask = png.decode_png((out / "raytraced_mask.png").read_bytes())
    assert mask.shape == (48, 64) and {0, 255} <= set(np.unique(mask))


def test_shadows_refuse_an_area_light_and_a_dark_light(script, user_blend, tmp_path):
    r = script("shadows.py", user_blend, "--light", "Area", "--out", tmp_path / "o")
    assert r.returncode == 2 and _errors(r.stderr) == [
        "shadows.py: error: light 'Area' is an area light: the shadow lab compares hard shadows of point, spot "
        "and sun lights (add one, or change its type)"]
    bpy.ops.wm.open_mainfile(filepath=str(user_blend))
    bpy.data.objects["Light"].data.energy = 0.0
    dark = tmp_path / "dark.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(dark), copy=True)
    r = script("shadows.py", dark, "--light", "Light", "--out", tmp_path / "o")
    assert r.returncode == 2 and "gives no light (0 W" in r.stderr and len(_errors(r.stderr)) == 1
    assert not (tmp_path / "o").exists()


def test_ssao_on_a_file_made_with_blenders_operators(script, user_blend, tmp_path):
    out = tmp_path / "out"
    r = script("ssao.py", user_blend, "--methods", "gtao,hemisphere", "--samples", 16, "--reference-samples", 64,
               "--out", out)
    assert r.returncode == 0, r.stderr
    rep = json.loads((out / "ssao_report.json").read_text())
    assert rep["resolution"] == [64, 48] and rep["geometry_pixels"] > 0.5 * 64 * 48
    ref, _ = exr.read_exr(out / "reference_ao.exr")
    geo = ref["A"] > 0.5
    for name in ("reference", "gtao", "hemisphere"):
        ch, _ = exr.read_exr(out / f"{name}_ao.exr")
        k = ch["Y"][geo]
        assert np.isfinite(k).all() and k.min() >= 0.0 and k.max() <= 1.0
        assert k.mean() > 0.5 and k.min() < 0.9          # mostly open floor, occluded near the objects
    # noise of 64 samples is <= 0.0625 per pixel; GTAO is within a few times that of the reference
    assert rep["methods"]["gtao"]["rmse"] < 0.2


def test_envmap_of_a_world_with_an_environment_texture(script, tmp_path):
    """A uniform environment L in an image: E(n) = π L strength for every normal (REFERENCE.md §1)."""
    radiance = np.array([0.5, 0.25, 0.125])
    hdr = tmp_path / "sky.hdr"
    io_hdr.write_hdr(hdr, np.broadcast_to(radiance, (16, 32, 3)))
    world = bpy.data.worlds.new("Sky")
    bpy.context.scene.world = world
    compat.ensure_use_nodes(world)
    nt = world.node_tree
    bg = nt.nodes.get("Background") or nt.nodes.new("ShaderNodeBackground")
    bg.inputs["Strength"].default_value = 2.0
    tex = nt.nodes.new("ShaderNodeTexEnvironment")
    tex.image = bpy.data.images.load(str(hdr))
    nt.links.new(tex.outputs["Color"], bg.inputs["Color"])
    blend = tmp_path / "world.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend), copy=True)
    r = script("envmap.py", blend, "--width", 32, "--out", tmp_path / "o")
    assert r.returncode == 0, r.stderr
    ch, _ = exr.read_exr(tmp_path / "o" / "irradiance_latlong.exr")
    e = np.stack([ch[c] for c in "RGB"], -1)
    assert e.shape == (16, 32, 3)
    np.testing.assert_allclose(e, np.broadcast_to(2 * math.pi * radiance, e.shape), rtol=2e-3)


# ------------------------------------------------------------------------------- refused up front (16.4-16.6)

@pytest.mark.parametrize("name, args, largest", [
    ("ssao.py", ["--samples", "100000000"], "<= 1024"),
    ("ssao.py", ["--resolution", "8192", "--reference-samples", "65536"], "the largest"),
    ("ssao.py", ["--resolution", "4096", "--samples", "1024", "--methods", "crytek,hemisphere,hbao,gtao"],
     "the largest"),
    ("envmap.py", ["--width", "10000000", "--env", "sky.exr"], "the largest width that fits is"),
    ("shadows.py", ["--scene", "sphere", "--light-type", "point", "--shadowmap-size", "16384",
                    "--resolution", "8192"], "the largest"),
    ("shadows.py", ["--scene", "sphere", "--bias", "nan"], "--bias: must be a finite number"),
    ("shadows.py", ["--scene", "sphere", "--slope-bias", "inf"], "--slope-bias: must be a finite number"),
    ("envmap.py", ["--width", "nan", "--env", "sky.exr"], "--width"),
    ("demo.py", ["--samples", "1e9"], "--samples"),
])
def test_costs_that_do_not_fit_are_refused_before_any_work(script, tmp_path, name, args, largest):
    t = time.perf_counter()
    r = script(name, *args, "--out", tmp_path / "o")
    lines = _errors(r.stderr)
    assert r.returncode == 2 and len(lines) == 1 and largest in lines[0], r.stderr
    assert not (tmp_path / "o").exists()
    assert time.perf_counter() - t < 60           # refused, not run: a run of any of these takes hours


def test_the_named_largest_value_fits_and_the_next_does_not(monkeypatch):
    from addon.core import budget
    from addon.core.ssao import limits
    from addon.core.shadow import depth_map
    from addon.core.errors import InputError
    monkeypatch.setattr(budget, "memory_budget", lambda: 8 << 30)
    with pytest.raises(InputError, match="needs about 25 GiB of memory") as e:
        limits.check_cost(8192, 8192, 1, 1)
    best = int(str(e.value).rsplit(" ", 1)[1])
    assert best == int(math.sqrt((8 << 30) / limits.BYTES_PER_PIXEL))
    limits.check_cost(best, best, 1, 1)
    with pytest.raises(InputError, match=f"the largest shadow-map size that fits is "):
        depth_map.check_cost(128, 128, 16384, faces=6)
    cost = lambda n: (n * 1000, 0.0)  # noqa: E731
    assert budget.largest(cost, 1, 10 ** 9, memory=123456) == 123
    assert budget.largest(cost, 200, 10 ** 9, memory=123456) is None


def test_environment_negative_or_too_bright_is_refused(script, tmp_path):
    for value, message in ((-1.0, "negative radiance"), (3e38, "too bright")):
        env = tmp_path / "env.exr"
        exr.write_exr(env, {c: np.full((8, 16), value if c != "G" else abs(value) * 0.5) for c in "RGB"})
        r = script("envmap.py", "--env", env, "--out", tmp_path / "o")
        assert r.returncode == 2 and message in r.stderr and len(_errors(r.stderr)) == 1, r.stderr
        assert not (tmp_path / "o").exists()


def test_every_script_refuses_an_out_that_is_a_file_and_a_corrupt_blend(tmp_path):
    """16.8: exit 2 with one line, for every script, at once (the processes run side by side); 24.7: also a
    .blend whose header version was damaged to 1.00 (Blender's loader crashed on it)."""
    a_file = tmp_path / "taken"
    a_file.write_text("x")
    whole = tmp_path / "whole.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(whole), copy=True)
    corrupt = tmp_path / "corrupt.blend"
    corrupt.write_bytes(whole.read_bytes()[:4096])                   # truncated by a full disk or a copy
    plain = tmp_path / "plain.blend"                                 # issue 24.7: Blender's loader segfaults
    bpy.ops.wm.save_as_mainfile(filepath=str(plain), copy=True, compress=False)
    data = plain.read_bytes()
    digits = 4 if data[7:9] == b"17" else 3                          # 'BLENDER17-01v0503' or 'BLENDER-v405'
    damaged = tmp_path / "damaged_version.blend"
    damaged.write_bytes(data[:17 - 4] + b"0100" + data[17:] if digits == 4 else data[:9] + b"100" + data[12:])
    runs = {}
    for name in SCRIPTS:
        if name not in NO_OUT:
            runs[(name, "out")] = [name, *REQUIRED.get(name, ()), "--out",
                                   a_file / "scene.glb" if name in OUT_FILE else a_file]
        if name in BLEND_SCRIPTS:
            runs[(name, "blend")] = [name, corrupt, *REQUIRED.get(name, ()), "--out", tmp_path / f"o_{name}"]
            runs[(name, "header")] = [name, damaged, *REQUIRED.get(name, ()), "--out", tmp_path / f"o_{name}"]
    procs = {k: subprocess.Popen([sys.executable, os.path.join(ROOT, "scripts", a[0]), *map(str, a[1:])],
                                 stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=ROOT)
             for k, a in runs.items()}
    for (name, kind), p in procs.items():
        _, err = p.communicate(timeout=300)
        lines = _errors(err)
        assert p.returncode == 2 and len(lines) == 1, (name, kind, err)
        assert ("output folder is a file" if kind == "out" else "damaged or not a Blender file") in lines[0]
        assert kind != "header" or "older than the" in lines[0], lines
        assert not (tmp_path / f"o_{name}").exists()
    assert set(BLEND_SCRIPTS) <= set(SCRIPTS) and len(runs) >= 20


# ------------------------------------------------------------------------------- Ctrl-C (16.2)

def test_ctrl_c_during_the_cycles_reference_stops_with_130_and_leaves_nothing(tmp_path):
    out, tmp = tmp_path / "out", tmp_path / "tmp"
    tmp.mkdir()
    env = dict(os.environ, TMPDIR=str(tmp))
    p = subprocess.Popen([sys.executable, os.path.join(ROOT, "scripts", "ssao.py"), "--scene", "corner",
                          "--methods", "gtao", "--resolution", "256", "--reference-samples", "1024", "--out", str(out)],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=ROOT, env=env)
    seen = []
    for line in p.stderr:
        seen.append(line)
        if "reference: Cycles AO pass" in line:
            break
    time.sleep(1.0)                                # inside Cycles' render (13.6 s at this size; 0.9 s at 64²)
    t = time.perf_counter()
    p.send_signal(signal.SIGINT)
    rest, err = p.communicate(timeout=300)
    seen.append(err)
    lines = _errors("".join(seen))
    assert p.returncode == 130, "".join(seen)
    assert lines == ["ssao.py: interrupted: stopped, the file and finished outputs are as they were"]
    assert time.perf_counter() - t < 120
    leftovers = [os.path.join(d, f) for d, _, fs in os.walk(out) for f in fs] if out.exists() else []
    assert leftovers == [] and os.listdir(tmp) == []    # no report, no cache entry, no temporary file


# ------------------------------------------------------------------------------- leftovers and cache

def test_comparisons_leave_no_render_result_but_keep_the_users(tmp_path):
    from addon.lab import shadows
    scene = ssao_scenes.build_scene("plane", 16, 1.0)
    options = SSAOOptions(methods=["gtao"], samples=4, reference_samples=4, resolution=None)
    ssao_lab.compare(scene, None, options)
    assert not [im for im in bpy.data.images if im.type == "RENDER_RESULT"]
    shadows.compare_builtin("sphere", "sun", tmp_path, ShadowOptions(methods="raytraced,shadowmap", resolution=16,
                                                                     shadowmap_size=32))
    assert not [im for im in bpy.data.images if im.type == "RENDER_RESULT"]
    scene.render.engine = "BLENDER_WORKBENCH"
    bpy.ops.render.render(scene=scene.name)                       # the user's own render
    before = [im.name for im in bpy.data.images if im.type == "RENDER_RESULT"]
    ssao_lab.compare(scene, None, options)
    assert before and [im.name for im in bpy.data.images if im.type == "RENDER_RESULT"] == before
    remove_scene(scene)


def test_a_damaged_cache_entry_is_a_miss_and_is_replaced(tmp_path):
    scene = ssao_scenes.build_scene("plane", 16, 1.0)
    try:
        with ssao_lab.preserved(scene):
            key = ssao_lab.scene_key(scene, 1.0, 8)
            entry = tmp_path / f"ssao_reference_{key}.npz"
            entry.write_bytes(b"PK\x03\x04 truncated")
            first = ssao_lab.render_reference(scene, 1.0, 8, str(tmp_path))
            assert first["cached"] is False and first["k"].shape == (16, 16)
            again = ssao_lab.render_reference(scene, 1.0, 8, str(tmp_path))
            assert again["cached"] is True and np.array_equal(again["k"], first["k"])
            assert sorted(os.listdir(tmp_path)) == [entry.name]      # written under a unique name, renamed
    finally:
        remove_scene(scene)


def test_ctrl_c_during_the_demo_stops_with_130_and_no_report(tmp_path):
    out, tmp = tmp_path / "out", tmp_path / "tmp"
    tmp.mkdir()
    p = subprocess.Popen([sys.executable, os.path.join(ROOT, "scripts", "demo.py"), "--quick", "--out", str(out)],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=ROOT,
                         env=dict(os.environ, TMPDIR=str(tmp)))
    seen = []
    for line in p.stderr:
        seen.append(line)
        if line.startswith("[demo 4/"):              # the light-map bake (Cycles) has started
            break
    time.sleep(0.3)
    p.send_signal(signal.SIGINT)
    _, err = p.communicate(timeout=300)
    lines = [line for line in _errors("".join(seen) + err) if "warning:" not in line]
    assert p.returncode == 130 and lines == ["demo.py: interrupted: stopped, the file and finished outputs are as "
                                             "they were"], "".join(seen) + err
    files = [f for _, _, fs in os.walk(out) for f in fs]
    assert "demo_report.json" not in files and not [f for f in files if ".tmp" in f] and os.listdir(tmp) == []


def test_an_empty_out_is_refused_by_every_script_and_button(tmp_path, addon_registered):
    """24.8: an empty output folder wrote into the current folder; now exit 2 with one line, nothing written."""
    cwd = tmp_path / "cwd"
    cwd.mkdir()
    procs = {name: subprocess.Popen([sys.executable, os.path.join(ROOT, "scripts", name), *REQUIRED.get(name, ()),
                                     "--out", ""], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                    cwd=str(cwd))
             for name in SCRIPTS if name not in NO_OUT}
    for name, p in procs.items():
        _, err = p.communicate(timeout=300)
        lines = _errors(err)
        want = "no output file given" if name in OUT_FILE else "no output folder given"
        assert p.returncode == 2 and len(lines) == 1 and want in lines[0], (name, err)
    assert not list(cwd.iterdir())
    bpy.ops.mesh.primitive_plane_add()
    settings = bpy.context.scene.illumination
    ready = []
    for group, op in ((settings.lightmaps, bpy.ops.illumination.bake_lightmaps),
                      (settings.ssao, bpy.ops.illumination.ssao_compare),
                      (settings.shadows, bpy.ops.illumination.run_shadow_comparison)):
        group.output_dir = str(tmp_path / "maps")
        if op.poll():
            ready.append(op.idname())
            group.output_dir = ""
            assert not op.poll(), op.idname()
    assert "ILLUMINATION_OT_bake_lightmaps" in ready
    with pytest.raises(RuntimeError, match="Choose an output folder"):
        bpy.ops.illumination.radiosity(output_dir="")


def test_late_failures_are_refused_before_any_work(tmp_path):
    """24.12: an SSAO radius whose float32 square overflows, a cache that is a file, and an output folder whose
    name the file system cannot take were found only after the work (NaN images, exit 1); now exit 2 at once."""
    a_file = tmp_path / "taken"
    a_file.write_text("x")
    long_name = tmp_path / ("x" * 300)
    base = ["--scene", "plane", "--resolution", "8", "--samples", "1", "--reference-samples", "1"]
    runs = {"radius": ["ssao.py", *base, "--radius", "1e300", "--out", tmp_path / "o1"],
            "cache": ["ssao.py", *base, "--cache", a_file, "--out", tmp_path / "o2"],
            "long ssao": ["ssao.py", *base, "--out", long_name],
            "long bake": ["bake.py", "--objects", "Cube", "--maps", "ao", "--out", long_name / "maps"]}
    procs = {k: subprocess.Popen([sys.executable, os.path.join(ROOT, "scripts", a[0]), *map(str, a[1:])],
                                 stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=ROOT)
             for k, a in runs.items()}
    expected = {"radius": "must be value <=", "cache": "output folder is a file",
                "long ssao": "name too long", "long bake": "name too long"}
    for k, p in procs.items():
        _, err = p.communicate(timeout=300)
        lines = _errors(err)
        assert p.returncode == 2 and len(lines) == 1 and expected[k] in lines[0], (k, err)
    assert sorted(os.listdir(tmp_path)) == ["taken"]


def _processes_naming(text):
    """PIDs of the running processes whose command line contains ``text``."""
    pids = []
    for pid in filter(str.isdigit, os.listdir("/proc")):
        try:
            with open(f"/proc/{pid}/cmdline", "rb") as f:
                if text.encode() in f.read():
                    pids.append(int(pid))
        except OSError:
            continue
    return pids


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT])
def test_stopping_a_jobs_run_stops_its_shards(tmp_path, sig):
    """24.6: SIGTERM or Ctrl-C to a --jobs run reaches its shard processes and the parent waits for them:
    exit 130, no shard left running, nothing written after the parent has gone."""
    for i in range(4):
        bpy.ops.mesh.primitive_uv_sphere_add(location=(3 * i, 0, 1))
    bpy.ops.mesh.primitive_plane_add(size=20)
    blend = tmp_path / "scene.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend), copy=True)
    out = tmp_path / "maps"
    names = [o.name for o in bpy.context.scene.objects if o.type == "MESH"]
    p = subprocess.Popen([sys.executable, os.path.join(ROOT, "scripts", "bake.py"), str(blend), "--objects", *names,
                          "--maps", "irradiance", "--resolution", "256", "--samples", "4096", "--out", str(out),
                          "--jobs", "2"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=ROOT)
    deadline = time.monotonic() + 120
    while len(_processes_naming(str(out))) < 3 and time.monotonic() < deadline:      # the parent and 2 shards
        time.sleep(0.2)
    time.sleep(4)                                                                    # the shards are baking
    assert p.poll() is None and len(_processes_naming(str(out))) == 3
    t0 = time.monotonic()
    p.send_signal(sig)
    _, err = p.communicate(timeout=120)
    assert p.returncode == 130, err
    assert time.monotonic() - t0 < 30, err
    assert _processes_naming(str(out)) == []
    files = {f: os.path.getmtime(os.path.join(out, f)) for f in os.listdir(out)} if out.exists() else {}
    time.sleep(3)
    after = {f: os.path.getmtime(os.path.join(out, f)) for f in os.listdir(out)} if out.exists() else {}
    assert after == files


@pytest.fixture
def small_disk(tmp_path):
    """A 64 KiB tmpfs (root only; skipped where it cannot be mounted)."""
    disk = tmp_path / "disk"
    disk.mkdir()
    if subprocess.run(["mount", "-t", "tmpfs", "-o", "size=64k", "tmpfs", str(disk)], capture_output=True).returncode:
        pytest.skip("cannot mount a small tmpfs here")
    try:
        yield disk
    finally:
        subprocess.run(["umount", str(disk)], capture_output=True)


def test_a_full_disk_is_one_line_and_keeps_what_was_finished(tmp_path, small_disk):
    """24.9: a full disk while OpenEXR writes was an internal error; now exit 1 with the disk-full line, the
    maps finished before and the report that lists them intact, no temporary file left."""
    bpy.ops.mesh.primitive_plane_add(size=1, location=(30, 0, 0))
    bpy.context.object.name = "Small"
    bpy.ops.mesh.primitive_plane_add(size=20)
    bpy.context.object.name = "Big"
    bpy.ops.mesh.primitive_uv_sphere_add(radius=8, location=(0, 0, 8.3))       # noisy AO over most of Big
    blend = tmp_path / "two.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend), copy=True)
    out = small_disk / "maps"
    r = subprocess.run([sys.executable, os.path.join(ROOT, "scripts", "bake.py"), str(blend), "--objects", "Small",
                        "Big", "--maps", "ao", "--texel-density", "16", "--samples", "4", "--out", str(out)],
                       capture_output=True, text=True, cwd=ROOT, timeout=300)
    lines = [ln for ln in _errors(r.stderr) if not ln.startswith("bake.py: warning: ")]   # the planes' low fill
    assert r.returncode == 1 and len(lines) == 1, r.stderr
    assert lines[0] == f"bake.py: error: No space left on device: {out / 'Big_ao.exr'}"
    assert sorted(set(os.listdir(out)) - {".il-uv-cache"}) == ["Small_ao.exr", "Small_ao.png", "bake_report.json"]
    report = json.loads((out / "bake_report.json").read_text())
    assert list(report["objects"]) == ["Small"]
    w, h = report["objects"]["Small"]["ao"]["resolution"]
    assert exr.read_exr(out / "Small_ao.exr")[0]["Y"].shape == (h, w)


EXIT_CHATTER = ("import atexit, os, runpy, sys; "
                "atexit.register(os.write, 1, b'Error: Not freed memory blocks: 18\\n'); "
                "atexit.register(os.write, 2, b'Blender quit\\n'); "
                "sys.argv = sys.argv[1:]; runpy.run_path(sys.argv[0], run_name='__main__')")
"""Runs a script as the process Blender shuts down after: lines written to descriptors 1 and 2 once it has ended
(bpy 4.5 prints its leak count on stdout after opening a file a newer Blender saved)."""


@pytest.mark.both_versions
def test_stdout_and_stderr_carry_the_projects_lines_only(tmp_path):
    """25.7: Blender's "Read blend:", "Info: Baking map saved to internal image..." and Mesa's EGL lines went to the
    scripts' stdout and stderr; a pipeline parsing them now sees only the project's progress, warnings and
    summary, also what Blender prints as the process ends (:data:`EXIT_CHATTER`)."""
    import re
    bpy.ops.mesh.primitive_plane_add(size=4)
    bpy.context.object.name = "Floor"
    bpy.ops.mesh.primitive_cube_add(size=1, location=(0, 0, 0.5))
    blend = tmp_path / "s.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend), copy=True)
    runs = {"bake.py": [str(blend), "--objects", "Floor", "Cube", "--maps", "ao", "irradiance", "--resolution", "16",
                        "--samples", "2", "--out", str(tmp_path / "maps")],
            "shadows.py": ["--scene", "sphere", "--methods", "raytraced,shadowmap,workbench", "--resolution", "24",
                           "--out", str(tmp_path / "shadows")]}
    ours = {"bake.py": re.compile(r"^(\S+ (ao|irradiance): .+\.exr \d+x\d+ |baked |report: )"),
            "shadows.py": re.compile(r"^(shadows: report |  \w+ +error )")}
    for name, args in runs.items():
        r = subprocess.run([sys.executable, "-c", EXIT_CHATTER, os.path.join(ROOT, "scripts", name), *args],
                           capture_output=True, text=True, cwd=ROOT, timeout=300)
        assert r.returncode == 0, r.stderr
        out = r.stdout.splitlines()
        assert out and all(ours[name].match(line) for line in out), (name, r.stdout)
        assert all(line.startswith(("[", f"{name}: warning: ")) for line in r.stderr.splitlines()), (name, r.stderr)
