"""Save what a bake touches and put it back, also after an error or an interruption.

Usage::

    with SavedState(scene, objects) as state:
        state.track(bpy.data.images, img)   # temporary data-blocks removed on exit
        ...

On exit (normal, exception or KeyboardInterrupt) the render engine, Cycles sampling settings and bake
settings, the world and its AO distance, selection, active object, material slots, active UV layer /
render UV layer, active colour attributes and the mode are restored; every temporary data-block
registered with ``track`` is removed, meshes flipped with ``flip_normals`` are flipped back, and so are UV layers / colour attributes registered with
``created_uv`` / ``created_attribute``, and layers saved with ``save_uv`` get their UVs back, unless
their (mesh name, name) is in ``keep`` (the products of a successful bake).
"""
import bpy
import numpy as np

_CYCLES = ("device", "samples", "seed", "use_denoising", "use_adaptive_sampling", "max_bounces",
           "diffuse_bounces", "glossy_bounces", "transmission_bounces", "volume_bounces",
           "transparent_max_bounces", "use_animated_seed", "sample_offset", "sample_clamp_direct",
           "sample_clamp_indirect")


def _rna_values(struct):
    out = {}
    for prop in struct.bl_rna.properties:
        if prop.identifier == "rna_type" or prop.is_readonly or prop.type in {"POINTER", "COLLECTION"}:
            continue
        try:
            value = getattr(struct, prop.identifier)
        except AttributeError:
            continue
        if hasattr(value, "__len__") and not isinstance(value, str):
            value = tuple(value) if prop.type != "ENUM" else set(value)
        out[prop.identifier] = value
    return out


def _set_rna_values(struct, values):
    for key, value in values.items():
        try:
            if getattr(struct, key) != value:
                setattr(struct, key, value)
        except (AttributeError, TypeError, ValueError):
            pass


def _hidden(obj, view_layer):
    """Hidden in the viewport (the eye); False for an object outside ``view_layer``."""
    try:
        return obj.hide_get(view_layer=view_layer)
    except RuntimeError:
        return False


