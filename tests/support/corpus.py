"""A corpus of .blend files made the way users make them, for end-to-end tests of every tool.

Only Blender's own operators, data API and importers/exporters build these files, never the
project's builders (addon/lab/*): every mesh primitive, unapplied modifiers, linked duplicates,
odd meshes, files that went out and back through OBJ/PLY/STL/glTF, emissive meshes, and objects
the tools cannot handle. Each .blend starts from Blender's default file (its Camera, point Light
and World) and adds a sun, a spot and an area light.

``build(outdir) -> manifest`` runs the building in a subprocess of ``sys.executable`` (the bpy
module) so the caller's bpy state is untouched, and reuses ``outdir`` when its manifest was made
by the same corpus.py and Python. ``python tests/support/corpus.py OUTDIR`` does the same and
prints the manifest's path.

Manifest (``manifest.json``): {"hash", "blender", "files": {STEM: {"path", "camera", "world",
"lights": [{"name", "type"}], "meshes": [{"name", "kind", "faces", "materials", "uv",
"hidden_render", "emissive"}], "unsupported": [{"name", "type", "kind"}], "objects": {NAME:
KIND}, "emitters": [NAME], "receiver": NAME or None}}}; public_like adds "scan", "soup", "gltf",
"gltf_image", "multi", "slots": [{"material", "color", "emission", "strength"}], "area_lights", "sky".
"""
import hashlib
import json
import os
import shutil
import subprocess
import sys
import tempfile

MANIFEST = "manifest.json"
EXPORT_NAMES = {"obj": "shapes.obj", "ply": "monkey.ply", "stl": "column.stl", "gltf": "balls.glb"}
SUN_STRENGTH = 3.0                 # W/m^2
SUN_ROTATION = (0.5, 0.2, 0.4)     # XYZ Euler, radians
SKY_UPPER, SKY_LOWER = 1.0, 0.2    # modifiers.blend world: lat-long texture, radiance above / below the horizon
FILES = ("primitives", "modifiers", "odd_meshes", "imported", "emissive", "unsupported", "public_like")
PUBLIC_SLOTS = (("Slot Red", (0.8, 0.1, 0.1), None, 0.0), ("Slot Green", (0.1, 0.7, 0.1), None, 0.0),
                ("Slot Glow", (0.5, 0.5, 0.5), (1.0, 0.6, 0.2), 3.0))   # public_like's multi-material mesh
PUBLIC_SKY = (2.0, 0.3)            # public_like's .hdr world: radiance at the zenith, below the horizon


def corpus_hash():
    """Content hash of this file and the interpreter that builds with it."""
    with open(os.path.abspath(__file__), "rb") as f:
        data = f.read()
    return hashlib.sha256(data + sys.executable.encode()).hexdigest()[:16]


def _valid(outdir, digest):
    path = os.path.join(outdir, MANIFEST)
    try:
        with open(path) as f:
            manifest = json.load(f)
    except (OSError, ValueError):
        return None
    if manifest.get("hash") != digest:
        return None
    if not all(os.path.isfile(entry["path"]) for entry in manifest["files"].values()):
        return None
    return manifest


def build(outdir, timeout=600):
    """Build the corpus into ``outdir`` (or reuse it) and return the manifest dict.

    The files are made in a sibling temporary folder and moved into place, so two concurrent
    builders never see half a corpus.
    """
    outdir = os.path.abspath(outdir)
    digest = corpus_hash()
    manifest = _valid(outdir, digest)
    if manifest is not None:
        return manifest
    parent = os.path.dirname(outdir)
    os.makedirs(parent, exist_ok=True)
    work = tempfile.mkdtemp(prefix=".corpus-", dir=parent)
    try:
        proc = subprocess.run([sys.executable, os.path.abspath(__file__), "--inside", work, outdir, digest],
                              capture_output=True, text=True, timeout=timeout)
        if proc.returncode != 0:
            tail = "\n".join((proc.stderr or proc.stdout).strip().splitlines()[-15:])
            raise RuntimeError(f"corpus build failed (exit {proc.returncode}):\n{tail}")
        if os.path.isdir(outdir) and _valid(outdir, digest) is None:
            shutil.rmtree(outdir, ignore_errors=True)
        try:
            os.rename(work, outdir)
        except OSError:
            if _valid(outdir, digest) is None:      # another builder won the race with the same content
                raise
    finally:
        if os.path.isdir(work):
            shutil.rmtree(work, ignore_errors=True)
    manifest = _valid(outdir, digest)
    if manifest is None:
        raise RuntimeError(f"corpus build wrote no valid manifest in {outdir}")
    return manifest


# ----------------------------------------------------------------------------------------------
# Everything below runs inside the builder subprocess (imports bpy).


def _use_nodes(idblock):
    """use_nodes = True where it still means something (4.5; deprecated and always True in 5.x)."""
    prop = idblock.bl_rna.properties.get("use_nodes")
    if prop is not None and not getattr(prop, "is_deprecated", False) and not idblock.use_nodes:
        idblock.use_nodes = True


