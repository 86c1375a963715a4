"""Light maps shown on the user's materials (Preview / Remove Preview in the Light maps panel).

:func:`apply_lightmaps` gives every material slot of each baked mesh a preview material: an Emission shader of
colour base × map and strength 1/π (irradiance E: the radiance ρE/π of the lit Lambertian surface) or 1 (AO k_A:
the radiance ρ k_A of the surface under a white sky of radiance 1), so EEVEE and Cycles show the baked light
without scene lights (world black: nothing else is added). The base colour ρ is the material's Principled (or
Diffuse) Base Color, value or the nodes that feed it (:mod:`.source`); the map is the EXR named in the folder's
bake_report.json, read through the object's light-map UV layer (the report's "uv_layer"; a vertex-target map
through its colour attribute). A batch bake leaves the file without its generated layer: the layer is then added
from the bake folder's UV cache (the layout the map was baked on, as the export reads it; ``il_lightmap_added_uv``
on the mesh) and taken away again with the last preview of the mesh. Metallic, specular, normal maps and alpha are
not shown.

The preview goes into the object's own slot (the slot is switched to link to the object, so meshes that share data
show their own maps; the mesh's materials are not touched); the preview material keeps what the slot had
(``il_lightmap_original``, ``il_lightmap_link``, ``il_lightmap_hidden``: ID properties, so the originals are saved
with the file) and :func:`remove_lightmaps` puts it back, per slot.
"""
import math
import os

import bpy
import numpy as np

from ..bake import uvcache
from ..bake.report import REPORT, entry_file, read_objects
from ..bake.uv import ADDED_BY_PREVIEW as ADDED_UV, MAX_UV_LAYERS
from ..blender import compat
from ..blender.materials import is_preview, user_material
from ..blender.scene import corner_uv
from ..core.errors import InputError
from . import source
from .material import split_shadable

#: operator source -> (report map kind, Emission Strength)
SOURCES = {"IRRADIANCE": ("irradiance", 1.0 / math.pi), "AO": ("ao", 1.0)}
TAG = "il_lightmap"
ADDED_SLOT = "il_lightmap_added_slot"


def read_report(folder):
    """{object name: {map kind: entry}} of ``folder``/bake_report.json; InputError when there is none."""
    path = os.path.join(folder, REPORT)
    if not os.path.isfile(path):
        raise InputError(f"no {REPORT} in {folder}: bake the light maps there first (Bake), or choose the "
                         "folder they were baked to")
    return read_objects(path)


#: The map file of a report entry (its "file"'s name in the folder: also a copied or moved one), or None.
map_file = entry_file


def _cached_layout(obj, entry, folder, replacing):
    """(UVs (flat, 2 per loop) ``entry``'s map was baked through, from ``folder``'s UV cache, for ``obj``'s mesh as
    it is now, None) when the layer can be added (``replacing``: one a preview added is rewritten), else (None, why
    not)."""
    me, ref = obj.data, entry.get("uv_cache")
    if me.library is not None:
        return None, "its mesh is linked from a library (no layer can be added)"
    if not replacing and len(me.uv_layers) >= MAX_UV_LAYERS:
        return None, f"its mesh has {MAX_UV_LAYERS} UV layers already (no layer can be added)"
    layout = uvcache.file_layout(folder, ref, obj, bpy.context.scene) if ref else None
    if layout is None:
        return None, "nor its layout for the mesh as it is now in the bake folder's UV cache"
    return layout, None


def _mesh_users(obj):
    """The objects of ``obj``'s mesh: ``obj`` alone unless the mesh has other users (only then is every object looked
    through)."""
    me = obj.data
    return [o for o in bpy.data.objects if o.data == me] if me.users > 1 else [obj]


def _other_previews(obj, meshes):
    """Objects not in ``meshes`` that share ``obj``'s mesh and show a preview."""
    return [o.name for o in _mesh_users(obj) if o not in meshes and previewed([o])]


