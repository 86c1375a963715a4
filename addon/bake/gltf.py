"""Baked light maps in a glTF binary (.glb) written by Blender's own glTF exporter (issue 28, item 2).

:func:`export_glb` writes the scene with ``bpy.ops.export_scene.gltf`` and adds the light-map parts through the
exporter's user-extension hooks (``glTF2ExportUserExtension`` on an add-on entry that exists only during the
call, then removed):

- each baked mesh carries its light-map UV layer (the report's "uv_layer") as ``TEXCOORD_1``: the exporter writes
  every UV layer of a mesh as ``TEXCOORD_<its index>``, so the export runs on a temporary copy of each baked mesh
  whose layers are ordered [the render layer, the light-map layer, the others] (a mesh whose only layer is the
  light-map layer gets a copy of it as ``TEXCOORD_0``);
- AO is the material's ``occlusionTexture`` with ``texCoord: 1``: an 8-bit PNG of k_A (R = G = B, linear), only
  where irradiance is not exported too (unless ``ao_with_irradiance``): a client multiplies the light map's
  indirect diffuse by the occlusion (three.js aomap_fragment), and E already holds the occlusion;
- irradiance is the material extension ``MOZ_lightmap`` {"index", "texCoord": 1, "intensity"}: an 8-bit RGB PNG of
  E / max(E) (linear, not sRGB: the loader must read it as linear data), ``intensity`` = max(E) in W/m², the largest
  channel value of the map; decoded texel / 255 × intensity = E within half a step, intensity / 510;
- a directional (L1 SH) map is the material's ``extras.il_directional`` (:data:`DIRECTIONAL_DECODE`): four 8-bit
  linear PNGs in glTF's Y-up frame, e0 = the constant part of E(n) as E / max with its ``intensity``, and Godot 4.3's
  packed l1 maps, so E(n) = e0 (1 + 4 Σ_m (2 l1_m − 1) n_m) in W/m².

Maps are per object, so each baked object gets temporary copies of its materials (named as the originals in the
glTF); objects without a material get a plain one. Objects of an atlas each carry their part through their own
light-map UVs; texels of one map file are encoded once. Everything temporary (mesh and material copies, the add-on
entry) is removed after the export, also on errors; the session's objects get their meshes and slots back.
"""
import contextlib
import os
import sys

import bpy
import numpy as np

from ..blender import interrupt
from ..blender.materials import user_link, user_material
from ..blender.state import SavedState
from ..core import directional
from ..core.errors import ILError, InputError
from ..core.io import exr
from ..core.io.png import encode_png
from . import cycles, uvcache
from .inputs import SCENE_PARTS, changed_since
from .kinds import KINDS
from .report import REPORT, entry_file, read_objects

EXTENSION = "MOZ_lightmap"
LEVELS = 255
TAG, NAME = "il_gltf_lightmap", "il_gltf_name"
LINEAR, CLAMP = 9729, 33071          # glTF sampler LINEAR, CLAMP_TO_EDGE


def encode_irradiance(values):
    """(H, W, 3) E in W/m² -> (uint8 (H, W, 3) of round(255 E / max E), intensity = max E); an all-zero map gets
    intensity 1. Negative values (a denoiser's undershoot) are clipped to 0."""
    e = np.clip(np.asarray(values, np.float64), 0.0, None)
    peak = float(e.max()) if e.size else 0.0
    intensity = peak if peak > 0.0 else 1.0
    return np.rint(e / intensity * LEVELS).clip(0, LEVELS).astype(np.uint8), intensity


def encode_ao(values):
    """(H, W) k_A in [0, 1] -> uint8 (H, W, 3), R = G = B = round(255 k_A) (glTF reads occlusion from R)."""
    q = np.rint(np.clip(np.asarray(values, np.float64), 0.0, 1.0) * LEVELS).astype(np.uint8)
    return np.repeat(q[..., None], 3, axis=-1)


