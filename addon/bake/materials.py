"""The temporary bake materials of a run: each kind's builder (``Kind.material``) and their assignment."""
import bpy

from ..blender import compat, materials
from .kinds import KINDS


IMAGE = "IL bake image"
"""The image node of a temporary material (its active node: Cycles bakes into it)."""


class TemporaryMaterials:
    """The temporary materials of a run, made once and assigned per map.

    AO (geometry only): one material with no closure (materials.no_closure) shared by every slot, just a
    carrier of the active image node: Cycles then samples no BSDF and no light at the baked points, and
    the AO pass, which reads the geometry only, is the same bit for bit as with a white Lambert (measured
    on the demo's four objects) in less than half the time.

    Directional: the irradiance material with the Lambert's normal tilted by nodes set per bake
    (:func:`directional_material`, :func:`show_bake`).

    The originals are the user's own materials (``blender.materials.user_material``: a light-map preview, shading
    model or environment mapping shown on a slot is looked through).

    Irradiance: per original slot material a copy whose surface is
    ``Mix(original, white Lambert, factor = Light Path "Is Camera Ray")``. Cycles starts
    every bake sample at the baked point with a camera path state (PATH_RAY_CAMERA,
    cleared at the first bounce), so the receiving point is white Lambertian (the
    DIFFUSE bake without COLOR then returns E/π even on black, metallic or textured
    surfaces, REFERENCE.md §1) while every ray that reaches the object later sees its
    own albedo and emission: bounces between baked objects stay physical. The copy's
    Displacement input is unlinked so that E is taken about the mesh normal.
    """

    def __init__(self, state):
        self.state = state
        self.made = {}            # (kind, original material or None, group key) -> (material, image node)
        self.first = {}           # (kind, original material or None) -> (first material made, its image node's name)

    def assign(self, group, kind):
        """Put the ``kind`` materials on every slot of ``group``; return their image nodes."""
        nodes = []
        for o in group:
            originals = [materials.user_material(mat) for _, mat in self.state.slots[o.name]] or [None]
            if len(o.material_slots) == 0:
                o.data.materials.append(None)
            for slot, orig in zip(o.material_slots, originals):
                mat, tex = self.material(kind, orig)
                if slot.material != mat:
                    slot.material = mat
                if tex not in nodes:
                    nodes.append(tex)
        return nodes

    def batch_slots(self, obj, kind, key, image):
        """The ``kind`` materials of ``obj``'s slots (one for an object without slots) for a batched bake, their
        image nodes on ``image``: made once per group ``key`` and original material."""
        originals = [materials.user_material(mat) for _, mat in self.state.slots[obj.name]] or [None]
        out = []
        for orig in originals:
            mat, tex = self.material(kind, orig, key)
            tex.image = image
            out.append(mat)
        return out

    def material(self, kind, orig, key=None):
        """(material, active image node) of ``kind`` for a slot of material ``orig`` (None: no material) in
        group ``key`` (None: per-object bakes), made once by the kind's builder (``Kind.material``): one per
        original material when the kind is ``per_material``, else one shared by every slot."""
        record = KINDS[kind]
        cache = (kind, orig if record.per_material else None, key)
        if cache not in self.made:
            first = self.first.get(cache[:2])
            if first is None:
                mat = globals()[record.material](self, orig)
                tex = mat.node_tree.nodes.new("ShaderNodeTexImage")
                tex.name = IMAGE                # renamed ".001" when the user's material has a node of that name
                self.first[cache[:2]] = (mat, tex.name)
            else:                           # a copy of the first: a sixth of the time of building it again
                mat = self.state.track(bpy.data.materials, first[0].copy())
                tex = mat.node_tree.nodes[first[1]]
            mat.node_tree.nodes.active = tex
            self.made[cache] = (mat, tex)
        return self.made[cache]

    def new(self, name):
        """An empty tracked material (removed when the run ends)."""
        return self.state.track(bpy.data.materials, materials.empty_material(name))

    def copy(self, orig):
        """A tracked copy of material ``orig``."""
        return self.state.track(bpy.data.materials, orig.copy())


def ao_material(temporary, orig):
    """AO: a material with no closure, the same for every slot (see :class:`TemporaryMaterials`)."""
    return materials.no_closure("IL bake AO", temporary.new("IL bake AO"))


def irradiance_material(temporary, orig):
    """Irradiance: ``orig``'s surface mixed with a white Lambert on camera rays, its displacement unlinked
    (see :class:`TemporaryMaterials`)."""
    mat, nt, out, mix = _camera_mix(temporary, orig)
    nt.links.new(materials.white_diffuse_node(nt).outputs["BSDF"], mix.inputs[2])
    nt.links.new(mix.outputs["Shader"], out.inputs["Surface"])
    return mat


TILT = "IL tilt"
"""The Combine XYZ node holding a directional bake's tilt vector t (``Bake.tilt``)."""
NORMAL_SWITCH = "IL normal switch"
"""The Value node choosing the receiver (0) or the emission of its normal (1) (``Bake.normal``)."""


