"""Light-map bakes of meshes and scenes made with Blender's own operators: a primitive added with a negative scale
(inside out), a scene without a world, Array and Mirror copies sharing light-map texels. Closed forms from
REFERENCE.md §1 and §3."""
import math

import bpy
import bmesh  # noqa: E402  (after bpy)
import numpy as np
import pytest

from addon.bake import BakeOptions, bake_lightmaps
from addon.core.io import exr
from addon.core.errors import ILError, ILWarning
from addon.blender import compat, scene as sc


def added(op, **kw):
    op(**kw)
    obj = bpy.context.object
    obj.select_set(False)
    return obj


def normals_and_loops(obj):
    me = obj.data
    n = np.zeros(len(me.polygons) * 3)
    me.polygons.foreach_get("normal", n)
    v = np.zeros(len(me.loops), int)
    me.loops.foreach_get("vertex_index", v)
    return n, v


def vertex_values(out, name, kind):
    ch, _ = exr.read_exr(out / f"{name}_{kind}_vertex.exr")
    return ch["Y"].ravel() if kind == "ao" else np.stack([ch[c].ravel() for c in "RGB"], -1)


# ------------------------------------------------------------------ inside-out primitives (negative scale)

@pytest.mark.both_versions
def test_cube_added_with_negative_scale_bakes_its_outside(tmp_path):
    """primitive_cube_add(scale=(-1, 1, 1)) writes the scale into the vertices: object scale 1, every normal
    pointing into the cube. A unit cube alone under a uniform sky of radiance L is open on every outward face:
    k_A = 1 and E = π L exactly (REFERENCE.md §1), as for the cube added with a positive scale."""
    scene = bpy.context.scene
    sc.world(scene, strength=0.5)
    cube = added(bpy.ops.mesh.primitive_cube_add, size=1.0, scale=(-1.0, 1.0, 1.0))
    assert tuple(cube.scale) == (1.0, 1.0, 1.0) and cube.matrix_world.determinant() > 0
    before = normals_and_loops(cube)
    with pytest.warns(ILWarning, match="normals point into a closed, empty surface"):
        bake_lightmaps([cube], ["ao", "irradiance"], tmp_path / "v",
                       BakeOptions(target="vertex", samples=4, bounces=0), scene=scene)
    assert np.all(vertex_values(tmp_path / "v", "Cube", "ao") == 1.0)
    np.testing.assert_allclose(vertex_values(tmp_path / "v", "Cube", "irradiance"), math.pi * 0.5, rtol=1e-4)
    with pytest.warns(ILWarning, match="normals point into"):
        rep = bake_lightmaps([cube], ["ao"], tmp_path / "i", BakeOptions(resolution=32, samples=4, margin=1),
                             scene=scene)
    ch, _ = exr.read_exr(tmp_path / "i" / "Cube_ao.exr")
    covered = ch["A"] > 0.5
    assert covered.sum() > 0.5 * rep["objects"]["Cube"]["ao"]["chart_area"] * 32 * 32
    assert np.all(ch["Y"][covered] == 1.0)
    after = normals_and_loops(cube)            # the user's mesh faces inward again, corners in their order
    assert np.array_equal(before[0], after[0]) and np.array_equal(before[1], after[1])