DIRECTIONAL = "il_directional"
DIRECTIONAL_DECODE = ("E(n) = e0 * (1 + 4 * ((2 * l1[0] - 1) * n.y + (2 * l1[1] - 1) * n.z + (2 * l1[2] - 1) * n.x)) "
                      "in W/m^2, n the unit shading normal in glTF's world frame (Y up), e0 = texel(e0) / 255 * "
                      "intensity, l1[m] = texel(l1[m]) / 255 (RGB each, linear, texCoord 1); a Lambertian surface "
                      "shows base colour * E(n) / pi. The l1 maps are Godot 4.3's LightmapGI SH layers (clamped to "
                      "[0, 1], which loses light where the directional part exceeds 4 e0 on an axis).")


def encode_directional(values):
    """(H, W, 12) L1 SH coefficients (Blender's frame) -> ([uint8 (H, W, 3) of e0, l1 (y), l1 (z), l1 (x)], intensity):
    e0 = the constant part of E(n) as E / max (:func:`encode_irradiance`), the l1 maps Godot-packed in [0, 1]."""
    coeffs = directional.to_y_up(np.asarray(values, np.float64))
    e0, intensity = encode_irradiance(directional.ambient(coeffs))
    _, l1 = directional.godot_packed(coeffs)
    return [e0] + [np.rint(m * LEVELS).clip(0, LEVELS).astype(np.uint8) for m in l1], intensity


def read_map(kind, path):
    """The values of map file ``path`` of ``kind`` (``Kind.from_exr``); InputError naming the file when it cannot be
    read, lacks the kind's channels or holds values that are not finite (a file edited or written by another tool:
    the bake never writes them), so an export refuses it before writing anything."""
    try:
        channels, _ = exr.read_exr(path)
        values = KINDS[kind].from_exr(channels)
    except KeyError as e:
        raise InputError(f"{path}: no channel {e}, so not a map of kind '{kind}': bake it again") from None
    except (OSError, RuntimeError, ValueError) as e:
        raise InputError(f"{path}: cannot be read as a {kind} map ({e}): bake it again") from None
    bad = ~np.isfinite(values)
    if bad.any():
        raise InputError(f"{path}: {int(bad.sum())} value(s) of the {kind} map are not finite (NaN or infinite): "
                         f"bake it again")
    return values


def encoding_error(intensity):
    """The largest |decoded - E| of :func:`encode_irradiance` (half an 8-bit step of ``intensity``)."""
    return intensity / (2 * LEVELS)


