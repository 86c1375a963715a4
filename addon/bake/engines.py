"""The Godot and Unity files beside an exported .glb (core.io.engines; docs/lightmaps.md, "Godot 4 and Unity").

The irradiance maps of the objects the .glb carries are handed over (to Godot their directional maps instead,
in its SH mode, when every one of them has one); every file is written in the .glb's
folder under the .glb's own stem, through a temporary name and a rename.
"""
import dataclasses
import math
import os

from ..core import errors
from ..core.errors import InputError
from ..core.io import engines, exr
from ..core.io.files import write_bytes
from ..core.io.files import write_json
from .gltf import Plan, read_map


def _node_parts(obj):
    parts = []
    while obj is not None:
        parts.insert(0, obj.name)
        obj = obj.parent
    return parts


def _engine_map(scene, plan, names, kind):
    users, map_of, maps = {}, {}, {}
    for name in names:
        entry = plan.maps.get(name, {}).get(kind)
        if entry is None:
            continue
        _, file = entry
        if file not in maps:
            maps[file] = read_map(kind, file)
        users[name] = _node_parts(scene.objects[name])
        map_of[name] = file
    return engines.EngineMap(users, map_of, maps)


@dataclasses.dataclass(frozen=True)
class EngineMaps:
    """What the engine files hand over: ``irradiance`` (:class:`core.io.engines.EngineMap`), ``directional`` (the
    one Godot takes instead, or None: some object has irradiance and no directional map) and ``handed`` (the objects
    with either map)."""
    irradiance: object
    directional: object
    handed: frozenset


def engine_maps(scene, folder, names, godot=True, unity=False):
    """The :class:`EngineMaps` of the objects ``names`` for the engine files; InputError when none has a map to hand
    over (for ``unity``, no irradiance map) or, for ``godot``, when the stacked texture would be too large, the
    nodes' names would not stay the glTF's (:func:`core.io.engines.godot_name_clashes`) or an object hangs from a
    bone or deforms with an armature (Godot's import moves it under the skeleton). The export script calls it
    before writing the .glb, so that a refusal writes nothing."""
    plan = Plan(folder, scene)
    em = _engine_map(scene, plan, names, "irradiance")
    every = _engine_map(scene, plan, names, "directional")
    sh = every if every.map_of and set(every.map_of) >= set(em.map_of) else None
    if not (em.map_of or sh):
        raise InputError("--godot / --unity: no exported object has an irradiance or directional map to hand over")
    if unity and not em.map_of:
        raise InputError("--unity: no exported object has an irradiance map, which is what Unity takes (directional "
                         "maps go to Godot): bake --maps irradiance too")
    if godot:
        engines.check_godot_size(sh or em, 4 if sh else 1)
        needed = {part for parts in (sh or em).users.values() for part in parts}
        clashes = engines.godot_name_clashes([o.name for o in scene.objects], needed)
        if clashes:
            listed = "; ".join(", ".join(f"'{n}'" for n in group) for group in clashes)
            raise InputError(f"--godot: objects whose names Godot's glTF import makes alike (it writes "
                             f"{engines.GODOT_INVALID} as _, then numbers the copies): {listed}: rename them so "
                             f"that the light maps find their nodes")
        rigged = sorted(name for name in (sh or em).map_of if _rigged(scene.objects[name]))
        if rigged:
            raise InputError("--godot: parented to a bone or deformed by an armature, which Godot's import moves "
                             "under the skeleton: " + ", ".join(f"'{n}'" for n in rigged) + ": parent them to an "
                             "object")
    return EngineMaps(em, sh, frozenset(em.map_of) | frozenset(every.map_of))


def _ancestors(obj):
    """Names of ``obj``'s parent, its parent's parent, ... (:func:`_node_parts` the other way, without ``obj``)."""
    return _node_parts(obj)[-2::-1]


def _rigged(obj):
    while obj is not None:
        if obj.parent is not None and obj.parent_type in ("BONE", "ARMATURE"):
            return True
        obj = obj.parent
    return False


def write_engine_files(scene, folder, glb, names, godot=True, unity=True, maps=None):
    """Write the Godot and/or Unity files for the objects ``names`` of the export ``glb``; return their paths.
    ``maps``: :func:`engine_maps` of those objects when the caller has them (else read here). Godot's node paths
    are those its import gives the .glb's nodes (:func:`core.io.engines.godot_paths`: objects whose parent the
    glTF leaves out, a camera or a light, hang from the next one up; names Godot numbers are numbered)."""
    found = maps or engine_maps(scene, folder, names, godot, unity)
    em, sh = found.irradiance, found.directional
    for asked, engine, covered, why in ((godot, "Godot", (sh or em).map_of, "a directional map only, while others "
                                         "have irradiance only: Godot takes one kind for all"),
                                        (unity, "Unity", em.map_of, "no irradiance map, which is what Unity takes")):
        left = sorted(found.handed - set(covered))
        if asked and left:
            errors.warn(f"not in the {engine} files ({why}; bake irradiance for them too): " + ", ".join(left))
    out, stem = os.path.dirname(glb), os.path.splitext(os.path.basename(glb))[0]
    written = []
    gltf = engines.read_glb_json(glb)
    ancestors = {n: _ancestors(scene.objects[n]) for n in found.handed if n in scene.objects}
    if godot:
        taken = sh or em
        paths = engines.godot_paths(gltf, ancestors)
        lost = sorted(name for name in taken.map_of if name not in paths)
        if lost:
            raise InputError("--godot: not a node of the .glb: " + ", ".join(lost))
        taken = dataclasses.replace(taken, users={name: paths[name] for name in taken.map_of})
        image, where = engines.godot_sh_layers(taken) if sh else engines.godot_layers(taken)
        layers = 4 * len(where) if sh else len(where)
        texture = f"{stem}.lightmap.exr"
        exr.write_exr(os.path.join(out, texture), {c: image[..., i] for i, c in enumerate("RGB")},
                      {"il:quantity": "Godot LightmapGI " + ("SH layers L0' = E0/pi, l1 packed" if sh else
                                                             "slices E/pi"),
                       "il:units": "W/(m^2 sr)", "il:slices": layers})
        written.append(os.path.join(out, texture))
        for name, text in ((texture + ".import", engines.godot_import(layers)),
                           (f"{stem}.lightmap.tres", engines.godot_resource(taken, texture, where, bool(sh)))):
            written.append(_write_text(os.path.join(out, name), text))
    if unity and em.map_of:
        files = {}
        for i, key in enumerate(em.keys()):
            files[key] = f"{stem}.unity_lightmap_{i}.exr"
            rgb = em.maps[key] / math.pi
            exr.write_exr(os.path.join(out, files[key]), {c: rgb[..., j] for j, c in enumerate("RGB")},
                          {"il:quantity": "E/pi (Unity lightmapColor)", "il:units": "W/(m^2 sr)"})
            written.append(os.path.join(out, files[key]))
        path = os.path.join(out, f"{stem}.unity.json")
        nodes = gltf.get("nodes", [])
        paths = {name: [nodes[i].get("name") for i in chain]
                 for name, chain in engines.own_nodes(gltf, ancestors).items()}
        write_json(path, engines.unity_layout(em, files, paths))
        written.append(path)
    return written


def _write_text(path, text):
    write_bytes(path, text.encode("utf-8"))
    return path

