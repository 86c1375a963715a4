"""The one Cycles setup (CPU, fixed samples and seed, no denoising, pixel filter), EEVEE's, and renders handed
to numpy (through a temporary multilayer EXR, the scene's output settings left as they were)."""
import os
import tempfile

import bpy
import numpy as np

from . import compat, interrupt
from .state import SavedState
from ..core.io import exr
from ..core.errors import ILError


def use_cycles_cpu(scene):
    """Cycles on the CPU: the engine and device every tool renders and bakes with (a new scene's default)."""
    scene.render.engine = compat.CYCLES
    scene.cycles.device = "CPU"


def cycles_cpu(scene, samples, seed=0, adaptive=False, pixel_filter=None, clamp=None):
    """The reproducible Cycles setup of every render and bake: CPU, ``samples`` per pixel, a fixed ``seed``
    (not animated), no denoising, adaptive sampling only with ``adaptive``.

    ``pixel_filter``: pixel filter width in pixels (0.01: every sample through the pixel centre, no jitter);
    ``clamp``: direct and indirect sample clamp (0: none, unbiased). None leaves the scene's value.
    """
    use_cycles_cpu(scene)
    cy = scene.cycles
    cy.samples = int(samples)
    cy.seed = int(seed)
    if hasattr(cy, "use_animated_seed"):
        cy.use_animated_seed = False
    cy.use_adaptive_sampling = bool(adaptive)
    cy.use_denoising = False
    if pixel_filter is not None:
        cy.filter_width = float(pixel_filter)
    if clamp is not None:
        cy.sample_clamp_direct = cy.sample_clamp_indirect = float(clamp)


def eevee(scene, samples, pixel_filter):
    """EEVEE with ``samples`` render samples and a ``pixel_filter`` pixels wide filter (<= 0.01: no jitter)."""
    scene.render.engine = compat.EEVEE
    scene.eevee.taa_render_samples = int(samples)
    scene.render.filter_size = float(pixel_filter)


def settings(scene):
    """(owner, attribute) of every setting :func:`cycles_cpu` and :func:`eevee` write, to save them (blender.state)."""
    cy = scene.cycles
    return ([(scene.render, "engine"), (scene.render, "filter_size"), (scene.eevee, "taa_render_samples")]
            + [(cy, a) for a in ("device", "samples", "seed", "use_animated_seed", "use_adaptive_sampling",
                                 "use_denoising", "filter_width", "sample_clamp_direct", "sample_clamp_indirect")
               if hasattr(cy, a)])


def output_settings(scene):
    """(owner, attribute) of the output path and image format :func:`render_layers` sets for its render."""
    r, im = scene.render, scene.render.image_settings
    return ([(r, "filepath"), (r, "use_file_extension")] + ([(im, "media_type")] if hasattr(im, "media_type") else [])
            + [(im, "file_format"), (im, "color_mode"), (im, "color_depth"), (im, "exr_codec")])


def render_layers(scene, camera=None):
    """Render ``scene`` (all enabled passes of its active view layer); return ``{pass: array}``.

    Each array is (H, W) or (H, W, C) with row 0 at the top. Pass names are
    Blender's ("Combined", "Depth", "Normal", "AO", ...); channels are
    R, G, B, A / X, Y, Z / V as Blender writes them.
    """
    if camera is not None:
        scene.camera = camera
    if scene.camera is None:
        raise ILError(f"scene '{scene.name}' has no camera")
    r = scene.render
    had_result = _render_results()
    with tempfile.TemporaryDirectory(prefix="il_render_") as tmp:
        path = os.path.join(tmp, "passes.exr")
        try:
            with SavedState(scene, settings=output_settings(scene)):
                compat.set_multilayer_exr(r.image_settings)
                r.filepath = path
                r.use_file_extension = False
                scene.view_layers[0].update()  # drivers of a scene that is not the window's are stale otherwise
                with interrupt.blender_call():
                    bpy.ops.render.render(write_still=True, scene=scene.name)
        finally:
            if not had_result:
                for image in _render_results():
                    bpy.data.images.remove(image)
        if not os.path.exists(path):
            raise ILError("the render wrote no image")
        parts = exr.read_multipart(path)
    return _group_passes(parts, scene.view_layers[0].name if len(scene.view_layers) == 1 else None)