def _plan(meshes, maps, kind, folder):
    """([(object, entry, file, UVs of the layer to add or None)], warnings) of ``meshes`` that can show their
    ``kind`` map."""
    todo, none, missing = [], [], []
    for obj in meshes:
        entry = maps.get(obj.name, {}).get(kind)
        if entry is None:
            none.append(obj.name)
            continue
        uv, attr = entry.get("uv_layer"), entry.get("attribute")
        path = map_file(folder, entry) if attr is None else None
        layer = obj.data.uv_layers.get(uv) if uv else None
        ours = layer is not None and obj.data.get(ADDED_UV) == uv         # added by a preview: maybe another bake's
        layout = why = None
        if attr is None and path is not None and uv and (layer is None or ours):
            layout, why = _cached_layout(obj, entry, folder, ours)
            if layout is not None and ours and not np.array_equal(corner_uv(obj.data, uv).ravel(), layout):
                others = _other_previews(obj, meshes)
                if others:
                    layout, why = None, (f"shares its mesh with {', '.join(others)}, whose preview shows another "
                                         "bake's layout: preview them together or remove that preview first")
        if attr is not None and obj.data.color_attributes.get(attr) is None:
            missing.append(f"'{obj.name}': no colour attribute '{attr}' (its vertex {kind} map); a batch bake does "
                           "not save the .blend: bake in this file or open the copy the bake saved")
        elif attr is None and why is not None and ours:
            missing.append(f"'{obj.name}': the layer '{uv}' a preview added holds another bake's layout and this "
                           f"one cannot replace it: {why}")
        elif attr is None and (not uv or layer is None) and layout is None:
            missing.append(f"'{obj.name}': no UV layer '{uv}' (the layout of its {kind} map), {why or 'no layout'}: "
                           "bake in this file or open the copy the bake saved (--save-as)")
        elif attr is None and path is None:
            missing.append(f"'{obj.name}': its {kind} map {entry.get('file')} is missing")
        else:
            todo.append((obj, entry, path, layout))
    warnings = [f"no {kind} map in {os.path.join(folder, REPORT)} for: {', '.join(none)}"] if none else []
    return todo, warnings + [f"{m}; skipped" for m in missing]


def _image(path):
    """The preview's image of ``path`` (one per file, reloaded so a new bake shows): linear, colour not
    multiplied by the coverage alpha, full float precision."""
    image = next((im for im in bpy.data.images if im.get(TAG) == path), None)
    if image is None:
        image = bpy.data.images.load(path, check_existing=False)
        image[TAG] = path
    else:
        image.reload()
    image.colorspace_settings.name = "Non-Color"
    image.alpha_mode = "CHANNEL_PACKED"
    if hasattr(image, "use_half_precision"):
        image.use_half_precision = False
    return image


def _upstream(node):
    seen, todo = set(), [node]
    while todo:
        n = todo.pop()
        if n.name not in seen:
            seen.add(n.name)
            todo += [lk.from_node for i in n.inputs for lk in i.links]
    return seen