def test_inside_out_room_with_a_light_inside_keeps_its_normals(tmp_path):
    """A cube whose normals face inward with a light in it is a room: its inside is baked, no warning, and its
    AO of 0 everywhere (closed, smaller than the AO distance) is a result, not an error.
    Point light P at the centre of a 4 m room, radius 0: E at the centre of a wall (d = 2 m, normal incidence)
    is P / (4π d²) (REFERENCE.md §1); the vertex bake of a subdivided wall sees it at its middle vertex."""
    scene = bpy.context.scene
    room = added(bpy.ops.mesh.primitive_cube_add, size=4.0, scale=(1.0, 1.0, -1.0))
    bm = bmesh.new()
    bm.from_mesh(room.data)
    bmesh.ops.subdivide_edges(bm, edges=bm.edges[:], cuts=1, use_grid_fill=True)
    bm.to_mesh(room.data)
    bm.free()
    sc.light(scene, "Bulb", "POINT", 100.0)
    import warnings
    with warnings.catch_warnings():
        warnings.simplefilter("error", ILWarning)
        bake_lightmaps([room], ["irradiance"], tmp_path, BakeOptions(target="vertex", samples=64, bounces=0),
                       scene=scene)
        bake_lightmaps([room], ["ao"], tmp_path / "ao", BakeOptions(target="vertex", samples=4), scene=scene)
    assert np.all(vertex_values(tmp_path / "ao", room.name, "ao") == 0.0)     # closed, within the AO distance
    e = vertex_values(tmp_path, room.name, "irradiance")[:, 0]
    co = np.array([v.co[:] for v in room.data.vertices])
    centre = np.flatnonzero(np.isclose(np.abs(co).max(axis=1), 2.0) & (np.sum(np.isclose(co, 0.0), axis=1) == 2))
    assert len(centre) == 6
    np.testing.assert_allclose(e[centre], 100.0 / (4 * math.pi * 4.0), rtol=0.02)


def test_mesh_with_one_inside_out_part_is_skipped_with_one_line(tmp_path):
    scene = bpy.context.scene
    good = added(bpy.ops.mesh.primitive_cube_add, size=1.0, location=(0, 0, 0.5))
    both = added(bpy.ops.mesh.primitive_cube_add, size=1.0, location=(3, 0, 0.5))
    flipped = added(bpy.ops.mesh.primitive_cube_add, size=1.0, location=(5, 0, 0.5), scale=(-1.0, 1.0, 1.0))
    with bpy.context.temp_override(active_object=both, selected_editable_objects=[both, flipped]):
        bpy.ops.object.join()
    with pytest.warns(ILWarning, match=r"skipped Cube\.001: 1 of its closed parts have normals pointing inward "
                                       r"and nothing inside .*Recalculate Outside"):
        rep = bake_lightmaps([good, both], ["ao"], tmp_path, BakeOptions(target="vertex", samples=2), scene=scene)
    assert list(rep["objects"]) == ["Cube"]


def test_ao_of_zero_everywhere_measured_inside_the_object_is_refused(tmp_path):
    """An inside-out cube whose faces are split apart (as from an STL import) is not a closed shell, so it is
    baked as it is: 0 on every vertex, every face looking into the cube. That map is refused, never written."""
    scene = bpy.context.scene
    cube = added(bpy.ops.mesh.primitive_cube_add, size=1.0, scale=(-1.0, 1.0, 1.0))
    bm = bmesh.new()
    bm.from_mesh(cube.data)
    bmesh.ops.split_edges(bm, edges=bm.edges[:])
    bm.to_mesh(cube.data)
    bm.free()
    with pytest.raises(ILError, match="ao: 0 on every vertex: its faces look into the object itself.*Recalculate Outside"):
        bake_lightmaps([cube], ["ao"], tmp_path, BakeOptions(target="vertex", samples=4), scene=scene)
    assert not (tmp_path / "Cube_ao_vertex.exr").exists()


# ------------------------------------------------------------------ a scene without a world

def _plane_with_uvs(scene, size):
    obj = sc.plane(scene, "R", size)
    me = obj.data
    layer = me.uv_layers.new(name="UVMap")
    co = np.array([v.co[:] for v in me.vertices])
    vi = np.array([l.vertex_index for l in me.loops])
    layer.data.foreach_set("uv", (co[vi, :2] / size + 0.5).ravel())
    return obj


