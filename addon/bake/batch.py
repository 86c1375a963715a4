"""Batched bakes: the image maps of many objects in the Cycles calls of one map, through a temporary object
joining their evaluated meshes (one scene sync per call)."""
import dataclasses
import time

import bpy
import numpy as np

from ..blender.scene import attribute, set_attribute
from ..blender.state import remove_ids
from . import cost, cycles, evaluated
from .passes import BakeResult, PassSum, denoised, estimated, fixed_calls, sample_passes
from .plan import speed


BATCH_TEXELS = 1 << 22
"""Most map texels one batched Cycles call bakes: its images live together (4 Mi texels: 64 MiB of float RGBA
images, as much again read back), so a level never holds more than that beyond one map's arrays."""


PROXY = "IL bake batch"


PROXY_UV = "IL bake UV"


_RAY_VISIBILITY = ("visible_camera", "visible_diffuse", "visible_glossy", "visible_transmission",
                   "visible_volume_scatter", "visible_shadow")


def _batch_refusal(obj, layers, state, depsgraph, instanced):
    """Why ``obj`` is baked by its own Cycles call instead of in a batch (:func:`bake_batch`), or None.

    A batch stands a joined copy of the objects' evaluated meshes in for them, so an object is batched only
    when that copy is the same surface to Cycles: positive scale (a mirrored object's winding would flip),
    visible to every ray kind, no holdout or shadow catcher (custom normals are carried: :func:`_joined`),
    its light-map layer in the evaluated mesh, not hidden for render, not part of a collection another
    object instances (hiding it would hide the instances too), and no Geometry Nodes that branch on Is Viewport (the
    joined copy is the viewport's evaluation, with the render's settings: ``cycles.render_variants``)."""
    if obj in state.render_hidden:
        return "hidden for render"
    if obj.matrix_world.determinant() <= 0:
        return "negative scale"
    if not all(getattr(obj, a, True) for a in _RAY_VISIBILITY) or obj.is_holdout or obj.is_shadow_catcher:
        return "ray visibility"
    if obj.name in instanced:
        return "instanced"
    if any(m.type == "NODES" and m.show_render and _is_viewport_in(m.node_group) for m in obj.modifiers):
        return "geometry nodes that branch on Is Viewport"
    if not evaluated.figure(obj, depsgraph, _carries, layers.get(obj.name)):
        return "light-map layer not in the evaluated mesh"
    return None


def _is_viewport_in(tree, seen=None):
    """Node tree ``tree``, or a group it uses, has an Is Viewport node (each tree read once: ``seen``)."""
    seen = set() if seen is None else seen
    if tree is None or tree.name in seen:
        return False
    seen.add(tree.name)
    return any(n.bl_idname == "GeometryNodeIsViewport"
               or (getattr(n, "node_tree", None) is not None and _is_viewport_in(n.node_tree, seen))
               for n in tree.nodes)


def _carries(me, layer):
    """Evaluated mesh ``me`` carries UV layer ``layer``."""
    return layer in me.uv_layers


def _instanced(scene):
    """Names of the objects in a collection some object of the scene instances."""
    members = set()
    for o in scene.objects:
        if o.instance_type == "COLLECTION" and o.instance_collection is not None:
            members.update(x.name for x in o.instance_collection.all_objects)
    return members


def batches(scene, plan, layers, state, options, maps=None):
    """Split the image-target ``plan`` [:class:`plan.Target`] into (batches, singles): batches are lists of
    targets whose maps (of kinds ``maps``, default ``options.maps``) share Cycles calls (one pass plan,
    at most the texels :func:`_pass_plan` allows each, at least one entry),
    singles are baked by their own calls (target error: each map chooses its own samples; vertex target;
    objects :func:`_batch_refusal` refuses)."""
    if options.target != "image" or options.target_error is not None or not options.batch:
        return [], list(plan)
    scene.view_layers[0].update()
    depsgraph = scene.view_layers[0].depsgraph
    instanced = _instanced(scene)
    pace = speed(scene, options)
    batched, singles = [], []
    for target in plan:
        if any(_batch_refusal(o, layers, state, depsgraph, instanced) for o in target.group):
            singles.append(target)
        else:
            batched.append(target)
    if sum(len(target.group) for target in batched) < 2:      # one object: its own call is the same call
        return [], list(plan)
    out, open_ = [], {}
    for target in batched:
        t = target.texels
        plan_, cap = _pass_plan(t, maps or options.maps, options, pace)
        batch = open_.get(plan_)
        if batch is None or batch.texels + t > cap:
            batch = open_[plan_] = _Open()
            out.append(batch.targets)
        batch.targets.append(target)
        batch.texels += t
    return out, singles


