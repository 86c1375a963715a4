"""blender.scene's readers of evaluated meshes: what Cycles renders, also for an object left in edit mode (a file
saved in edit mode opens so), whose depsgraph mesh wraps the edit mesh and reads as empty."""
import bpy
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
