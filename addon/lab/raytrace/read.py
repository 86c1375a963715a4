"""The user's scene as the numpy ray tracer sees it (core.raytrace.Scene): triangles with their corner
(split) normals and materials from the render-mode depsgraph, point/spot/sun lights and the world's
constant colour -- and a list of what Whitted leaves out or reads approximately."""
import math

import numpy as np
from mathutils import Vector

from ...blender import compat, render
from ...core.errors import InputError
from ...core.raytrace import Light, Material, Scene
from ...nodes import source
from ...nodes.models import BY_ID
from ...nodes.material import EMISSION, read_parameters
from ..envmap import image_pixels, is_srgb_bytes

SURFACE_TYPES = {"MESH", "CURVE", "SURFACE", "FONT", "META"}
#: Below this Roughness a Principled metal is a perfect mirror and a transmissive one smooth glass.
SMOOTH = 1e-3


def _mesh(ob, uv_maps=()):
    """(corner positions (T, 3, 3), corner normals (T, 3, 3), material index (T,), {UV map: corner UVs (T, 3, 2)})
    of an evaluated object, in object space; ``uv_maps``: the layers to read ("" = the render-active one; a layer
    the mesh lacks is left out)."""
    me = ob.to_mesh()
    if me is None:
        ob.to_mesh_clear()
        return None
    try:
        me.calc_loop_triangles()
        lt = me.loop_triangles
        co = np.zeros(len(me.vertices) * 3, np.float64)
        me.vertices.foreach_get("co", co)
        idx = np.zeros(len(lt) * 3, np.int64)
        lt.foreach_get("vertices", idx)
        nrm = np.zeros(len(lt) * 9, np.float32)
        lt.foreach_get("split_normals", nrm)
        mi = np.zeros(len(lt), np.int64)
        lt.foreach_get("material_index", mi)
        uvs = {}
        if uv_maps:
            loops = np.zeros(len(lt) * 3, np.int64)
            lt.foreach_get("loops", loops)
            render_layer = next((u for u in me.uv_layers if u.active_render), None)
            for name in uv_maps:
                layer = me.uv_layers.get(name) if name else render_layer
                if layer is None:
                    continue
                uv = np.zeros(len(me.loops) * 2, np.float64)
                layer.data.foreach_get("uv", uv)
                uvs[name] = uv.reshape(-1, 2)[loops].reshape(-1, 3, 2)
    finally:
        ob.to_mesh_clear()
    return co.reshape(-1, 3)[idx.reshape(-1, 3)], nrm.reshape(-1, 3, 3).astype(np.float64), mi, uvs


def _texture(socket, name, notes):
    """((k_d image (H, W, 3), sRGB-encoded?), UV map name) of an Image Texture feeding ``socket`` straight, or
    (None, None) with a note saying why its unlinked value is used instead."""
    node = socket.node
    if node.bl_idname != "ShaderNodeTexImage" or socket.name != "Color":
        notes.append(f"material '{name}': Base Color is driven by a {node.bl_label} node: its unlinked value is used")
        return None, None
    if node.image is None:
        notes.append(f"material '{name}': its Image Texture has no image: the unlinked Base Color is used")
        return None, None
    vector = node.inputs["Vector"]
    uv_map = ""
    if vector.is_linked:
        src = vector.links[0].from_node
        if src.bl_idname == "ShaderNodeUVMap":
            uv_map = src.uv_map
        elif not (src.bl_idname == "ShaderNodeTexCoord" and vector.links[0].from_socket.name == "UV"):
            notes.append(f"material '{name}': its Image Texture reads {src.bl_label} coordinates, not a UV map: "
                         "the unlinked Base Color is used")
            return None, None
    try:
        image = image_pixels(node.image, decode=False)
    except InputError as e:
        notes.append(f"material '{name}': {e}: the unlinked Base Color is used")
        return None, None
    srgb = is_srgb_bytes(node.image)
    if node.projection != "FLAT" or node.extension != "REPEAT" or node.interpolation != "Linear":
        notes.append(f"material '{name}': its Image Texture ({node.projection.lower()}, {node.extension.lower()}, "
                     f"{node.interpolation.lower()}) is read flat, repeated and bilinear")
    return (image, srgb), uv_map


