"""Every difference between the Blender versions the project supports (5.3, 5.2 LTS, 4.5 LTS), in one place.

Callers never test ``bpy.app.version`` themselves; they call these helpers.
"""
import bpy

VERSION = bpy.app.version
IS_5 = VERSION >= (5, 0, 0)

#: Render engine id of EEVEE (EEVEE Next was renamed back to EEVEE in 5.0).
EEVEE = "BLENDER_EEVEE" if IS_5 else "BLENDER_EEVEE_NEXT"
WORKBENCH = "BLENDER_WORKBENCH"
CYCLES = "CYCLES"


def set_eevee_ao_distance(scene, view_layer, distance):
    """EEVEE's horizon-scan AO distance: per view layer in 5.0, per scene in 4.5."""
    if IS_5:
        view_layer.eevee.ambient_occlusion_distance = distance
    else:
        scene.eevee.gtao_distance = distance


def set_multilayer_exr(image_settings, depth="32"):
    """Multilayer float EXR output (5.0 needs the media type set first)."""
    if IS_5:
        image_settings.media_type = "MULTI_LAYER_IMAGE"
    image_settings.file_format = "OPEN_EXR_MULTILAYER"
    image_settings.color_depth = depth
    image_settings.exr_codec = "ZIP"


def set_single_exr(image_settings, depth="32"):
    """Single-layer float EXR output."""
    if IS_5:
        image_settings.media_type = "IMAGE"
    image_settings.file_format = "OPEN_EXR"
    image_settings.color_depth = depth
    image_settings.exr_codec = "ZIP"


def set_png(image_settings, color_mode="RGB", depth="8"):
    """8- or 16-bit PNG output."""
    if IS_5:
        image_settings.media_type = "IMAGE"
    image_settings.file_format = "PNG"
    image_settings.color_mode = color_mode
    image_settings.color_depth = depth


def uses_nodes(idblock):
    """Whether a material, world or light renders through its node tree. ``use_nodes`` is deprecated and
    always True for materials and worlds from 5.0 and for lights from 5.1 (reading it warns there)."""
    prop = idblock.bl_rna.properties.get("use_nodes")
    if prop is None or getattr(prop, "is_deprecated", IS_5 and not isinstance(idblock, bpy.types.Light)):
        return True
    return idblock.use_nodes


def ensure_use_nodes(idblock):
    """Make a material or world (4.5) render through its node tree; a no-op where it always does."""
    if not uses_nodes(idblock):
        idblock.use_nodes = True


#: 5.3 composites through the scene's compositor effects (``scene.compositing_node_group`` is deprecated).
COMPOSITOR_EFFECTS = "compositor_effects" in bpy.types.Scene.bl_rna.properties


def new_compositor(scene, name="IL Compositor"):
    """An empty compositor node tree for ``scene`` and the node its result must be linked to.

    5.x: a compositor node group with a color output, made the scene's compositor (5.3: as a compositor
    effect; 5.0-5.2: scene.compositing_node_group); 4.5: the scene's own node tree with a Composite node.
    Returns ``(tree, output_socket)``.
    """
    if IS_5:
        tree = bpy.data.node_groups.new(name, "CompositorNodeTree")
        tree.interface.new_socket("Image", in_out="OUTPUT", socket_type="NodeSocketColor")
        if COMPOSITOR_EFFECTS:
            scene.compositor_effects.new(name=name).node_group = tree
        else:
            scene.compositing_node_group = tree
        out = tree.nodes.new("NodeGroupOutput")
    else:
        scene.use_nodes = True
        tree = scene.node_tree
        for node in list(tree.nodes):
            tree.nodes.remove(node)
        out = tree.nodes.new("CompositorNodeComposite")
    return tree, out.inputs[0]


def remove_compositor(scene, tree):
    """Undo :func:`new_compositor` (the scene itself is usually removed right after)."""
    if IS_5:
        if COMPOSITOR_EFFECTS:
            for effect in [e for e in scene.compositor_effects if e.node_group == tree]:
                scene.compositor_effects.remove(effect)
        else:
            scene.compositing_node_group = None
        bpy.data.node_groups.remove(tree)


#: Name of the Object Index render pass in the multilayer EXR (renamed in 5.0).
OBJECT_INDEX_PASS = "Object Index" if IS_5 else "IndexOB"


#: Name of the ambient-occlusion pass in a multilayer EXR (and render_layers' dict).
AO_PASS = "Ambient Occlusion" if IS_5 else "AO"


def eevee_ao_distance_owner(scene, view_layer):
    """``(owner, attribute)`` of EEVEE's AO distance (see set_eevee_ao_distance), to save and restore it."""
    return (view_layer.eevee, "ambient_occlusion_distance") if IS_5 else (scene.eevee, "gtao_distance")


#: ``options`` for a StringProperty holding a path that may start with "//" (relative to the .blend):
#: 5.0 warns when such a value is set on a path property that does not declare it; 4.5 has no such flag.
BLEND_RELATIVE_PATH = ({"PATH_SUPPORTS_BLEND_RELATIVE"}
                       if "is_path_supports_blend_relative" in bpy.types.Property.bl_rna.properties else set())


#: Name of Cycles' Diffuse Direct pass in a multilayer EXR (and render_layers' dict), renamed in 5.0.
DIFFUSE_DIRECT_PASS = "Diffuse Direct" if IS_5 else "DiffDir"


def fcurves(anim_data):
    """The F-curves of ``anim_data``'s (or an NLA strip's) action for its slot (layered actions in both
    versions), or []."""
    from bpy_extras import anim_utils
    action = getattr(anim_data, "action", None)
    if action is None:
        return []
    bag = anim_utils.action_get_channelbag_for_slot(action, anim_data.action_slot)
    return list(bag.fcurves) if bag is not None else []


#: Whether Cycles' image bake writes every texel whose square a UV triangle touches (conservative
#: rasterisation, 5.3), not only the texels whose centre lies inside a triangle (5.2, 4.5). Measured: random
#: UV triangles in a 24² map give exactly the square-overlap texels in 5.3.0, the centre texels in 5.2.3.
BAKE_TOUCHED_TEXELS = VERSION >= (5, 3, 0)


#: Whether ``Mesh.from_pydata`` / ``Mesh.update(calc_edges=True)`` (the torus primitive too) leave a
#: ``.select_edge`` attribute typed INT32_2D instead of BOOLEAN, on which writing edge selection through RNA
#: crashes Blender: measured in 5.0.1; BOOLEAN in 5.2.3, 5.3.0 and 4.5. Light-map UVs never write those flags
#: (``bake.unwrap``); tests use this to know whether the trigger is there.
MISTYPED_SELECT_EDGE = VERSION[:2] == (5, 0)


#: Rounding of Cycles' mesh normals: Cycles (after 5.0) stores them octahedral-encoded in 2 x 16 bits
#: (intern/cycles ``packed_normal``: 65535 steps over [-1, 1], rounded to the nearest), so each octahedral
#: coordinate is off by up to this and the shading normal (= the Normal pass) by about as much: an exact
#: (0, -1, 0) renders as (0, -1, -1/65535). 0 where Cycles keeps float normals (4.5, 5.0.1). Measured: that
#: Normal pass in 5.2.3 and 5.3.0 (5.1, unsupported, not checked). Compare shading against the Normal pass,
#: not against the normal the mesh was given.
CYCLES_NORMAL_ERROR = 1.0 / 65535.0 if VERSION >= (5, 1, 0) else 0.0
