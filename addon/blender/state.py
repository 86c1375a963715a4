"""Leave the user's file as it was: save what a job touches and put it back, also after an error or Ctrl-C.

Usage::

    with SavedState(scene, objects, settings=[(scene.render, "engine"), ...]) as state:
        state.world(sc.black_world)         # a world while the job runs, when the scene has none
        state.track(bpy.data.images, img)   # temporary data-blocks removed on exit
        ...

The one implementation: the bake, the SSAO lab, the shadow lab (its light) and render.render_layers use it.
On exit (normal, exception or KeyboardInterrupt):

- always: the selection and the active object of the scene's first view layer are put back;
- ``settings``, (owner, attribute) RNA values saved on entry (render, Cycles, EEVEE, display, passes, a
  light's data, ...), are put back in order, and those refused once (an image format's media type before
  its file format) again at the end;
- ``objects``: their mode, material slots, viewport / render visibility, and their meshes' materials,
  active / render UV layer and active colour attributes are put back; UV layers / colour attributes
  registered with ``created_uv`` / ``created_attribute`` are removed, layers saved with ``save_uv`` get their
  UVs back and meshes flipped with ``flip_normals`` are flipped back, unless their (mesh name, name) is in
  ``keep`` (the products of a successful bake);
- every data-block registered with ``track`` (or added by ``world``) is removed.
"""
import bpy
import numpy as np

_ERRORS = (AttributeError, TypeError, ValueError, ReferenceError)


def remove_ids(tracked):
    """Remove the data-blocks of ``tracked`` [(collection, data-block)] still in the file: all but scenes in one
    ``BlendData.batch_remove`` (one pass over the file's users, where each ``remove`` makes its own: O(N²) for a
    level's N temporaries), scenes, and all when the batch is refused, one by one; one that cannot be removed is
    left."""
    alive = []
    for collection, idblock in tracked:
        try:
            idblock.name
        except ReferenceError:                 # removed already (a bake's proxy, an unwrap's scratch scene)
            continue
        alive.append((collection, idblock))
    rest = [(c, i) for c, i in alive if isinstance(i, bpy.types.Scene)]
    batch = [i for c, i in alive if not isinstance(i, bpy.types.Scene)]
    try:
        if batch:
            bpy.data.batch_remove(batch)
    except RuntimeError:
        rest = alive
    for collection, idblock in rest:
        try:
            collection.remove(idblock)
        except (ReferenceError, RuntimeError):
            pass


def rna_settings(struct):
    """(struct, identifier) of every plain writable RNA property of ``struct`` (no pointers, collections)."""
    out = []
    for prop in struct.bl_rna.properties:
        if prop.identifier == "rna_type" or prop.is_readonly or prop.type in {"POINTER", "COLLECTION"}:
            continue
        if hasattr(struct, prop.identifier):
            out.append((struct, prop.identifier))
    return out


def world_settings(scene):
    """The scene's world pointer and, when it has a world, that world's AO distance and Cycles sampling method."""
    items = [(scene, "world")]
    if scene.world is not None:
        items.append((scene.world.light_settings, "distance"))
        if hasattr(scene.world, "cycles"):
            items.append((scene.world.cycles, "sampling_method"))
    return items


def _snapshot(value):
    """A copy of an RNA value that later reads compare with (arrays as tuples, enum flags as sets)."""
    if isinstance(value, (set, frozenset)):
        return set(value)
    if hasattr(value, "__len__") and not isinstance(value, str):
        return tuple(value)
    return value


def _hidden(obj, view_layer):
    """Hidden in the viewport (the eye); False for an object outside ``view_layer``."""
    try:
        return obj.hide_get(view_layer=view_layer)
    except RuntimeError:
        return False


class SavedState:
    """Context manager: ``scene``'s selection, ``settings`` and ``objects`` (and their meshes) as the user left them."""

    def __init__(self, scene, objects=(), settings=()):
        self.scene = scene
        self.objects = list(objects)
        self.settings = list(settings)
        self.temp = []            # (collection, id) removed on exit
        self.uv_created = []      # (mesh, layer name) removed on exit unless kept
        self.attr_created = []    # (mesh, attribute name) removed on exit unless kept
        self.uv_saved = {}        # (mesh name, layer name) -> (mesh, UVs) of a rewritten layer, put back unless kept
        self.keep = set()         # (mesh name, layer/attribute name) to keep
        self.render_hidden = []   # objects hidden for render, shown to Cycles for their own map only
        self.flipped = []         # meshes whose normals are flipped for the bake, flipped back last on exit

    # ---- save
    def __enter__(self):
        vl = self.scene.view_layers[0]
        self.saved = []
        for owner, attr in self.settings:
            try:
                self.saved.append((owner, attr, _snapshot(getattr(owner, attr))))
            except AttributeError:
                pass
        self.selection = {o.name: o.select_get(view_layer=vl) for o in vl.objects}
        self.active = vl.objects.active
        self.visibility = {o.name: (o, _hidden(o, vl), o.hide_viewport, o.hide_render) for o in self.objects}
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

    def world(self, make):
        """The scene's world; when it has none, ``make()``'s world, assigned until exit and then removed."""
        if self.scene.world is None:
            self.scene.world = self.track(bpy.data.worlds, make())
        return self.scene.world

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
        self._restore_settings()
        remove_ids(reversed(self.temp))
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

    def _restore_settings(self):
        refused = []
        for owner, attr, value in self.saved:
            try:
                if _snapshot(getattr(owner, attr)) != value:
                    setattr(owner, attr, value)
            except _ERRORS:
                refused.append((owner, attr, value))
        for owner, attr, value in refused:      # order-dependent ones (media type before file format)
            try:
                setattr(owner, attr, value)
            except _ERRORS:
                pass
