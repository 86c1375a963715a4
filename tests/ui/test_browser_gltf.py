"""The exported .glb in a real client (issue 28, item 3): three.js (web/package.json, pinned) in headless Chromium
loads what scripts/export_lightmaps.py wrote, with the MOZ_lightmap plugin of web/moz_lightmap.js registered as
engines do, renders the Blender camera without scene lights into a float render target, and its pixels match
Cycles' render of the applied preview (base colour x E/pi as emission) on the same camera.

The difference is taken apart, each part against its own bound, on the pixels whose 3 x 3 neighbourhood in Cycles'
object-index and normal passes is one face of one object (no silhouettes, no cube edges):
- three.js = rho/pi x the bilinear value of the 8-bit map x intensity at its own UVs (TEXCOORD_1, read back in a
  second pass), and Cycles = rho/pi x the EXR's bilinear value at its UV pass: both within float32 rounding;
- encoding: the 8-bit map's bilinear value is within intensity / 510 of the EXR's (docs/lightmaps.md, "Export");
- rasteriser: the GPU snaps vertices to 2^-SUBPIXEL_BITS px (4 in SwiftShader) and Cycles' 0.01 px filter jitters
  the sample by 0.005 px, so the two UVs of a pixel differ by at most (2^-(bits+1) + 0.005) x the screen Jacobian
  of the UVs (asserted), and E by that times its slope (texture size x the largest neighbouring texel jump).
So |three.js - Blender| <= rho/pi (intensity / 510 + slope x UV bound) per pixel and channel, asserted everywhere;
the share of pixels inside the encoding bound alone is printed.
The materials have Specular IOR Level 0 (KHR_materials_specular factor 0): three.js weights the light map's diffuse
by 1 - the specular lobe's directional albedo (lights_physical_pars_fragment), which is 1 only then; the page also
renders with the default dielectric specular (F0 0.04), strictly darker, and the test prints by how much."""
import base64
import contextlib
import json
import math
import os
import signal
import subprocess
import threading
import time
from functools import partial
from http.server import SimpleHTTPRequestHandler, ThreadingHTTPServer

import bpy
import numpy as np
import pytest

from addon.bake import bake_lightmaps
from addon.bake.options import BakeOptions
from addon.blender import compat, render
from addon.blender import scene as sc
from addon.core.io import exr
from addon.nodes import lightmap_preview as lp
from tests.scripts.test_export_lightmaps import _image, _read_glb
from tests.ui.test_lightmap_preview import _bilinear

pytestmark = pytest.mark.browser

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
WEB = os.path.join(ROOT, "web")
CHROMIUM = os.environ.get("IL_CHROMIUM", "/usr/bin/chromium")
PAINT, LABEL = (0.8, 0.4, 0.2), (0.2, 0.6, 0.9)
WIDTH, HEIGHT = 96, 72
TIMEOUT = 180.0


def _missing():
    """What the browser test lacks, or None."""
    if not os.access(CHROMIUM, os.X_OK):
        return f"no Chromium at {CHROMIUM} (./run test installs Debian's chromium)"
    if not os.path.isfile(os.path.join(WEB, "node_modules", "three", "build", "three.module.js")):
        return "web/node_modules has no three.js (./run test runs npm ci --prefix web)"
    return None


@pytest.fixture
def browser_ready():
    reason = _missing()
    if reason is not None:
        if os.environ.get("CI"):
            pytest.fail(f"CI must run the browser test: {reason}")
        pytest.skip(reason)


class _Handler(SimpleHTTPRequestHandler):
    """web/ as static files, plus the test's own ``extra`` paths (bytes); POST /result hands the page's JSON
    to ``box``."""

    def __init__(self, *args, extra, box, **kwargs):
        self.extra, self.box = extra, box
        super().__init__(*args, directory=WEB, **kwargs)

    def do_GET(self):
        if self.path in self.extra:
            data = self.extra[self.path]
            self.send_response(200)
            self.send_header("Content-Type", "application/octet-stream")
            self.send_header("Content-Length", str(len(data)))
            self.end_headers()
            self.wfile.write(data)
            return
        super().do_GET()

    def do_POST(self):
        body = self.rfile.read(int(self.headers.get("Content-Length", 0)))
        self.send_response(204)
        self.end_headers()
        self.box["result"] = json.loads(body)
        self.box["done"].set()

    def guess_type(self, path):
        return "text/javascript" if str(path).endswith(".js") else super().guess_type(path)

    def log_message(self, *args):
        pass


