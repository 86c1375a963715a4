"""Godot and Unity hand-off files (core.io.engines): what each engine reads back from them."""
import math
import re

import numpy as np

from addon.core.io import engines


def _maps():
    rng = np.random.default_rng(3)
    a = rng.uniform(0, 5, (16, 16, 3)).astype(np.float32)      # an object's own map
    b = rng.uniform(0, 5, (8, 12, 3)).astype(np.float32)       # an atlas two objects share
    return engines.EngineMap(users={"Floor": ["Floor"], "Lamp.001": ["Room", "Lamp.001"], 'Odd "x"': ['Odd "x"']},
                             map_of={"Floor": "a", "Lamp.001": "b", 'Odd "x"': "b"}, maps={"a": a, "b": b})


def _godot_read(image, side, rect, slice_index, u, v):
    """Godot's lookup of uv2 = (u, v) (glTF convention, v down): uvw.xy = uv2 * rect.size + rect.position in the
    slice, nearest texel."""
    x = u * rect[0] * side
    y = v * rect[1] * side
    return image[slice_index * side + int(y), int(x)]


def test_godot_slices_give_each_object_its_own_texels_as_e_over_pi():
    em = _maps()
    image, where = engines.godot_layers(em)
    side = 16
    assert image.shape == (2 * side, side, 3)
    for key, m in em.maps.items():
        i, rect = where[key]
        h, w = m.shape[:2]
        assert rect == (w / side, h / side)
        for y in range(h):
            for x in range(w):
                got = _godot_read(image, side, rect, i, (x + 0.5) / w, (y + 0.5) / h)
                np.testing.assert_allclose(got, m[y, x] / math.pi, rtol=1e-6)
    i, _ = where["b"]
    assert not image[i * side + 8:(i + 1) * side].any() and not image[i * side:(i + 1) * side, 12:].any()


def test_godot_resource_lists_every_user_with_its_slice_and_rect():
    em = _maps()
    _, where = engines.godot_layers(em)
    text = engines.godot_resource(em, "scene.lightmap.exr", where)
    assert text.startswith('[gd_resource type="LightmapGIData"')
    assert 'path="scene.lightmap.exr"' in text and 'lightmap_textures = [ExtResource("1_lightmap")]' in text
    users = re.findall(r'NodePath\("((?:[^"\\]|\\.)*)"\), Rect2\(0, 0, ([0-9.e-]+), ([0-9.e-]+)\), (\d+), -1',
                       text)
    assert len(users) == 3
    by_path = {p: (float(sx), float(sy), int(i)) for p, sx, sy, i in users}
    assert by_path["../Floor"] == (1.0, 1.0, where["a"][0])
    assert by_path["../Room/Lamp_001"] == (0.75, 0.5, where["b"][0])     # "." is not allowed in Godot node names
    assert by_path["../Odd _x_"][2] == where["b"][0]                 # so is '"'
    assert "slices/vertical=2" in engines.godot_import(2)


def test_unity_layout_shares_one_lightmap_per_atlas():
    em = _maps()
    layout = engines.unity_layout(em, {"a": "a.exr", "b": "b.exr"})
    r = layout["renderers"]
    assert r["Lamp.001"]["lightmapIndex"] == r['Odd "x"']["lightmapIndex"] != r["Floor"]["lightmapIndex"]
    assert [m["lightmapColor"] for m in layout["lightmaps"]] == ["a.exr", "b.exr"]
    assert all(v["lightmapScaleOffset"] == [1.0, 1.0, 0.0, 0.0] for v in r.values())
    assert "path" not in r["Floor"]
    r = engines.unity_layout(em, {"a": "a.exr", "b": "b.exr"}, {"Floor": ["Floor"], "Lamp.001": ["Room", "Lamp.001"]})
    assert r["renderers"]["Lamp.001"]["path"] == "Room/Lamp.001" and r["renderers"]["Floor"]["path"] == "Floor"


