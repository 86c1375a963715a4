"""The bpy side of the shadow lab: a private render scene, the ray-traced reference, light-view
depth maps, EEVEE and Workbench masks, and the occluders' triangles -- all on one pixel grid.

The user's scene is never rendered or edited directly: a temporary scene links the objects its
render draws (blender.scene.rendered_objects: not hidden for render, not in an excluded or
render-disabled collection; minus every other light; instancers bring their instances), gets its
own camera settings, passes and a white diffuse material override, and is removed afterwards. The
light's own settings (LIGHT_SETTINGS) are set for the lab and put back on exit by
blender.state.SavedState, also after an error.
"""
import contextlib
import math
import time

import bpy
import numpy as np
from mathutils import Vector

from ...blender import compat
from ...core import camera as cam
from ...core.shadow import metrics
from ...core.shadow import depth_map
from ...core.errors import ILError, InputError
from ...blender import materials, render, scene as sc
from ...blender.state import SavedState

#: The light's settings the lab changes (radius 0, no blend, shadows on, no EEVEE jitter), put back on exit.
LIGHT_SETTINGS = ("shadow_soft_size", "angle", "spot_blend", "use_shadow", "use_shadow_jitter")
#: Where a shadow map's depth comes from (ShadowFrame.depth_maps; core.shadow.depth_map.DEPTH_SOURCES).
DEPTH_SOURCES = depth_map.DEPTH_SOURCES
#: Pixel filter width of every lab render (pixels): every sample through the pixel centre.
FILTER_WIDTH = 0.01

#: Object types Cycles renders as a surface that Blender evaluates to a mesh (triangulated for the
#: planar and volume methods); other renderable types are listed as skipped.
SURFACE_TYPES = {"MESH", "CURVE", "SURFACE", "FONT", "META"}
#: Object types that draw nothing in a render (never listed as skipped).
NOT_RENDERED = {"LIGHT", "CAMERA", "EMPTY", "SPEAKER", "LIGHT_PROBE", "LATTICE", "ARMATURE"}


class LightInfo:
    """The light under test as numbers: kind, position, direction, homogeneous form, E⊥."""

    def __init__(self, obj):
        if obj.type != "LIGHT":
            raise InputError(f"'{obj.name}' is not a light")
        kind = obj.data.type
        if kind not in {"SUN", "POINT", "SPOT"}:
            raise InputError(f"light '{obj.name}' is an {kind.lower()} light: the shadow lab compares hard "
                             "shadows of point, spot and sun lights (add one, or change its type)")
        self.obj, self.kind = obj, kind
        m = obj.matrix_world
        self.position = np.array(m.translation, np.float64)
        d = np.array(m.to_3x3() @ Vector((0.0, 0.0, -1.0)), np.float64)
        self.direction = d / np.linalg.norm(d)
        self.h = np.append(-self.direction, 0.0) if kind == "SUN" else np.append(self.position, 1.0)
        self.spot_cos = math.cos(obj.data.spot_size / 2) if kind == "SPOT" else None
        self.colour = float(np.mean(obj.data.color))
        self.energy = float(obj.data.energy)
        if not (self.energy > 0 and self.colour > 0 and math.isfinite(self.energy * self.colour)):
            unit = "W/m²" if kind == "SUN" else "W"
            raise InputError(f"light '{obj.name}' gives no light ({self.energy:g} {unit}, colour "
                             f"{tuple(round(c, 3) for c in obj.data.color)}): the reference would be all shadow; "
                             "give it a positive power and colour")

    def to_light(self, points):
        """Unit vectors from points toward the light, and distances (inf for the sun)."""
        p = np.asarray(points, np.float64)
        if self.kind == "SUN":
            return np.broadcast_to(-self.direction, p.shape).copy(), np.full(p.shape[:-1], np.inf)
        v = self.position - p
        dist = np.linalg.norm(v, axis=-1)
        return v / np.maximum(dist, 1e-12)[..., None], dist

    def irradiance_normal(self, points):
        """E⊥ in W/m²: sun strength, or P/(4π d²) for point and spot (REFERENCE.md §1), times colour."""
        _, dist = self.to_light(points)
        if self.kind == "SUN":
            return np.full(dist.shape, self.energy * self.colour)
        return self.energy * self.colour / (4 * math.pi * dist ** 2)

    def reach(self, points, normals):
        """True where the light can reach at all: facing it (n·l > 0) and, for a spot, inside the cone."""
        l, _ = self.to_light(points)
        ok = np.einsum("...i,...i->...", normals, l) > 0
        if self.kind == "SPOT":
            ok &= np.einsum("...i,...i->...", -l, self.direction) > self.spot_cos
        return ok