def material(mat, notes):
    """A core Material from a Blender material: an IL material's model and parameters; else a Principled BSDF's
    Metallic 1 + Roughness 0 -> mirror (F0 = Base Color), Transmission 1 + Roughness 0 -> glass (IOR, tint = Base
    Color), otherwise Blinn-Phong from Base Color, Roughness and Specular (nodes.source.model_parameters)."""
    name = mat.name if mat is not None else "(none)"
    if mat is not None and mat.get("il_model") in BY_ID and mat.node_tree is not None:
        model = BY_ID[mat["il_model"]]
        params = {n: d for n, _, d, *_ in model.params}
        params.update(read_parameters(mat))
        params = {k: (np.asarray(v[:3], float) if isinstance(v, tuple) else v) for k, v in params.items()}
        if float(params.get("Physical", 1.0)) != 1.0:
            notes.append(f"material '{name}': empirical attenuation (Physical {params['Physical']:g}) read as 1/d²")
        const = np.zeros(3)
        if "Ka" in params:
            const += params["Ka"] * np.asarray(params.get("Ambient Light", np.zeros(3)))[:3]
            params["Ka"] = 0.0
        if EMISSION in params:
            const += np.asarray(params[EMISSION])[:3]
            params[EMISSION] = np.zeros(3)
        return Material(name, model=model.id, params={}, emission=tuple(const),
                        twin=lambda n, l, v, I, m=model, p=params: m.twin(n, l, v, I, p))
    s = source.read_surface(mat)
    node = _principled(mat)
    transmission = float(node.inputs["Transmission Weight"].default_value) if node is not None and \
        "Transmission Weight" in node.inputs else 0.0
    emission = tuple(c * s.emission_strength for c in s.emission)
    smooth = node is not None and s.roughness <= SMOOTH and (transmission >= 1 - SMOOTH or s.metallic >= 1 - SMOOTH)
    if smooth and s.base_source is not None:
        notes.append(f"material '{name}': Base Color is linked: its unlinked value is the mirror's or glass's colour")
    if node is not None and s.roughness <= SMOOTH and transmission >= 1 - SMOOTH:
        return Material(name, params={"kd": (0, 0, 0)}, ior=float(node.inputs["IOR"].default_value), tint=s.base,
                        emission=emission)
    if node is not None and s.roughness <= SMOOTH and s.metallic >= 1 - SMOOTH:
        return Material(name, params={"kd": (0, 0, 0)}, mirror=s.base, emission=emission)
    if transmission > 0 or (s.metallic > 0 and s.roughness <= SMOOTH):
        notes.append(f"material '{name}': partly transmissive or metallic: read as Blinn-Phong, no secondary rays")
    texture, uv_map = (None, None) if s.base_source is None else _texture(s.base_source, name, notes)
    texture, srgb = texture if texture is not None else (None, False)
    params, _ = source.model_parameters("BLINN_PHONG", s)
    blinn = BY_ID["BLINN_PHONG"]
    full = {n: d for n, _, d, *_ in blinn.params}
    full.update({k: v for k, v in params.items() if k != EMISSION})
    full.update({"Ka": 0.0, EMISSION: np.zeros(3)})
    full = {k: (np.asarray(v[:3], float) if isinstance(v, tuple) else v) for k, v in full.items()}
    if not s.specular:
        return Material(name, params={"kd": tuple(full["Kd"])}, emission=emission, texture=texture,
                        texture_srgb=srgb, texture_tint=tuple(full["Kd"]), uv_map=uv_map)
    return Material(name, model="BLINN_PHONG", params={}, emission=emission, texture=texture, texture_srgb=srgb,
                    texture_tint=tuple(full["Kd"]), uv_map=uv_map,
                    twin=lambda n, l, v, I, kd=None, p=full: blinn.twin(n, l, v, I, p if kd is None else
                                                                         {**p, "Kd": kd}))


