"""Irradiance light maps handed to engines that take maps baked elsewhere (issue 28, item 4). No bpy.

Both engines multiply the light map by the albedo and nothing else (Godot's scene shader: ``ambient_light +=
lightmap × exposure_normalization; ambient_light *= albedo``; Unity's ``DecodeLightmap(…) × albedo``), so a
texel holds the radiance of a white Lambertian surface, L = E/π in W/(m² sr): what Blender shows as pixel value
1 with exposure 0. The UVs are the light-map layer exported as ``TEXCOORD_1`` (Godot: UV2; Unity's glTF importers:
uv2); glTF's flipped v and the image row order cancel, so the maps are written as the bake wrote them.

- Godot 4.3+ with directional maps: its SH mode (``uses_spherical_harmonics``), four slices per map (L0' and the
  packed l1 of :func:`..directional.godot_packed`); otherwise:
- Godot 4.3+: one float EXR of S x (n·S) texels, the n maps stacked as slices of S x S (S the largest map side,
  each map at its slice's top-left), with the ``.import`` that makes Godot import it as a Texture2DArray of n
  slices, and a ``LightmapGIData`` text resource: ``user_data`` = [NodePath, Rect2(0, 0, w/S, h/S), slice, -1]
  per object (Godot reads uv2 × Rect2.size + Rect2.position).
- Unity: per map an EXR of E/π and a JSON of ``lightmapIndex`` and ``lightmapScaleOffset`` (x, y scale, z, w
  offset) per renderer, for ``LightmapSettings.lightmaps`` and ``Renderer.lightmapIndex`` /
  ``lightmapScaleOffset`` set from a script. Objects of one atlas share a map; their UVs are already in it.
"""
import dataclasses
import json
import math
import struct

import numpy as np

from .. import directional
from ..errors import InputError

GODOT_INVALID = '.:@/"%'
"""Characters Godot replaces with "_" in node names (String::get_invalid_node_name_characters)."""


@dataclasses.dataclass(frozen=True)
class EngineMap:
    """The irradiance maps of the objects to hand over: ``users`` {object name: node path parts from the scene root
    (parents first)} and ``map_of`` {object name: map key}; ``maps`` {map key: E (H, W, 3) in W/m²}."""
    users: dict
    map_of: dict
    maps: dict

    def keys(self):
        """Map keys in a fixed order (first use by object name)."""
        seen = []
        for name in sorted(self.map_of):
            if self.map_of[name] not in seen:
                seen.append(self.map_of[name])
        return seen


def godot_node_name(name):
    """The name Godot's glTF import gives a node called ``name``."""
    return "".join("_" if c in GODOT_INVALID else c for c in name)


def godot_name_clashes(names, needed):
    """Groups (sorted lists) of ``names`` (every node of the glTF) that Godot's glTF import gives one node name
    (:func:`godot_node_name`; it then numbers all but the first, scene-wide, in the glTF's order), among them a name
    of ``needed`` (the nodes a LightmapGIData path runs through)."""
    groups = {}
    for name in names:
        groups.setdefault(godot_node_name(name), []).append(name)
    return [sorted(g) for _, g in sorted(groups.items()) if len(g) > 1 and any(n in needed for n in g)]


def read_glb_json(path):
    """The JSON chunk of the glTF binary at ``path`` as a dict (InputError when it is not one)."""
    with open(path, "rb") as f:
        head = f.read(20)
        if len(head) < 20 or head[:4] != b"glTF" or head[16:20] != b"JSON":
            raise InputError(f"{path}: not a glTF binary")
        (length,) = struct.unpack("<I", head[12:16])
        return json.loads(f.read(length))


def _joints(gltf):
    return {j for skin in gltf.get("skins", []) for j in skin.get("joints", [])}


def own_nodes(gltf, ancestors=None):
    """{glTF node name: [its node's index and its parents', scene root first]} of the glTF JSON ``gltf``'s nodes that
    are neither a skin's joint nor under one (the joints are left out, as Godot's import leaves them). A node name
    the glTF repeats (an object and the copy a collection instance places, written in either order) is the node
    whose parents' names are the object's ``ancestors`` ({name: [parent, grandparent, ...]}) that are glTF nodes,
    else its first node."""
    nodes = gltf.get("nodes", [])
    joints = _joints(gltf)
    parent = {c: i for i, node in enumerate(nodes) for c in node.get("children", [])}
    in_gltf = {node.get("name") for node in nodes}
    out, own = {}, {}
    for i, node in enumerate(nodes):
        chain, j = [], i
        while j is not None and j not in joints:
            chain.insert(0, j)
            j = parent.get(j)
        if j is not None:
            continue
        name = node.get("name")
        mine = name in (ancestors or {}) and [a for a in ancestors[name] if a in in_gltf] == [
            nodes[k].get("name") for k in chain[-2::-1]]
        if name not in out or (mine and not own[name]):
            out[name], own[name] = chain, mine
    return out


def godot_paths(gltf, ancestors=None):
    """{glTF node name: [its node's name and its parents' in Godot's import, scene root first]} of :func:`own_nodes`.
    Godot's glTF import names the nodes in their index order, each with :data:`GODOT_INVALID` as "_" and numbered
    (2, 3, ...) when the name is taken, "Skeleton3D" taken first (GLTFDocument::_parse_scenes, _assign_node_names,
    _gen_unique_name)."""
    nodes = gltf.get("nodes", [])
    joints = _joints(gltf)
    taken, names = {"Skeleton3D"}, {}
    for i, node in enumerate(nodes):
        if i in joints:
            continue
        base = godot_node_name(node.get("name") or "Node")
        name, k = base, 1
        while name in taken:
            k += 1
            name = f"{base}{k}"
        taken.add(name)
        names[i] = name
    return {name: [names[i] for i in chain] for name, chain in own_nodes(gltf, ancestors).items()}


