"""One map of one object group through Cycles: the scene set up for bakes, the ``object.bake`` call, reading
its image or colour attribute back, and the bake of a map (calls, passes, estimate, denoising)."""
import contextlib
import dataclasses
import time

import bpy
import numpy as np

from ..blender import compat, interrupt, render, scene as sc
from ..blender.state import rna_settings, world_settings
from ..core import errors
from ..core.errors import ILError, InputError
from . import orientation, uv as uvmod, uvchecks
from .kinds import KINDS
from .materials import show_bake
from .passes import (ESTIMATES, BakeResult, PassSum, bake_to_error, denoised, estimated, fixed_calls,
                     sample_passes, warn_capped)
from .plan import speed


def bake_settings(scene):
    """What a bake may change besides its objects, saved and put back by SavedState: the Cycles setup, every
    bounce limit, the bake settings, the world and its AO distance."""
    cy = scene.cycles
    bounces = [(cy, a) for a in ("max_bounces", "diffuse_bounces", "glossy_bounces", "transmission_bounces",
                                 "volume_bounces", "transparent_max_bounces", "sample_offset") if hasattr(cy, a)]
    return render.settings(scene) + bounces + rna_settings(scene.render.bake) + world_settings(scene)


RENDER_VARIANTS = {"SUBSURF": (("levels", "render_levels"),), "MULTIRES": (("levels", "render_levels"),),
                   "SCREW": (("steps", "render_steps"),), "OCEAN": (("viewport_resolution", "resolution"),)}
"""Modifier settings (viewport, render) whose viewport value Blender's evaluation of the scene uses and whose render
value a render, and every Cycles bake (it evaluates the scene in its own render depsgraph), uses."""


def render_variants(scene, objects):
    """[(owner, viewport setting, the render value)] where the viewport's evaluation of ``objects`` differs from a
    render's: an object, or a collection of the scene holding one, disabled in viewports (the monitor icon: Blender
    leaves it out of the viewport's evaluation, modifiers unapplied) but rendered, a modifier on for one and not the
    other, the :data:`RENDER_VARIANTS` of a modifier, the scene's Simplify cap of subdivision levels.
    :func:`evaluate_as_render` sets them (SavedState saves the settings first)."""
    out = [(o, "hide_viewport", False) for o in objects if o.hide_viewport and not o.hide_render]
    disabled = [c for c in scene.collection.children_recursive if c.hide_viewport and not c.hide_render]
    if disabled:
        held = {o.as_pointer() for o in objects}
        out += [(c, "hide_viewport", False) for c in disabled if any(o.as_pointer() in held for o in c.all_objects)]
    for o in objects:
        for mod in o.modifiers:
            if mod.show_viewport != mod.show_render:
                out.append((mod, "show_viewport", mod.show_render))
            for view, rendered in RENDER_VARIANTS.get(mod.type, ()):
                if getattr(mod, view) != getattr(mod, rendered):
                    out.append((mod, view, getattr(mod, rendered)))
    r = scene.render
    if r.use_simplify and r.simplify_subdivision != r.simplify_subdivision_render:
        out.append((r, "simplify_subdivision", r.simplify_subdivision_render))
    return out


def evaluate_as_render(scene, variants):
    """Give the viewport's evaluation the render's ``variants`` (:func:`render_variants`) for the bake: the checks,
    seams and the batch's joined mesh then read the meshes Cycles bakes (a default Subdivision Surface is 1 level in
    the viewport and 2 in renders)."""
    for owner, attr, value in variants:
        setattr(owner, attr, value)
    if variants:
        scene.view_layers[0].update()


def setup_render(scene, options, state):
    """Cycles on the CPU (each bake call sets the rest, :func:`_bake_once`), the AO distance; a black world if none."""
    render.use_cycles_cpu(scene)
    state.world(sc.black_world).light_settings.distance = float(options.ao_distance)