class Plan:
    """What the export carries: {object name: {kind: (entry, file)}} of the baked meshes that can carry it, the
    light-map UV layer of each, the UVs of the layers the file lacks (``restore``: read from the bake folder's UV
    cache by the entries' "uv_cache", :func:`uvcache.file_layout`; a batch bake does not save the .blend) and the
    lines naming objects left out."""

    def __init__(self, folder, scene):
        path = os.path.join(folder, REPORT)
        if not os.path.isfile(path):
            raise InputError(f"no {REPORT} in {folder}: give the folder the light maps were baked to")
        report = read_objects(path)
        if not report:
            raise InputError(f"{path} is unreadable or lists no baked objects")
        self.maps, self.layers, self.notes, self.restore = {}, {}, [], {}
        vertex, no_uv, no_file, absent, changed, refs = [], [], [], [], [], {}
        for name, entries in sorted(report.items()):
            obj = scene.objects.get(name)
            if obj is None or obj.type != "MESH":
                absent.append(name)
                continue
            found = {}
            for kind in ("irradiance", "ao", "directional"):
                entry = entries.get(kind)
                if entry is None:
                    continue
                if entry.get("attribute") is not None:
                    vertex.append(f"{name} ({kind})")
                    continue
                layer = entry.get("uv_layer")
                if not isinstance(layer, str) or not layer:
                    no_uv.append(f"{name} ('{layer}')")
                    break
                ref = entry.get("uv_cache")
                if found and (self.layers[name] != layer or refs[name] != ref):
                    no_uv.append(f"{name} ({kind} on '{layer}', baked through another layout than its other maps)")
                    continue
                file = entry_file(folder, entry)
                if file is None:
                    no_file.append(f"{name} ({kind}: {entry.get('file')})")
                    continue
                if not found:
                    uv = uvcache.file_layout(folder, ref, obj, scene)
                    if uv is None and uvcache.cached_entry(folder, ref):
                        changed.append(name)
                        break
                    if uv is None and obj.data.uv_layers.get(layer) is None:
                        no_uv.append(f"{name} ('{layer}')")
                        break
                    if uv is not None:
                        self.restore[name] = uv      # the layout the maps were baked on, over the file's layer
                    refs[name] = ref
                self.layers[name] = layer
                found[kind] = (entry, file)
            else:
                if found:
                    self.maps[name] = found
                continue
            self.maps.pop(name, None)
            self.layers.pop(name, None)
            self.restore.pop(name, None)
        if no_uv:
            self.notes.append("skipped, the light-map UV layer is neither in the .blend nor in the bake folder's UV "
                              "cache (.il-uv-cache; a mesh edited since the bake, a layer of your own that the file "
                              "lost): " + ", ".join(sorted(set(no_uv))))
        if changed:
            self.notes.append("skipped, the mesh's corners are not those its light-map layout was made for (edited "
                              "since the bake: bake it again): " + ", ".join(changed))
        if vertex:
            self.notes.append("skipped, vertex-colour maps are not exported: " + ", ".join(vertex))
        if no_file:
            self.notes.append("skipped, map file missing: " + ", ".join(no_file))
        if absent:
            self.notes.append("in the report but not a mesh in the scene: " + ", ".join(absent))
        unlit = sorted(name for name, maps in self.maps.items() for kind, (entry, _) in maps.items()
                       if entry.get("unlit"))
        if unlit:
            self.notes.append("exported black, the bake found no light reaching them (their report entries' "
                              "\"unlit\"): " + ", ".join(unlit))
        keyed = sorted(o.name for o in scene.objects if o.type == "MESH" and o.data.shape_keys is not None
                       and any(m.show_viewport or m.show_render for m in o.modifiers))
        if keyed:
            self.notes.append("shape keys not exported, as Blender's glTF exporter applies the modifiers of these "
                              "objects (so that the triangles are those baked): " + ", ".join(keyed))
        placed = sorted({f"{name} (by '{o.name}')" for o in scene.objects if o.instance_type == "COLLECTION"
                         and o.instance_collection is not None for name in self.maps
                         if name in o.instance_collection.all_objects})
        if placed:
            self.notes.append("placed again by a collection instance, whose copies carry the map baked where the "
                              "object itself stands (make the instance real to bake each copy): " + ", ".join(placed))

    def changed(self, scene):
        """The lines naming what changed since the maps were baked (:func:`inputs.changed_since` of each map's entry
        "inputs"): the objects moved, edited or given other modifiers or materials (or another file's objects of
        the same names), and once for all, lights or a world that changed."""
        changed = changed_since(scene, {(scene.objects[name], kind): entry.get("inputs")
                                        for name, maps in self.maps.items() for kind, (entry, _) in maps.items()})
        own = [f"{name} ({', '.join(SCENE_PARTS[p] for p in parts if p != 'lighting')})"
               for name, parts in sorted(changed.items()) if parts != ["lighting"]]
        lines = ["changed since the bake, so their maps show them as they were then (bake them again with "
                 "--overwrite): " + ", ".join(own)] if own else []
        if any("lighting" in parts for parts in changed.values()):
            lines.append(f"{SCENE_PARTS['lighting']} changed since the bake, so the maps of their light (irradiance, "
                         f"directional) show it as it was then (bake them again with --overwrite)")
        return lines

    def encoded(self, ao_with_irradiance=False):
        """{(kind, file): (PNG bytes, or a directional map's four, intensity)} of every map to export (AO where no
        irradiance is, unless ``ao_with_irradiance``), each file read once (:func:`read_map`: a file that cannot be
        exported is refused here, before anything is written)."""
        out = {}
        for maps in self.maps.values():
            for kind, (_, path) in maps.items():
                if (kind, path) in out or kind == "ao" and "irradiance" in maps and not ao_with_irradiance:
                    continue
                values = read_map(kind, path)
                if kind == "directional":
                    layers, intensity = encode_directional(values)
                    out[(kind, path)] = [encode_png(p) for p in layers], intensity
                else:
                    pixels, intensity = encode_irradiance(values) if kind == "irradiance" else (encode_ao(values), 1.0)
                    out[(kind, path)] = encode_png(pixels), intensity
        return out


