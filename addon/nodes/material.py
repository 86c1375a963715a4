"""Materials that sum a shading model over the scene's lights, each light linked by drivers.

A material built here holds, left to right:
- a frame "Parameters" with one Value or RGB node per model input (what the panel edits),
  fanned out to the model's nodes, and a frame "Attenuation" (Physical, C1, C2, C3,
  Spot Exponent) fanned out to every light node;
- one "IL <model>: surface" node (internal group ".IL <model> Surface": n, v and every term that
  depends only on the shading point and the parameters), whose outputs feed every light's model node;
- one frame per light: an "IL Light: <name>" node of that light type's group (".IL Light Point",
  "Spot", "Sun" or "Hemi": the "IL Light" group without the other types' nodes) whose Position,
  Direction, Color, Power and Spot Cutoff (those its type reads) are driven by the light object
  (moving or editing the light updates the shading), feeding the model's light half
  (".IL <model> Light"), which adds I times its factor to the radiance of the lights before it
  (superposition; the first starts from ambient plus emission, counted once);
- the total into one Emission shader.
Blender converts every node of a material at every render (about 13 us a node here), so each light
costs only its own type's nodes and the model's light half; the public "IL <model>" groups hold both
halves. The switches (Distribution, Geometry, Normalized, Physical) are hub nodes as well, but the light
halves and light groups linked are the variants their values select (".IL Cook-Torrance Light [GGX,
Smith]": only the chosen branches, see :func:`specialize`); the add-on's handlers relink them when a switch
changes, and a switch between 0 and 1, animated or driven gets the group with both branches (always
right, only slower). Without lights the material still works: one public model node with a black light, i.e. ambient
and emission only. A light whose type changes needs Relink Lights (as before: the type is not driven).
The emission is the model's radiance, not a lamp: its emission sampling is off, so Cycles builds
no light tree over the shaded triangles (other surfaces still receive it through their BSDF rays), unless
the material emits ("Emission Color" not black): then other surfaces sample it as Cycles would the original.
An area light is linked as a Lambertian spot at its centre (:func:`link_light`).
"""
import math
import threading

import bpy

from ..blender import compat
from ..blender.materials import layers, user_material
from ..core.errors import InputError
from ..core.lights import TYPES
from . import groups, source
from .models import BY_ID, MODELS
from .options import ShadingOptions

#: {model id: label}, from the registry (nodes/models).
MODEL_LABELS = {m.id: m.label for m in MODELS}
ATTENUATION_INPUTS = ("Physical", "C1", "C2", "C3", "Spot Exponent")
#: Added to a model without it (Oren-Nayar, Cook-Torrance) when the material emits.
EMISSION = "Emission Color"
DRIVER_PREFIX = 'nodes["IL Light:'

#: -Z axis of the world rotation (Euler XYZ: R = Rz Ry Rx), the way a light points; simple expressions only.
DIRECTION_EXPR = ("-(cos(z)*sin(y)*cos(x) + sin(z)*sin(x))",
                  "-(sin(z)*sin(y)*cos(x) - cos(z)*sin(x))",
                  "-(cos(y)*cos(x))")


def model_parameters(model):
    """[(name, socket type, default)] of the model's parameters (every input but the light's two)."""
    return [(n, t, d) for n, t, d, *_ in BY_ID[model].params]


def light_type(obj):
    """The IL Light "Type" of a Blender light (a sun with the custom property il_hemi is a hemisphere; an area
    light is a spot: :func:`link_light`)."""
    kind = obj.data.type
    if kind == "SUN" and obj.data.get("il_hemi"):
        return TYPES["HEMI"]
    return {"POINT": TYPES["POINT"], "SPOT": TYPES["SPOT"], "SUN": TYPES["SUN"], "AREA": TYPES["SPOT"]}.get(kind)


def light_warnings(linked):
    """Warnings on the lights a material sums over: area lights approximated, nothing that lights."""
    out = []
    areas = [o for o in linked if o.data.type == "AREA"]
    if areas:
        odd = [o.name for o in areas if getattr(o.data, "spread", math.pi) < math.pi - 1e-6
               or not getattr(o.data, "normalize", True)]
        out.append(f"area light{'s' if len(areas) > 1 else ''} {', '.join(repr(o.name) for o in areas)} modelled "
                   "as a Lambertian point emitter at the centre (a spot along -Z, I = (P/pi) cos theta, cutoff "
                   "90 deg): exact far away, relative error ~ (size/distance)^2 near the light"
                   + (f"; the spread below 180 deg or Normalize off of {', '.join(odd)} is not modelled"
                      if odd else ""))
    if linked and all(o.data.energy <= 0.0 or not any(o.data.color) for o in linked):
        out.append("every linked light has zero power: the material shows ambient and emission only")
    return out