def build_preview(orig, obj, entry, path, source_id):
    """A new preview material for a slot holding ``orig`` (None: empty) of ``obj``; see the module docstring."""
    kind, strength = SOURCES[source_id]
    base_mat = user_material(orig)              # the base colour shown: the user's own under any layer
    surface = source.read_surface(base_mat)
    label = f"IL {kind} {obj.name}: {orig.name if orig is not None else 'empty'}"
    if surface.base_source is not None:
        mat = base_mat.copy()       # keeps the nodes (textures, their UVs) that feed Base Color, nothing else
        for key in [k for k in mat.keys() if k.startswith("il_")]:
            del mat[key]
        tree = mat.node_tree
        keep = _upstream(surface.base_source.node)
        ad = tree.animation_data
        for fc in list(ad.drivers) if ad is not None else []:
            if not any(fc.data_path.startswith(f'nodes["{k}"]') for k in keep):
                ad.drivers.remove(fc)
        for node in list(tree.nodes):
            if node.name not in keep:
                tree.nodes.remove(node)
        base = tree.nodes[surface.base_source.node.name].outputs[surface.base_source.identifier]
    else:
        mat = bpy.data.materials.new(label)
        compat.ensure_use_nodes(mat)
        mat.node_tree.nodes.clear()
        base = None
    mat.name = label
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    attr = entry.get("attribute")
    if attr is not None:
        lookup = nodes.new("ShaderNodeVertexColor")
        lookup.layer_name = attr
    else:
        uv = nodes.new("ShaderNodeUVMap")
        uv.uv_map = entry["uv_layer"]
        lookup = nodes.new("ShaderNodeTexImage")
        lookup.image, lookup.interpolation, lookup.extension = _image(path), "Linear", "EXTEND"
        links.new(uv.outputs["UV"], lookup.inputs["Vector"])
    lookup.name = lookup.label = f"IL light map ({kind})"
    times = nodes.new("ShaderNodeVectorMath")
    times.operation, times.name, times.label = "MULTIPLY", "IL base x map", "IL base x map"
    if base is not None:
        links.new(base, times.inputs[0])
    else:
        times.inputs[0].default_value = surface.base
    links.new(lookup.outputs["Color"], times.inputs[1])
    emit = nodes.new("ShaderNodeEmission")
    emit.name = emit.label = "IL light-map radiance"
    emit.inputs["Strength"].default_value = strength
    links.new(times.outputs["Vector"], emit.inputs["Color"])
    out = nodes.new("ShaderNodeOutputMaterial")
    out.target, out.is_active_output = "ALL", True
    links.new(emit.outputs["Emission"], out.inputs["Surface"])
    for i, node in enumerate((lookup, times, emit, out)):
        node.location = (300 + 250 * i, 0)
    if hasattr(mat, "cycles"):
        mat.cycles.emission_sampling = "NONE"   # the map is the light: other surfaces need not sample it
    mat[TAG] = kind
    mat["il_lightmap_file"] = path or attr
    return mat


def previewed(objects):
    """Whether a slot of ``objects`` shows a preview material."""
    return any(is_preview(s.material) for o in objects for s in getattr(o, "material_slots", ()))


def _apply_object(obj, entry, path, source_id, made):
    data = obj.data
    if len(obj.material_slots) == 0:
        data.materials.append(None)
        data[ADDED_SLOT] = True
    for slot in obj.material_slots:
        _restore_slot(slot)
        link, orig = slot.link, slot.material
        mat = build_preview(orig, obj, entry, path, source_id)     # first: a failure leaves the slot as it was
        made.append(mat)
        slot.link = "OBJECT"
        hidden = slot.material if link == "DATA" else None
        mat["il_lightmap_link"] = link
        if orig is not None:
            mat["il_lightmap_original"] = orig
        if hidden is not None:
            mat["il_lightmap_hidden"] = hidden
        slot.material = mat


def _restore_slot(slot):
    """Give ``slot`` back what the preview replaced; True when it held one."""
    mat = slot.material
    if not is_preview(mat):
        return False
    if mat["il_lightmap_link"] == "DATA":
        slot.material = mat.get("il_lightmap_hidden")
        slot.link = "DATA"
    else:
        slot.material = mat.get("il_lightmap_original")
    return True


def _restore_object(obj):
    count = sum(_restore_slot(slot) for slot in obj.material_slots)
    data = obj.data
    if data is not None and ADDED_SLOT in data and not previewed([obj]):
        if len(data.materials) == 1 and data.materials[0] is None:
            data.materials.clear()
        del data[ADDED_SLOT]
    if data is not None and ADDED_UV in data and not previewed(_mesh_users(obj)):
        _remove_added_layer(data)
    return count


