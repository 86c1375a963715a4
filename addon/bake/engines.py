"""The Godot and Unity files beside an exported .glb (core.io.engines; docs/lightmaps.md, "Godot 4 and Unity").

The irradiance maps of the objects the .glb carries are handed over (to Godot their directional maps instead,
in its SH mode, when every one of them has one); every file is written in the .glb's
folder under the .glb's own stem, through a temporary name and a rename.
"""
import math
import os

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


def _engine_map(scene, folder, names, kind="irradiance"):
    plan = Plan(folder, scene)
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


def engine_maps(scene, folder, names, godot=True):
    """(irradiance :class:`core.io.engines.EngineMap`, directional one or None) of the objects ``names`` for the
    engine files; InputError when none has a map to hand over or, for ``godot``, when the stacked texture would be
    too large or the nodes' names would not stay the glTF's (:func:`core.io.engines.godot_name_clashes`). The
    export script calls it before writing the .glb, so that a refusal writes nothing."""
    em = _engine_map(scene, folder, names)
    sh = _engine_map(scene, folder, names, "directional")
    sh = sh if sh.map_of and set(sh.map_of) >= set(em.map_of) else None
    if not (em.map_of or sh):
        raise InputError("--godot / --unity: no exported object has an irradiance or directional map to hand over")
    if godot:
        engines.check_godot_size(sh or em, 4 if sh else 1)
        needed = {part for parts in (sh or em).users.values() for part in parts}
        clashes = engines.godot_name_clashes([o.name for o in scene.objects], needed)
        if clashes:
            listed = "; ".join(", ".join(f"'{n}'" for n in group) for group in clashes)
            raise InputError(f"--godot: objects whose names Godot's glTF import makes alike (it writes "
                             f"{engines.GODOT_INVALID} as _, then numbers the copies): {listed}: rename them so "
                             f"that the light maps find their nodes")
    return em, sh


def write_engine_files(scene, folder, glb, names, godot=True, unity=True, maps=None):
    """Write the Godot and/or Unity files for the objects ``names`` of the export ``glb``; return their paths.
    ``maps``: :func:`engine_maps` of those objects when the caller has them (else read here)."""
    em, sh = maps or engine_maps(scene, folder, names, godot)
    out, stem = os.path.dirname(glb), os.path.splitext(os.path.basename(glb))[0]
    written = []
    if godot:
        image, where = engines.godot_sh_layers(sh) if sh else engines.godot_layers(em)
        layers = 4 * len(where) if sh else len(where)
        texture = f"{stem}.lightmap.exr"
        exr.write_exr(os.path.join(out, texture), {c: image[..., i] for i, c in enumerate("RGB")},
                      {"il:quantity": "Godot LightmapGI " + ("SH layers L0' = E0/pi, l1 packed" if sh else
                                                             "slices E/pi"),
                       "il:units": "W/(m^2 sr)", "il:slices": layers})
        written.append(os.path.join(out, texture))
        for name, text in ((texture + ".import", engines.godot_import(layers)),
                           (f"{stem}.lightmap.tres", engines.godot_resource(sh or em, texture, where, bool(sh)))):
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
        write_json(path, engines.unity_layout(em, files))
        written.append(path)
    return written


def _write_text(path, text):
    write_bytes(path, text.encode("utf-8"))
    return path