def scene_lights(scene, mode="ALL", selected=()):
    """Light objects to link: every renderable light of the scene, or the selected ones."""
    pool = selected if mode == "SELECTED" else scene.objects
    return [o for o in pool if o.type == "LIGHT" and not o.hide_render and o.name in scene.objects]


# -- drivers ----------------------------------------------------------------------------------------

def _driver(socket, index, expression, variables):
    fcurve = socket.driver_add("default_value", index) if index is not None else socket.driver_add("default_value")
    drv = fcurve.driver
    drv.type = "SCRIPTED"
    for var in list(drv.variables):
        drv.variables.remove(var)
    for name, setup in variables:
        var = drv.variables.new()
        var.name = name
        setup(var)
    drv.expression = expression
    return fcurve


def _transform(obj, kind):
    def setup(var):
        var.type = "TRANSFORMS"
        t = var.targets[0]
        t.id = obj
        t.transform_type = kind
        t.transform_space = "WORLD_SPACE"
        if kind.startswith("ROT"):
            t.rotation_mode = "XYZ"
    return setup


def _prop(light_data, path):
    def setup(var):
        var.type = "SINGLE_PROP"
        t = var.targets[0]
        t.id_type = "LIGHT"
        t.id = light_data
        t.data_path = path
    return setup


def link_light(node, obj):
    """Drive ``node`` (an "IL Light" group node or one of its per-type versions) from the light object ``obj``:
    only the inputs its type reads (a point light no direction, a sun or hemisphere no position). An area light
    of power P is a Lambertian emitter at its centre: a spot along its -Z of cutoff 90 deg, exponent 1 and
    power 4P, so that I(theta) = (P/pi) cos theta (its Spot Exponent is its own, not the material's)."""
    data = obj.data
    kind = light_type(obj)
    pos, dirn = node.inputs["Position"], node.inputs["Direction"]
    for k, axis in enumerate("XYZ"):
        if kind in (TYPES["POINT"], TYPES["SPOT"]):
            _driver(pos, k, "p", [("p", _transform(obj, f"LOC_{axis}"))])
        if kind != TYPES["POINT"]:
            _driver(dirn, k, DIRECTION_EXPR[k], [(a, _transform(obj, f"ROT_{a.upper()}")) for a in "xyz"])
        _driver(node.inputs["Color"], k, "c", [("c", _prop(data, f"color[{k}]"))])
    if data.type == "AREA":
        _driver(node.inputs["Power"], None, "4 * e", [("e", _prop(data, "energy"))])
        node.inputs["Spot Cutoff"].default_value = math.pi / 2
        node.inputs["Spot Exponent"].default_value = 1.0
    else:
        _driver(node.inputs["Power"], None, "e", [("e", _prop(data, "energy"))])
    if data.type == "SPOT":
        _driver(node.inputs["Spot Cutoff"], None, "s / 2", [("s", _prop(data, "spot_size"))])
    node.inputs["Type"].default_value = float(kind)
    ground = data.get("il_ground_color")
    if ground is not None:
        node.inputs["Ground Color"].default_value = (*list(ground)[:3], 1.0)


def _remove_il_drivers(tree):
    ad = tree.animation_data
    if ad is None:
        return
    for fc in list(ad.drivers):
        if fc.data_path.startswith(DRIVER_PREFIX):
            ad.drivers.remove(fc)


# -- material ---------------------------------------------------------------------------------------

def read_parameters(mat):
    """{name: value} of the material's "Parameters" and "Attenuation" nodes."""
    out = {}
    for node in mat.node_tree.nodes:
        name = node.get("il_param")
        if name:
            value = node.outputs[0].default_value
            out[name] = tuple(value) if hasattr(value, "__len__") else float(value)
    return out


def parameter_nodes(mat):
    """The nodes the panel edits, in socket order: [(name, node)]."""
    if mat is None or not mat.get("il_model") or mat.node_tree is None:
        return []
    nodes = {n.get("il_param"): n for n in mat.node_tree.nodes if n.get("il_param")}
    order = [n for n, *_ in model_parameters(mat["il_model"])] + [EMISSION] + list(ATTENUATION_INPUTS)
    return [(name, nodes[name]) for name in order if name in nodes]