@contextlib.contextmanager
def world_for(scene, kind):
    """The world as the bakes of ``kind`` need it: a kind no light shades (AO, ``Kind.lit`` False) never samples
    the world, so its importance map, which Cycles builds at every call (21 s of a 64² atlas's AO call under the
    corpus's 64x32 environment texture, 0.6 s without), is turned off for them (the same pixels, bit for bit)."""
    world = scene.world
    if KINDS[kind].lit or world is None or not hasattr(world, "cycles"):
        yield
        return
    before = world.cycles.sampling_method
    world.cycles.sampling_method = "NONE"
    try:
        yield
    finally:
        world.cycles.sampling_method = before


def show(objects, state):
    """Hidden objects are baked: shown in the viewport for the bake (Cycles ignores viewport hiding); objects
    hidden for render are shown to Cycles only while their own map bakes (:func:`_bake_once`), so they
    occlude and light themselves but no other object, as in a render without them."""
    vl = state.scene.view_layers[0]
    state.render_hidden = [o for o in objects if o.hide_render]
    for o in objects:
        state.unhide(o)
    if state.render_hidden:
        errors.warn("baked although hidden for render: " + ", ".join(o.name for o in state.render_hidden)
                    + " (each is shown to Cycles only for its own map: it occludes itself, and other objects' "
                    "maps are baked without it, as a render sees them)")
    return vl


def flip_inside_out(scene, objects, flips, state):
    """Flip the normals of the inside-out meshes found by :func:`validate` for the bake (with a warning), and
    check that the evaluated meshes now face out (a modifier may depend on the side the normals face)."""
    if not flips:
        return
    for mesh in dict.fromkeys(flips.values()):
        state.flip_normals(mesh)
    uvmod.geometry_changed(flips.values())
    scene.view_layers[0].update()
    for o in objects:
        if o.name in flips and orientation.empty_inward_shells(scene, o)[0] > 0:
            raise InputError(f"'{o.name}': its normals point into a closed, empty surface and flipping them does "
                             f"not turn its evaluated mesh outward (a modifier depends on them): {orientation.FIX}")
    errors.warn(orientation.describe(list(flips)))


def bake_map(scene, group, kind, options, layers, size, image_nodes, state):
    """Bake one map of one object group (UVs and materials in place); return a :class:`BakeResult`.

    Samples and the error estimate (``ESTIMATES``), per mode:
    - target_error: pilot pairs and a final pair (:func:`bake_to_error`), error measured;
    - a kind baked in ``halves`` (irradiance), N >= 2 samples: two independent half bakes, error measured from
      their difference (E is not a binary quantity: there is no a-priori bound);
    - otherwise one N-sample bake (Cycles' stratified sampler converges faster than two independent halves
      would), error from the kind's ``variance`` (AO: the binomial bound √(mean k_A(1 - k_A)/N), REFERENCE.md §3).
    Denoising (image target) runs last; the estimate then stays that of the map before denoising.
    Each bake is the Cycles calls of :func:`sample_passes` (one call unless it is estimated beyond cost.PASS_SECONDS).
    """
    t0 = time.perf_counter()
    image_target = options.target == "image"
    if KINDS[kind].images_only and not image_target:
        raise InputError(f"{kind} maps are image maps only (12 channels do not fit a colour attribute): use the "
                         f"image target")
    for o in state.render_hidden:               # hidden for render: seen by Cycles only for its own map
        if o.hide_render != (o not in group):
            o.hide_render = o not in group
    image = None
    if image_target:
        image = state.track(bpy.data.images, bpy.data.images.new(f"IL {kind}", size[0], size[1],
                                                                 float_buffer=True, alpha=True))
        for tex in image_nodes:
            tex.image = image
    else:
        for o in group:
            me = o.data
            name = KINDS[kind].attribute
            if name not in me.color_attributes:
                me.color_attributes.new(name, "FLOAT_COLOR", "POINT")
                state.created_attribute(me, name)
            me.color_attributes.active_color_name = name
    uv_name = layers.get(group[0].name) if image_target else None
    inside = centre_texels(group, layers, size) if image_target else None
    texels = size[0] * size[1] if image_target else sum(len(o.data.loops) for o in group)
    once = _Bake(scene, group, kind, options, image, uv_name, inside, texels, speed(scene, options))

    pilot, capped = 0, False
    if options.target_error is not None:
        values, mask, n, pilot, err = bake_to_error(once, options)
        estimate = ESTIMATES["pilots"]
        capped = warn_capped(group, kind, n, err, options)
    else:
        parts = [once(m, seed) for m, seed in fixed_calls(kind, options)]
        values, mask, n, err, estimate = estimated(kind, options, parts)
    if image is not None:
        bpy.data.images.remove(image)           # one map's image at a time (memory, cost.BYTES_PER_TEXEL)
    if image_target and options.denoise:
        values, estimate = denoised(values, mask, kind, estimate)
    return BakeResult(values, mask, n, time.perf_counter() - t0, err, estimate, pilot, once.cycles_seconds, capped)