def render_in_browser(glb_bytes, params, tmp_path):
    """(the page's JSON, stderr tail): web/render.html in headless Chromium (SwiftShader WebGL) over a loopback
    http.server; the browser's process group is killed after the result or after ``TIMEOUT`` seconds."""
    box = {"done": threading.Event()}
    extra = {"/scene.glb": glb_bytes, "/params.json": json.dumps(dict(params, glb="/scene.glb")).encode()}
    server = ThreadingHTTPServer(("127.0.0.1", 0), partial(_Handler, extra=extra, box=box))
    threading.Thread(target=server.serve_forever, daemon=True).start()
    profile = tmp_path / "chromium-profile"
    profile.mkdir()
    log = open(tmp_path / "chromium.log", "w+b")
    url = f"http://127.0.0.1:{server.server_address[1]}/render.html"
    proc = subprocess.Popen(
        [CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync", "--mute-audio",
         "--use-angle=swiftshader", "--enable-unsafe-swiftshader", f"--user-data-dir={profile}", url],
        stdout=log, stderr=log, stdin=subprocess.DEVNULL, start_new_session=True)
    try:
        deadline = time.monotonic() + TIMEOUT
        while not box["done"].wait(0.2) and time.monotonic() < deadline and proc.poll() is None:
            pass
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGKILL)
        proc.wait(10)
        server.shutdown()
        server.server_close()
        log.seek(0)
        tail = log.read().decode(errors="replace")[-3000:]
        log.close()
    if "result" not in box:
        pytest.fail(f"no result from the page within {TIMEOUT:.0f} s (browser exit {proc.returncode}):\n{tail}")
    return box["result"], tail