def _hub(nodes, frame, name, value, color, y):
    node = nodes.new("ShaderNodeRGB" if color else "ShaderNodeValue")
    node.name = node.label = name
    node["il_param"] = name
    node.parent = frame
    node.location = (-1100, y)
    v = value if not color else (tuple(value) + (1.0,) * 4)[:4]
    node.outputs[0].default_value = v
    return node


def _emits(mat, model, params):
    """Whether the material gets an emission hub although ``model`` has no "Emission Color" input."""
    if any(n == EMISSION for n, *_ in model_parameters(model)):
        return False
    value = params.get(EMISSION)
    return EMISSION in _sources(mat) or (value is not None and any(tuple(value)[:3]))


def _sources(mat):
    """{parameter: output socket} of the nodes kept from the user's material that feed a parameter
    (``mat["il_sources"]``: {parameter: [node name, output identifier]})."""
    out, tree = {}, mat.node_tree
    for name, (node_name, ident) in dict(mat.get("il_sources", {})).items():
        node = tree.nodes.get(node_name) if tree is not None else None
        socket = next((o for o in node.outputs if o.identifier == ident), None) if node is not None else None
        if socket is not None:
            out[name] = socket
    return out


def build_material(mat, model, light_objects, attenuation="PHYSICAL", coefficients=(1.0, 0.0, 1.0), params=None):
    """(Re)build ``mat``'s tree: parameters, one IL Light + model node per light, their sum. Nodes tagged
    "il_source" (kept from the user's material, :func:`assign_materials`) stay: each one in
    ``mat["il_sources"]`` feeds its parameter times the parameter's hub (a tint)."""
    if model not in BY_ID:
        raise InputError(f"unknown shading model '{model}' (one of {', '.join(BY_ID)})")
    if attenuation not in ("PHYSICAL", "EMPIRICAL"):
        raise InputError(f"attenuation must be PHYSICAL or EMPIRICAL, got '{attenuation}'")
    params = dict(params or {})
    model_group = groups.ensure_group(groups.MODEL_GROUPS[model])
    for public in (model_group, groups.ensure_group(groups.LIGHT)):
        public.use_fake_user = True     # the material uses internal halves: keep the public groups in the saved file
    kinds = {v: k for k, v in TYPES.items()}
    compat.ensure_use_nodes(mat)
    tree = mat.node_tree
    _remove_il_drivers(tree)
    for node in [n for n in tree.nodes if not n.get("il_source")]:
        tree.nodes.remove(node)
    nodes, links = tree.nodes, tree.links
    sources = _sources(mat)
    emits = _emits(mat, model, params)

    frame = nodes.new("NodeFrame")
    frame.name = frame.label = "Parameters"
    hub = {}
    y = 300
    for name, stype, default in model_parameters(model) + ([(EMISSION, groups.C, groups.BLACK)] if emits else []):
        color = stype == groups.C
        hub[name] = _hub(nodes, frame, name, params.get(name, default), color, y)
        y -= 200 if color else 110
    feed = dict(hub)
    for name, socket in sources.items():
        if name in hub:
            mul = nodes.new("ShaderNodeVectorMath")
            mul.operation = "MULTIPLY"
            mul.name = mul.label = f"{name}: source x tint"
            mul.location = (-950, hub[name].location.y)
            links.new(socket, mul.inputs[0])
            links.new(hub[name].outputs[0], mul.inputs[1])
            feed[name] = mul
    att_frame = nodes.new("NodeFrame")
    att_frame.name = att_frame.label = "Attenuation"
    c1, c2, c3 = coefficients
    att_values = {"Physical": params.get("Physical", 1.0 if attenuation == "PHYSICAL" else 0.0),
                  "C1": params.get("C1", c1), "C2": params.get("C2", c2), "C3": params.get("C3", c3),
                  "Spot Exponent": params.get("Spot Exponent", 0.0)}
    for name in ATTENUATION_INPUTS:
        hub[name] = _hub(nodes, att_frame, name, att_values[name], False, y)
        y -= 110

    total = None
    if light_objects:
        surface = nodes.new("ShaderNodeGroup")
        surface.node_tree = groups.ensure_group(groups.surface_group_name(model_group.name))
        surface.name = surface.label = f"{model_group.name}: surface (shared by every light)"
        surface.location = (-800, 600)
        for name, *_ in model_parameters(model):
            links.new(feed[name].outputs[0], surface.inputs[name])
        half = groups.ensure_group(groups.light_group_name(model_group.name))
        switches, once = BY_ID[model].switches, BY_ID[model].once
        total = surface.outputs[once] if once else None
    for k, obj in enumerate(light_objects or [None]):
        label = obj.name if obj is not None else "no lights (ambient and emission only)"
        lframe = nodes.new("NodeFrame")
        lframe.name = lframe.label = f"Light: {label}"
        model_node = nodes.new("ShaderNodeGroup")
        model_node.name = f"{model_group.name}: {label}"
        model_node.parent = lframe
        model_node.location = (-300, 300 - 420 * k)
        model_node.node_tree = model_group if obj is None else half
        if obj is None:
            for name, *_ in model_parameters(model):
                links.new(feed[name].outputs[0], model_node.inputs[name])
            model_node.inputs["Light Color"].default_value = (0.0, 0.0, 0.0, 1.0)
            total = model_node.outputs["Color"]
            continue
        if total is not None:
            links.new(total, model_node.inputs[groups.SUM[0]])
        total = model_node.outputs["Color"]
        for name in switches:
            links.new(hub[name].outputs[0], model_node.inputs[name])
        for socket in surface.outputs:
            links.new(socket, model_node.inputs[socket.name])
        light_node = nodes.new("ShaderNodeGroup")
        light_node.node_tree = groups.ensure_group(groups.LIGHT_OF_TYPE[kinds[light_type(obj)]])
        light_node.name = f"IL Light: {obj.name}"
        light_node["il_light"] = obj.name
        light_node.parent = lframe
        light_node.location = (-600, 300 - 420 * k)
        for name in ATTENUATION_INPUTS:
            if not (name == "Spot Exponent" and obj.data.type == "AREA"):
                links.new(hub[name].outputs[0], light_node.inputs[name])
        links.new(light_node.outputs["Light Vector"], model_node.inputs["Light Vector"])
        links.new(light_node.outputs["Light Color"], model_node.inputs["Light Color"])
        link_light(light_node, obj)
    if emits:
        add = nodes.new("ShaderNodeVectorMath")
        add.operation = "ADD"
        add.name = add.label = "+ Emission Color"
        add.location = (50, 300)
        links.new(total, add.inputs[0])
        links.new(feed[EMISSION].outputs[0], add.inputs[1])
        total = add.outputs[0]
    emission = nodes.new("ShaderNodeEmission")
    emission.location = (250, 300)
    links.new(total, emission.inputs["Color"])
    out = nodes.new("ShaderNodeOutputMaterial")
    out.location = (450, 300)
    links.new(emission.outputs[0], out.inputs["Surface"])
    if hasattr(getattr(mat, "cycles", None), "emission_sampling"):
        value = params.get(EMISSION)
        lamp = EMISSION in sources or (value is not None and any(tuple(value)[:3]))
        mat.cycles.emission_sampling = "AUTO" if lamp else "NONE"
    mat["il_model"] = model
    mat["il_attenuation"] = attenuation
    mat["il_version"] = groups.GROUP_VERSION
    specialize(mat)
    return mat