class SavedState:
    """Context manager: the state of ``scene`` and of ``objects`` (and their meshes) as the user left it."""

    def __init__(self, scene, objects):
        self.scene = scene
        self.objects = list(objects)
        self.temp = []            # (collection, id) removed on exit
        self.uv_created = []      # (mesh, layer name) removed on exit unless kept
        self.attr_created = []    # (mesh, attribute name) removed on exit unless kept
        self.uv_saved = {}        # (mesh name, layer name) -> (mesh, UVs) of a rewritten layer, put back unless kept
        self.keep = set()         # (mesh name, layer/attribute name) to keep
        self.render_hidden = []   # objects hidden for render, shown to Cycles for their own map only
        self.flipped = []         # meshes whose normals are flipped for the bake, flipped back last on exit

    # ---- save
    def __enter__(self):
        sc, r = self.scene, self.scene.render
        vl = sc.view_layers[0]
        self.engine = r.engine
        self.cycles = {k: getattr(sc.cycles, k) for k in _CYCLES if hasattr(sc.cycles, k)}
        self.bake = _rna_values(r.bake)
        self.world = sc.world
        self.ao_distance = sc.world.light_settings.distance if sc.world else None
        self.selection = {o.name: o.select_get(view_layer=vl) for o in vl.objects}
        self.visibility = {o.name: (o, _hidden(o, vl), o.hide_viewport, o.hide_render) for o in self.objects}
        self.active = vl.objects.active
        self.slots = {}
        self.meshes = {}
        for o in self.objects:
            self.slots[o.name] = [(s.link, s.material) for s in o.material_slots]
            me = o.data
            self.meshes[me.name] = {
                "materials": list(me.materials),
                "uv_active": me.uv_layers.active_index,
                "uv_render": next((l.name for l in me.uv_layers if l.active_render), None),
                "color_active": me.color_attributes.active_color_name,
                "color_render": me.color_attributes.render_color_index,
                "attr_active": me.attributes.active.name if me.attributes.active else None,
            }
        return self

    def unhide(self, obj, render=False):
        """Show ``obj`` in the viewport (and to Cycles rays with ``render``) until exit."""
        vl = self.scene.view_layers[0]
        if _hidden(obj, vl):
            obj.hide_set(False, view_layer=vl)
        if obj.hide_viewport:
            obj.hide_viewport = False
        if render and obj.hide_render:
            obj.hide_render = False

    def flip_normals(self, mesh):
        """Flip ``mesh``'s normals (winding; each corner keeps its UVs and attributes) until exit."""
        if mesh not in self.flipped:
            mesh.flip_normals()
            self.flipped.append(mesh)

    # ---- register temporaries
    def track(self, collection, idblock):
        self.temp.append((collection, idblock))
        return idblock

    def created_uv(self, mesh, name):
        self.uv_created.append((mesh, name))

    def created_attribute(self, mesh, name):
        self.attr_created.append((mesh, name))

    def save_uv(self, mesh, name):
        """Remember the UVs of an existing layer about to be rewritten (first call wins)."""
        if (mesh.name, name) not in self.uv_saved and (mesh, name) not in self.uv_created:
            data = np.zeros(len(mesh.loops) * 2, np.float32)
            mesh.uv_layers[name].data.foreach_get("uv", data)
            self.uv_saved[(mesh.name, name)] = (mesh, data)

    # ---- restore
    def __exit__(self, *exc):
        sc = self.scene
        vl = sc.view_layers[0]
        for o in self.objects:
            if o.mode != "OBJECT":
                try:
                    with bpy.context.temp_override(scene=sc, view_layer=vl, active_object=o, object=o):
                        bpy.ops.object.mode_set(mode="OBJECT")
                except RuntimeError:
                    pass
        for o in self.objects:
            saved = self.slots[o.name]
            me = o.data
            mats = self.meshes[me.name]["materials"]
            if len(me.materials) != len(mats):
                me.materials.clear()          # clear() also resyncs the object's slot count (pop() does not)
                for m in mats:
                    me.materials.append(m)
            for i, m in enumerate(mats):
                if me.materials[i] != m:
                    me.materials[i] = m
            for slot, (link, mat) in zip(o.material_slots, saved):
                if slot.link != link:
                    slot.link = link
                if slot.material != mat:
                    slot.material = mat
        for me, name in self.uv_created:
            if (me.name, name) not in self.keep and name in me.uv_layers:
                me.uv_layers.remove(me.uv_layers[name])
        for key, (me, data) in self.uv_saved.items():
            if key not in self.keep and key[1] in me.uv_layers:
                me.uv_layers[key[1]].data.foreach_set("uv", data)
        for me, name in self.attr_created:
            if (me.name, name) not in self.keep and name in me.color_attributes:
                me.color_attributes.remove(me.color_attributes[name])
        for o in self.objects:
            me = o.data
            m = self.meshes.get(me.name)
            if m is None:
                continue
            if m["uv_render"] is not None and m["uv_render"] in me.uv_layers:
                me.uv_layers[m["uv_render"]].active_render = True
            if 0 <= m["uv_active"] < len(me.uv_layers):
                me.uv_layers.active_index = m["uv_active"]
            if m["color_active"] is not None and m["color_active"] in me.color_attributes:
                me.color_attributes.active_color_name = m["color_active"]
            if 0 <= m["color_render"] < len(me.color_attributes):
                me.color_attributes.render_color_index = m["color_render"]
            if m["attr_active"] is not None and m["attr_active"] in me.attributes:
                me.attributes.active = me.attributes[m["attr_active"]]
        for collection, idblock in reversed(self.temp):
            try:
                collection.remove(idblock)
            except (ReferenceError, RuntimeError):
                pass
        r = sc.render
        if r.engine != self.engine:
            r.engine = self.engine
        for k, v in self.cycles.items():
            if getattr(sc.cycles, k) != v:
                setattr(sc.cycles, k, v)
        _set_rna_values(r.bake, self.bake)
        if sc.world != self.world:
            sc.world = self.world
        if self.world is not None and self.world.light_settings.distance != self.ao_distance:
            self.world.light_settings.distance = self.ao_distance
        for obj, hidden, viewport, render in self.visibility.values():
            try:
                if obj.hide_render != render:
                    obj.hide_render = render
                if obj.hide_viewport != viewport:
                    obj.hide_viewport = viewport
                if _hidden(obj, vl) != hidden:
                    obj.hide_set(hidden, view_layer=vl)
            except ReferenceError:
                pass
        for o in filter(None, vl.objects):
            want = self.selection.get(o.name, False)
            if o.select_get(view_layer=vl) != want:
                o.select_set(want, view_layer=vl)
        if vl.objects.active != self.active:
            vl.objects.active = self.active
        for me in reversed(self.flipped):     # last: UVs put back above were saved in the flipped order
            me.flip_normals()
        self.flipped = []
        return False