def _principled(name, base):
    mat = bpy.data.materials.new(name)
    compat.ensure_use_nodes(mat)
    bsdf = next(n for n in mat.node_tree.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled")
    bsdf.inputs["Base Color"].default_value = (*base, 1.0)
    bsdf.inputs["Specular IOR Level"].default_value = 0.0
    return mat


def _scene():
    """A 2 m plane and a 0.6 m cube (two materials) made with Blender's operators, lit by a sun and a dim sky."""
    scene = bpy.context.scene
    bpy.ops.mesh.primitive_plane_add(size=2.0)
    plane = bpy.context.active_object
    bpy.ops.mesh.primitive_cube_add(size=0.6, location=(0.0, 0.0, 0.3))
    cube = bpy.context.active_object
    plane.data.materials.append(_principled("Paint", PAINT))
    cube.data.materials.append(_principled("Label", LABEL))
    plane.pass_index, cube.pass_index = 1, 2
    bpy.ops.object.light_add(type="SUN", rotation=(math.radians(40), math.radians(-25), 0.0))
    sun = bpy.context.active_object
    sun.data.energy = 3.0
    sun.data.angle = math.radians(3.0)
    sc.world(scene, strength=0.3)
    return scene, plane, cube, sun


def _camera(scene):
    cam = sc.camera(scene, "Camera", (1.3, -1.6, 1.25), target=(0.0, 0.0, 0.1), lens=35.0)
    cam.data.sensor_fit = "VERTICAL"
    scene.render.resolution_x, scene.render.resolution_y = WIDTH, HEIGHT
    scene.render.resolution_percentage = 100
    scene.render.pixel_aspect_x = scene.render.pixel_aspect_y = 1.0
    bpy.context.view_layer.update()
    to_yup = np.array([[1, 0, 0, 0], [0, 0, 1, 0], [0, -1, 0, 0], [0, 0, 0, 1]], float)   # glTF: +Y up, -Y -> +Z
    matrix = to_yup @ np.array(cam.matrix_world)
    return {"width": WIDTH, "height": HEIGHT, "fov": math.degrees(cam.data.angle_y), "near": cam.data.clip_start,
            "far": cam.data.clip_end, "matrix": matrix.T.ravel().tolist()}


def _interior(index, normal):
    """Pixels whose 3 x 3 neighbourhood is one face of one object (Cycles' object index and normal passes)."""
    keep = index > 0
    h, w = index.shape
    pad_i = np.pad(index, 1, mode="edge")
    pad_n = np.pad(normal, ((1, 1), (1, 1), (0, 0)), mode="edge")
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            keep &= pad_i[1 + dy:1 + dy + h, 1 + dx:1 + dx + w] == index
            keep &= np.abs(pad_n[1 + dy:1 + dy + h, 1 + dx:1 + dx + w] - normal).max(-1) < 1e-3
    keep[[0, -1], :] = keep[:, [0, -1]] = False
    return keep


def _exr_rgb(path):
    chans, _ = exr.read_exr(path)
    return np.stack([chans[c] for c in "RGB"], -1).astype(np.float64)


def _slopes(img, u, v):
    """Per sample and channel, bounds of |dE/du| and |dE/dv| of the bilinear map ``img`` (row 0 at v = 0) over the
    cell around (u, v) and its neighbours: the texture size times the largest jump between neighbouring texels."""
    h, w = img.shape[:2]
    jx, jy = np.abs(np.diff(img, axis=1)), np.abs(np.diff(img, axis=0))
    x0, y0 = np.floor(u * w - 0.5).astype(int), np.floor(v * h - 0.5).astype(int)
    du, dv = np.zeros((len(u), img.shape[2])), np.zeros((len(u), img.shape[2]))
    for n, (x, y) in enumerate(zip(x0, y0)):
        du[n] = w * jx[max(y - 1, 0):y + 3, max(x - 1, 0):max(x + 2, 1)].max((0, 1))
        dv[n] = h * jy[max(y - 1, 0):max(y + 2, 1), max(x - 1, 0):x + 3].max((0, 1))
    return du, dv


def test_three_js_shows_what_the_preview_shows(tmp_path, script, browser_ready):
    start = time.monotonic()
    scene, plane, cube, sun = _scene()
    maps = tmp_path / "maps"
    report = bake_lightmaps([plane, cube], ["irradiance"], str(maps),
                            BakeOptions(resolution=32, samples=16, bounces=1, margin=2), scene=scene)["objects"]
    blend = tmp_path / "baked.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(blend), copy=True, compress=False)
    glb = tmp_path / "scene.glb"
    r = script("export_lightmaps.py", blend, "--lightmaps", maps, "--out", glb)
    assert r.returncode == 0, r.stderr

    # Blender: the preview (emission only), no lights, black world, one sample through each pixel centre; the
    # UV pass is the light-map layer (made the render layer after the export; the preview names its layer)
    params = _camera(scene)
    lp.apply_lightmaps([plane, cube], str(maps), "IRRADIANCE")
    sun.hide_render = True
    scene.world.node_tree.nodes["Background"].inputs["Strength"].default_value = 0.0
    render.cycles_cpu(scene, samples=1, pixel_filter=0.01)
    layer = scene.view_layers[0]
    layer.use_pass_object_index = layer.use_pass_normal = layer.use_pass_uv = True
    for obj in (plane, cube):
        obj.data.uv_layers[report[obj.name]["irradiance"]["uv_layer"]].active_render = True
    passes = render.render_layers(scene)
    blender = passes["Combined"][..., :3].astype(np.float64)
    index = np.rint(passes["IndexOB" if "IndexOB" in passes else "Object Index"]).astype(int)
    uv_blender = np.stack([passes["UV"][..., 2], 1.0 - passes["UV"][..., 1]], -1)     # channels A, V, U; glTF v

    page, log = render_in_browser(glb.read_bytes(), params, tmp_path)
    assert "error" not in page, page.get("error", "") + "\n" + log

    def image(key):
        raw = np.frombuffer(base64.b64decode(page[key]), np.float32).reshape(HEIGHT, WIDTH, 4)
        return raw[::-1].astype(np.float64)                  # GL's row 0 is the bottom
    three, uv_three, dielectric = image("pixels")[..., :3], image("uvs"), image("dielectric")[..., :3]
    mats = {m["mesh"]: m for m in page["materials"]}
    assert all(m["lightMap"] and m["channel"] == 1 and m["colorSpace"] == "" and not m["aoMap"]
               and m["specularIntensity"] == 0 for m in mats.values()), mats
    gltf, binary = _read_glb(glb)

    keep = _interior(index, passes["Normal"])
    peak = blender[keep].max()
    eps = 1e-5 * peak                                         # float32 arithmetic of both renderers
    # the rasteriser's sub-pixel grid (SUBPIXEL_BITS) moves each vertex by up to half a step; Cycles' 0.01 px
    # filter moves the sample by up to 0.005 px: the surface point moves by at most their sum, in UV by that
    # times the screen Jacobian of the UVs (central differences of three.js's UV image)
    shift = 2.0 ** -(page["subpixelBits"] + 1) + 0.005
    jx = (np.roll(uv_three, -1, 1) - np.roll(uv_three, 1, 1))[..., :2] / 2
    jy = (np.roll(uv_three, -1, 0) - np.roll(uv_three, 1, 0))[..., :2] / 2
    uv_bound = shift * (np.abs(jx) + np.abs(jy))
    diff, bound, encode, uv_ratio = [], [], [], []
    for obj, colour in ((plane, PAINT), (cube, LABEL)):
        on = keep & (index == obj.pass_index)
        node = next(n for n in gltf["nodes"] if n["name"] == obj.name)
        moz = gltf["materials"][gltf["meshes"][node["mesh"]]["primitives"][0]["material"]]["extensions"]["MOZ_lightmap"]
        intensity = moz["intensity"]
        assert mats[obj.name]["intensity"] == pytest.approx(intensity, rel=1e-6)
        rho = np.array(colour) / math.pi
        png = _image(gltf, binary, moz["index"]) / 255.0 * intensity
        e = _exr_rgb(report[obj.name]["irradiance"]["file"])
        assert np.all(np.rint(uv_three[on][:, 2]) == 1 + list(mats).index(obj.name))    # the same object
        u, v = uv_three[on][:, 0], uv_three[on][:, 1]
        # three.js = base colour / pi x the 8-bit map's bilinear value at its UVs (linear, intensity, no AO)
        assert np.abs(three[on] - rho * _bilinear(png, u, v)).max() <= eps
        # Cycles = base colour / pi x the EXR's bilinear value at its UVs (the preview)
        ub, vb = uv_blender[on][:, 0], uv_blender[on][:, 1]
        assert np.abs(blender[on] - rho * _bilinear(e, ub, vb)).max() <= eps
        # the two rasterisers hit the same surface points within the sub-pixel bound
        uv_ratio.append((np.abs(uv_three[on][:, :2] - uv_blender[on]) / uv_bound[on]).max())
        du, dv = _slopes(e, u, v)
        raster = rho * (du * uv_bound[on][:, :1] + dv * uv_bound[on][:, 1:])
        diff.append(np.abs(three[on] - blender[on]))
        encode.append(np.broadcast_to(rho * intensity / 510, diff[-1].shape))
        bound.append(encode[-1] + raster)
    diff, bound, encode = np.concatenate(diff), np.concatenate(bound), np.concatenate(encode)
    rel = diff.max(axis=1) / peak
    lit = keep & (blender.min(-1) > 0.05 * peak)
    darker = dielectric[lit] / three[lit]
    inside = np.all(diff <= encode + eps, axis=1).mean()
    print(f"three.js r{page['revision']} ({page['renderer']}, {page['subpixelBits']} sub-pixel bits): "
          f"{len(diff)} of {WIDTH * HEIGHT} pixels compared; |three.js - Blender| max {rel.max():.2e}, p99 "
          f"{np.percentile(rel, 99):.2e} of the peak {peak:.4f}; encoding bound {encode.max() / peak:.2e} of the "
          f"peak, {100 * inside:.1f} % of pixels inside it; with the rasteriser term max "
          f"{bound.max() / peak:.2e}, median {np.median(bound.max(1)) / peak:.2e}; UV shift up to "
          f"{max(uv_ratio):.2f} of its bound; default dielectric specular: x {np.median(darker):.3f} (median), "
          f"{darker.min():.3f} to {darker.max():.3f}; {time.monotonic() - start:.1f} s")
    assert len(diff) > 0.3 * WIDTH * HEIGHT
    assert max(uv_ratio) <= 1.0
    assert np.all(diff <= bound + eps)
    assert np.all(darker < 1.0) and np.all(darker > 0.0)
    # the sun and sky reached the maps: contact shadow and lit faces differ by far more than the bound
    assert blender[keep].min() < 0.5 * peak
