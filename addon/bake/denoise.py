"""Blender's own denoiser (OpenImageDenoise through the compositor's Denoise node) on a baked map.

The map goes in as an image, a throw-away scene composites it (no 3D render: the
compositor has no Render Layers node) and writes a float EXR that is read back.
"""
import os
import tempfile

import bpy
import numpy as np

from ..blender import compat, interrupt
from ..core.io import exr
from ..core.errors import ILError


def denoise(values):
    """Denoise (H, W) or (H, W, 3) float values (row 0 at the bottom, Blender's order); same shape back."""
    a = np.asarray(values, np.float32)
    grey = a.ndim == 2
    rgb = np.repeat(a[..., None], 3, axis=2) if grey else a[..., :3]
    h, w = rgb.shape[:2]
    px = np.ones((h, w, 4), np.float32)
    px[..., :3] = rgb
    img = bpy.data.images.new("IL denoise input", w, h, float_buffer=True, alpha=True)
    scene = bpy.data.scenes.new("IL denoise")
    images_before = set(bpy.data.images)
    tree = None
    try:
        img.pixels.foreach_set(px.ravel())
        r = scene.render
        r.resolution_x, r.resolution_y, r.resolution_percentage = w, h, 100
        r.engine = compat.CYCLES
        r.use_compositing, r.use_sequencer = True, False
        scene.view_settings.view_transform = "Standard"
        scene.view_settings.look = "None"
        tree, out = compat.new_compositor(scene)
        node_in = tree.nodes.new("CompositorNodeImage")
        node_in.image = img
        node = tree.nodes.new("CompositorNodeDenoise")
        tree.links.new(node_in.outputs["Image"], node.inputs["Image"])
        tree.links.new(node.outputs["Image"], out)
        compat.set_single_exr(r.image_settings)
        r.image_settings.color_mode = "RGB"
        with tempfile.TemporaryDirectory(prefix="il_denoise_") as tmp:
            path = os.path.join(tmp, "denoised.exr")
            r.filepath, r.use_file_extension = path, False
            with interrupt.blender_call():
                bpy.ops.render.render(write_still=True, scene=scene.name)
            if not os.path.exists(path):
                raise ILError("the denoiser wrote no image")
            channels, _ = exr.read_exr(path)
    finally:
        if tree is not None:
            compat.remove_compositor(scene, tree)
        bpy.data.scenes.remove(scene)
        bpy.data.images.remove(img)
        for extra in set(bpy.data.images) - images_before:     # "Render Result", 4.5's "Viewer Node"
            bpy.data.images.remove(extra)
    out = np.flipud(np.stack([channels[c] for c in "RGB"], axis=-1))
    return out.mean(axis=2) if grey else out