def _reorder_uvs(me, layer):
    """Put ``layer`` at index 1 of mesh ``me`` (a temporary copy): [render layer, ``layer``, others]."""
    n = len(me.loops)
    data = {}
    for lay in me.uv_layers:
        a = np.empty(2 * n, np.float32)
        lay.data.foreach_get("uv", a)
        data[lay.name] = a
    render = next((lay.name for lay in me.uv_layers if lay.active_render), layer)
    active = me.uv_layers.active.name if me.uv_layers.active else render
    others = [k for k in data if k != layer]
    first = render if render != layer else (others[0] if others else None)
    if first is None:
        first = "UVMap" if layer != "UVMap" else "UVMap.base"
        data[first] = data[layer]
    order = [first, layer] + [k for k in others if k != first]
    while len(me.uv_layers):
        me.uv_layers.remove(me.uv_layers[0])
    for k in order:
        new = me.uv_layers.new(name=k, do_init=False)
        new.data.foreach_set("uv", data[k])
    me.uv_layers.active = me.uv_layers[active]
    me.uv_layers[render].active_render = True
    if [lay.name for lay in me.uv_layers].index(layer) != 1:
        raise ILError(f"could not put UV layer '{layer}' of mesh '{me.name}' at TEXCOORD_1")


@contextlib.contextmanager
def _prepared(scene, plan):
    """Temporary mesh copies (light-map layer at index 1) and per-object material copies tagged with the object: copies
    of the user's own materials under the add-on's layers (``blender.materials.user_material``: a light-map preview,
    a shading model and environment mapping are not what an engine draws), linked as the user linked them, and on
    the mesh copy also where linked to the object (Blender's exporter reads the mesh's own materials when it applies
    modifiers)."""
    saved, meshes, materials = [], [], []
    try:
        for name in plan.maps:
            obj = scene.objects[name]
            slots = [(s.link, s.material) for s in obj.material_slots]
            saved.append((obj, obj.data, slots))
            me = obj.data.copy()
            meshes.append(me)
            me[NAME] = obj.data.name
            obj.data = me
            if name in plan.restore:
                layer = me.uv_layers.get(plan.layers[name]) or me.uv_layers.new(name=plan.layers[name], do_init=False)
                if layer is None:
                    raise InputError(f"'{name}': its mesh has as many UV layers as Blender holds: the light-map layer "
                                     f"from the bake folder's UV cache cannot be added")
                layer.data.foreach_set("uv", plan.restore[name])
            _reorder_uvs(me, plan.layers[name])
            if not obj.material_slots:
                mat = bpy.data.materials.new(f"{name} light map")
                materials.append(mat)
                mat[NAME] = f"{name} light map"
                mat[TAG] = name
                me.materials.append(mat)
                continue
            for i, slot in enumerate(obj.material_slots):
                link, orig = user_link(slot), user_material(slot.material)
                mat = orig.copy() if orig is not None else bpy.data.materials.new(f"{name} light map")
                materials.append(mat)
                mat[NAME] = orig.name if orig is not None else f"{name} light map"
                mat[TAG] = name
                slot.link = link
                if link == "OBJECT":
                    slot.material = mat
                me.materials[i] = mat
        yield
    finally:
        for obj, data, slots in saved:
            for slot, (link, mat) in zip(obj.material_slots, slots):
                slot.link = link
                if link == "OBJECT":
                    slot.material = mat
            obj.data = data
        for me in meshes:
            bpy.data.meshes.remove(me)
        for mat in materials:
            bpy.data.materials.remove(mat)


