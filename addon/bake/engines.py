"""The Godot and Unity files beside an exported .glb (core.io.engines; docs/lightmaps.md, "Godot 4 and Unity").

Only the irradiance maps of the objects the .glb carries are handed over; every file is written in the .glb's
folder under the .glb's own stem, through a temporary name and a rename.
"""
import math
import os

import numpy as np

from ..core.io import engines, exr
from ..core.io.files import write_json
from .gltf import Plan


def _node_parts(obj):
    parts = []
    while obj is not None:
        parts.insert(0, obj.name)
        obj = obj.parent
    return parts


def _engine_map(scene, folder, names):
    plan = Plan(folder, scene)
    users, map_of, maps = {}, {}, {}
    for name in names:
        entry = plan.maps.get(name, {}).get("irradiance")
        if entry is None:
            continue
        _, file = entry
        if file not in maps:
            channels, _ = exr.read_exr(file)
            maps[file] = exr_rgb(channels)
        users[name] = _node_parts(scene.objects[name])
        map_of[name] = file
    return engines.EngineMap(users, map_of, maps)


def exr_rgb(channels):
    """(H, W, 3) of an irradiance EXR's R, G, B."""
    return np.stack([channels[c] for c in "RGB"], axis=-1)


def write_engine_files(scene, folder, glb, names, godot=True, unity=True):
    """Write the Godot and/or Unity files for the objects ``names`` of the export ``glb``; return their paths."""
    em = _engine_map(scene, folder, names)
    if not em.map_of:
        return []
    out, stem = os.path.dirname(glb), os.path.splitext(os.path.basename(glb))[0]
    written = []
    if godot:
        image, where = engines.godot_layers(em)
        texture = f"{stem}.lightmap.exr"
        exr.write_exr(os.path.join(out, texture), {c: image[..., i] for i, c in enumerate("RGB")},
                      {"il:quantity": "E/pi (Godot LightmapGI slices)", "il:units": "W/(m^2 sr)",
                       "il:slices": len(where)})
        written.append(os.path.join(out, texture))
        for name, text in ((texture + ".import", engines.godot_import(len(where))),
                           (f"{stem}.lightmap.tres", engines.godot_resource(em, texture, where))):
            written.append(_write_text(os.path.join(out, name), text))
    if unity:
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
    tmp = f"{path}.{os.getpid()}.tmp"
    with open(tmp, "w", encoding="utf-8", newline="\n") as f:
        f.write(text)
    os.replace(tmp, path)
    return path