# -- switches fixed at build time ---------------------------------------------------------------------

def _animated_paths(tree):
    """The data paths of ``tree`` that drivers, its action or its NLA strips' actions change."""
    ad = tree.animation_data
    if ad is None:
        return set()
    curves = list(ad.drivers) + compat.fcurves(ad)
    for track in ad.nla_tracks:
        for strip in track.strips:
            curves += compat.fcurves(strip)
    return {fc.data_path for fc in curves}


def _switch_value(socket, link, animated):
    """The number a group node's switch input holds for every shading point, or None: its own value when
    unlinked (``link`` None), a parameter node's when linked straight from one (not muted, nor the link);
    None when that value is in ``animated`` (:func:`_animated_paths`)."""
    if link is not None:
        if link.from_node.bl_idname != "ShaderNodeValue" or link.is_muted or link.from_node.mute:
            return None
        socket = link.from_node.outputs[0]
    return None if f"{socket.path_from_id()}.default_value" in animated else socket.default_value


def _sockets(group):
    return [(i.in_out, i.name, i.identifier) for i in group.interface.items_tree if i.item_type == "SOCKET"]


def _swap_group(tree, node, group, into):
    """``node.node_tree = group``, keeping the node's links and input values by socket name. Blender keeps
    them by socket identifier, and a group rebuilt in place from an older version numbers the sockets it
    gained differently from one built fresh. ``into`` ({input socket pointer: link}) is rebuilt then."""
    if _sockets(node.node_tree) == _sockets(group):
        node.node_tree = group
        return
    ins = {s.name: into[s.as_pointer()].from_socket for s in node.inputs if s.as_pointer() in into}
    values = {s.name: (tuple(s.default_value) if hasattr(s.default_value, "__len__") else s.default_value)
              for s in node.inputs if hasattr(s, "default_value")}
    outs = [(lk.from_socket.name, lk.to_socket) for lk in tree.links if lk.from_node == node]
    into.clear()
    node.node_tree = group
    for lk in [lk for lk in tree.links if node in (lk.from_node, lk.to_node)]:
        tree.links.remove(lk)
    for socket in node.inputs:
        if socket.name in values and hasattr(socket, "default_value"):
            socket.default_value = values[socket.name]
        if socket.name in ins:
            tree.links.new(ins[socket.name], socket)
    for name, to_socket in outs:
        tree.links.new(node.outputs[name], to_socket)
    into.update({lk.to_socket.as_pointer(): lk for lk in tree.links})