class ShadowFrame:
    """``with ShadowFrame(scene, "Light", 128) as s:`` -- the reference and every method's inputs."""

    def __init__(self, scene, light_name, resolution=128, samples=1):
        if light_name not in scene.objects:
            lights = sorted(o.name for o in scene.objects if o.type == "LIGHT")
            raise InputError(f"no light named '{light_name}' in scene '{scene.name}' "
                             + (f"(its lights: {', '.join(lights)})" if lights else "(it has no lights)"))
        if scene.camera is None:
            raise InputError(f"scene '{scene.name}' has no camera")
        if resolution < 8 or resolution > depth_map.MAX_RESOLUTION:
            raise InputError(f"resolution must be between 8 and {depth_map.MAX_RESOLUTION}, got {resolution}")
        if samples < 1:
            raise InputError(f"samples must be positive, got {samples}")
        self.user_scene = scene
        scene.view_layers[0].update()
        self.light = LightInfo(scene.objects[light_name])
        self.resolution, self.samples = int(resolution), int(samples)
        rx, ry = scene.render.resolution_x, scene.render.resolution_y
        self.width = self.resolution
        self.height = max(1, round(self.resolution * ry / rx))
        self.surfaces, self.skipped = [], []
        self.tmp = None
        self._made = []
        self._restore = contextlib.ExitStack()

    # -- set-up and tear-down -------------------------------------------------------------
    def __enter__(self):
        try:
            self._open()
        except BaseException:
            self.close()
            raise
        return self

    def __exit__(self, *exc):
        self.close()
        return False

    def _open(self):
        user, data = self.user_scene, self.light.obj.data
        self._restore.enter_context(SavedState(user, settings=[(data, k) for k in LIGHT_SETTINGS if hasattr(data, k)]))
        if data.type in {"POINT", "SPOT"}:
            data.shadow_soft_size = 0.0
        if data.type == "SUN":
            data.angle = 0.0
        if data.type == "SPOT":
            data.spot_blend = 0.0
        data.use_shadow = True
        tmp = bpy.data.scenes.new("IL Shadow Lab")
        self.tmp = tmp
        rendered = sc.rendered_objects(user)
        if self.light.obj not in rendered:
            raise InputError(f"light '{self.light.obj.name}' is not rendered (hidden for render, or in a collection "
                             "excluded from the view layer or disabled in renders)")
        for obj in rendered:
            if obj.type == "LIGHT" and obj != self.light.obj:
                continue
            tmp.collection.objects.link(obj)
        tmp.camera = user.camera
        tmp.render.pixel_aspect_x = user.render.pixel_aspect_x
        tmp.render.pixel_aspect_y = user.render.pixel_aspect_y
        tmp.view_settings.view_transform = "Standard"
        mat = _white_diffuse()
        self._made.append(mat)
        tmp.view_layers[0].material_override = mat
        self.gather_surfaces()
        if not self.surfaces:
            raise InputError(f"scene '{user.name}' has no visible mesh"
                             + (f" (not usable: {', '.join(self.skipped)})" if self.skipped else ""))

    def gather_surfaces(self):
        """Read the private scene's render-mode depsgraph (blender.render.with_render_depsgraph,
        blender.scene.evaluated_surfaces): set and return ``surfaces``, every object and instance of a
        SURFACE_TYPES type with triangles in world space, as Cycles renders them -- the one set of
        triangles the planar, volume and raster shadow-map methods use -- and ``skipped``, what Cycles
        renders that is not triangulated. :meth:`__enter__` calls it once."""
        self.tmp.camera = self.user_scene.camera         # a render needs one; depth_maps leaves none
        self.surfaces, other = render.with_render_depsgraph(
            self.tmp, lambda dg: sc.evaluated_surfaces(dg, SURFACE_TYPES))
        # a metaball's surface lives in its family's basis object
        self.skipped = list(dict.fromkeys(n for n, t in other if t not in NOT_RENDERED and t != "META"))
        return self.surfaces

    def close(self):
        """Remove the private scene (the user's objects stay: they live in the user's scene too), the
        lab's cameras and material, and give the light its settings back (blender.state.SavedState)."""
        if self.tmp is not None:
            sc.remove_scene(self.tmp, self._made)
            self.tmp = None
        self._made = []
        self._restore.close()

    # -- renders ----------------------------------------------------------------------------
    def _render(self, engine, camera, width, height, passes):
        tmp = self.tmp
        tmp.camera = camera
        tmp.render.resolution_x, tmp.render.resolution_y = width, height
        tmp.render.resolution_percentage = 100
        tmp.render.engine = engine
        vl = tmp.view_layers[0]
        for name in ("use_pass_z", "use_pass_position", "use_pass_normal", "use_pass_diffuse_direct"):
            setattr(vl, name, name in passes)
        return render.render_layers(tmp)

    def render_reference(self):
        """Cycles, radius-0 light, ``samples`` samples through pixel centres (filter width 0.01 px).

        Sets ``position``, ``normal``, ``depth``, ``receiver``, ``reach``, the camera rays and
        ``reference`` (the hard ray-traced mask); returns the seconds it took.
        """
        t = time.perf_counter()
        tmp = self.tmp
        render.cycles_cpu(tmp, self.samples, pixel_filter=FILTER_WIDTH)
        tmp.cycles.max_bounces = 0
        p = self._render(compat.CYCLES, self.user_scene.camera, self.width, self.height,
                         {"use_pass_z", "use_pass_position", "use_pass_normal", "use_pass_diffuse_direct"})
        self.depth = np.asarray(p["Depth"], np.float64)
        self.receiver = np.isfinite(self.depth) & (self.depth < 0.5 * cam.SKY_DEPTH)
        self.position = np.asarray(p["Position"][..., :3], np.float64)
        n = np.asarray(p["Normal"][..., :3], np.float64)
        self.normal = n / np.maximum(np.linalg.norm(n, axis=-1, keepdims=True), 1e-12)
        self.to_light, _ = self.light.to_light(self.position)
        self.reach = self.receiver & self.light.reach(self.position, self.normal)
        self.world_to_view, self.proj, _, _ = render.camera_matrices(self.tmp, self.user_scene.camera)
        self.origins, self.dirs = cam.pixel_rays(self.world_to_view, self.proj, self.width, self.height)
        self.near = self.user_scene.camera.data.clip_start
        unshadowed = metrics.unshadowed_diffuse(
            self.normal, self.to_light, self.light.irradiance_normal(self.position))
        direct = _pass(p, compat.DIFFUSE_DIRECT_PASS)
        self.reference = self.reach & metrics.lit_from_pass(direct, unshadowed, self.receiver)
        return time.perf_counter() - t

    def _light_camera(self, name, location, rotation, ortho_scale=None, angle=None, near=1e-3, far=1e4):
        data = bpy.data.cameras.new(name)
        if ortho_scale is not None:
            data.type = "ORTHO"
            data.ortho_scale = ortho_scale
        else:
            data.lens_unit = "FOV"
            data.angle = angle
        data.sensor_fit = "AUTO"
        data.clip_start, data.clip_end = near, far
        obj = bpy.data.objects.new(name, data)
        obj.location = location
        obj.rotation_euler = rotation
        self.tmp.collection.objects.link(obj)
        return obj

    def _scene_radius(self):
        """Centre and radius of the box bounding every surface's vertices."""
        pts = np.concatenate([x.verts for x in self.surfaces])
        lo, hi = pts.min(0), pts.max(0)
        centre = (lo + hi) / 2
        return centre, float(np.linalg.norm(hi - lo) / 2)

    def light_cameras(self):
        """Cameras at the light: a fitted orthographic one (sun), the spot cone, or six cube faces."""
        light = self.light
        rot = light.obj.matrix_world.to_euler()
        if light.kind == "SUN":
            centre, radius = self._scene_radius()
            rot_m = np.array(light.obj.matrix_world.to_3x3().normalized())
            pts = self.position[self.receiver] @ rot_m          # receiver points in the light's frame
            lo, hi = pts.min(0)[:2], pts.max(0)[:2]
            mid = rot_m @ np.array([*(lo + hi) / 2, 0.0])
            mid = mid - rot_m[:, 2] * (rot_m[:, 2] @ mid) + rot_m[:, 2] * (rot_m[:, 2] @ centre)
            loc = mid - self.light.direction * (radius + 1.0)
            scale = float(max(hi - lo)) * 1.02 + 1e-3
            return [self._light_camera("IL Sun Map", loc, rot, ortho_scale=scale, far=2 * radius + 4.0)]
        if light.kind == "SPOT":
            return [self._light_camera("IL Spot Map", light.position, rot, angle=light.obj.data.spot_size)]
        faces = []
        for i, axis in enumerate(((1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1), (0, 0, -1))):
            rot = Vector(axis).to_track_quat("-Z", "Y" if axis[1] == 0 else "Z").to_euler()
            faces.append(self._light_camera(f"IL Cube {i}", light.position, rot, angle=math.pi / 2))
        return faces

    def depth_maps(self, size, source="raster", stats=None):
        """Light-view depth maps of ``size``² texels; returns (maps, seconds).

        ``source`` "raster": the casters' evaluated triangles rasterised in numpy at texel centres
        (core.shadow.depth_map.rasterize); "cycles": Cycles' Depth pass, 1 sample through texel centres
        (also renders what is not triangulated, see ``skipped``). Both use the same light cameras.
        ``stats`` (a dict) gets the rasteriser's counts (core.shadow.raster.rasterize_depth).
        """
        if size < 2 or size > 16384:
            raise InputError(f"--shadowmap-size must be between 2 and 16384, got {size}")
        depth_map.check_source(source)
        t = time.perf_counter()
        maps = []
        cams = self.light_cameras()
        try:
            tmp = self.tmp
            if source == "cycles":
                render.cycles_cpu(tmp, 1, pixel_filter=FILTER_WIDTH)
                tmp.cycles.max_bounces = 0
                hidden = [o for o in tmp.objects if not o.visible_shadow]     # seen by light cameras otherwise
                with SavedState(tmp, settings=[(o, "visible_camera") for o in hidden]):
                    for o in hidden:
                        o.visible_camera = False
                    for c in cams:
                        p = self._render(compat.CYCLES, c, size, size, {"use_pass_z"})
                        w2v, proj, _, _ = render.camera_matrices(tmp, c)
                        maps.append(depth_map.DepthMap(p["Depth"], w2v, proj))
            else:
                tris = self.caster_triangles()
                tmp.render.resolution_x = tmp.render.resolution_y = size
                tmp.render.resolution_percentage = 100
                for c in cams:
                    w2v, proj, _, _ = render.camera_matrices(tmp, c)
                    maps.append(depth_map.rasterize(tris, w2v, proj, size, c.data.clip_start, c.data.clip_end, stats))
        finally:
            for c in cams:
                data = c.data
                bpy.data.objects.remove(c)
                bpy.data.cameras.remove(data)
        return maps, time.perf_counter() - t

    def caster_triangles(self, exclude=None):
        """(T, 3, 3) world-space triangles of every surface that casts shadows (:meth:`gather_surfaces`,
        Surface.casts), without the Surface ``exclude``."""
        parts = [x.verts[x.tris] for x in self.surfaces if x.casts and x is not exclude]
        return np.concatenate(parts) if parts else np.zeros((0, 3, 3))

    def surfaces_named(self, name):
        """The :class:`blender.scene.Surface` copies of the object called ``name``: the object itself and each
        instance of it (a collection instance, an instancer's copy)."""
        return [x for x in self.surfaces if x.obj is not None and x.obj.name == name]

    def engine_mask(self, engine):
        """EEVEE or Workbench's own shadow: (lit mask, seconds) from two renders, shadows on and off.

        A pixel is lit where the shadowed render keeps at least half the unshadowed value. Workbench
        multiplies a pixel outside the stencil shadow by smoothstep(shift, f, n·l) with
        f = 1 - focus (1 - shift) (get_shadow() in Workbench's world-light GLSL): shift 0 and focus 1
        make that a step at n·l = 0, so only the stencil decides (focus 0 would darken every
        surface lit at more than 60° incidence below half and read it as shadow).
        Call after :meth:`render_reference`.
        """
        t = time.perf_counter()
        tmp = self.tmp
        cam_obj = self.user_scene.camera
        if engine == "eevee":
            eng, passes = compat.EEVEE, {"use_pass_diffuse_direct"}
            render.eevee(tmp, 1, pixel_filter=FILTER_WIDTH)
            if hasattr(self.light.obj.data, "use_shadow_jitter"):
                self.light.obj.data.use_shadow_jitter = False
            key = compat.DIFFUSE_DIRECT_PASS
        elif engine == "workbench":
            if self.light.kind != "SUN":
                raise InputError("Workbench draws shadows for one directional light only: use a sun light")
            eng, passes, key = compat.WORKBENCH, set(), "Combined"
            disp = tmp.display
            disp.render_aa = "OFF"
            disp.shading.light = "STUDIO"
            disp.shading.color_type = "SINGLE"
            disp.shading.single_color = (0.8, 0.8, 0.8)
            disp.shading.shadow_intensity = 1.0
            disp.shadow_shift = 0.0
            disp.shadow_focus = 1.0
            disp.light_direction = compat_workbench_direction(self.light.direction)
        else:
            raise InputError(f"unknown engine method '{engine}'")
        vl = tmp.view_layers[0]
        override = vl.material_override
        if engine == "workbench":
            vl.material_override = None     # the override blacks out Workbench's shadow pass
        vals = []
        for shadows in (True, False):
            if engine == "eevee":
                self.light.obj.data.use_shadow = shadows
            else:
                tmp.display.shading.show_shadows = shadows
            p = self._render(eng, cam_obj, self.width, self.height, passes)
            vals.append(np.asarray(_pass(p, key), np.float64)[..., :3].mean(-1))
        self.light.obj.data.use_shadow = True
        vl.material_override = override
        on, off = vals
        if engine == "workbench" and self.reference[self.receiver].any() and not np.any(on[self.receiver] > 0):
            raise ILError("Workbench returned a black image with shadows on where the reference is lit "
                          "(no stencil buffer in this GL context?)")
        lit = self.reach & (off > 0) & (on >= metrics.LIT_FRACTION * off)
        return lit, time.perf_counter() - t


def _pass(passes, name):
    """``passes[name]``, or ILError naming the passes the render did return."""
    if name not in passes:
        raise ILError(f"the render has no {name} pass (got {', '.join(passes)})")
    return passes[name]


def _white_diffuse():
    """A white Lambertian material (Diffuse BSDF, colour 1, roughness 0) for the material override."""
    return materials.white_lambert("IL Shadow Lab White")


def compat_workbench_direction(direction):
    """scene.display.light_direction L for a sun shining along ``direction`` D (world space, unit).

    Workbench swaps L's y and z and negates x and z (ShadowPass::init in workbench_shadow.cc) to
    get the world direction in which it extrudes the volumes, D = (-L.x, L.z, -L.y); inverted,
    L = (-D.x, -D.z, D.y). Checked against the sources of 4.2+ and by the measured error (0 on
    the sphere, stairs and acne scenes; any other sign pattern lights nothing).
    """
    d = np.asarray(direction, np.float64)
    return (float(-d[0]), float(-d[2]), float(d[1]))