def _render_results():
    """The file's "Render Result" images (a render adds one when there is none; the user's one stays)."""
    return [im for im in bpy.data.images if im.type == "RENDER_RESULT"]


def _group_passes(parts, layer):
    """``{"ViewLayer.Normal.X": a, ...}`` -> ``{"Normal": (H, W, 3)}``, channel order as Blender's."""
    order = "RGBAXYZVUW"
    grouped = {}
    for channels in parts.values():
        for name, a in channels.items():
            bits = name.split(".")
            pass_name = bits[-2] if len(bits) >= 2 else "Combined"
            grouped.setdefault(pass_name, {})[bits[-1]] = a
    out = {}
    for pass_name, chans in grouped.items():
        keys = sorted(chans, key=lambda k: order.index(k) if k in order else len(order))
        stack = np.stack([chans[k] for k in keys], axis=-1)
        out[pass_name] = stack[..., 0] if stack.shape[-1] == 1 else stack
    return out


def camera_matrices(scene, camera=None):
    """``(world_to_view, proj, width, height)`` of the scene camera as numpy arrays (see core.camera)."""
    cam = camera or scene.camera
    if cam is None:
        raise ILError(f"scene '{scene.name}' has no camera")
    r = scene.render
    width = int(r.resolution_x * r.resolution_percentage / 100)
    height = int(r.resolution_y * r.resolution_percentage / 100)
    view_layer = scene.view_layers[0]
    view_layer.update()
    depsgraph = view_layer.depsgraph
    proj = cam.calc_matrix_camera(depsgraph, x=width, y=height,
                                  scale_x=r.pixel_aspect_x, scale_y=r.pixel_aspect_y)
    world_to_view = np.array(cam.matrix_world.inverted(), dtype=np.float64)
    return world_to_view, np.array(proj, dtype=np.float64), width, height


class _DepsgraphReader(bpy.types.RenderEngine):
    """A render engine that draws nothing: it hands the render-mode depsgraph to ``call``."""
    bl_idname = "IL_DEPSGRAPH_READER"
    bl_label = "Illumination Lab depsgraph reader"
    call = None
    outcome = None

    def render(self, depsgraph):
        cls = type(self)
        try:
            cls.outcome = (True, cls.call(depsgraph))
        except BaseException as e:           # noqa: BLE001 - Blender would print and swallow it
            cls.outcome = (False, e)


def with_render_depsgraph(scene, call):
    """``call(depsgraph)`` on ``scene``'s render-mode depsgraph -- what a final render evaluates: modifiers'
    render settings (a Subdivision's render levels), render visibility of objects, collections and
    instancers -- and its result. The viewport's depsgraph (``view_layer.depsgraph``) evaluates the
    viewport settings instead. A 4x4 render with a stand-in engine (registered only meanwhile); the
    scene's engine and resolution are put back."""
    r = scene.render
    if scene.camera is None:
        raise ILError(f"scene '{scene.name}' has no camera")
    cls = _DepsgraphReader
    registered = "bl_rna" in cls.__dict__
    if not registered:
        bpy.utils.register_class(cls)
    cls.call, cls.outcome = call, None
    had_result = _render_results()
    try:
        with SavedState(scene, settings=[(r, "engine"), (r, "resolution_x"), (r, "resolution_y"),
                                         (r, "resolution_percentage")]):
            r.engine = cls.bl_idname
            r.resolution_x = r.resolution_y = 4
            r.resolution_percentage = 100
            scene.view_layers[0].update()
            with interrupt.blender_call():
                bpy.ops.render.render(scene=scene.name)
    finally:
        cls.call = None
        if not had_result:
            for image in _render_results():
                bpy.data.images.remove(image)
        if not registered:
            bpy.utils.unregister_class(cls)
    if cls.outcome is None:
        raise ILError(f"scene '{scene.name}' could not be evaluated for rendering")
    ok, value = cls.outcome
    cls.outcome = None
    if not ok:
        raise value
    return value