def _extension_class(plan, state, ao_with_irradiance=False):
    """The exporter's user extension for ``plan``; ``state`` holds the maps encoded (``Plan.encoded``) and collects
    textures (one per map file), intensities and errors (the exporter logs and swallows a hook's exceptions)."""
    from io_scene_gltf2.io.com import gltf2_io
    from io_scene_gltf2.io.com.gltf2_io_extensions import Extension
    from io_scene_gltf2.io.exp.binary_data import BinaryData

    def gltf_texture(png, name):
        image = gltf2_io.Image(buffer_view=BinaryData(data=png), extensions=None, extras=None,
                               mime_type="image/png", name=name, uri=None)
        if "sampler" not in state:
            state["sampler"] = gltf2_io.Sampler(extensions=None, extras=None, mag_filter=LINEAR,
                                                min_filter=LINEAR, name=None, wrap_s=CLAMP, wrap_t=CLAMP)
        return gltf2_io.Texture(extensions=None, extras=None, name=name, sampler=state["sampler"], source=image)

    def texture(kind, path):
        """(glTF texture, intensity) of a map file; a directional map gives ([four textures], intensity)."""
        key = (kind, path)
        if key not in state["textures"]:
            png, intensity = state["encoded"][key]
            name = os.path.splitext(os.path.basename(path))[0]
            if kind == "directional":
                tex = [gltf_texture(p, f"{name}_{part}") for p, part in zip(png, ("e0", "l1y", "l1z", "l1x"))]
            else:
                tex = gltf_texture(png, name)
            state["textures"][key] = (tex, intensity)
        return state["textures"][key]

    class LightmapExtension:
        def gather_mesh_hook(self, gltf2_mesh, blender_mesh, *rest):
            """(mesh, blender mesh, object, vertex groups, modifiers, materials, settings) in 4.5-5.3: the
            temporary copy's glTF mesh gets the original mesh's name (a mesh with its modifiers applied is a new
            one: the name is then its object's temporary copy's)."""
            try:
                obj = rest[0] if rest else None
                for me in (blender_mesh, getattr(obj, "data", None)):
                    if me is not None and me.get(NAME):
                        gltf2_mesh.name = me[NAME]
                        break
            except Exception as e:  # noqa: BLE001
                state["errors"].append(f"{type(e).__name__}: {e}")

        def gather_material_hook(self, gltf2_material, blender_material, export_settings):
            try:
                name = blender_material.get(TAG) if blender_material is not None else None
                if name is None or name not in plan.maps:
                    return
                gltf2_material.name = blender_material.get(NAME, gltf2_material.name)
                maps = plan.maps[name]
                if "ao" in maps and (ao_with_irradiance or "irradiance" not in maps):
                    tex, _ = texture("ao", maps["ao"][1])
                    gltf2_material.occlusion_texture = gltf2_io.MaterialOcclusionTextureInfoClass(
                        extensions=None, extras=None, index=tex, strength=1.0, tex_coord=1)
                if "irradiance" in maps:
                    tex, intensity = texture("irradiance", maps["irradiance"][1])
                    if gltf2_material.extensions is None:
                        gltf2_material.extensions = {}
                    gltf2_material.extensions[EXTENSION] = Extension(
                        name=EXTENSION, extension={"index": tex, "texCoord": 1, "intensity": intensity},
                        required=False)
                if "directional" in maps:
                    (e0, *l1), intensity = texture("directional", maps["directional"][1])
                    extras = dict(gltf2_material.extras or {})
                    extras[DIRECTIONAL] = {"texCoord": 1, "e0": {"index": e0, "intensity": intensity},
                                           "l1": [{"index": t} for t in l1], "decode": DIRECTIONAL_DECODE}
                    gltf2_material.extras = extras
                state["done"].add(name)
            except Exception as e:  # noqa: BLE001 - the exporter would only log it
                state["errors"].append(f"{type(e).__name__}: {e}")

    return LightmapExtension