def _node_path(parts):
    path = "/".join(godot_node_name(p) for p in parts)
    return "../" + path.replace("\\", "\\\\")


GODOT_MAX_BYTES = 1 << 30
"""The largest stacked Godot texture written (float32 RGB): every map is padded to the largest side."""


def check_godot_size(em, layers=1):
    """InputError when the stacked Texture2DArray of ``em`` (``layers`` per map) would exceed GODOT_MAX_BYTES."""
    keys = em.keys()
    side = max(max(em.maps[k].shape[:2]) for k in keys)
    size = layers * len(keys) * side * side * 12
    if size > GODOT_MAX_BYTES:
        raise InputError(f"the Godot light-map array would be {size / 2 ** 30:.1f} GiB ({len(keys)} maps padded to "
                         f"{side}x{side}): bake the objects into a shared atlas (--atlas) or at smaller sizes")


def godot_layers(em):
    """(image (n·S, S, 3) of E/π, {map key: (slice, (w/S, h/S))}): the maps stacked top to bottom."""
    keys = em.keys()
    side = max(max(em.maps[k].shape[:2]) for k in keys)
    image = np.zeros((len(keys) * side, side, 3), np.float32)
    where = {}
    for i, k in enumerate(keys):
        h, w = em.maps[k].shape[:2]
        image[i * side:i * side + h, :w] = em.maps[k][..., :3] / math.pi
        where[k] = (i, (w / side, h / side))
    return image, where


def godot_sh_layers(em):
    """Godot's SH mode from directional maps (``em.maps``: (H, W, 12) L1 coefficients, Blender's frame): (image
    (4·n·S, S, 3), {map key: (slice, (w/S, h/S))}); each map's four layers L0' = E0 L00/π, then the packed l1 of
    n_y, n_z, n_x (core.directional.godot_packed, in Godot's Y-up frame) stacked as consecutive slices, as Godot's
    shader reads them (slice index × 4 + layer)."""
    keys = em.keys()
    side = max(max(em.maps[k].shape[:2]) for k in keys)
    image = np.zeros((4 * len(keys) * side, side, 3), np.float32)
    where = {}
    for i, k in enumerate(keys):
        h, w = em.maps[k].shape[:2]
        l0, l1 = directional.godot_packed(directional.to_y_up(np.asarray(em.maps[k], np.float64)))
        for j, layer in enumerate([np.clip(l0, 0.0, None)] + list(l1)):
            row = (4 * i + j) * side
            image[row:row + h, :w] = layer
        where[k] = (i, (w / side, h / side))
    return image, where


def godot_import(slices):
    """The ``.import`` text that makes Godot import the stacked EXR as a Texture2DArray of ``slices``, uncompressed
    (VRAM compression would quantise HDR values), without mipmaps, as Godot's own LightmapGI writes it."""
    return ("[remap]\n\nimporter=\"2d_array_texture\"\ntype=\"CompressedTexture2DArray\"\n\n[params]\n\n"
            "compress/mode=3\ncompress/channel_pack=1\nmipmaps/generate=false\n"
            f"slices/horizontal=1\nslices/vertical={int(slices)}\n")


def godot_resource(em, texture_file, where, sh=False):
    """The ``LightmapGIData`` text resource (.tres) that references ``texture_file`` (a path relative to the
    resource) and every object as a user of its slice; ``sh``: the texture holds :func:`godot_sh_layers`."""
    users = []
    for name in sorted(em.map_of):
        i, (sx, sy) = where[em.map_of[name]]
        users.append(f'NodePath("{_node_path(em.users[name])}"), Rect2(0, 0, {sx:.9g}, {sy:.9g}), {i}, -1')
    texture = texture_file.replace("\\", "/").replace('"', '\\"')
    return ("[gd_resource type=\"LightmapGIData\" load_steps=2 format=3]\n\n"
            f"[ext_resource type=\"TextureLayered\" path=\"{texture}\" id=\"1_lightmap\"]\n\n"
            "[resource]\nlightmap_textures = [ExtResource(\"1_lightmap\")]\n"
            f"uses_spherical_harmonics = {'true' if sh else 'false'}\n"
            + ("_uses_packed_directional = true\n" if sh else "")
            + f"user_data = [{', '.join(users)}]\n")


def unity_layout(em, files, paths=None):
    """The JSON-ready dict for Unity: ``files`` {map key: file name of its E/π EXR}; ``paths`` {object: the glTF
    names of its node and its parents, root first} (:func:`own_nodes`), each renderer's "path" (a collection
    instance's copy has the object's name under another parent)."""
    keys = em.keys()
    return {"units": "texel = E/pi in W/(m^2 sr), the radiance of a white Lambertian surface",
            "uv": "uv2 (glTF TEXCOORD_1)",
            "lightmaps": [{"index": i, "lightmapColor": files[k]} for i, k in enumerate(keys)],
            "renderers": {name: {"lightmapIndex": keys.index(em.map_of[name]),
                                 "lightmapScaleOffset": [1.0, 1.0, 0.0, 0.0]}
                          | ({"path": "/".join(paths[name])} if paths and name in paths else {})
                          for name in sorted(em.map_of)}}