def _principled(mat):
    if mat is None or not compat.uses_nodes(mat) or mat.node_tree is None:
        return None
    return next((n for n in mat.node_tree.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled"), None)


def _light(ob, m, notes):
    data = ob.data
    kind = data.type
    if kind == "AREA":
        notes.append(f"area light '{ob.name}': left out (Whitted's lights are points)")
        return None
    if kind not in {"POINT", "SPOT", "SUN"}:
        return None
    if kind in {"POINT", "SPOT"} and data.shadow_soft_size > 0:
        notes.append(f"light '{ob.name}': radius {data.shadow_soft_size:g} m read as a point (soft shadow left out)")
    if kind == "SUN" and data.angle > 0:
        notes.append(f"sun '{ob.name}': angle {math.degrees(data.angle):g}° read as 0 (soft shadow left out)")
    if kind == "SPOT" and data.spot_blend > 0:
        notes.append(f"spot '{ob.name}': blend {data.spot_blend:g} read as 0 (hard cone)")
    d = np.array(m.to_3x3() @ Vector((0.0, 0.0, -1.0)), np.float64)
    return Light(kind, float(data.energy), tuple(data.color), tuple(m.translation), tuple(d / np.linalg.norm(d)),
                 data.spot_size / 2 if kind == "SPOT" else math.pi / 4)


def world_radiance(scene, notes):
    """The world's constant radiance (RGB) for rays that leave the scene; black with a note when it is not one
    colour."""
    w = scene.world
    if w is None:
        return np.zeros(3)
    if not compat.uses_nodes(w) or w.node_tree is None:
        return np.asarray(w.color[:3], np.float64)
    outs = [n for n in w.node_tree.nodes if n.bl_idname == "ShaderNodeOutputWorld" and n.is_active_output] or \
        [n for n in w.node_tree.nodes if n.bl_idname == "ShaderNodeOutputWorld"]
    if not outs or not outs[0].inputs["Surface"].is_linked:
        return np.zeros(3)
    bg = outs[0].inputs["Surface"].links[0].from_node
    if bg.bl_idname != "ShaderNodeBackground" or bg.inputs["Color"].is_linked or bg.inputs["Strength"].is_linked:
        notes.append("world: not a constant Background: black for Whitted")
        return np.zeros(3)
    rad = np.asarray(bg.inputs["Color"].default_value[:3], np.float64) * float(bg.inputs["Strength"].default_value)
    if rad.any():
        notes.append("world: its light on surfaces (sky light) is left out; seen directly and in mirrors it is kept")
    return rad


def read(scene, accel=None):
    """(core.raytrace.Scene, notes) of what ``scene`` renders (render-mode depsgraph); ``accel``: the intersection
    engine's class (None: the numpy BVH)."""
    notes = []

    def collect(dg):
        tris, normals, mats, uvs, lights, cache, table = [], [], [], [], [], {}, {}
        for inst in dg.object_instances:
            ob = inst.object
            if not inst.show_self:
                continue
            m = inst.matrix_world.copy()
            if ob.type == "LIGHT":
                light = _light(ob, m, notes)
                if light is not None:
                    lights.append(light)
                continue
            if ob.type not in SURFACE_TYPES:
                continue
            slots = [s.material for s in ob.material_slots] or [None]
            ids = []
            for s in slots:
                k = s.name if s is not None else None
                if k not in table:
                    table[k] = (len(table), material(s, notes))
                ids.append(table[k][0])
            by_id = {i: m for i, m in table.values()}
            uv_maps = tuple(sorted({by_id[i].uv_map for i in ids if by_id[i].texture is not None}))
            key = (ob.original.as_pointer(), ob.data.as_pointer() if ob.data else 0, uv_maps)
            if key not in cache:
                cache[key] = _mesh(ob, uv_maps)
            got = cache[key]
            if got is None or not len(got[0]):
                continue
            corners, nrm, mi, layers = got
            mw = np.array(m, np.float64)
            corners = corners @ mw[:3, :3].T + mw[:3, 3]
            nm = np.linalg.inv(mw[:3, :3]).T
            nrm = nrm @ nm.T
            nrm /= np.maximum(np.linalg.norm(nrm, axis=-1, keepdims=True), 1e-300)
            mirrored = np.linalg.det(mw[:3, :3]) < 0
            if mirrored:
                corners, nrm = corners[:, ::-1], nrm[:, ::-1]
            tri_mats = np.asarray(ids)[np.clip(mi, 0, len(ids) - 1)]
            tri_uvs = np.zeros((len(corners), 3, 2))
            for i in set(ids):
                m_ = by_id[i]
                if m_.texture is None:
                    continue
                if m_.uv_map not in layers:
                    notes.append(f"material '{m_.name}' on '{ob.name}': no UV map '{m_.uv_map or 'render'}': its "
                                 "texture is read at UV (0, 0)")
                    continue
                sel = tri_mats == i
                tri_uvs[sel] = layers[m_.uv_map][sel][:, ::-1] if mirrored else layers[m_.uv_map][sel]
            tris.append(corners)
            normals.append(nrm)
            mats.append(tri_mats)
            uvs.append(tri_uvs)
        return tris, normals, mats, uvs, lights, [m for _, m in sorted(table.values(), key=lambda x: x[0])]

    tris, normals, mats, uvs, lights, materials = render.with_render_depsgraph(scene, collect)
    if not tris:
        tris, normals, mats = [np.zeros((0, 3, 3))], [np.zeros((0, 3, 3))], [np.zeros(0, np.int64)]
        uvs = [np.zeros((0, 3, 2))]
    if not lights:
        notes.append("no point, spot or sun light: only emission and the background")
    rt = Scene(np.concatenate(tris), np.concatenate(mats), materials or [Material()], lights,
               normals=np.concatenate(normals), background=world_radiance(scene, notes), uvs=np.concatenate(uvs),
               **({"accel": accel} if accel is not None else {}))
    return rt, list(dict.fromkeys(notes))