def test_godot_sh_layers_give_e_over_pi_of_the_l1_model_in_godots_frame():
    """Godot's SH decode, L0' + 4 L0' Σ (2 l1' - 1) n (n in its Y-up frame), of the four consecutive layers of a
    slice equals E(n)/π of the directional map's L1 model wherever the packing does not clamp."""
    from addon.core import directional
    rng = np.random.default_rng(5)
    a = rng.uniform(1.0, 3.0, (6, 6, 3))
    b = rng.uniform(-0.4, 0.4, (6, 6, 3, 3)) * a[..., None, :]        # |b| < a: nothing clamps
    coeffs = directional.coefficients(a, b)                               # Blender's frame, Z up
    em = engines.EngineMap({"Wall": ["Wall"]}, {"Wall": "w"}, {"w": coeffs})
    image, where = engines.godot_sh_layers(em)
    i, rect = where["w"]
    assert image.shape == (4 * 6, 6, 3) and rect == (1.0, 1.0) and i == 0
    l0, l1y, l1z, l1x = (image[k * 6:(k + 1) * 6] for k in range(4))
    for n_blender in ([0, 0, 1.0], [0.6, 0, 0.8], [0, -0.6, 0.8], [1.0, 0, 0]):
        nb = np.array(n_blender)
        ng = np.array([nb[0], nb[2], -nb[1]])                            # glTF / Godot: x, z, -y
        godot = l0 + 4 * l0 * ((2 * l1y - 1) * ng[1] + (2 * l1z - 1) * ng[2] + (2 * l1x - 1) * ng[0])
        np.testing.assert_allclose(godot, directional.irradiance(coeffs, nb) / math.pi, rtol=1e-5, atol=1e-6)
    text = engines.godot_resource(em, "s.exr", where, sh=True)
    assert "uses_spherical_harmonics = true" in text and "_uses_packed_directional = true" in text


def test_a_godot_array_too_large_is_refused_with_the_way_out():
    import pytest
    from addon.core.errors import InputError
    big = engines.EngineMap({f"O{i}": [f"O{i}"] for i in range(3)}, {f"O{i}": i for i in range(3)},
                            {0: np.zeros((4, 4, 3)), 1: np.zeros((4, 4, 3)), 2: np.zeros((4, 4, 3))})
    engines.check_godot_size(big)
    small_limit = engines.GODOT_MAX_BYTES
    try:
        engines.GODOT_MAX_BYTES = 3 * 16 * 12 - 1
        with pytest.raises(InputError, match="--atlas"):
            engines.check_godot_size(big)
    finally:
        engines.GODOT_MAX_BYTES = small_limit


def test_godot_paths_are_the_names_godots_import_gives_the_glb_nodes():
    """Godot names a glTF's nodes in index order: invalid characters as "_", a taken name numbered from 2,
    "Skeleton3D" taken first (GLTFDocument::_assign_node_names); a skin's joints and what hangs from them are not
    nodes of the scene. Paths run from the scene root through the glTF's parents, not Blender's (a light's child is
    a root node when the light is not exported)."""
    gltf = {"nodes": [{"name": "Skeleton3D"}, {"name": "x.y"}, {"name": "x_y", "children": [3]}, {"name": "x_y2"},
                      {"name": "Rig", "children": [5]}, {"name": "Bone", "children": [6]}, {"name": "OnBone"},
                      {"name": "OnSun"}],
            "skins": [{"joints": [5]}]}
    assert engines.godot_paths(gltf) == {"Skeleton3D": ["Skeleton3D2"], "x.y": ["x_y"], "x_y": ["x_y2"],
                                         "x_y2": ["x_y2", "x_y22"], "Rig": ["Rig"], "OnSun": ["OnSun"]}


def test_an_object_and_its_collection_instance_copy_are_told_apart_by_their_parents():
    """Blender 4.5's exporter writes a collection instance's copy of "Cone" (under "Props Instance") before the
    object itself (a root node; 5.x writes it after): the object's node is the one whose glTF parents are its own
    parents that the glTF holds (a lamp parent, not exported, counts as none), Godot's "Cone2" here; without the
    objects' parents the first node is taken. Unity's renderer entry carries the glTF path of the same node."""
    gltf = {"nodes": [{"name": "Props Instance", "children": [1]}, {"name": "Cone"}, {"name": "Shelf", "children": [3]},
                      {"name": "Cone"}, {"name": "Cup"}, {"name": "Props Instance 2", "children": [6]}, {"name": "Cup"}]}
    assert engines.godot_paths(gltf)["Cone"] == ["Props Instance", "Cone"]
    parents = {"Cone": ["Shelf"], "Cup": ["Sun"]}
    paths = engines.godot_paths(gltf, parents)
    assert paths["Cone"] == ["Shelf", "Cone2"] and paths["Cup"] == ["Cup"]
    nodes = engines.own_nodes(gltf, parents)
    assert nodes["Cone"] == [2, 3] and nodes["Cup"] == [4]
    assert engines.own_nodes({"nodes": [{"name": "I", "children": [1]}, {"name": "Cone"}, {"name": "Cone"}]}) == {
        "I": [0], "Cone": [0, 1]}                                           # no parents given: the first node