def _add_layer(me, name, uvs):
    """Give ``me`` the light-map layer ``name`` with ``uvs`` (tagged, for :func:`_remove_added_layer`), or rewrite
    the one a preview added. Returns what undoes it: None (nothing done), "added", or the UVs it held."""
    layer = me.uv_layers.get(name)
    if layer is None:
        me.uv_layers.new(name=name, do_init=False).data.foreach_set("uv", uvs)
        me[ADDED_UV] = name
        return "added"
    held = corner_uv(me, name).ravel().copy()
    if np.array_equal(held, uvs):
        return None
    layer.data.foreach_set("uv", uvs)
    return held


def _remove_added_layer(me):
    layer = me.uv_layers.get(me[ADDED_UV])
    if layer is not None:
        me.uv_layers.remove(layer)
    del me[ADDED_UV]


def _drop_unused(mats):
    """Remove preview materials nothing uses any more, and their map images nothing else uses."""
    images = set()
    for mat in mats:
        if mat.users == 0:
            images |= {n.image for n in mat.node_tree.nodes if n.bl_idname == "ShaderNodeTexImage"
                       and n.image is not None and n.image.get(TAG)}
            bpy.data.materials.remove(mat)
    for image in images:
        if image.users == 0:
            bpy.data.images.remove(image)


def apply_lightmaps(objects, folder, source_id="IRRADIANCE"):
    """Show the ``source_id`` map ("IRRADIANCE" or "AO") of ``folder``'s bake_report.json on the meshes of
    ``objects``. Returns (report {"objects": {name: {"map", "file", "uv_layer", "slots"}}}, warnings naming the
    skipped objects: not meshes, no map, no light-map UV layer, missing file). A second apply replaces the
    preview. Raises InputError (changing nothing) when no object can show a map; on any error the objects
    already done get their materials back."""
    if source_id not in SOURCES:
        raise InputError(f"unknown light-map source '{source_id}' (one of {', '.join(SOURCES)})")
    kind = SOURCES[source_id][0]
    meshes, skipped = split_shadable(list(objects))
    warnings = [f"skipped {'; '.join(skipped)}"] if skipped else []
    if not meshes:
        raise InputError(f"nothing to preview: select a baked mesh ({'; '.join(skipped) or 'nothing is selected'})")
    todo, why = _plan(meshes, read_report(folder), kind, folder)
    warnings += why
    if not todo:
        raise InputError(f"no {kind} map to show: {'; '.join(why)}")
    made, done, replaced, added = [], [], [], []
    try:
        for obj, entry, path, layout in todo:
            replaced += [s.material for s in obj.material_slots if is_preview(s.material)]
            done.append(obj)
            undo = _add_layer(obj.data, entry["uv_layer"], layout) if layout is not None else None
            if undo is not None:
                added.append((obj.data, entry["uv_layer"], undo))
            _apply_object(obj, entry, path, source_id, made)
    except Exception:
        for obj in done:
            _restore_object(obj)
        for me, name, undo in reversed(added):
            if isinstance(undo, str):
                if ADDED_UV in me:
                    _remove_added_layer(me)
            elif me.uv_layers.get(name) is not None:
                me.uv_layers[name].data.foreach_set("uv", undo)
        _drop_unused(made)
        raise
    _drop_unused(set(replaced))
    report = {"objects": {o.name: {"map": kind, "file": p or e.get("attribute"), "uv_layer": e.get("uv_layer"),
                                   "uv_from_cache": lay is not None, "slots": len(o.material_slots)}
                          for o, e, p, lay in todo},
              "source": source_id, "folder": folder}
    return report, warnings


def remove_lightmaps(objects):
    """Give the slots of ``objects`` back what :func:`apply_lightmaps` replaced (slots it added removed). As
    Remove Shading Model, the preview materials and map images left unused stay until the file is saved (Blender
    drops them then; Undo finds them). Returns the number of slots restored."""
    return sum(_restore_object(o) for o in objects if getattr(o, "material_slots", None) is not None)