def directional_material(temporary, orig):
    """Directional: as :func:`irradiance_material`, with the white Lambert's normal tilted,
    n = normalize(N + t - (t·N) N) (N the Geometry normal, t the TILT node), and a Mix by the NORMAL_SWITCH value
    to an emission of n × 0.5 + 0.5, which an EMIT bake reads back (the world-space n of every bake sample)."""
    mat, nt, out, mix = _camera_mix(temporary, orig)
    geo = nt.nodes.new("ShaderNodeNewGeometry")
    tilt = nt.nodes.new("ShaderNodeCombineXYZ")
    tilt.name = tilt.label = TILT

    def vmath(op, a, b=None, c=None, scale=None):
        node = nt.nodes.new("ShaderNodeVectorMath")
        node.operation = op
        nt.links.new(a, node.inputs[0])
        for i, x in ((1, b), (2, c)):
            if isinstance(x, tuple):
                node.inputs[i].default_value = x
            elif x is not None:
                nt.links.new(x, node.inputs[i])
        if scale is not None:
            nt.links.new(scale, node.inputs["Scale"])
        return node.outputs["Value" if op == "DOT_PRODUCT" else "Vector"]

    normal = geo.outputs["Normal"]
    along = vmath("SCALE", normal, scale=vmath("DOT_PRODUCT", tilt.outputs["Vector"], normal))
    n = vmath("NORMALIZE", vmath("ADD", normal, vmath("SUBTRACT", tilt.outputs["Vector"], along)))
    diffuse = materials.white_diffuse_node(nt)
    nt.links.new(n, diffuse.inputs["Normal"])
    nt.links.new(diffuse.outputs["BSDF"], mix.inputs[2])
    emission = nt.nodes.new("ShaderNodeEmission")
    emission.inputs["Strength"].default_value = 1.0
    nt.links.new(vmath("MULTIPLY_ADD", n, (0.5, 0.5, 0.5), (0.5, 0.5, 0.5)), emission.inputs["Color"])
    switch = nt.nodes.new("ShaderNodeValue")
    switch.name = switch.label = NORMAL_SWITCH
    switch.outputs[0].default_value = 0.0
    pick = nt.nodes.new("ShaderNodeMixShader")
    nt.links.new(switch.outputs[0], pick.inputs["Fac"])
    nt.links.new(mix.outputs["Shader"], pick.inputs[1])
    nt.links.new(emission.outputs["Emission"], pick.inputs[2])
    nt.links.new(pick.outputs["Shader"], out.inputs["Surface"])
    return mat


def show_bake(objects, bake):
    """Set the TILT and NORMAL_SWITCH nodes of the slot materials of ``objects`` to ``bake`` (a :class:`kinds.Bake`)."""
    for o in objects:
        for slot in o.material_slots:
            nt = slot.material.node_tree if slot.material is not None else None
            tilt = nt.nodes.get(TILT) if nt is not None else None
            if tilt is None:
                continue
            for i, x in enumerate(bake.tilt):
                if tilt.inputs[i].default_value != x:
                    tilt.inputs[i].default_value = x
            switch = nt.nodes[NORMAL_SWITCH].outputs[0]
            if switch.default_value != bake.normal:
                switch.default_value = float(bake.normal)


def _camera_mix(temporary, orig):
    """(material, node tree, output, Mix shader) for ``orig``: a tracked copy (or a plain diffuse of its viewport
    colour), displacement unlinked, its surface in the Mix's first input and "Is Camera Ray" as its factor; the
    caller links the receiver into the second input and the Mix (or more) into the output's Surface."""
    if orig is None or not compat.uses_nodes(orig) or orig.node_tree is None:
        # Cycles shades such a slot with a plain diffuse of the viewport colour (grey without material)
        mat = temporary.new(f"IL bake {orig.name if orig else 'default'}")
        nt = mat.node_tree
        base = nt.nodes.new("ShaderNodeBsdfDiffuse")
        base.inputs["Color"].default_value = tuple(orig.diffuse_color) if orig else (0.8, 0.8, 0.8, 1.0)
        surface = base.outputs["BSDF"]
        out = None
    else:
        mat = temporary.copy(orig)
        mat.name = f"IL bake {orig.name}"
        nt = mat.node_tree
        out = nt.get_output_node("CYCLES")
        surface = None
        if out is not None:
            links = out.inputs["Surface"].links
            surface = links[0].from_socket if links else None
            for link in out.inputs["Displacement"].links:
                nt.links.remove(link)
    if out is None:
        for n in nt.nodes:
            if n.bl_idname == "ShaderNodeOutputMaterial":
                n.is_active_output = False
        out = nt.nodes.new("ShaderNodeOutputMaterial")
        out.target = "ALL"
        out.is_active_output = True
    mix = nt.nodes.new("ShaderNodeMixShader")
    path = nt.nodes.new("ShaderNodeLightPath")
    nt.links.new(path.outputs["Is Camera Ray"], mix.inputs["Fac"])
    if surface is not None:
        nt.links.new(surface, mix.inputs[1])
    return mat, nt, out, mix