def specialize(mat):
    """Link, in ``mat``, each IL internal group node to the variant its switches select
    (:func:`groups.variant`: Distribution, Geometry, Normalized, Physical at 0 or 1 give a group with only
    the chosen branches; any other value, or a switch that is animated, driven or fed by other nodes,
    the group with both). Run at build, by the add-on's handlers when a switch changes, and before renders.
    A material built by an older group version gets the groups with both branches (its links may predate
    the terms a variant reads: Relink Lights gives it variants); one linked from a library is left as it is.
    Returns how many nodes changed group."""
    tree = getattr(mat, "node_tree", None)
    if tree is None or not mat.get("il_model") or mat.library is not None:
        return 0
    current = mat.get("il_version") == groups.GROUP_VERSION
    bases = {node.node_tree.get("il_base") for node in tree.nodes if getattr(node, "node_tree", None) is not None}
    for base in bases - {None}:     # older groups rebuilt first: that frees the links to sockets they lose
        groups.ensure_group(base)
    changed, animated = 0, _animated_paths(tree)
    into = {lk.to_socket.as_pointer(): lk for lk in tree.links}   # NodeSocket.links reads every link of the tree
    for node in tree.nodes:
        group = getattr(node, "node_tree", None)
        base = group.get("il_base") if group is not None else None
        names = groups.switches(base) if base else ()
        if not names:
            continue
        if current:
            values = {k: _switch_value(node.inputs[k], into.get(node.inputs[k].as_pointer()), animated)
                      for k in names}
            want = groups.variant(base, values)
        else:
            want = groups.ensure_group(base)
        if want != group:
            _swap_group(tree, node, want, into)
            changed += 1
    if not current:
        _link_surface_terms(tree)
    return changed


def _link_surface_terms(tree):
    """Each light half's unlinked input linked from the surface half's output of that name (the terms a newer
    group version reads, which a material built by an older one does not link)."""
    bases = {n: n.node_tree.get("il_base") for n in tree.nodes if getattr(n, "node_tree", None) is not None}
    surface = next((n for n, b in bases.items() if b and b.endswith(" Surface")), None)
    for node in (n for n, b in bases.items() if b and b.endswith(" Light")) if surface is not None else ():
        for socket in node.inputs:
            if not socket.is_linked and socket.name in surface.outputs:
                tree.links.new(surface.outputs[socket.name], socket)


def specialize_all():
    """:func:`specialize` every IL material of the file; returns how many nodes changed group."""
    return sum(specialize(m) for m in il_materials())


@bpy.app.handlers.persistent
def on_depsgraph_update(scene, depsgraph):
    """A switch edited (panel, node editor, Python, undo): relink that material's variants."""
    for update in depsgraph.updates:
        if isinstance(update.id, bpy.types.Material) and update.id.get("il_model"):
            specialize(update.id.original)


def scene_il_materials(scene):
    """The IL materials in the slots of ``scene``'s objects and of the objects its collection instances
    place, each once."""
    found, objects = {}, list(scene.objects)
    for obj in scene.objects:
        if obj.instance_type == "COLLECTION" and obj.instance_collection is not None:
            objects += list(obj.instance_collection.all_objects)
    for obj in objects:
        for slot in obj.material_slots:
            mat = slot.material
            if mat is not None and mat.get("il_model") and mat.node_tree is not None:
                found[mat.as_pointer()] = mat
    return list(found.values())


