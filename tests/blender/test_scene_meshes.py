"""blender.scene's readers of evaluated meshes: what Cycles renders, also for an object left in edit mode (a file
saved in edit mode opens so), whose depsgraph mesh wraps the edit mesh and reads as empty."""
import bpy
import numpy as np
import pytest

from addon.blender import scene as sc


@pytest.mark.both_versions
def test_an_object_in_edit_mode_reads_its_whole_evaluated_mesh():
    """A cube in edit mode reads 8 vertices and 12 triangles, as out of edit mode (without modifiers its depsgraph
    mesh is the edit-mesh wrapper); with a Subdivision modifier 26 and 48 (level 1, as Cycles renders it)."""
    bpy.ops.mesh.primitive_cube_add()
    cube = bpy.context.object
    depsgraph = bpy.context.evaluated_depsgraph_get()
    co, tris = sc.evaluated_triangles(cube, depsgraph)
    assert (len(co), len(tris)) == (8, 12)
    bpy.ops.object.mode_set(mode="EDIT")
    try:
        depsgraph = bpy.context.evaluated_depsgraph_get()
        co, tris = sc.evaluated_triangles(cube, depsgraph)
        assert (len(co), len(tris)) == (8, 12)
        with sc.evaluated_mesh(cube, depsgraph) as me:
            assert len(me.vertices) == 8
        cube.modifiers.new("Subdivision", "SUBSURF").levels = 1
        depsgraph = bpy.context.evaluated_depsgraph_get()
        co, tris = sc.evaluated_triangles(cube, depsgraph)
        assert (len(co), len(tris)) == (26, 48)
    finally:
        bpy.ops.object.mode_set(mode="OBJECT")


def _blender_triangles(me):
    """Blender's own loop triangles of ``me``, read element by element (the reference)."""
    me.calc_loop_triangles()
    return sc.read(me.loop_triangles, "loops", np.int32, 3).reshape(-1, 3)


def _mesh(name, co, faces):
    me = bpy.data.meshes.new(name)
    me.from_pydata([tuple(map(float, p)) for p in co], [], faces)
    me.update()
    return me


@pytest.mark.both_versions
def test_triangles_and_quads_are_tessellated_as_blender_does():
    """Meshes of triangles and quads get the corners of Blender's own loop triangles without reading them: random
    non-planar and planar concave quads (split both ways), mixed with triangles, a subdivided Suzanne; face
    starts and sizes are Blender's. A mesh with a larger face, or a quad too close to Blender's split test (a
    zero-area quad), is read from Blender (the same corners)."""
    rng = np.random.default_rng(5)
    n = 2 * sc.TESSELLATED
    meshes = []
    for planar in (False, True):
        co = rng.normal(size=(4 * n, 3))
        if planar:
            co[:, 2] = 0.0
        q = co.reshape(-1, 4, 3)
        a, b, c = q[:, 1] - q[:, 0], q[:, 2] - q[:, 0], q[:, 3] - q[:, 0]
        test = np.sum(np.cross(a, b) * np.cross(c, b), axis=1)
        scale = np.linalg.norm(a, axis=1) * np.linalg.norm(c, axis=1) * np.sum(b * b, axis=1)
        q = q[np.abs(test) > 1e-2 * scale]     # no quad near the split test's boundary (those are read)
        meshes.append(_mesh("quads", q.reshape(-1, 3), [tuple(range(4 * i, 4 * i + 4)) if i % 3
                                                        else tuple(range(4 * i, 4 * i + 3)) for i in range(len(q))]))
    bpy.ops.mesh.primitive_monkey_add()
    suzanne = bpy.context.object
    suzanne.modifiers.new("Subdivision", "SUBSURF").levels = 2
    meshes.append(suzanne.evaluated_get(bpy.context.evaluated_depsgraph_get()).data)
    flipped = 0
    for me in meshes:
        me.calc_loop_triangles()
        mine = sc._tessellated(me, sc.read(me.loop_triangle_polygons, "value", np.int32))
        assert mine is not None and mine.dtype == np.int32
        np.testing.assert_array_equal(mine, _blender_triangles(me))
        np.testing.assert_array_equal(sc.corner_triangles(me), mine)
        np.testing.assert_array_equal(sc.face_starts(me), sc.read(me.polygons, "loop_start", np.int32))
        np.testing.assert_array_equal(sc.face_sizes(me), sc.read(me.polygons, "loop_total", np.int32))
        start = sc.read(me.polygons, "loop_start", np.int32)
        flipped += int(np.sum(mine[:, 0] != start[sc.read(me.loop_triangle_polygons, "value", np.int32)]))
    assert flipped > n / 4                    # quads split at corners 1-3 (their second triangle starts there)
    hexagon = [(np.cos(a), np.sin(a), 0.0) for a in np.linspace(0, 6, 6)]
    ngon = _mesh("ngon", hexagon + [(0, 0, 1), (1, 0, 1), (1, 1, 1)], [tuple(range(6)), (6, 7, 8)])
    zero = _mesh("zero area", [(0, 0, 0), (1, 0, 0), (2, 0, 0), (3, 0, 0)], [(0, 1, 2, 3)])
    many = _mesh("ngons", [(x + np.cos(a), np.sin(a), 0.0) for x in range(300) for a in np.linspace(0, 6, 6)],
                 [tuple(range(6 * k, 6 * k + 6)) for k in range(300)])          # above TESSELLATED: read too
    for me in (ngon, zero, many):
        me.calc_loop_triangles()
        assert sc._tessellated(me, sc.read(me.loop_triangle_polygons, "value", np.int32)) is None
        np.testing.assert_array_equal(sc.corner_triangles(me), _blender_triangles(me))
        np.testing.assert_array_equal(sc.face_starts(me), sc.read(me.polygons, "loop_start", np.int32))
    assert len(many.loop_triangles) > sc.TESSELLATED
    loose = _mesh("loose", [(0, 0, 0), (1, 0, 0)], [])
    for me in (loose, bpy.data.meshes.new("empty")):
        assert sc.corner_triangles(me).shape == (0, 3) and sc.face_starts(me).shape == sc.face_sizes(me).shape == (0,)