@dataclasses.dataclass
class _Bake:
    """``once(samples, seed) -> (values, mask)``: one bake of a map of ``group`` in the Cycles calls of
    :func:`sample_passes`, summed by :class:`PassSum`; ``cycles_seconds`` adds up the time inside the calls."""
    scene: object
    group: list
    kind: str
    options: object
    image: object
    uv_name: str
    inside: object
    texels: int
    pace: object
    cycles_seconds: float = 0.0

    def __call__(self, samples, seed):
        total = PassSum(samples)
        for n, s in sample_passes(self.kind, samples, seed, self.texels, self.pace):
            values, mask, seconds = _bake_once(self.scene, self.group, self.kind, n, s, self.image, self.uv_name,
                                               self.options, self.inside)
            self.cycles_seconds += seconds
            total.add(values, mask, n)
        return total.result()


def _set_bounces(cy, kind, options):
    """The kind's bounces (:meth:`Kind.cycles_bounces`): AO needs the first hit only, no bounces (same k_A,
    measured, and much cheaper); irradiance: the chosen number of diffuse bounces."""
    diffuse, total = KINDS[kind].cycles_bounces(options)
    if cy.diffuse_bounces != diffuse:
        cy.diffuse_bounces = diffuse
    if cy.max_bounces != total:
        cy.max_bounces = total


def _bake_once(scene, group, kind, samples, seed, image, uv_name, options, inside=None):
    """One Cycles bake call; returns (values, mask, seconds inside the call) with the kind's scale applied
    (E multiplied by π; an image's mask within ``inside``, see :func:`read_image`)."""
    if image is not None:
        read, seconds = bake_images(scene, group, kind, samples, seed, uv_name, options, {"": image}, {"": inside})
        return read[""] + (seconds,)
    seconds = call_bake(scene, group, kind, samples, seed, None, options)
    record = KINDS[kind]
    values = {}
    for o in group:
        attr = o.data.color_attributes[record.attribute]
        c = np.zeros(len(attr.data) * 4, np.float32)
        attr.data.foreach_get("color", c)
        values[o.name] = record.read(c.reshape(-1, 4))
    return values, None, seconds


def bake_images(scene, objects, kind, samples, seed, uv_name, options, images, inside):
    """One bake of ``samples`` at ``seed`` of the objects into ``images`` {name: image} (their materials' active
    image nodes), masks within ``inside`` {name: mask or None}: one Cycles call, or for a kind of several
    ``bakes`` each call in turn (:func:`materials.show_bake` sets the materials for it) and the kind's
    ``combine`` of their values. Returns ({name: (values, mask)}, seconds inside the calls)."""
    record = KINDS[kind]
    parts, seconds = {name: [] for name in images}, 0.0
    for bake in record.bakes or (None,):
        if bake is not None:
            show_bake(objects, bake)
        for image in images.values():
            image.pixels.foreach_set(np.zeros(image.size[0] * image.size[1] * 4, np.float32))
        seconds += call_bake(scene, objects, kind, samples, seed, uv_name, options, bake)
        for name, image in images.items():
            parts[name].append(read_image(image, kind, inside[name], bake))
    if not record.bakes:
        return {name: p[0] for name, p in parts.items()}, seconds
    out = {}
    for name, p in parts.items():
        mask = p[0][1]
        values = record.combine([v for v, _ in p])
        values[~mask] = 0.0
        out[name] = values, mask
    return out, seconds