@pytest.mark.both_versions
def test_scene_without_a_world_is_black_as_cycles_renders_it(tmp_path):
    """No world, no light: E = 0 exactly (a new 5.0 world is grey 0.05 unless blackened). No world, a point light
    of P = 100 W, radius 0, at height h = 2 over a 2 m plane: E = P cos θ / (4π d²) = P h / (4π d³) at every
    texel centre (REFERENCE.md §1), within the Monte Carlo noise of the two-halves estimate."""
    scene = sc.new_scene("T")
    assert scene.world is None
    plane = _plane_with_uvs(scene, 2.0)
    n = 8
    bake_lightmaps([plane], ["irradiance"], tmp_path / "dark",
                   BakeOptions(resolution=n, samples=4, bounces=0, uv_layer="UVMap", margin=0), scene=scene)
    ch, _ = exr.read_exr(tmp_path / "dark" / "R_irradiance.exr")
    assert ch["A"].min() == 1.0 and all(np.all(ch[c] == 0.0) for c in "RGB")
    assert scene.world is None and not [w for w in bpy.data.worlds if w.name.startswith("IL ")]
    sc.light(scene, "Bulb", "POINT", 100.0, location=(0, 0, 2.0))
    rep = bake_lightmaps([plane], ["irradiance"], tmp_path / "lit",
                         BakeOptions(resolution=n, samples=16, bounces=0, uv_layer="UVMap", margin=0), scene=scene)
    ch, _ = exr.read_exr(tmp_path / "lit" / "R_irradiance.exr")
    c = (np.arange(n) + 0.5) / n * 2.0 - 1.0
    x, y = np.meshgrid(c, c[::-1])
    d = np.sqrt(x * x + y * y + 4.0)
    ref = 100.0 * 2.0 / (4 * math.pi * d ** 3)
    err = rep["objects"]["R"]["irradiance"]["estimated_error"]
    for k in "RGB":
        assert abs(np.mean(ch[k] - ref)) < 4 * err / n + 1e-3 * ref.mean()      # the map's mean: 4 σ of the mean
        assert np.sqrt(np.mean((ch[k] - ref) ** 2)) < 3 * err + 1e-3 * ref.mean()


# ------------------------------------------------------------------ Array and Mirror copies

def test_array_and_mirror_copies_sharing_texels_are_reported(tmp_path):
    """The light-map layer is made on the base mesh: an Array of 3 repeats its UVs 3 times and a Mirror twice in
    the evaluated mesh, so (nearly) every covered texel holds several faces; a plain cube holds one per texel."""
    scene = bpy.context.scene
    plain = added(bpy.ops.mesh.primitive_cube_add, size=0.5, location=(0, 0, 0.25))
    row = added(bpy.ops.mesh.primitive_cube_add, size=0.5, location=(0, 3, 0.25))
    row.name = "Row"
    mod = row.modifiers.new("Three", "ARRAY")
    mod.count, mod.relative_offset_displace = 3, (1.5, 0.0, 0.0)
    pair = added(bpy.ops.mesh.primitive_cone_add, radius1=0.3, depth=0.5, location=(0.6, -3, 0.25))
    pair.name = "Pair"
    pair.modifiers.new("Sym", "MIRROR").use_axis = (True, False, False)
    with pytest.warns(ILWarning) as caught:
        rep = bake_lightmaps([plain, row, pair], ["ao"], tmp_path, BakeOptions(resolution=32, samples=1, margin=1),
                             scene=scene)
    said = [str(w.message) for w in caught]
    assert any("'Row': Array copies share the light-map texels" in m and "'Three'" in m and "apply the modifier" in m
               for m in said)
    assert any("'Pair': Mirror copies share the light-map texels" in m and "'Sym'" in m for m in said)
    assert not any("'Cube'" in m and "share" in m for m in said)
    overlap = {name: maps["ao"]["overlap"] for name, maps in rep["objects"].items()}
    assert overlap["Cube"] == 0.0 and overlap["Row"] > 0.9 and overlap["Pair"] > 0.9
    for name in ("Cube", "Row"):
        _, header = exr.read_exr(tmp_path / f"{name}_ao.exr")
        assert float(header["il:overlap"]) == pytest.approx(overlap[name], abs=1e-6)