@dataclasses.dataclass
class _Open:
    """A batch being filled: its targets and their texels so far."""
    targets: list = dataclasses.field(default_factory=list)
    texels: int = 0


def _pass_plan(texels, maps, options, pace=None):
    """(the samples of every Cycles call of a fixed-sample map of ``texels`` texels, per kind of ``maps``; the most
    texels a batch of such maps may hold: BATCH_TEXELS, and each call within cost.PASS_SECONDS). A batch joins
    maps of one plan only, so each image comes out as its own calls make it. ``pace``: :class:`cost.Speed`."""
    pace = pace or cost.PLAIN
    plan_, cap = [], BATCH_TEXELS
    for kind in maps:
        calls = tuple(n for samples, seed in fixed_calls(kind, options)
                      for n, _ in sample_passes(kind, samples, seed, texels, pace))
        plan_.append((kind, calls))
        cap = min(cap, max(1, int(cost.pass_budget(kind, pace) // (pace.rate(kind) * max(calls)))))
    return tuple(plan_), cap


class _Proxy:
    """A temporary object whose mesh joins the batch's evaluated meshes in world space (modifiers applied),
    one UV layer (each object's light-map layer) and one material slot per object slot, whose material's
    active image node is that object's group image; the objects themselves are hidden for render while it
    stands in for them. Cycles bakes every material's image in one call (one scene sync)."""

    def __init__(self, scene, batch, kind, layers, temporary, images, state):
        self.scene, self.batch, self.kind, self.layers = scene, batch, kind, layers
        self.temporary, self.images, self.state = temporary, images, state
        self.obj, self.hidden = None, []

    def __enter__(self):
        self.scene.view_layers[0].update()       # the light-map UVs written since the last evaluation
        depsgraph = self.scene.view_layers[0].depsgraph
        parts, materials_ = [], []
        for target in self.batch:
            for o in target.group:
                part = evaluated.figure(o, depsgraph, evaluated.Triangles.of, self.layers[o.name])
                part = part.placed(o.matrix_world)
                slots = self.temporary.batch_slots(o, self.kind, target.name, self.images[target.name])
                part.material = len(materials_) + np.clip(part.material, 0, len(slots) - 1)
                materials_ += slots
                parts.append(part)
        mesh = self.state.track(bpy.data.meshes, bpy.data.meshes.new(PROXY))
        _joined(parts, mesh)
        for mat in materials_:
            mesh.materials.append(mat)
        self.obj = self.state.track(bpy.data.objects, bpy.data.objects.new(PROXY, mesh))
        self.scene.collection.objects.link(self.obj)
        for target in self.batch:
            for o in target.group:
                if not o.hide_render:
                    o.hide_render = True
                    self.hidden.append(o)
        return self

    def __exit__(self, *exc):
        for o in self.hidden:
            o.hide_render = False
        if self.obj is not None:
            mesh = self.obj.data
            bpy.data.objects.remove(self.obj)
            bpy.data.meshes.remove(mesh)
            self.scene.view_layers[0].update()
        return False


def _joined(parts, mesh):
    """Fill the empty ``mesh`` with every part (:class:`evaluated.Triangles` in world space; vertices offset, one
    triangle per loop triangle), UVs as PROXY_UV, material indices, flat faces and sharp edges kept, and the custom
    normals of the parts that have them (the others' corners keep the normals Blender makes: zero vectors)."""
    offsets = np.cumsum([0] + [len(p.co) for p in parts])
    co = np.concatenate([p.co for p in parts]) if parts else np.zeros((0, 3), np.float32)
    tris = np.concatenate([p.tris + k for p, k in zip(parts, offsets)]) if parts else np.zeros((0, 3), np.int64)
    sharp = np.concatenate([p.sharp + k for p, k in zip(parts, offsets)]) if parts else np.zeros((0, 2), np.int64)
    t = len(tris)
    mesh.vertices.add(len(co))
    set_attribute(mesh, "position", "FLOAT_VECTOR", "POINT", co.astype(np.float32).ravel())
    mesh.loops.add(3 * t)
    set_attribute(mesh, ".corner_vert", "INT", "CORNER", tris.astype(np.int32).ravel())
    mesh.polygons.add(t)
    mesh.polygons.foreach_set("loop_start", np.arange(0, 3 * t, 3, dtype=np.int32))
    mesh.update(calc_edges=True)
    if not t:
        return
    material = np.concatenate([p.material for p in parts]).astype(np.int32)
    set_attribute(mesh, "material_index", "INT", "FACE", material)
    set_attribute(mesh, "sharp_face", "BOOLEAN", "FACE", ~np.concatenate([p.smooth for p in parts]))
    mesh.uv_layers.new(name=PROXY_UV, do_init=False)
    uv = np.concatenate([p.uv for p in parts]).astype(np.float32).ravel()
    set_attribute(mesh, PROXY_UV, "FLOAT2", "CORNER", uv)
    if len(sharp):
        n = len(co) + 1
        key = lambda e: np.minimum(e[:, 0], e[:, 1]) * n + np.maximum(e[:, 0], e[:, 1])
        edges = attribute(mesh, ".edge_verts", np.int32).reshape(-1, 2).astype(np.int64)
        set_attribute(mesh, "sharp_edge", "BOOLEAN", "EDGE", np.isin(key(edges), key(sharp)))
    if any(len(p.normals) for p in parts):
        normals = [p.normals if len(p.normals) else np.zeros((len(p.tris), 3, 3), np.float32) for p in parts]
        mesh.normals_split_custom_set(np.concatenate(normals).reshape(-1, 3))
    mesh.update()


def bake_batch(scene, batch, kind, options, layers, temporary, state):
    """Bake map ``kind`` of every group of ``batch`` (:class:`plan.Target` of one pass plan,
    :func:`batches`) in the Cycles calls of one map (:func:`fixed_calls`, :func:`sample_passes`) through a
    :class:`_Proxy`;
    return ``{name: BakeResult}``.

    Same texels, samples and seeds as the groups' own calls: Cycles seeds a bake sample by its pixel in its
    image, so each image comes out as its own call makes it (tests/bake/test_bake_level.py). The call's seconds
    are shared among the groups by texels."""
    t0 = time.perf_counter()
    for o in state.render_hidden:               # hidden for render: seen by Cycles only for its own map
        if not o.hide_render:
            o.hide_render = True
    images = {name: state.track(bpy.data.images, bpy.data.images.new(f"IL {kind} {name}", size[0], size[1],
                                                                     float_buffer=True, alpha=True))
              for name, size in ((t.name, t.size) for t in batch)}
    parts = {name: [] for name in images}
    inside = {t.name: cycles.centre_texels(t.group, layers, t.size) for t in batch}
    seconds = 0.0
    try:
        with _Proxy(scene, batch, kind, layers, temporary, images, state) as proxy:
            largest = max(t.texels for t in batch)   # batches() joins maps of one pass plan
            pace = speed(scene, options)
            for samples, seed in fixed_calls(kind, options):
                sums = {name: PassSum(samples) for name in images}
                for n, s in sample_passes(kind, samples, seed, largest, pace):
                    read, t = cycles.bake_images(scene, [proxy.obj], kind, n, s, PROXY_UV, options, images, inside)
                    seconds += t
                    for name in images:
                        sums[name].add(*read[name], n)
                for name in images:
                    parts[name].append(sums[name].result())
    finally:
        remove_ids((bpy.data.images, image) for image in images.values())
    texels = {t.name: t.texels for t in batch}
    total = sum(texels.values())
    elapsed = time.perf_counter() - t0
    results = {}
    for name in list(parts):
        values, mask, n, err, estimate = estimated(kind, options, parts.pop(name))
        if options.denoise:
            values, estimate = denoised(values, mask, kind, estimate)
        share = texels[name] / total
        results[name] = BakeResult(values, mask, n, elapsed * share, err, estimate, 0, seconds * share)
    return results