def call_bake(scene, group, kind, samples, seed, uv_name, options, bake=None):
    """One ``object.bake`` of the objects ``group`` (into their active image nodes with ``uv_name``, else into
    their active colour attributes), of type and pass filter of ``bake`` (one of the kind's ``bakes``) or of the
    kind; returns the seconds inside the call.

    Cycles: ``samples`` and ``seed``, no denoising, adaptive sampling or sample clamping (Blender clamps
    indirect light at 10 by default: a biased E where light is trapped, e.g. under a lamp near a ceiling)."""
    render.cycles_cpu(scene, samples, seed, clamp=0.0)
    _set_bounces(scene.cycles, kind, options)
    vl = scene.view_layers[0]
    for o in filter(None, vl.objects):
        want = o in group
        if o.select_get(view_layer=vl) != want:
            o.select_set(want, view_layer=vl)
    vl.objects.active = group[0]
    kwargs = dict(margin=0, use_clear=False, use_selected_to_active=False, save_mode="INTERNAL",
                  target="IMAGE_TEXTURES" if uv_name is not None else "VERTEX_COLORS")
    if uv_name is not None:
        kwargs["uv_layer"] = uv_name
    kwargs["type"] = KINDS[kind].bake_type if bake is None else bake.bake_type
    pass_filter = KINDS[kind].cycles_pass_filter(options, bake)
    if pass_filter is not None:
        kwargs["pass_filter"] = pass_filter
    ctx = dict(scene=scene, view_layer=vl, active_object=group[0], object=group[0],
               selected_objects=list(group), selected_editable_objects=list(group))
    t = time.perf_counter()
    try:
        with interrupt.blender_call(), bpy.context.temp_override(**ctx):
            result = bpy.ops.object.bake(**kwargs)
    except RuntimeError as e:
        raise ILError(f"Cycles bake failed: {str(e).strip().splitlines()[-1]}") from e
    seconds = time.perf_counter() - t
    if "FINISHED" not in result:
        lost = [o.name for o in group
                if uv_name is not None and uv_name not in o.evaluated_get(vl.depsgraph).data.uv_layers]
        if lost:
            raise InputError(f"{', '.join(repr(n) for n in lost)}: the evaluated mesh has no UV layer '{uv_name}' (a "
                             f"modifier, e.g. Geometry Nodes, makes a new mesh without it): apply the modifier, or "
                             f"keep the layer in its node tree")
        raise ILError(f"Cycles bake did not finish ({', '.join(result)})")
    return seconds


def read_image(image, kind, inside=None, bake=None):
    """(values, covered mask) of a baked image (the kind's scale applied: E multiplied by π; or as ``bake``, one of
    the kind's ``bakes``, reads it): the texels Cycles baked, within the mask
    ``inside`` when given (:func:`centre_texels`); values 0 elsewhere."""
    w, h = image.size
    px = np.zeros(w * h * 4, np.float32)
    image.pixels.foreach_get(px)
    px = px.reshape(h, w, 4)
    mask = px[..., 3] > 0.5
    values = (KINDS[kind] if bake is None else bake).read(px)
    if inside is not None:
        mask &= inside
        values[~mask] = 0.0
    return values.astype(np.float32), mask


def centre_texels(group, layers, size):
    """Where Cycles also bakes texels a UV triangle only touches (``compat.BAKE_TOUCHED_TEXELS``): the (H, W)
    mask of texels whose centre lies inside one of the group's UV triangles, the texels a map holds everywhere
    (coverage, margins and dilation are measured on them; a touched texel between two charts holds whichever
    chart Cycles rasterised last). None where Cycles bakes those texels only."""
    if not compat.BAKE_TOUCHED_TEXELS:
        return None
    w, h = size
    inside = np.zeros((h, w), bool)
    for o in group:
        inside |= uvchecks.coverage(uvmod.triangles_uv(o, layers[o.name]), w, h)
    return inside