@bpy.app.handlers.persistent
def on_render(scene, *_):
    """Before a render started from Python (``blender -b``: no depsgraph update ran since the last edit): the
    materials that render. Renders started from the UI run this in their own thread: there the depsgraph
    handler has already done it, and data must not change, so only the main thread acts."""
    if threading.current_thread() is threading.main_thread():
        for mat in scene_il_materials(scene):
            specialize(mat)


@bpy.app.handlers.persistent
def on_load(*_):
    """After a file opens (saved in a state the handlers did not see)."""
    specialize_all()


#: (handler list, function) pairs the add-on adds on register and removes on unregister.
HANDLERS = (("depsgraph_update_post", on_depsgraph_update), ("render_pre", on_render), ("load_post", on_load))


def add_handlers():
    for name, fn in HANDLERS:
        handlers = getattr(bpy.app.handlers, name)
        if fn not in handlers:
            handlers.append(fn)


def remove_handlers():
    for name, fn in HANDLERS:
        handlers = getattr(bpy.app.handlers, name)
        while fn in handlers:
            handlers.remove(fn)


_SKIP_REASONS = {"type": ("not a mesh", "not meshes"), "faces": ("a mesh without faces", "meshes without faces")}


def _unshadable(obj):
    """Why ``obj`` cannot take a shading material (a key of _SKIP_REASONS or a sentence), or None."""
    if obj.type == "LIGHT":
        return None
    if obj.type != "MESH":
        return "type"
    lib = obj.library or obj.data.library
    if lib is not None:
        return f"linked from {bpy.path.basename(lib.filepath)}, not editable here"
    if len(obj.data.polygons) == 0:
        return "faces"
    return None


def split_shadable(objects, lights=False):
    """(meshes that can be shaded, ["A, B: reason", ...] for the rest); selected lights are neither (the lights
    of a shading model), or not meshes with ``lights``."""
    meshes, by_reason = [], {}
    for obj in objects:
        reason = "type" if lights and obj.type == "LIGHT" else _unshadable(obj)
        if reason is not None:
            by_reason.setdefault(reason, []).append(obj.name)
        elif obj.type == "MESH":
            meshes.append(obj)
    return meshes, [f"{', '.join(names)}: {_SKIP_REASONS.get(r, (r, r))[len(names) > 1]}"
                    for r, names in by_reason.items()]


def shading_options(options, lights="ALL", attenuation="PHYSICAL", coefficients=(1.0, 0.0, 1.0)):
    """``options`` itself when it is a :class:`.options.ShadingOptions`; else one made from a model id and the
    other settings (the form scripts and tests call with)."""
    if isinstance(options, ShadingOptions):
        return options
    c1, c2, c3 = coefficients
    return ShadingOptions(model=options, lights=lights, attenuation=attenuation, c1=c1, c2=c2, c3=c3)


def assign_shading_model(scene, objects, model, lights="ALL", attenuation="PHYSICAL",
                         coefficients=(1.0, 0.0, 1.0), params=None, name=None):
    """:func:`assign_materials`, returning (the IL material of the first slot shaded, warnings)."""
    mats, warnings = assign_materials(scene, objects, model, lights, attenuation, coefficients, params, name)
    return mats[0], warnings


def make_before_slots_change(meshes, originals, make, made):
    """``make(original)`` for each of ``originals`` (what the slots' new materials are made from, and None for the
    meshes without slots) before any slot changes; when one fails, the materials in ``made`` (which ``make`` fills)
    are removed and nothing else has changed. Then the light-map previews come off ``meshes`` and each mesh without
    slots gets an empty one (marked ``il_added_slot``)."""
    try:
        for orig in list(originals) + [None] * any(len(obj.material_slots) == 0 for obj in meshes):
            make(orig)
    except BaseException:
        for mat in made.values():
            bpy.data.materials.remove(mat)
        raise
    take_off_previews(meshes)
    for obj in meshes:
        if len(obj.material_slots) == 0:
            obj.data.materials.append(None)
            obj.data["il_added_slot"] = True


def take_off_previews(meshes):
    """Take a light-map preview shown on ``meshes`` off (the slots get back the user's materials and links) before a
    shading model or environment mapping replaces what the slots show."""
    from .lightmap_preview import remove_lightmaps        # it imports this module
    remove_lightmaps(meshes)


def _upstream(socket):
    """Names of the nodes that feed ``socket``'s node, that node included."""
    seen, todo = set(), [socket.node]
    while todo:
        node = todo.pop()
        if node.name not in seen:
            seen.add(node.name)
            todo += [lk.from_node for i in node.inputs for lk in i.links]
    return seen