# ------------------------------------------------------------------ wording

def test_skipped_objects_are_named_with_the_right_article(tmp_path):
    from addon.bake.options import article
    from addon.core.errors import InputError
    scene = bpy.context.scene
    bpy.ops.object.empty_add()
    empty = bpy.context.object
    bpy.ops.object.camera_add()
    cam = bpy.context.object
    with pytest.raises(InputError, match=r"'Empty' is not a mesh \(an empty\); 'Camera' is not a mesh \(a camera\)"):
        bake_lightmaps([empty, cam], ["ao"], tmp_path, BakeOptions(target="vertex", samples=1), scene=scene)
    assert [article(w) for w in ("empty", "armature", "light", "8x8", "11x11", "18x18", "80x80", "800x800",
                                 "16x16", "1024x1024", "8192x8192", "11000x11000")] == [
        "an empty", "an armature", "a light", "an 8x8", "an 11x11", "an 18x18", "an 80x80", "an 800x800",
        "a 16x16", "a 1024x1024", "an 8192x8192", "an 11000x11000"]


# ------------------------------------------------------------------ fill of generated layouts (issue 27)

def _fill(obj, side):
    from addon.bake import uv as uvmod
    from addon.core import lightmap
    return float(lightmap.coverage_mask(uvmod.triangles_uv(obj, "Lightmap"), side, side).mean())


@pytest.mark.both_versions
def test_a_map_its_charts_cannot_fill_gets_one_line_with_the_cause_and_the_side_that_fills(tmp_path):
    """A triangle soup (a split ico sphere) at 64²: one line naming the coverage, the texels per triangle and a
    side; the report carries it and its coverage is the fill measured from the UVs (5.2 and 4.5: Cycles' own
    rasteriser decides texels whose centre lies on an edge, within 1 %). A cylinder at the side a
    low-fill line suggests fills what the line says."""
    scene = bpy.context.scene
    soup = added(bpy.ops.mesh.primitive_ico_sphere_add, subdivisions=3)
    soup.name = "Soup"
    bm = bmesh.new()
    bm.from_mesh(soup.data)
    bmesh.ops.split_edges(bm, edges=bm.edges[:])
    bm.to_mesh(soup.data)
    bm.free()
    cyl = added(bpy.ops.mesh.primitive_cylinder_add, location=(3, 0, 0))
    opts = BakeOptions(resolution=64, samples=1, margin=2)
    with pytest.warns(ILWarning) as caught:
        rep = bake_lightmaps([soup, cyl], ["ao"], tmp_path / "a", opts, scene=scene)
    lines = [str(w.message) for w in caught if "light-map charts cover only" in str(w.message)]
    entry = rep["objects"]["Soup"]["ao"]
    fill = _fill(soup, 64)
    assert fill < 0.55 and entry["coverage"] == pytest.approx(fill, abs=1e-6 if compat.BAKE_TOUCHED_TEXELS else 0.01)
    soup_line = next(m for m in lines if m.startswith("'Soup'"))
    assert f"{100 * fill:.1f} %" in soup_line and "texels per triangle" in soup_line
    assert entry["low_fill"] == soup_line
    assert __import__("json").loads(exr.read_exr(tmp_path / "a" / "Soup_ao.exr")[1]["il:low_fill"])["Soup"] == soup_line
    cyl_lines = [m for m in lines if m.startswith("'Cylinder'")]
    if cyl_lines:                          # the suggested side reaches the fill it names
        side = int(cyl_lines[0].split("a resolution of about ")[1].split()[0])
        goal = float(cyl_lines[0].split(" fills ")[1].split()[0]) / 100
        bake_lightmaps([cyl], ["ao"], tmp_path / "b", opts.replace(resolution=side), scene=scene)
        assert _fill(cyl, side) >= goal - 0.02
    else:
        assert _fill(cyl, 64) >= 0.55