def _builder():
    import bmesh
    import bpy

    def new_file():
        """Blender's default file, minus the default cube; a sun, a spot and an area light added."""
        bpy.ops.wm.read_factory_settings(use_empty=False)
        scene = bpy.context.scene
        cube = bpy.data.objects.get("Cube")
        if cube is not None:
            bpy.data.objects.remove(cube)
            if "Cube" in bpy.data.meshes and bpy.data.meshes["Cube"].users == 0:
                bpy.data.meshes.remove(bpy.data.meshes["Cube"])
        if scene.world is None:
            scene.world = bpy.data.worlds.new("World")
        world = scene.world
        _use_nodes(world)
        bg = world.node_tree.nodes.get("Background")
        if bg is not None:
            bg.inputs["Color"].default_value = (0.05, 0.05, 0.06, 1.0)
            bg.inputs["Strength"].default_value = 1.0
        light = bpy.data.objects.get("Light")
        if light is not None:
            light.data.energy = 800.0
        bpy.ops.object.light_add(type="SUN", location=(2.0, -2.0, 8.0), rotation=SUN_ROTATION)
        bpy.context.object.data.energy = SUN_STRENGTH
        bpy.ops.object.light_add(type="SPOT", location=(-4.0, -4.0, 6.0), rotation=(0.7, 0.0, -0.78))
        bpy.context.object.data.energy = 600.0
        bpy.ops.object.light_add(type="AREA", location=(0.0, 3.0, 5.0), rotation=(-0.5, 0.0, 0.0))
        bpy.context.object.data.energy = 300.0
        bpy.context.object.data.size = 2.0
        scene.render.resolution_x, scene.render.resolution_y = 64, 48
        deselect()
        return scene

    def deselect():
        for o in bpy.context.view_layer.objects:
            o.select_set(False)

    def principled(name, color, emission=None, strength=0.0):
        mat = bpy.data.materials.new(name)
        _use_nodes(mat)
        bsdf = mat.node_tree.nodes["Principled BSDF"]
        bsdf.inputs["Base Color"].default_value = (*color, 1.0)
        if emission is not None:
            bsdf.inputs["Emission Color"].default_value = (*emission, 1.0)
            bsdf.inputs["Emission Strength"].default_value = strength
        return mat

    def give(obj, mat):
        obj.data.materials.append(mat)
        return obj

    def added():
        obj = bpy.context.object
        deselect()
        return obj

    def ngon_mesh(name, verts, faces, edges=()):
        me = bpy.data.meshes.new(name)
        me.from_pydata(verts, list(edges), faces)
        me.update()
        obj = bpy.data.objects.new(name, me)
        bpy.context.collection.objects.link(obj)
        return obj

    def uv_unwrap(obj):
        """A UV layer as a user makes it: edit mode, select all, Smart UV Project."""
        bpy.context.view_layer.objects.active = obj
        obj.select_set(True)
        bpy.ops.object.mode_set(mode="EDIT")
        bpy.ops.mesh.select_all(action="SELECT")
        bpy.ops.uv.smart_project()
        bpy.ops.object.mode_set(mode="OBJECT")
        deselect()

    def save(outdir, stem):
        path = os.path.join(outdir, stem + ".blend")
        bpy.ops.wm.save_as_mainfile(filepath=path, compress=False, relative_remap=True)
        return path

    # ------------------------------------------------------------------ primitives.blend
    def primitives(outdir):
        new_file()
        kinds = {}
        colors = [(0.8, 0.2, 0.2), (0.2, 0.8, 0.2), (0.2, 0.3, 0.8), (0.8, 0.8, 0.2), (0.8, 0.3, 0.8),
                  (0.2, 0.8, 0.8), (0.9, 0.6, 0.3), (0.6, 0.6, 0.6), (0.4, 0.7, 0.3), (0.8, 0.8, 0.8)]
        ops = [
            ("cube", lambda: bpy.ops.mesh.primitive_cube_add(size=1.0, location=(-2.0, -1.0, 0.5))),
            ("uv_sphere", lambda: bpy.ops.mesh.primitive_uv_sphere_add(radius=0.5, location=(-0.7, -1.0, 0.5))),
            ("ico_sphere", lambda: bpy.ops.mesh.primitive_ico_sphere_add(radius=0.5, location=(0.6, -1.0, 0.5))),
            ("cylinder", lambda: bpy.ops.mesh.primitive_cylinder_add(radius=0.4, depth=1.0,
                                                                    location=(1.9, -1.0, 0.5))),
            ("cone", lambda: bpy.ops.mesh.primitive_cone_add(radius1=0.5, depth=1.0, location=(-2.0, 1.0, 0.5))),
            ("torus", lambda: bpy.ops.mesh.primitive_torus_add(location=(-0.6, 1.0, 0.25),
                                                              major_radius=0.5, minor_radius=0.2)),
            ("monkey", lambda: bpy.ops.mesh.primitive_monkey_add(size=1.0, location=(0.7, 1.0, 0.6))),
            ("grid", lambda: bpy.ops.mesh.primitive_grid_add(size=1.0, location=(2.0, 1.0, 0.3))),
            ("circle_filled", lambda: bpy.ops.mesh.primitive_circle_add(radius=0.5, fill_type="NGON",
                                                                       location=(0.0, 0.0, 0.05))),
            ("plane", lambda: bpy.ops.mesh.primitive_plane_add(size=8.0, location=(0.0, 0.0, 0.0))),
        ]
        for (kind, op), color in zip(ops, colors):
            op()
            obj = added()
            give(obj, principled(f"{obj.name} Material", color))
            kinds[obj.name] = "primitive:" + kind
        bpy.data.objects["Suzanne"].rotation_euler = (0.0, 0.0, 0.6)
        return save(outdir, "primitives"), kinds, {"receiver": "Plane"}

    # ------------------------------------------------------------------ modifiers.blend
    def modifiers(outdir):
        new_file()
        kinds = {}
        bpy.ops.mesh.primitive_plane_add(size=8.0)
        floor = added()
        give(floor, principled("Floor Material", (0.7, 0.7, 0.7)))
        kinds[floor.name] = "primitive:plane"

        def mod(add, kind, mtype, name, setup, color):
            add()
            obj = added()
            obj.name = name
            bpy.context.view_layer.objects.active = obj
            bpy.ops.object.modifier_add(type=mtype)
            setup(obj.modifiers[-1])
            give(obj, principled(f"{name} Material", color))
            kinds[obj.name] = "modifier:" + kind
            return obj

        def bevel(m):
            m.width, m.segments = 0.08, 2

        def subsurf(m):
            m.levels, m.render_levels = 2, 2

        def array(m):
            m.count = 3
            m.relative_offset_displace = (1.2, 0.0, 0.0)

        def mirror(m):
            m.use_axis = (True, False, False)

        def solidify(m):
            m.thickness = 0.1

        mod(lambda: bpy.ops.mesh.primitive_cube_add(size=0.8, location=(-2.5, -2.0, 0.4)),
            "bevel", "BEVEL", "Bevelled", bevel, (0.8, 0.3, 0.2))
        mod(lambda: bpy.ops.mesh.primitive_cube_add(size=0.8, location=(-1.0, -2.0, 0.5)),
            "subdivision", "SUBSURF", "Subdivided", subsurf, (0.2, 0.7, 0.3))
        mod(lambda: bpy.ops.mesh.primitive_cube_add(size=0.4, location=(0.3, -2.0, 0.2)),
            "array", "ARRAY", "Arrayed", array, (0.2, 0.3, 0.8))
        mirrored = mod(lambda: bpy.ops.mesh.primitive_monkey_add(size=0.8, location=(2.5, -2.0, 0.5)),
                       "mirror", "MIRROR", "Mirrored", mirror, (0.8, 0.7, 0.2))
        mirrored.modifiers[-1].use_clip = False
        mod(lambda: bpy.ops.mesh.primitive_grid_add(size=1.0, location=(-2.5, 0.0, 0.6),
                                                    rotation=(0.4, 0.0, 0.0)),
            "solidify", "SOLIDIFY", "Solidified", solidify, (0.5, 0.5, 0.8))

        bpy.ops.mesh.primitive_uv_sphere_add(radius=0.45, location=(-0.7, 0.2, 0.75))
        cutter = added()
        cutter.name = "Cutter"
        cutter.display_type = "WIRE"
        cutter.hide_render = True
        kinds[cutter.name] = "boolean_cutter"

        def boolean(m):
            m.operation = "DIFFERENCE"
            m.object = cutter

        mod(lambda: bpy.ops.mesh.primitive_cube_add(size=0.8, location=(-1.0, 0.0, 0.4)),
            "boolean", "BOOLEAN", "Booleaned", boolean, (0.8, 0.5, 0.5))

        # Alt-D: a linked duplicate sharing the mesh
        bpy.ops.mesh.primitive_cylinder_add(radius=0.3, depth=0.8, location=(0.6, 0.0, 0.4))
        original = added()
        original.name = "Pillar"
        give(original, principled("Pillar Material", (0.6, 0.4, 0.3)))
        kinds[original.name] = "linked_original"
        bpy.context.view_layer.objects.active = original
        original.select_set(True)
        bpy.ops.object.duplicate(linked=True)
        linked = bpy.context.object
        linked.location = (1.4, 0.0, 0.4)
        linked.name = "Pillar Linked"
        deselect()
        kinds[linked.name] = "linked_duplicate"

        bpy.ops.mesh.primitive_cube_add(size=0.6, location=(2.5, 0.0, 0.3))
        neg = added()
        neg.scale = (-1.0, 1.0, 1.0)           # the operator's scale= would go into the vertices
        neg.name = "Negative Scale"
        give(neg, principled("Negative Material", (0.3, 0.8, 0.8)))
        kinds[neg.name] = "negative_scale"

        bpy.ops.mesh.primitive_uv_sphere_add(radius=0.5, location=(-2.5, 2.0, 0.3))
        squash = added()
        squash.scale = (1.6, 0.6, 0.6)
        squash.name = "Non-uniform Scale"
        give(squash, principled("Squashed Material", (0.9, 0.9, 0.5)))
        kinds[squash.name] = "non_uniform_scale"

        bpy.ops.mesh.primitive_cube_add(size=0.5, location=(-1.0, 2.0, 0.25))
        parent = added()
        parent.name = "Parent"
        give(parent, principled("Parent Material", (0.4, 0.4, 0.9)))
        kinds[parent.name] = "parent"
        bpy.ops.mesh.primitive_ico_sphere_add(radius=0.2, location=(-1.0, 2.0, 0.75))
        child = added()
        child.name = "Child"
        give(child, principled("Child Material", (0.9, 0.4, 0.4)))
        child.select_set(True)
        parent.select_set(True)
        bpy.context.view_layer.objects.active = parent
        bpy.ops.object.parent_set(type="OBJECT", keep_transform=True)
        deselect()
        parent.rotation_euler = (0.0, 0.0, 0.5)
        kinds[child.name] = "parented_child"

        # a collection and an instance of it (Add > Collection Instance)
        props = bpy.data.collections.new("Props")
        bpy.context.scene.collection.children.link(props)
        bpy.ops.mesh.primitive_cone_add(radius1=0.25, depth=0.5, location=(0.4, 2.0, 0.25))
        prop = added()
        prop.name = "Prop Cone"
        for c in list(prop.users_collection):
            c.objects.unlink(prop)
        props.objects.link(prop)
        give(prop, principled("Prop Material", (0.3, 0.9, 0.3)))
        kinds[prop.name] = "collection_member"
        bpy.ops.object.collection_instance_add(collection=props.name, location=(1.2, 2.0, 0.0))
        inst = added()
        inst.name = "Props Instance"
        kinds[inst.name] = "collection_instance"

        # several materials on one mesh
        bpy.ops.mesh.primitive_cube_add(size=0.6, location=(2.4, 2.0, 0.3))
        multi = added()
        multi.name = "Multi Material"
        for i, color in enumerate([(0.9, 0.1, 0.1), (0.1, 0.9, 0.1), (0.1, 0.1, 0.9)]):
            give(multi, principled(f"Multi {i}", color))
        for poly in multi.data.polygons:
            poly.material_index = poly.index % 3
        kinds[multi.name] = "multi_material"

        # an image-textured Principled material, image generated and packed
        bpy.ops.mesh.primitive_uv_sphere_add(radius=0.35, location=(0.0, -0.8, 0.35))
        textured = added()
        textured.name = "Textured"
        image = bpy.data.images.new("Checker", 32, 32)
        px = [((x // 4 + y // 4) % 2) * 0.8 + 0.1 for y in range(32) for x in range(32)]
        image.pixels[:] = [c for v in px for c in (v, v * 0.7, 0.3, 1.0)]
        image.pack()
        mat = principled("Textured Material", (1.0, 1.0, 1.0))
        tex = mat.node_tree.nodes.new("ShaderNodeTexImage")
        tex.image = image
        mat.node_tree.links.new(tex.outputs["Color"], mat.node_tree.nodes["Principled BSDF"].inputs["Base Color"])
        give(textured, mat)
        kinds[textured.name] = "image_textured"

        # the world lit by a lat-long image, as with an HDRI: SKY_UPPER above the horizon, SKY_LOWER below
        w, h = 64, 32
        sky = bpy.data.images.new("Sky", w, h, float_buffer=True)
        sky.pixels[:] = [c for row in range(h) for v in [SKY_UPPER if row >= h // 2 else SKY_LOWER]
                         for _ in range(w) for c in (v, v, v, 1.0)]
        sky.pack()
        nt = bpy.context.scene.world.node_tree
        env = nt.nodes.new("ShaderNodeTexEnvironment")
        env.image = sky
        nt.links.new(env.outputs["Color"], nt.nodes["Background"].inputs["Color"])
        return save(outdir, "modifiers"), kinds, {"receiver": floor.name, "sky": [SKY_UPPER, SKY_LOWER]}

    # ------------------------------------------------------------------ odd_meshes.blend
    def odd_meshes(outdir):
        new_file()
        kinds = {}
        bpy.ops.mesh.primitive_plane_add(size=8.0)
        floor = added()
        give(floor, principled("Floor Material", (0.7, 0.7, 0.7)))
        kinds[floor.name] = "primitive:plane"

        # n-gons: an L-shaped (concave) prism with 6-sided caps
        prof = [(0, 0), (1, 0), (1, 0.4), (0.4, 0.4), (0.4, 1), (0, 1)]
        verts = [(x - 2.8, y - 2.5, z) for z in (0.0, 0.5) for x, y in prof]
        faces = [tuple(range(5, -1, -1)), tuple(range(6, 12))]
        faces += [(i, (i + 1) % 6, (i + 1) % 6 + 6, i + 6) for i in range(6)]
        give(ngon_mesh("NGon Prism", verts, faces), principled("NGon Material", (0.8, 0.3, 0.2)))
        kinds["NGon Prism"] = "ngons"

        # zero-area face: the top of a cube scaled to a point (S 0 in edit mode)
        bpy.ops.mesh.primitive_cube_add(size=0.8, location=(-1.0, -2.0, 0.4))
        zero = added()
        zero.name = "Zero Area"
        top = [v for v in zero.data.vertices if v.co.z > 0]
        for v in top:
            v.co = (0.0, 0.0, 0.4)
        give(zero, principled("Zero Material", (0.2, 0.8, 0.3)))
        kinds[zero.name] = "zero_area_faces"

        # colinear faces: a strip of good quads plus two triangles whose corners lie on a line
        verts = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (2, 0, 0), (3, 0, 0), (2, 1, 0)]
        faces = [(0, 1, 2, 3), (1, 4, 5), (2, 1, 6)]
        verts = [(x * 0.5 + 0.5, y * 0.5 - 2.5, 0.3) for x, y, _ in verts]
        verts[6] = (verts[2][0] + 0.5, verts[2][1] + 0.5, 0.3)      # 2, 1, 6 are not colinear
        verts[5] = (verts[4][0] + 0.5, verts[4][1], 0.3)             # 1, 4, 5 are
        give(ngon_mesh("Colinear", verts, faces), principled("Colinear Material", (0.2, 0.3, 0.8)))
        kinds["Colinear"] = "colinear_faces"

        # a single triangle (a circle with three vertices, filled)
        bpy.ops.mesh.primitive_circle_add(vertices=3, radius=0.5, fill_type="NGON", location=(2.5, -2.0, 0.3))
        tri = added()
        tri.name = "Triangle"
        give(tri, principled("Triangle Material", (0.8, 0.8, 0.2)))
        kinds[tri.name] = "single_triangle"

        # non-manifold: three faces sharing one edge
        verts = [(0, 0, 0), (0, 0, 0.6), (0.6, 0, 0), (-0.4, 0.4, 0), (-0.4, -0.4, 0)]
        verts = [(x - 2.5, y, z + 0.1) for x, y, z in verts]
        faces = [(0, 2, 1), (0, 1, 3), (0, 4, 1)]
        give(ngon_mesh("Non-manifold", verts, faces), principled("NM Material", (0.8, 0.3, 0.8)))
        kinds["Non-manifold"] = "non_manifold"

        # loose vertices and edges beside the faces of a cube (bmesh, as add-on scripts do)
        bpy.ops.mesh.primitive_cube_add(size=0.6, location=(-1.0, 0.0, 0.3))
        loose = added()
        loose.name = "Loose Parts"
        bm = bmesh.new()
        bm.from_mesh(loose.data)
        a = bm.verts.new((0.8, 0.0, 0.0))
        b = bm.verts.new((0.8, 0.5, 0.0))
        bm.edges.new((a, b))
        bm.verts.new((0.0, 0.8, 0.8))
        bm.to_mesh(loose.data)
        bm.free()
        give(loose, principled("Loose Material", (0.2, 0.8, 0.8)))
        kinds[loose.name] = "loose_verts_edges"

        # Mesh.from_pydata (Mesh.update(calc_edges=True) inside): a closed tetrahedron
        verts = [(0, 0, 0), (0.8, 0, 0), (0.4, 0.7, 0), (0.4, 0.25, 0.7)]
        verts = [(x + 0.3, y - 0.2, z) for x, y, z in verts]
        faces = [(0, 2, 1), (0, 1, 3), (1, 2, 3), (2, 0, 3)]
        me = bpy.data.meshes.new("Pydata Tetra")
        me.from_pydata(verts, [], faces)
        me.update(calc_edges=True)
        tet = bpy.data.objects.new("Pydata Tetra", me)
        bpy.context.collection.objects.link(tet)
        give(tet, principled("Tetra Material", (0.9, 0.6, 0.3)))
        kinds[tet.name] = "from_pydata"

        # bmesh-made sphere
        me = bpy.data.meshes.new("BMesh Sphere")
        bm = bmesh.new()
        bmesh.ops.create_uvsphere(bm, u_segments=16, v_segments=8, radius=0.4)
        bmesh.ops.translate(bm, verts=bm.verts, vec=(2.0, 0.0, 0.45))
        bm.to_mesh(me)
        bm.free()
        sph = bpy.data.objects.new("BMesh Sphere", me)
        bpy.context.collection.objects.link(sph)
        give(sph, principled("BMesh Material", (0.6, 0.9, 0.4)))
        kinds[sph.name] = "bmesh"
        return save(outdir, "odd_meshes"), kinds, {"receiver": floor.name}

    # ------------------------------------------------------------------ imported.blend
    def imported(outdir, tmp):
        new_file()
        bpy.ops.mesh.primitive_torus_add(location=(-1.5, -1.0, 0.25), major_radius=0.5, minor_radius=0.2)
        give(added(), principled("Torus Red", (0.8, 0.2, 0.2)))
        bpy.ops.mesh.primitive_cube_add(size=0.7, location=(0.0, -1.0, 0.35))
        give(added(), principled("Cube Green", (0.2, 0.8, 0.2)))
        bpy.ops.mesh.primitive_monkey_add(size=0.8, location=(1.5, -1.0, 0.5))
        added()
        bpy.ops.mesh.primitive_cylinder_add(radius=0.35, depth=0.8, location=(-1.5, 1.0, 0.4))
        added()
        bpy.ops.mesh.primitive_uv_sphere_add(radius=0.4, location=(0.0, 1.0, 0.4))
        give(added(), principled("Sphere Blue", (0.2, 0.3, 0.8)))
        bpy.ops.mesh.primitive_cone_add(radius1=0.4, depth=0.8, location=(1.5, 1.0, 0.4))
        give(added(), principled("Cone Yellow", (0.8, 0.8, 0.2)))
        bpy.ops.mesh.primitive_plane_add(size=8.0)
        give(added(), principled("Ground", (0.7, 0.7, 0.7)))
        groups = {"obj": ["Torus", "Cube", "Plane"], "ply": ["Suzanne"], "stl": ["Cylinder"],
                  "gltf": ["Sphere", "Cone"]}
        paths = {}
        for fmt, names in groups.items():
            deselect()
            for n in names:
                bpy.data.objects[n].select_set(True)
            path = os.path.join(tmp, EXPORT_NAMES[fmt])
            if fmt == "obj":
                bpy.ops.wm.obj_export(filepath=path, export_selected_objects=True, export_materials=True)
            elif fmt == "ply":
                bpy.ops.wm.ply_export(filepath=path, export_selected_objects=True)
            elif fmt == "stl":
                bpy.ops.wm.stl_export(filepath=path, export_selected_objects=True)
            else:
                bpy.ops.export_scene.gltf(filepath=path, export_format="GLB", use_selection=True)
            paths[fmt] = path

        new_file()
        kinds = {}
        for fmt, path in paths.items():
            before = set(bpy.data.objects)
            if fmt == "obj":
                bpy.ops.wm.obj_import(filepath=path)
            elif fmt == "ply":
                bpy.ops.wm.ply_import(filepath=path)
            elif fmt == "stl":
                bpy.ops.wm.stl_import(filepath=path)
            else:
                bpy.ops.import_scene.gltf(filepath=path)
            for obj in set(bpy.data.objects) - before:
                kinds[obj.name] = "import:" + fmt
        deselect()
        receiver = next((n for n, k in kinds.items() if k == "import:obj" and n.startswith("Plane")), None)
        return save(outdir, "imported"), kinds, {"receiver": receiver}

    # ------------------------------------------------------------------ emissive.blend
    def emissive(outdir):
        new_file()
        kinds = {}
        # a room a user makes: a cube, front face deleted, normals flipped inward; walls coloured
        bpy.ops.mesh.primitive_cube_add(size=2.0, location=(0.0, 0.0, 1.0))
        room = added()
        room.name = "Room"
        for mat in (principled("White", (0.73, 0.73, 0.73)), principled("Red", (0.63, 0.065, 0.05)),
                    principled("Green", (0.14, 0.45, 0.09))):
            give(room, mat)
        bm = bmesh.new()
        bm.from_mesh(room.data)
        front = [f for f in bm.faces if f.normal.y < -0.9]
        bmesh.ops.delete(bm, geom=front, context="FACES")
        bmesh.ops.reverse_faces(bm, faces=bm.faces)
        for f in bm.faces:
            f.material_index = 1 if f.normal.x > 0.9 else 2 if f.normal.x < -0.9 else 0
        bm.to_mesh(room.data)
        bm.free()
        kinds[room.name] = "room_open_box"

        bpy.ops.mesh.primitive_plane_add(size=0.5, location=(0.0, 0.0, 1.98), rotation=(3.14159265, 0.0, 0.0))
        lamp = added()
        lamp.name = "Ceiling Lamp"
        give(lamp, principled("Lamp Emission", (0.8, 0.8, 0.8), emission=(1.0, 0.85, 0.6), strength=15.0))
        kinds[lamp.name] = "emitter:principled"

        bpy.ops.mesh.primitive_uv_sphere_add(radius=0.08, location=(-0.6, 0.5, 1.6))
        bulb = added()
        bulb.name = "Bulb"
        mat = bpy.data.materials.new("Bulb Emission")
        _use_nodes(mat)
        nt = mat.node_tree
        nt.nodes.remove(nt.nodes["Principled BSDF"])
        em = nt.nodes.new("ShaderNodeEmission")
        em.inputs["Color"].default_value = (0.6, 0.8, 1.0, 1.0)
        em.inputs["Strength"].default_value = 20.0
        nt.links.new(em.outputs["Emission"], nt.nodes["Material Output"].inputs["Surface"])
        give(bulb, mat)
        kinds[bulb.name] = "emitter:emission_shader"

        bpy.ops.mesh.primitive_cube_add(size=0.5, location=(0.35, 0.3, 0.25), rotation=(0.0, 0.0, 0.3))
        block = added()
        block.name = "Block"
        give(block, principled("Block White", (0.73, 0.73, 0.73)))
        kinds[block.name] = "primitive:cube"
        bpy.ops.mesh.primitive_uv_sphere_add(radius=0.3, location=(-0.4, -0.2, 0.3))
        ball = added()
        ball.name = "Ball"
        bpy.ops.object.shade_smooth()
        give(ball, principled("Ball White", (0.73, 0.73, 0.73)))
        kinds[ball.name] = "primitive:uv_sphere"

        cam = bpy.data.objects["Camera"]
        cam.location = (0.0, -4.2, 1.0)
        cam.rotation_euler = (1.5708, 0.0, 0.0)
        # the default lights stay where users leave them: outside the room
        return save(outdir, "emissive"), kinds, {"receiver": None}

    # ------------------------------------------------------------------ unsupported.blend
    def unsupported(outdir):
        bpy.ops.wm.read_factory_settings(use_empty=True)
        bpy.ops.mesh.primitive_monkey_add(size=0.8)
        lib_obj = bpy.context.object
        lib_obj.name = "Library Monkey"
        give(lib_obj, principled("Library Material", (0.6, 0.5, 0.4)))
        lib_path = os.path.join(outdir, "library.blend")
        bpy.ops.wm.save_as_mainfile(filepath=lib_path, compress=False)

        new_file()
        kinds = {}
        bpy.ops.mesh.primitive_plane_add(size=8.0)
        floor = added()
        give(floor, principled("Floor Material", (0.7, 0.7, 0.7)))
        kinds[floor.name] = "primitive:plane"
        bpy.ops.mesh.primitive_cube_add(size=0.8, location=(0.0, 0.0, 0.4))
        cube = added()
        give(cube, principled("Cube Material", (0.8, 0.3, 0.2)))
        kinds[cube.name] = "primitive:cube"

        bpy.ops.curve.primitive_bezier_curve_add(location=(-2.0, -1.0, 0.5))
        curve = added()
        curve.data.bevel_depth = 0.05
        kinds[curve.name] = "unsupported:curve"
        bpy.ops.object.text_add(location=(-1.0, -2.0, 0.1))
        kinds[added().name] = "unsupported:text"
        bpy.ops.object.metaball_add(type="BALL", radius=0.5, location=(2.0, -1.0, 0.5))
        kinds[added().name] = "unsupported:metaball"
        bpy.ops.mesh.primitive_circle_add(radius=0.5, fill_type="NOTHING", location=(2.0, 1.0, 0.3))
        wire = added()
        wire.name = "Wire Circle"
        kinds[wire.name] = "unsupported:mesh_no_faces"
        bpy.ops.object.empty_add(location=(0.0, 2.0, 1.0))
        kinds[added().name] = "unsupported:empty"

        # File > Link: an object (and its mesh) from another .blend, not editable here
        with bpy.data.libraries.load(lib_path, link=True, relative=True) as (src, dst):
            dst.objects = ["Library Monkey"]
        linked = dst.objects[0]
        bpy.context.scene.collection.objects.link(linked)
        kinds[linked.name] = "unsupported:library_linked_mesh"
        return save(outdir, "unsupported"), kinds, {"receiver": floor.name}

    # ------------------------------------------------------------------ public_like.blend
    def public_like(outdir, tmp):
        """Objects of ~0.2 m on a 1 m floor, area lights only and an HDR world: the kinds of file public
        scenes are (scans, soups, glTF and OBJ round trips, multi-material meshes), none of them closed."""
        import math
        from mathutils import Vector

        def aim(obj, location, target):
            obj.location = location
            direction = Vector(target) - Vector(location)
            obj.rotation_euler = direction.to_track_quat("-Z", "Y").to_euler()

        bpy.ops.wm.read_factory_settings(use_empty=False)
        scene = bpy.context.scene
        for name in ("Cube", "Light"):                    # no point light: area lights only
            obj = bpy.data.objects.get(name)
            if obj is not None:
                bpy.data.objects.remove(obj)
        scene.render.resolution_x, scene.render.resolution_y = 64, 48
        kinds = {}

        # the world: an equirectangular .hdr, written by Blender's image save and loaded as an HDRI is
        w, h = 32, 16
        sky = bpy.data.images.new("Sky Source", w, h, float_buffer=True)
        upper, lower = PUBLIC_SKY
        px = []
        for row in range(h):                              # row 0 at the bottom (Blender's pixel order)
            elevation = (row + 0.5) / h * math.pi - math.pi / 2
            v = lower if elevation < 0 else lower + (upper - lower) * math.sin(elevation)
            px += [(v, v * 0.95, v * 0.9, 1.0)] * w
        sky.pixels[:] = [c for p in px for c in p]
        hdr_path = os.path.join(tmp, "sky.hdr")
        sky.filepath_raw = hdr_path
        sky.file_format = "HDR"
        sky.save()
        bpy.data.images.remove(sky)
        hdri = bpy.data.images.load(hdr_path)
        hdri.name = "sky.hdr"
        hdri.pack()
        if scene.world is None:
            scene.world = bpy.data.worlds.new("World")
        _use_nodes(scene.world)
        nt = scene.world.node_tree
        env = nt.nodes.new("ShaderNodeTexEnvironment")
        env.image = hdri
        nt.links.new(env.outputs["Color"], nt.nodes["Background"].inputs["Color"])
        nt.nodes["Background"].inputs["Strength"].default_value = 1.0

        # a 1 m floor (4 vertices: coarse for vertex colours beside 0.1 m objects)
        bpy.ops.mesh.primitive_plane_add(size=1.0)
        floor = added()
        floor.name = "Floor"
        give(floor, principled("Floor Material", (0.6, 0.6, 0.6)))
        kinds[floor.name] = "primitive:plane"

        # a scan: a displaced UV sphere, its bottom cut off and a few faces missing (holes); open, not manifold
        bpy.ops.mesh.primitive_uv_sphere_add(segments=24, ring_count=12, radius=0.1)
        scan = added()
        scan.name = "Scan"
        noise = bpy.data.textures.new("Scan Noise", type="CLOUDS")
        noise.noise_scale = 0.3
        bpy.context.view_layer.objects.active = scan
        scan.select_set(True)
        bpy.ops.object.modifier_add(type="DISPLACE")
        scan.modifiers[-1].texture = noise
        scan.modifiers[-1].strength = 0.02
        bpy.ops.object.modifier_apply(modifier=scan.modifiers[-1].name)
        deselect()
        bm = bmesh.new()
        bm.from_mesh(scan.data)
        bottom = [f for f in bm.faces if f.calc_center_median().z < -0.05]
        bmesh.ops.delete(bm, geom=bottom, context="FACES")
        bm.faces.ensure_lookup_table()
        upper_faces = sorted((f for f in bm.faces if f.calc_center_median().z > 0.02), key=lambda f: f.index)
        holes = upper_faces[5::37][:4]
        bmesh.ops.delete(bm, geom=holes, context="FACES")
        bm.to_mesh(scan.data)
        bm.free()
        low = min(v.co.z for v in scan.data.vertices)
        scan.location = (-0.16, 0.08, -low)
        give(scan, principled("Scan Material", (0.7, 0.65, 0.55)))
        kinds[scan.name] = "scan:open"

        # a multi-material mesh: a box without its bottom, red and green sides and a glowing top
        bpy.ops.mesh.primitive_cube_add(size=0.12, location=(-0.08, -0.16, 0.06))
        multi = added()
        multi.name = "Multi"
        for name, color, emission, strength in PUBLIC_SLOTS:
            give(multi, principled(name, color, emission, strength))
        bm = bmesh.new()
        bm.from_mesh(multi.data)
        bmesh.ops.delete(bm, geom=[f for f in bm.faces if f.normal.z < -0.9], context="FACES")
        for f in bm.faces:
            f.material_index = 2 if f.normal.z > 0.9 else 1 if abs(f.normal.x) > 0.9 else 0
        bm.to_mesh(multi.data)
        bm.free()
        kinds[multi.name] = "multi_material:open"

        # a triangle soup: an ico sphere split into loose triangles, out and back through OBJ without an MTL
        bpy.ops.mesh.primitive_ico_sphere_add(subdivisions=2, radius=0.06, location=(0.17, 0.12, 0.06))
        soup = added()
        soup.name = "Soup"
        bpy.context.view_layer.objects.active = soup
        soup.select_set(True)
        bpy.ops.object.mode_set(mode="EDIT")
        bpy.ops.mesh.select_all(action="SELECT")
        bpy.ops.mesh.quads_convert_to_tris()
        bpy.ops.mesh.edge_split(type="EDGE")
        bpy.ops.object.mode_set(mode="OBJECT")
        obj_path = os.path.join(tmp, "soup.obj")
        bpy.ops.wm.obj_export(filepath=obj_path, export_selected_objects=True, export_materials=False)
        bpy.data.objects.remove(soup)

        # a textured mesh: an open cylinder (a label on a can), its Base Color an image made here, out and
        # back through glTF (.glb)
        bpy.ops.mesh.primitive_cylinder_add(vertices=24, radius=0.05, depth=0.14, end_fill_type="NOTHING",
                                            location=(0.14, -0.14, 0.07))
        can = added()
        can.name = "Can"
        label = bpy.data.images.new("Label", 32, 32)
        label.pixels[:] = [c for y in range(32) for x in range(32)
                           for c in ((0.9, 0.8, 0.1, 1.0) if (x // 8 + y // 8) % 2 else (0.1, 0.2, 0.8, 1.0))]
        label.pack()
        mat = principled("Can Label", (1.0, 1.0, 1.0))
        tex = mat.node_tree.nodes.new("ShaderNodeTexImage")
        tex.image = label
        mat.node_tree.links.new(tex.outputs["Color"], mat.node_tree.nodes["Principled BSDF"].inputs["Base Color"])
        give(can, mat)
        glb_path = os.path.join(tmp, "can.glb")
        can.select_set(True)
        bpy.ops.export_scene.gltf(filepath=glb_path, export_format="GLB", use_selection=True)
        deselect()
        bpy.data.objects.remove(can)
        bpy.data.materials.remove(mat)
        bpy.data.images.remove(label)

        for path, fmt in ((obj_path, "obj"), (glb_path, "gltf")):
            before = set(bpy.data.objects)
            if fmt == "obj":
                bpy.ops.wm.obj_import(filepath=path)
            else:
                bpy.ops.import_scene.gltf(filepath=path)
            new = sorted(set(bpy.data.objects) - before, key=lambda o: o.name)
            assert len(new) == 1 and new[0].type == "MESH", [o.name for o in new]
            kinds[new[0].name] = "import:" + fmt + (":soup" if fmt == "obj" else ":textured")
            if fmt == "obj":
                soup_name = new[0].name
            else:
                gltf_name = new[0].name
        deselect()
        images = [i for s in bpy.data.objects[gltf_name].material_slots if s.material
                  for n in s.material.node_tree.nodes if n.bl_idname == "ShaderNodeTexImage" and n.image
                  for i in [n.image]]
        assert images, "the glTF importer gave the mesh no image texture"
        for image in images:
            if image.packed_file is None:
                image.pack()

        # area lights only, a key and a fill, aimed at the objects
        target = (0.0, -0.02, 0.05)
        areas = []
        for name, location, power, size in (("Area Key", (0.45, -0.5, 0.8), 12.0, 0.25),
                                            ("Area Fill", (-0.7, -0.35, 0.45), 4.0, 0.4)):
            bpy.ops.object.light_add(type="AREA")
            light = added()
            light.name = light.data.name = name
            light.data.energy, light.data.size = power, size
            aim(light, location, target)
            areas.append(light.name)

        cam = bpy.data.objects["Camera"]
        aim(cam, (0.55, -0.75, 0.42), target)
        scene.camera = cam
        slots = [{"material": n, "color": list(c), "emission": list(e) if e else None, "strength": s}
                 for n, c, e, s in PUBLIC_SLOTS]
        extra = {"receiver": floor.name, "scan": scan.name, "soup": soup_name, "gltf": gltf_name,
                 "gltf_image": images[0].name, "multi": multi.name, "slots": slots, "area_lights": areas,
                 "sky": list(PUBLIC_SKY)}
        return save(outdir, "public_like"), kinds, extra

    # ------------------------------------------------------------------ manifest
    def describe(path, kinds, extra):
        bpy.ops.wm.open_mainfile(filepath=path)
        scene = bpy.context.scene
        entry = {"path": path, "camera": scene.camera.name if scene.camera else None,
                 "world": scene.world.name if scene.world else None,
                 "lights": [], "meshes": [], "unsupported": [], "objects": {}, "emitters": []}
        entry.update(extra)
        for obj in sorted(scene.objects, key=lambda o: o.name):
            kind = kinds.get(obj.name)
            if obj.type == "LIGHT":
                entry["lights"].append({"name": obj.name, "type": obj.data.type})
                kind = kind or "light:" + obj.data.type.lower()
            elif obj.type == "CAMERA":
                kind = kind or "camera"
            elif kind is None:
                kind = "other:" + obj.type.lower()
            entry["objects"][obj.name] = kind
            is_mesh = (obj.type == "MESH" and len(obj.data.polygons) > 0 and obj.library is None
                       and obj.data.library is None)
            if is_mesh:
                mats = [s.material.name for s in obj.material_slots if s.material]
                emissive_ = kind.startswith("emitter:")
                evaluated = obj.evaluated_get(bpy.context.evaluated_depsgraph_get()).data
                entry["meshes"].append({
                    "name": obj.name, "kind": kind, "mesh": obj.data.name, "faces": len(obj.data.polygons),
                    "vertices": len(obj.data.vertices), "evaluated_vertices": len(evaluated.vertices),
                    "materials": mats, "uv": [uv.name for uv in obj.data.uv_layers],
                    "hidden_render": bool(obj.hide_render), "emissive": emissive_})
                if emissive_:
                    entry["emitters"].append(obj.name)
            elif obj.type not in ("LIGHT", "CAMERA"):
                entry["unsupported"].append({"name": obj.name, "type": obj.type, "kind": kind})
        return entry

    return {"primitives": primitives, "modifiers": modifiers, "odd_meshes": odd_meshes,
            "imported": imported, "emissive": emissive, "unsupported": unsupported, "public_like": public_like,
            "describe": describe}


def _inside(work, final, digest):
    import bpy
    steps = _builder()
    tmp = tempfile.mkdtemp(prefix="corpus-export-")
    built = {}
    try:
        for stem in FILES:
            args = (work, tmp) if stem in ("imported", "public_like") else (work,)
            built[stem] = steps[stem](*args)
            print(f"corpus: built {stem}.blend", file=sys.stderr, flush=True)
        files = {}
        for stem, (path, kinds, extra) in built.items():
            entry = steps["describe"](path, kinds, extra)
            entry["path"] = os.path.join(final, os.path.basename(path))
            files[stem] = entry
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    manifest = {"hash": digest, "blender": bpy.app.version_string, "files": files}
    with open(os.path.join(work, MANIFEST), "w") as f:
        json.dump(manifest, f, indent=1, sort_keys=True)


def main(argv):
    if argv[:1] == ["--inside"]:
        _inside(*argv[1:4])
        return 0
    if len(argv) != 1 or argv[0].startswith("-"):
        print("usage: python tests/support/corpus.py OUTDIR", file=sys.stderr)
        return 2
    manifest = build(argv[0])
    files = manifest["files"]
    n_obj = sum(len(e["objects"]) for e in files.values())
    n_mesh = sum(len(e["meshes"]) for e in files.values())
    print(f"corpus: {len(files)} files, {n_obj} objects ({n_mesh} meshes)", file=sys.stderr)
    print(os.path.join(os.path.abspath(argv[0]), MANIFEST))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