@contextlib.contextmanager
def _as_rendered(scene):
    """The viewport's evaluation of ``scene`` given a render's settings (``cycles.render_variants``: the meshes the
    bake baked, e.g. a Subdivision Surface at its render levels) for the block; the settings come back after."""
    variants = cycles.render_variants(scene, list(scene.objects))
    try:
        with SavedState(scene, (), [(owner, attr) for owner, attr, _ in variants]):
            cycles.evaluate_as_render(scene, variants)
            yield
    finally:
        if variants:
            scene.view_layers[0].update()


@contextlib.contextmanager
def _registered(extension):
    """``extension`` seen by the glTF exporter (which collects ``glTF2ExportUserExtension`` of each enabled
    add-on's module) during the block only: a temporary add-on entry naming this module."""
    module = sys.modules[__name__]
    prefs = bpy.context.preferences
    dirty = prefs.is_dirty
    entry = prefs.addons.new()
    entry.module = __name__
    module.glTF2ExportUserExtension = extension
    try:
        yield
    finally:
        del module.glTF2ExportUserExtension
        prefs.addons.remove(entry)
        prefs.is_dirty = dirty


def export_glb(scene, folder, out, ao_with_irradiance=False):
    """Write ``scene`` as the glTF binary ``out`` with the light maps of ``folder``/bake_report.json (see the
    module docstring); return {"objects": {name: {kind: intensity}}, "notes": [lines], "path": out}, kinds as
    exported. ``out`` is written whole (a temporary file beside it, then moved) or not at all."""
    plan = Plan(folder, scene)
    if not plan.maps:
        raise InputError("no object of the report can carry its maps: " + "; ".join(plan.notes or ["none baked"]))
    state = {"textures": {}, "errors": [], "done": set(), "encoded": plan.encoded(ao_with_irradiance)}
    tmp = os.path.join(os.path.dirname(out), f".{os.path.basename(out)}.{os.getpid()}.tmp.glb")
    try:
        hooks = _extension_class(plan, state, ao_with_irradiance)
        with _as_rendered(scene):
            changed = plan.changed(scene)
            with _prepared(scene, plan), _registered(hooks), interrupt.blender_call():
                result = bpy.ops.export_scene.gltf(filepath=tmp, export_format="GLB", use_selection=False,
                                                   export_texcoords=True, export_animations=False,
                                                   export_apply=True)
        if "FINISHED" not in result:
            raise ILError(f"Blender's glTF exporter did not finish ({', '.join(result)})")
        if state["errors"]:
            raise ILError("light-map hook failed: " + "; ".join(state["errors"]))
        os.replace(tmp, out)
    finally:
        if os.path.exists(tmp):
            os.remove(tmp)
    missed = sorted(set(plan.maps) - state["done"])
    notes = plan.notes + changed
    if missed:
        notes.append("not exported (no material reached the exporter): " + ", ".join(missed))
    objects = {}
    for name in sorted(state["done"]):
        objects[name] = {kind: state["textures"][(kind, f)][1] for kind, (_, f) in plan.maps[name].items()
                         if kind != "ao" or ao_with_irradiance or "irradiance" not in plan.maps[name]}
    return {"objects": objects, "notes": notes, "path": out}