def _copy_with_sources(orig, sources):
    """A copy of ``orig`` keeping only the nodes that feed ``sources`` ({parameter: socket of orig's tree}),
    tagged "il_source", and ``il_sources`` naming them (see :func:`build_material`)."""
    mat = orig.copy()
    tree = mat.node_tree
    keep = set().union(*(_upstream(s) for s in sources.values()))
    ad = tree.animation_data
    for fc in list(ad.drivers) if ad is not None else []:
        if not any(fc.data_path.startswith(f'nodes["{k}"]') for k in keep):
            ad.drivers.remove(fc)
    for node in list(tree.nodes):
        if node.name in keep:
            node["il_source"] = True
            node.parent = None
        else:
            tree.nodes.remove(node)
    mat["il_sources"] = {k: [s.node.name, s.identifier] for k, s in sources.items()}
    return mat


def _convert(orig, model, linked, attenuation, coefficients, params, base_name):
    """A new IL material of ``model`` from the user's material ``orig`` (None: an empty slot, the model's
    defaults); returns (material, warnings)."""
    notes, values, sources = [], {}, {}
    if orig is not None and orig.get("il_model"):       # made before IL kept the originals: its own hubs
        names = {n for n, *_ in model_parameters(model)} | set(ATTENUATION_INPUTS)
        values = {k: v for k, v in read_parameters(orig).items() if k in names}
    elif orig is not None:
        surface = source.read_surface(orig)
        values, sources = source.model_parameters(model, surface)
        notes = surface.notes + source.lost(model, surface)
    values.update(params or {})
    sources = {k: v for k, v in sources.items() if k not in (params or {})}
    label = base_name or f"IL {MODEL_LABELS[model]}"
    mat = _copy_with_sources(orig, sources) if sources else bpy.data.materials.new(label)
    mat.name = f"{label}: {orig.name}" if orig is not None else label
    try:
        build_material(mat, model, linked, attenuation, coefficients, values)
    except Exception:
        bpy.data.materials.remove(mat)
        raise
    if orig is None:
        mat["il_empty"] = True
    else:
        mat["il_original"] = orig       # an ID property: a user, so the original is saved with the file
    warnings = [f"material '{orig.name}': not read or approximated: {'; '.join(notes)}"] if notes else []
    return mat, warnings


def material_slots_of(meshes):
    """(owner, index, material) of every slot of ``meshes``; owner is the mesh (a slot linked to the data, each
    shared mesh once) or the object slot (linked to the object)."""
    seen = set()
    for obj in meshes:
        first = obj.data.as_pointer() not in seen
        seen.add(obj.data.as_pointer())
        for i, slot in enumerate(obj.material_slots):
            if slot.link == "OBJECT":
                yield slot, None, slot.material
            elif first:
                yield obj.data, i, obj.data.materials[i]


def put_material(owner, index, mat):
    """Set the slot :func:`material_slots_of` yielded as (owner, index) to ``mat``."""
    if index is None:
        owner.material = mat
    else:
        owner.materials[index] = mat


