"""The bpy side of the reflection lab: Cycles' mirror (the reference, with the camera rays, the shading
normals and the mirror's pixel mask) and the environment captured at a point (a panoramic equirectangular
camera, the mirror hidden) -- one pixel grid, the user's scene put back on exit (blender.state.SavedState).
"""
import math
import time

import bpy
import numpy as np

from ...blender import compat, render
from ...blender.state import SavedState
from ...core import camera as cam
from ...core.errors import InputError

#: Pixel filter width of every lab render: each sample through the pixel (texel) centre.
FILTER_WIDTH = 0.01
#: Glossy and total bounces of the reference: enough for a bowl that reflects itself a few times.
BOUNCES = 16
PASS_INDEX = 7


def _mirror_material():
    mat = bpy.data.materials.new("IL Lab Mirror")
    compat.ensure_use_nodes(mat)
    nt = mat.node_tree
    nt.nodes.clear()
    g = nt.nodes.new("ShaderNodeBsdfGlossy")
    g.inputs["Roughness"].default_value = 0.0
    g.inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    nt.links.new(g.outputs[0], out.inputs["Surface"])
    return mat


class ReflectionFrame:
    """``with ReflectionFrame(scene, obj, resolution, samples) as f:`` -- f.reference(), f.capture(point, h)."""

    def __init__(self, scene, obj, resolution=64, samples=1):
        if scene.camera is None:
            raise InputError(f"scene '{scene.name}' has no camera")
        if obj.type != "MESH":
            raise InputError(f"'{obj.name}' is a {obj.type.lower()}, not a mesh: the mirror must be a mesh")
        self.scene, self.obj = scene, obj
        self.samples = int(samples)
        r = scene.render
        self.width = int(resolution)
        self.height = max(1, round(resolution * r.resolution_y / r.resolution_x))
        self._made = []

    def __enter__(self):
        sc, obj, vl = self.scene, self.obj, self.scene.view_layers[0]
        settings = render.settings(sc) + render.output_settings(sc) + [
            (sc.render, a) for a in ("resolution_x", "resolution_y", "resolution_percentage")] + [
            (sc, "camera"), (obj, "pass_index"), (obj, "visible_camera"), (vl, "use_pass_normal"),
            (vl, "use_pass_object_index")] + [
            (sc.cycles, a) for a in ("max_bounces", "glossy_bounces", "transparent_max_bounces")]
        self._state = SavedState(sc, objects=[obj], settings=settings)
        self._state.__enter__()
        self.camera = sc.camera
        mat = _mirror_material()
        self._made.append(mat)
        if len(obj.material_slots) == 0:
            obj.data.materials.append(None)
        for slot in obj.material_slots:
            slot.material = mat
        obj.pass_index = PASS_INDEX
        render.cycles_cpu(sc, self.samples, pixel_filter=FILTER_WIDTH)
        sc.cycles.max_bounces = sc.cycles.glossy_bounces = BOUNCES
        sc.cycles.transparent_max_bounces = BOUNCES
        return self

    def __exit__(self, *exc):
        try:
            self._state.__exit__(*exc)
        finally:
            for idb in self._made:
                coll = bpy.data.objects if isinstance(idb, bpy.types.Object) else (
                    bpy.data.cameras if isinstance(idb, bpy.types.Camera) else bpy.data.materials)
                coll.remove(idb)
            self._made = []
        return False

    def _render(self, camera, width, height):
        sc = self.scene
        sc.camera = camera
        sc.render.resolution_x, sc.render.resolution_y, sc.render.resolution_percentage = width, height, 100
        return render.render_layers(sc)

    def reference(self):
        """Cycles' mirror; sets ``mask`` (the mirror's pixels), ``normal``, ``dirs`` (camera rays); returns
        (RGB radiance (H, W, 3), seconds)."""
        vl = self.scene.view_layers[0]
        vl.use_pass_normal = vl.use_pass_object_index = True
        self.obj.visible_camera = True
        t = time.perf_counter()
        p = self._render(self.camera, self.width, self.height)
        seconds = time.perf_counter() - t
        n = np.asarray(p["Normal"][..., :3], np.float64)
        self.normal = n / np.maximum(np.linalg.norm(n, axis=-1, keepdims=True), 1e-12)
        index = p.get("IndexOB", p.get("Object Index"))      # the pass name in 4.5 and in 5.x
        self.mask = np.rint(np.asarray(index, np.float64)) == PASS_INDEX
        w2v, proj, _, _ = render.camera_matrices(self.scene, self.camera)
        _, self.dirs = cam.pixel_rays(w2v, proj, self.width, self.height)
        return np.asarray(p["Combined"][..., :3], np.float64), seconds

    def capture(self, point, height):
        """The scene seen from ``point`` without the mirror: lat-long (height, 2 height, 3) laid out as
        Blender's Environment Texture (core.envmap.latlong), each texel one ray through its centre."""
        data = bpy.data.cameras.new("IL Capture")
        self._made.append(data)
        data.type = "PANO"
        for owner in (data, getattr(data, "cycles", None)):
            if owner is not None and hasattr(owner, "panorama_type"):
                owner.panorama_type = "EQUIRECTANGULAR"
        data.clip_start = 1e-4
        obj = bpy.data.objects.new("IL Capture", data)
        self._made.insert(0, obj)
        obj.location = tuple(float(c) for c in point)
        obj.rotation_euler = (math.pi / 2, 0.0, -math.pi / 2)     # looks along +X, +Z up: Blender's lat-long
        self.scene.collection.objects.link(obj)
        vl = self.scene.view_layers[0]
        vl.use_pass_normal = vl.use_pass_object_index = False
        self.obj.visible_camera = False
        t = time.perf_counter()
        p = self._render(obj, 2 * int(height), int(height))
        self.obj.visible_camera = True
        return np.asarray(p["Combined"][..., :3], np.float64), time.perf_counter() - t