def assign_materials(scene, objects, model, lights="ALL", attenuation="PHYSICAL",
                     coefficients=(1.0, 0.0, 1.0), params=None, name=None):
    """Give every slot of the meshes in ``objects`` an IL material summing the model over the lights.

    ``model``: the :class:`.options.ShadingOptions` (model, lights, attenuation, c1 c2 c3; what the operator
    passes), or a model id with ``lights``, ``attenuation`` and ``coefficients`` (:func:`shading_options`).

    One IL material per material of the slots (one for a material several slots or objects share; one for
    the empty slots and slotless meshes, with the model's defaults): its parameters come from the user's
    material (:mod:`.source`; ``params`` override them), a texture feeding Base Color or Emission Color stays
    linked, and ``mat["il_original"]`` keeps the original for :func:`restore_materials` (saved with the file).
    ``objects`` is the selection: lights in it are the ones linked when ``lights`` is "SELECTED"; the rest
    (cameras, curves, empties, meshes without faces, library meshes) are skipped with one warning naming them.
    Returns ([IL materials], warnings). Raises InputError (and changes nothing) when no mesh can be shaded.
    """
    options = shading_options(model, lights, attenuation, coefficients)
    model, lights, attenuation, coefficients = options.model, options.lights, options.attenuation, options.coefficients
    if model not in BY_ID:
        raise InputError(f"unknown shading model '{model}' (one of {', '.join(BY_ID)})")
    if lights not in ("ALL", "SELECTED"):
        raise InputError(f"lights must be ALL or SELECTED, got '{lights}'")
    objects = list(objects)
    meshes, skipped = split_shadable(objects)
    if not meshes:
        what = "; ".join(skipped) if skipped else "nothing is selected"
        raise InputError(f"nothing to shade: select at least one mesh object ({what})")
    warnings = [f"skipped {'; '.join(skipped)}"] if skipped else []
    linked = []
    for obj in scene_lights(scene, lights, objects):
        if light_type(obj) is None:
            warnings.append(f"{obj.data.type.lower()} light '{obj.name}' is not supported and was skipped")
        else:
            linked.append(obj)
    if not linked:
        warnings.append("no lights to link: the material shows ambient and emission only "
                        "(add lights, then Relink Lights)")
    warnings += light_warnings(linked)
    made = {}

    def convert(orig):
        key = orig.as_pointer() if orig is not None else None
        if key not in made:
            mat, w = _convert(orig, model, linked, attenuation, coefficients, params, name)
            mat["il_lights_mode"] = lights
            mat["il_light_names"] = [o.name for o in linked]
            made[key] = mat
            warnings.extend(w)
        return made[key]

    make_before_slots_change(meshes, [user_material(cur) for _, _, cur in material_slots_of(meshes)], convert, made)
    replaced = set()
    for owner, index, cur in list(material_slots_of(meshes)):
        mat = convert(user_material(cur))
        if cur is not None and (cur.get("il_model") or cur.get("il_envmap") is not None) and cur != mat:
            replaced.add(cur)
        put_material(owner, index, mat)
    for old in replaced:
        if old.users == 0 and (old.get("il_original") is not None or old.get("il_empty")):
            bpy.data.materials.remove(old)      # an IL material of an earlier assignment nothing uses
    return list(made.values()), warnings


def restorable(objects):
    """Whether a slot of ``objects`` holds an IL material that knows what it replaced."""
    return any(_restores(slot.material) for obj in objects for slot in getattr(obj, "material_slots", ()))


def _restores(mat):
    return mat is not None and mat.get("il_model") and (mat.get("il_empty") or mat.get("il_original") is not None)


def restore_materials(objects):
    """Give the slots of ``objects`` back the materials :func:`assign_materials` replaced (empty slots empty,
    slots it added removed); IL materials left unused stay until the file is saved (Blender drops them then, as
any material without users). Returns the number of slots restored."""
    count, seen = 0, set()
    for obj in objects:
        data = obj.data if obj.type == "MESH" else None
        first = data is not None and data.as_pointer() not in seen
        if data is not None:
            seen.add(data.as_pointer())
        for i, slot in enumerate(obj.material_slots):
            mat = slot.material
            if not _restores(mat) or (slot.link != "OBJECT" and not first):
                continue
            if slot.link == "OBJECT":
                slot.material = user_material(mat)
            else:
                data.materials[i] = user_material(mat)
            count += 1
        if first and data.get("il_added_slot") and len(data.materials) == 1 and data.materials[0] is None:
            data.materials.clear()      # (pop leaves the objects' slot count stale)
        if first and "il_added_slot" in data and not any(layers(m)[0] for m in data.materials):
            del data["il_added_slot"]           # no layer left that needs it, also under another layer
    return count


def il_materials():
    """Every material built by :func:`build_material` (it carries "il_model")."""
    return [m for m in bpy.data.materials if m.get("il_model") and m.node_tree is not None]


def relink_lights(scene, materials=None):
    """Rebuild the light part of IL materials for the scene's current lights; returns (count, warnings).

    "ALL" materials follow every light of ``scene``; "SELECTED" ones keep the lights they had that
    still exist. Parameters are kept.
    """
    warnings, count = [], 0
    for mat in (il_materials() if materials is None else materials):
        if mat.get("il_lights_mode") == "SELECTED":
            names = [n for n in mat.get("il_light_names", []) if n in scene.objects]
            candidates = [scene.objects[n] for n in names]
        else:
            candidates = scene_lights(scene, "ALL")
        linked = [o for o in candidates if o.type == "LIGHT" and light_type(o) is not None]
        warnings += [w for w in light_warnings(linked) if w not in warnings]
        params = read_parameters(mat)
        build_material(mat, mat["il_model"], linked, mat.get("il_attenuation", "PHYSICAL"), params=params)
        mat["il_light_names"] = [o.name for o in linked]
        if not linked:
            warnings.append(f"material '{mat.name}' has no lights: ambient and emission only")
        count += 1
    return count, warnings
