"""A new user's walk through the UI (issue 8, item 4).

Panels are drawn with their real ``draw`` functions into a recording stand-in of ``UILayout``
that checks every call against the real UILayout's RNA (function names, keyword names, icons),
every ``prop`` against the data it names and every ``operator`` against the registered
operators. Every operator is then pressed the way a button does (default properties, output
folders in ``tmp_path``, small sizes) on the demo scene carrying the user's own materials,
images and UV maps: it finishes, or fails its poll with a message, or reports an ERROR --
never a traceback, never a silent cancel -- and the user's things survive each press.
Inside Blender an extension has no matplotlib or scipy: the walk runs with both blocked.
"""
import hashlib
import os
import re
import sys
import types

import bpy
import numpy as np
import pytest

from addon.blender import compat
from addon.blender import progress as progress_mod
from addon.core.io import exr
from addon.lab.demo import scene as demo

UI_FUNCS = bpy.types.UILayout.bl_rna.functions
UI_PROPS = {p.identifier for p in bpy.types.UILayout.bl_rna.properties}
ICONS = {i.identifier for i in UI_FUNCS["prop"].parameters["icon"].enum_items}
PANELS = ("IL_PT_main", "IL_PT_shading", "IL_PT_environment", "IL_PT_lightmaps", "IL_PT_envmap",
          "IL_PT_comparisons", "IL_PT_shadows", "IL_PT_ssao", "IL_PT_reflections", "IL_PT_raytrace")
SUBLAYOUTS = {"row", "column", "box", "split", "column_flow", "grid_flow", "menu_pie"}
PROP_CALLS = {"prop", "prop_enum", "prop_menu_enum", "props_enum", "prop_tabs_enum", "prop_search",
              "prop_with_menu", "prop_with_popover", "prop_decorator", "template_ID", "template_list"}
ID_COLLECTIONS = ("materials", "images", "meshes", "objects", "node_groups", "worlds", "scenes", "collections",
                  "cameras", "lights", "textures")
#: Reported to the lead (addon/bake is not this walk's to fix); test_bake_keeps_the_face_selection tracks it.
KNOWN_BAKE_ISSUES = ("face_select",)
from tests.conftest import ROOT  # noqa: E402
LONG = {"bake_lightmaps", "run_shadow_comparison", "ssao_compare", "radiosity", "raytrace_render", "reflections_compare"}


# ------------------------------------------------------------------ recording layout

def _operator_rna(idname, problems):
    mod, _, name = idname.partition(".")
    try:
        return getattr(getattr(bpy.ops, mod), name).get_rna_type()
    except (AttributeError, KeyError) as e:
        problems.append(f"operator '{idname}' is not registered ({e})")
        return None


class FakeOperatorProperties:
    """What ``layout.operator`` returns: property assignments are checked against the operator's RNA."""

    def __init__(self, idname, rna, problems):
        object.__setattr__(self, "_idname", idname)
        object.__setattr__(self, "_props", {p.identifier: p for p in rna.properties} if rna else {})
        object.__setattr__(self, "_problems", problems)
        object.__setattr__(self, "assigned", set())

    def __setattr__(self, key, value):
        self.assigned.add(key)
        prop = self._props.get(key)
        if prop is None:
            self._problems.append(f"{self._idname} has no property '{key}'")
        elif prop.type == "ENUM":
            items = {i.identifier for i in prop.enum_items}
            values = value if prop.is_enum_flag else {value}
            if not set(values) <= items:
                self._problems.append(f"{self._idname}.{key} = {value!r} is not one of {sorted(items)}")
        elif prop.type in ("INT", "FLOAT") and getattr(prop, "array_length", 0) == 0:
            if not prop.hard_min <= value <= prop.hard_max:
                self._problems.append(f"{self._idname}.{key} = {value} outside [{prop.hard_min}, {prop.hard_max}]")


class Recorder:
    def __init__(self):
        self.calls, self.problems, self.buttons = [], [], []

    def operators(self):
        return {c[1]["operator"] for c in self.calls if c[0] == "operator"}


class FakeLayout:
    """A stand-in for bpy.types.UILayout that records calls and checks them against the real RNA."""

    def __init__(self, rec):
        object.__setattr__(self, "_rec", rec)

    def __setattr__(self, key, value):
        if key not in UI_PROPS:
            self._rec.problems.append(f"UILayout has no attribute '{key}'")

    def __getattr__(self, name):
        if name in UI_PROPS:
            return {"scale_x": 1.0, "scale_y": 1.0, "ui_units_x": 0.0, "ui_units_y": 0.0}.get(name, True)
        func = UI_FUNCS.get(name)
        if func is None:
            self._rec.problems.append(f"UILayout has no function '{name}'")
            raise AttributeError(name)
        params = [p for p in func.parameters if not p.is_output]
        return lambda *args, **kw: self._call(name, params, args, kw)

    def _call(self, name, params, args, kw):
        rec = self._rec
        ids = [p.identifier for p in params]
        if len(args) > len(ids):
            rec.problems.append(f"{name}: {len(args)} positional arguments, takes {len(ids)}")
        bound = dict(zip(ids, args))
        for k in kw:
            if k not in ids:
                rec.problems.append(f"{name}: unknown keyword '{k}'")
            elif k in bound:
                rec.problems.append(f"{name}: '{k}' given twice")
        bound.update(kw)
        for p in params:
            if p.is_required and p.identifier not in bound:
                rec.problems.append(f"{name}: missing required '{p.identifier}'")
        icon = bound.get("icon")
        if icon is not None and icon not in ICONS:
            rec.problems.append(f"{name}: unknown icon '{icon}'")
        if "text" in bound and not isinstance(bound["text"], str):
            rec.problems.append(f"{name}: text {bound['text']!r} is not a string")
        rec.calls.append((name, bound))
        if name in PROP_CALLS:
            self._check_prop(name, bound.get("data"), bound.get("property"))
            if name == "prop_search":
                self._check_prop(name, bound.get("search_data"), bound.get("search_property"))
        if name in SUBLAYOUTS:
            return FakeLayout(rec)
        if name in ("panel", "panel_prop"):
            return FakeLayout(rec), FakeLayout(rec)
        if name in ("operator", "operator_menu_enum", "operator_enum", "operator_menu_hold"):
            idname = bound.get("operator", "")
            rna = _operator_rna(idname, rec.problems)
            if name != "operator" and rna is not None and bound.get("property") not in rna.properties:
                rec.problems.append(f"{idname} has no property '{bound.get('property')}'")
            props = FakeOperatorProperties(idname, rna, rec.problems)
            rec.buttons.append((idname, props))
            return props
        return None

    def _check_prop(self, name, data, prop):
        if data is None or prop is None:
            return
        if prop.startswith("["):
            try:
                data.path_resolve(prop)
            except ValueError:
                self._rec.problems.append(f"{name}: {data!r} has no custom property {prop}")
        elif prop not in data.bl_rna.properties:
            self._rec.problems.append(f"{name}: {type(data).__name__} has no property '{prop}'")


def draw_panels(context=None):
    """Poll and draw every IL panel (sub-panels only when their parent polls); return the Recorder."""
    context = context or bpy.context
    rec = Recorder()
    shown = set()
    for name in PANELS:
        cls = getattr(bpy.types, name)
        parent = getattr(cls, "bl_parent_id", "")
        if parent and parent not in shown:
            continue
        poll = getattr(cls, "poll", None)
        if poll is not None and not poll(context):
            continue
        shown.add(name)
        for fn in ("draw_header", "draw"):
            if hasattr(cls, fn):
                getattr(cls, fn)(types.SimpleNamespace(layout=FakeLayout(rec), bl_idname=name), context)
    rec.shown = shown
    return rec


def assert_clean(rec, where):
    assert rec.problems == [], f"{where}: {rec.problems}"


# ------------------------------------------------------------------ the user's file

def _user_material(name, image=None):
    mat = bpy.data.materials.new(name)
    compat.ensure_use_nodes(mat)
    nt = mat.node_tree
    bsdf = next(n for n in nt.nodes if n.bl_idname == "ShaderNodeBsdfPrincipled")
    bsdf.inputs["Base Color"].default_value = (0.7, 0.2, 0.1, 1.0)
    if image is not None:
        tex = nt.nodes.new("ShaderNodeTexImage")
        tex.name = "User Texture Node"
        tex.image = image
        nt.links.new(tex.outputs["Color"], bsdf.inputs["Base Color"])
    return mat


def user_demo():
    """The demo scene as a user would have it: own materials (one textured), image, UV maps, selection."""
    scene = demo.build_demo_scene(new_scene=True, resolution=(64, 48))
    bpy.context.window.scene = scene
    img = bpy.data.images.new("User Texture", 4, 4)
    img.pixels.foreach_set(np.linspace(0, 1, 64, dtype=np.float32))
    painted, plain = _user_material("User Painted", img), _user_material("User Plain")
    for role in ("Box", "Sphere", "Torus", "Floor"):
        obj = demo.get(scene, role)
        obj.data.materials.append(painted if role == "Box" else plain)
        obj.data.uv_layers.new(name="UVMap")
        obj.data.polygons.foreach_set("select", np.arange(len(obj.data.polygons)) % 3 == 0)
    vl = scene.view_layers[0]
    for o in scene.objects:
        o.select_set(o.get(demo.ROLE) in ("Box", "Sphere"), view_layer=vl)
    vl.objects.active = demo.get(scene, "Sphere")
    scene.cycles.samples = 7
    return scene


def _digest(values):
    return hashlib.sha1(np.asarray(values).tobytes()).hexdigest()[:12]


def _object_state(o, vl):
    st = {"materials": tuple(s.material.name if s.material else None for s in o.material_slots),
          "select": o.select_get(view_layer=vl), "hide_render": o.hide_render, "hide": o.hide_get(view_layer=vl),
          "matrix": tuple(round(v, 6) for row in o.matrix_basis for v in row), "data": getattr(o.data, "name", None)}
    if o.type == "MESH":
        me = o.data
        sel = np.zeros(len(me.polygons), bool)
        me.polygons.foreach_get("select", sel)
        st.update(uv=tuple(l.name for l in me.uv_layers),
                  uv_active=me.uv_layers.active.name if me.uv_layers.active else None,
                  uv_render=next((l.name for l in me.uv_layers if l.active_render), None),
                  color_active=me.color_attributes.active_color_name, face_select=_digest(sel),
                  verts=len(me.vertices))
    return st


def snapshot():
    snap = {"ids": {c: {i.name for i in getattr(bpy.data, c)} for c in ID_COLLECTIONS},
            "window_scene": bpy.context.window.scene.name, "scenes": {}, "images": {}, "materials": {}}
    for sc in bpy.data.scenes:
        vl, r = sc.view_layers[0], sc.render
        snap["scenes"][sc.name] = {
            "engine": r.engine, "samples": sc.cycles.samples, "device": sc.cycles.device,
            "resolution": (r.resolution_x, r.resolution_y, r.resolution_percentage), "filepath": r.filepath,
            "file_format": r.image_settings.file_format, "film_transparent": r.film_transparent,
            "world": sc.world.name if sc.world else None, "camera": sc.camera.name if sc.camera else None,
            "view_transform": sc.view_settings.view_transform,
            "passes": (vl.use_pass_z, vl.use_pass_normal, vl.use_pass_position, vl.use_pass_ambient_occlusion),
            "active": vl.objects.active.name if vl.objects.active else None,
            "objects": {o.name: _object_state(o, vl) for o in sc.objects}}
    for img in bpy.data.images:
        px = ""
        if img.name.startswith("User"):
            px = np.empty(len(img.pixels), np.float32)
            img.pixels.foreach_get(px)
            px = _digest(px)
        snap["images"][img.name] = (img.filepath, tuple(img.size), img.source, px)
    for m in bpy.data.materials:
        nt = m.node_tree
        snap["materials"][m.name] = (sorted(n.name for n in nt.nodes) if nt else [],
                                     sorted((l.from_node.name, l.to_node.name) for l in nt.links) if nt else [],
                                     m.users > 0 or m.use_fake_user)
    return snap


def assert_kept(before, after, step, reassigned=(), ignore=()):
    """Nothing the user had before ``step`` is gone or changed (``reassigned`` objects may get new materials;
    ``ignore``: object keys reported elsewhere)."""
    for coll, names in before["ids"].items():
        assert names <= after["ids"][coll], f"{step}: lost {coll} {sorted(names - after['ids'][coll])}"
    for name, sc in before["scenes"].items():
        now = after["scenes"][name]
        for key, value in sc.items():
            if key != "objects":
                assert now[key] == value, f"{step}: scene '{name}' {key} {value!r} -> {now[key]!r}"
        for oname, ost in sc["objects"].items():
            assert oname in now["objects"], f"{step}: object '{oname}' left scene '{name}'"
            for key, value in ost.items():
                if (key == "materials" and oname in reassigned) or key in ignore:
                    continue
                if key == "uv":     # products (the generated "Lightmap" layer) may be added, nothing removed
                    assert set(value) <= set(now["objects"][oname][key]), f"{step}: '{oname}' lost UV layers"
                    continue
                assert now["objects"][oname][key] == value, \
                    f"{step}: '{oname}' {key} {value!r} -> {now['objects'][oname][key]!r}"
    for name, value in before["images"].items():
        assert after["images"][name] == value, f"{step}: image '{name}' {value} -> {after['images'][name]}"
    for name, (nodes, links, used) in before["materials"].items():
        n2, l2, used2 = after["materials"][name]
        if name.startswith("User"):
            assert (n2, l2) == (nodes, links), f"{step}: material '{name}' nodes changed"
            assert used2, f"{step}: material '{name}' has no users left (lost on save)"


# ------------------------------------------------------------------ pressing buttons

def press(name, **props):
    """Call ``bpy.ops.illumination.<name>`` as a button does; return (outcome, message)."""
    op = getattr(bpy.ops.illumination, name)
    try:
        result = op(**props)
    except RuntimeError as e:
        msg = str(e).strip()
        if "Traceback" in msg or "Python:" in msg:
            return "TRACEBACK", msg
        if ".poll()" in msg:
            return "POLL", msg.split(".poll()", 1)[1].strip()
        if msg.startswith("Error:"):
            return "ERROR", msg[len("Error:"):].strip()
        return "OTHER", msg
    return ("FINISHED" if result == {"FINISHED"} else f"SILENT {sorted(result)}"), ""


def assert_says_why(outcome, message, expected, name):
    assert outcome == expected, f"{name}: {outcome} {message}"
    if outcome in ("POLL", "ERROR"):
        assert message and "context is incorrect" not in message and len(message) < 300, f"{name}: {message!r}"
        assert "''" not in message, f"{name}: an empty name in {message!r}"
        assert not re.search(r"(pass|use|give) --", message), f"{name}: a command-line flag as the only way out"


@pytest.fixture
def no_matplotlib_no_scipy(monkeypatch):
    """Blender's Python has numpy but neither matplotlib nor scipy: block them like a real install."""
    for key in [k for k in sys.modules if k.split(".")[0] in ("matplotlib", "scipy")] + ["matplotlib", "scipy"]:
        monkeypatch.setitem(sys.modules, key, None)


@pytest.fixture
def progress_log(monkeypatch):
    log = []
    init = progress_mod.Progress.__init__

    def recording_init(self, label, total):
        init(self, label, total)
        log.append(self)
    monkeypatch.setattr(progress_mod.Progress, "__init__", recording_init)
    return log


def small_settings(scene, tmp_path):
    s = scene.illumination
    lm = s.lightmaps
    lm.resolution, lm.samples, lm.bounces, lm.margin, lm.output_dir = 16, 2, 1, 1, str(tmp_path / "lightmaps") + os.sep
    sh = s.shadows
    sh.resolution, sh.shadowmap_size, sh.output_dir = 32, 64, str(tmp_path / "shadows")
    ss = s.ssao
    ss.resolution, ss.samples, ss.reference_samples, ss.output_dir = 32, 4, 8, str(tmp_path / "ssao") + os.sep
    rf = s.reflections
    rf.resolution, rf.map_size, rf.output_dir = 24, 8, str(tmp_path / "reflections") + os.sep
    rt = s.raytrace
    rt.resolution, rt.samples, rt.max_depth, rt.output_dir = 16, 2, 2, str(tmp_path / "raytrace") + os.sep


def small_env_file(path):
    h, w = 16, 32
    theta = (np.arange(h) + 0.5) / h * np.pi
    sky = np.broadcast_to((0.2 + np.cos(theta).clip(0))[:, None], (h, w)).astype(np.float32)
    exr.write_exr(str(path), {"R": sky, "G": sky, "B": 0.5 * sky})
    return str(path)


# ------------------------------------------------------------------ tests: panels

def _contexts():
    """(label, setup) pairs: each setup puts the file in one state a user can be in."""
    def empty():
        pass

    def demo_nothing_selected():
        sc = user_demo()
        for o in sc.objects:
            o.select_set(False)
        sc.view_layers[0].objects.active = None

    def active(role):
        def setup():
            sc = user_demo()
            sc.view_layers[0].objects.active = demo.get(sc, role)
        return setup

    def il_material():
        user_demo()
        assert press("assign_shading_model", model="COOK_TORRANCE")[0] == "FINISHED"

    def other_branches():
        sc = user_demo()
        s = sc.illumination
        s.shading.attenuation = "EMPIRICAL"
        s.lightmaps.size_mode, s.lightmaps.quality_mode = "DENSITY", "ERROR"
        s.shadows.last_report, s.shadows.last_summary = "/tmp/x/shadows_report.json", "planar 1.00%"
        s.ssao.last_report = '{"gtao": [0.05, -0.01, 0.2]}'

    def vertex_target():
        sc = user_demo()
        sc.illumination.lightmaps.target = "vertex"

    return [("empty scene", empty), ("demo, nothing selected", demo_nothing_selected),
            ("demo, camera active", active("Camera")), ("demo, light active", active("Key")),
            ("demo, user material active", active("Box")), ("demo, IL material active", il_material),
            ("other branches", other_branches), ("vertex target", vertex_target)]


@pytest.mark.both_versions
def test_every_panel_draws_in_every_state_and_shows_every_operator():
    shown_ops, unset = set(), {}
    for label, setup in _contexts():
        bpy.ops.wm.read_factory_settings(use_empty=True)
        setup()
        rec = draw_panels()
        assert_clean(rec, label)
        assert rec.shown == set(PANELS), f"{label}: panels hidden: {set(PANELS) - rec.shown}"
        shown_ops |= rec.operators()
        for idname, props in rec.buttons:
            rna = _operator_rna(idname, [])
            own = {p.identifier for p in rna.properties if p.identifier != "rna_type" and not p.is_hidden}
            unset.setdefault(idname, set()).update(own - props.assigned)
        if label == "demo, IL material active":
            labels = [c[1].get("text") for c in rec.calls if c[0] == "prop"]
            assert {"Roughness", "Physical"} <= set(labels), labels
    registered = {f"illumination.{n}" for n in dir(bpy.ops.illumination)}
    assert registered - shown_ops == set(), "operators without a button"
    assert shown_ops <= registered
    # a button whose operator has settings the panel does not pass must let the user set them before it runs
    for idname, names in unset.items():
        if names:
            cls = getattr(bpy.types, "ILLUMINATION_OT_" + idname.split(".")[1])
            assert "invoke" in vars(cls), f"{idname}: {sorted(names)} cannot be set before it runs"


def test_the_recording_layout_catches_mistakes():
    rec = Recorder()
    layout = FakeLayout(rec)
    s = bpy.context.scene.illumination.shadows
    layout.prop(s, "no_such_property")
    layout.column(align=True).operator("illumination.no_such_operator")
    layout.label(text="x", icon="NO_SUCH_ICON")
    layout.row(wrong_keyword=True)
    op = layout.operator("illumination.assign_shading_model")
    op.model = "NOT_A_MODEL"
    op.nothing = 1
    layout.use_property_split = True
    assert len(rec.problems) == 6, rec.problems


# ------------------------------------------------------------------ tests: operators

@pytest.mark.both_versions
def test_walk_every_button_on_the_demo_scene(tmp_path, no_matplotlib_no_scipy, progress_log):
    scene = user_demo()
    small_settings(scene, tmp_path)
    env = small_env_file(tmp_path / "sky.exr")
    box, sphere = demo.get(scene, "Box").name, demo.get(scene, "Sphere").name
    # (operator, properties, expected outcome, words the message must contain, objects whose material may change)
    steps = [
        ("add_node_groups", {}, "FINISHED", "", ()),
        ("relink_lights", {}, "FINISHED", "", ()),
        ("bake_lightmaps", {}, "FINISHED", "", ()),
        ("apply_lightmaps", {"source": "IRRADIANCE"}, "ERROR", "no irradiance map", ()),
        ("apply_lightmaps", {"source": "AO"}, "FINISHED", "", (box, sphere)),
        ("remove_lightmaps", {}, "FINISHED", "", (box, sphere)),
        ("export_lightmaps", {"filepath": str(tmp_path / "scene.txt")}, "ERROR", ".glb", ()),
        ("export_lightmaps", {"filepath": str(tmp_path / "scene.glb")}, "FINISHED", "", ()),
        ("reflections_compare", {}, "ERROR", "Environment Texture", ()),
        ("raytrace_render", {}, "FINISHED", "", ()),
        ("run_shadow_comparison", {}, "FINISHED", "", ()),
        ("ssao_compare", {}, "FINISHED", "", ()),
        ("envmap_irradiance", {"output_dir": str(tmp_path / "env")}, "ERROR", "Environment Texture", ()),
        ("envmap_irradiance", {"output_dir": str(tmp_path / "env"), "env_file": env}, "FINISHED", "", ()),
        ("radiosity", {"output_dir": str(tmp_path / "rad"), "compare": False}, "ERROR", "emits light", ()),
        ("assign_environment_mapping", {}, "ERROR", "Environment Texture", ()),
        ("remove_environment_mapping", {}, "POLL", "Nothing to restore", ()),
        ("add_environment_group", {}, "FINISHED", "", ()),
        ("assign_shading_model", {"model": "OREN_NAYAR"}, "FINISHED", "", (box, sphere)),
        ("relink_lights", {}, "FINISHED", "", ()),
        ("remove_shading_model", {}, "FINISHED", "", (box, sphere)),
        ("assign_shading_model", {"model": "OREN_NAYAR"}, "FINISHED", "", (box, sphere)),
        ("radiosity", {"output_dir": str(tmp_path / "rad"), "compare": False}, "ERROR", "", ()),
        ("build_shadow_scene", {}, "FINISHED", "", ()),
        ("run_shadow_comparison", {}, "FINISHED", "", ()),
        ("ssao_build_scene", {}, "FINISHED", "", ()),
        ("ssao_compare", {}, "FINISHED", "", ()),
        ("reflections_build_scene", {}, "FINISHED", "", ()),
        ("reflections_compare", {}, "FINISHED", "", ()),
        ("raytrace_build_scene", {}, "FINISHED", "", ()),
        ("raytrace_render", {}, "FINISHED", "", ()),
        ("build_cornell_box", {}, "FINISHED", "", ()),
        ("radiosity", {"output_dir": str(tmp_path / "cornell"), "samples": 2, "max_edge": 0.5}, "FINISHED", "", ()),
        ("build_demo_scene", {}, "FINISHED", "", ()),
    ]
    pressed = set()
    for k, (name, props, expected, words, reassigned) in enumerate(steps):
        step = f"step {k} {name}{props or ''}"
        if name.startswith("ssao_build"):
            bpy.context.scene.illumination.ssao.resolution = 32
        before, n_progress = snapshot(), len(progress_log)
        outcome, message = press(name, **props)
        assert_says_why(outcome, message, expected, step)
        assert words in message, f"{step}: {message!r}"
        after = snapshot()
        if name.startswith("build_") or name.endswith("_build_scene"):
            assert after["window_scene"] != before["window_scene"], f"{step}: the new scene is not shown"
            assert set(after["ids"]["scenes"]) - set(before["ids"]["scenes"]) == {after["window_scene"]}
            after = dict(after, window_scene=before["window_scene"])
        assert after["window_scene"] == before["window_scene"], step
        assert_kept(before, after, step, reassigned, ignore=KNOWN_BAKE_ISSUES)
        if name in LONG and outcome == "FINISHED":
            runs = progress_log[n_progress:]
            assert runs and max(p.done for p in runs) >= 2, f"{step}: no progress shown"
        assert_clean(draw_panels(), f"panels after {step}")
        pressed.add(name)
    assert pressed == set(dir(bpy.ops.illumination))
    user = bpy.data.scenes[scene.name]
    for role in ("Torus", "Floor"):
        assert demo.get(user, role).material_slots[0].material.name == "User Plain"
    assert demo.get(user, "Box").material_slots[0].material.get("il_model") == "OREN_NAYAR"


def test_assigning_a_model_shows_it_and_keeps_the_replaced_materials():
    scene = user_demo()
    torus = demo.get(scene, "Torus")
    torus.material_slots[0].link = "OBJECT"
    torus.material_slots[0].material = bpy.data.materials["User Painted"]
    box = demo.get(scene, "Box")
    for o in scene.objects:
        o.select_set(o in (torus, box))
    outcome, message = press("assign_shading_model", model="BLINN_PHONG")
    assert (outcome, message) == ("FINISHED", "")
    assert torus.active_material.get("il_model") == "BLINN_PHONG"      # the object-linked slot shows it too
    painted, plain = bpy.data.materials["User Painted"], bpy.data.materials["User Plain"]
    assert torus.active_material["il_original"] == painted and painted.users == 1   # kept by its IL material
    assert not plain.use_fake_user and plain.users >= 3      # still on the sphere and the floor, and the box's IL


def test_bake_keeps_the_face_selection(tmp_path):
    scene = user_demo()
    small_settings(scene, tmp_path)
    before = snapshot()
    assert press("bake_lightmaps") == ("FINISHED", "")
    assert_kept(before, snapshot(), "bake_lightmaps")


def test_a_second_bake_says_how_to_overwrite_in_ui_terms(tmp_path):
    scene = user_demo()
    small_settings(scene, tmp_path)
    assert press("bake_lightmaps") == ("FINISHED", "")
    outcome, message = press("bake_lightmaps")
    assert_says_why(outcome, message, "ERROR", "second bake")


def test_bad_cases_say_why(tmp_path, no_matplotlib_no_scipy):
    # an empty file: every button either works or says why
    absolute = {"envmap_irradiance": {"output_dir": str(tmp_path / "env")},
                "radiosity": {"output_dir": str(tmp_path / "rad"), "compare": False}}
    small_settings(bpy.context.scene, tmp_path)
    for name in dir(bpy.ops.illumination):
        bpy.context.window.scene = bpy.data.scenes["Scene"]
        outcome, message = press(name, **absolute.get(name, {}))
        assert outcome in ("FINISHED", "POLL", "ERROR"), f"empty file, {name}: {outcome} {message}"
        assert_says_why(outcome, message, outcome, f"empty file, {name}")

    # the demo scene, nothing selected / a camera selected and active / a mesh in edit mode
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = user_demo()
    small_settings(scene, tmp_path)
    vl = scene.view_layers[0]
    for o in scene.objects:
        o.select_set(False)
    vl.objects.active = None
    before = snapshot()
    assert_says_why(*press("bake_lightmaps"), "POLL", "bake_lightmaps, nothing selected")
    outcome, message = press("assign_shading_model")
    assert_says_why(outcome, message, "ERROR", "assign_shading_model, nothing selected")
    assert "select" in message
    camera = demo.get(scene, "Camera")
    camera.select_set(True)
    vl.objects.active = camera
    before = snapshot()
    outcome, message = press("bake_lightmaps")
    assert_says_why(outcome, message, "POLL", "bake_lightmaps, camera")
    assert "mesh" in message
    outcome, message = press("assign_shading_model")
    assert_says_why(outcome, message, "ERROR", "assign_shading_model, camera")
    assert camera.name in message
    assert_kept(before, snapshot(), "camera active")

    box = demo.get(scene, "Box")
    camera.select_set(False)
    box.select_set(True)
    vl.objects.active = box
    bpy.ops.object.mode_set(mode="EDIT")
    try:
        for name in ("bake_lightmaps", "run_shadow_comparison", "radiosity"):
            outcome, message = press(name, **absolute.get(name, {}))
            assert_says_why(outcome, message, "POLL", f"{name}, edit mode")
            assert "Object Mode" in message
    finally:
        bpy.ops.object.mode_set(mode="OBJECT")

    # radiosity on lamps only (no emissive surface): said at once, before any visibility ray
    plain = demo.build_demo_scene(new_scene=True)
    bpy.context.window.scene = plain
    outcome, message = press("radiosity", **absolute["radiosity"])
    assert_says_why(outcome, message, "ERROR", "radiosity, lamps only")
    assert "emits light" in message and "lamps" in message
    bpy.context.window.scene = scene

    # unsaved file, the default relative "//" output folders
    for section in ("lightmaps", "shadows", "ssao", "reflections", "raytrace"):
        getattr(scene.illumination, section).property_unset("output_dir")
    before = snapshot()
    for name in ("bake_lightmaps", "run_shadow_comparison", "ssao_compare", "envmap_irradiance", "radiosity",
                 "export_lightmaps", "reflections_compare", "raytrace_render"):
        outcome, message = press(name)
        assert outcome in ("POLL", "ERROR"), f"{name}, unsaved: {outcome} {message}"
        assert_says_why(outcome, message, outcome, f"{name}, unsaved")
        assert "Save the file" in message, f"{name}: {message}"
    assert_kept(before, snapshot(), "unsaved file")


def test_buttons_with_settings_open_a_dialog_first():
    asked = []
    wm = types.SimpleNamespace(invoke_props_dialog=lambda op, **kw: asked.append(op) or {"RUNNING_MODAL"})
    context = types.SimpleNamespace(window_manager=wm)
    for name in ("envmap_irradiance", "radiosity"):
        cls = getattr(bpy.types, f"ILLUMINATION_OT_{name}")
        assert cls.invoke("the operator", context, None) == {"RUNNING_MODAL"}
    assert asked == ["the operator"] * 2


def test_progress_drives_the_window_manager_in_the_ui(monkeypatch):
    calls = []
    wm = types.SimpleNamespace(windows=[object()], progress_begin=lambda a, b: calls.append(("begin", a, b)),
                               progress_update=lambda v: calls.append(("update", v)),
                               progress_end=lambda: calls.append(("end",)))
    fake = types.SimpleNamespace(app=types.SimpleNamespace(background=False),
                                 context=types.SimpleNamespace(window_manager=wm))
    monkeypatch.setattr(progress_mod, "bpy", fake)
    with progress_mod.Progress("bake", 3) as p:
        for k in range(3):
            p.step(f"map {k}")
    assert calls == [("begin", 0, 3), ("update", 0), ("update", 1), ("update", 2), ("end",)]


# ------------------------------------------------------------------ tests: a button gives what its script gives

def _argv(options):
    """The command line that asks the script for ``options``: one flag per field (core.options specs), spelled
    as scripts/_cli.add_options spells it (a bool only when it differs from its default)."""
    from addon.core import options as core_options
    argv = []
    for name, kind, default, spec in core_options.specs(type(options)):
        value = getattr(options, name)
        if not spec.cli or value is None or (kind is bool and value == default):
            continue
        flag = spec.flag or "--" + name.replace("_", "-")
        if kind is bool:
            argv.append(spec.flag or ("--no-" if default else "--") + name.replace("_", "-"))
        elif spec.multiple:
            argv += [flag, spec.separator.join(value)] if spec.separator else [flag, *value]
        else:
            argv += [flag, str(value)]
    return argv


def _user_file(tmp_path):
    """A file made the ordinary way: primitives, a light, a camera, saved to disk."""
    bpy.ops.mesh.primitive_plane_add(size=6)
    bpy.ops.mesh.primitive_cube_add(location=(0, 0, 1))
    bpy.ops.object.light_add(type="SUN", location=(2, -2, 5), rotation=(0.5, 0.3, 0))
    bpy.ops.object.camera_add(location=(6, -6, 5), rotation=(1.0, 0, 0.785))
    scene = bpy.context.scene
    scene.camera = bpy.context.object
    scene.render.resolution_x, scene.render.resolution_y = 48, 36
    path = str(tmp_path / "user.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    return scene, path


def _same_exr(a, b):
    ca, _ = exr.read_exr(a)
    cb, _ = exr.read_exr(b)
    assert sorted(ca) == sorted(cb), (a, b)
    for c in ca:
        assert ca[c].shape == cb[c].shape and np.allclose(ca[c], cb[c], rtol=1e-5, atol=1e-6), (a, c)


def test_bake_button_gives_what_bake_py_gives(tmp_path, script):
    scene, path = _user_file(tmp_path)
    s = scene.illumination.lightmaps
    s.maps, s.resolution, s.samples, s.bounces, s.margin = {"ao", "irradiance"}, 16, 4, 1, 1
    s.output_dir = str(tmp_path / "button")
    vl = scene.view_layers[0]
    for o in scene.objects:
        o.select_set(o.type == "MESH", view_layer=vl)
    vl.objects.active = scene.objects["Cube"]
    options = s.options()
    assert press("bake_lightmaps") == ("FINISHED", "")
    r = script("bake.py", path, "--objects", "Plane", "Cube", *_argv(options), "--out", tmp_path / "script")
    assert r.returncode == 0, r.stderr
    for name in ("Plane", "Cube"):
        for kind in ("ao", "irradiance"):
            _same_exr(tmp_path / "button" / f"{name}_{kind}.exr", tmp_path / "script" / f"{name}_{kind}.exr")


def test_ssao_and_shadow_buttons_give_what_their_scripts_give(tmp_path, script):
    scene, path = _user_file(tmp_path)
    ss = scene.illumination.ssao
    ss.methods, ss.resolution, ss.samples, ss.reference_samples, ss.radius = {"gtao", "hbao"}, 48, 4, 16, 0.75
    ss.radius_auto = False                 # the button uses the Radius field, as --radius does
    ss.output_dir = str(tmp_path / "ssao_button")
    assert press("ssao_compare") == ("FINISHED", "")
    from addon.lab.options import SSAOOptions
    from addon.ui import props
    argv = _argv(props.options(SSAOOptions, ss))
    r = script("ssao.py", path, *argv, "--out", tmp_path / "ssao_script")
    assert r.returncode == 0, r.stderr
    for m in ("reference", "gtao", "hbao"):
        _same_exr(tmp_path / "ssao_button" / f"{m}_ao.exr", tmp_path / "ssao_script" / f"{m}_ao.exr")

    st = scene.illumination.shadows
    st.methods, st.resolution, st.shadowmap_size, st.pcf = {"shadowmap", "volume_zfail"}, 40, 256, 3
    st.receiver, st.output_dir = "Plane", str(tmp_path / "shadow_button")
    assert press("run_shadow_comparison") == ("FINISHED", "")
    from addon.lab.options import ShadowOptions
    argv = _argv(props.options(ShadowOptions, st, methods=["raytraced", *sorted(st.methods)]))
    r = script("shadows.py", path, "--light", "Sun", *argv, "--out", tmp_path / "shadow_script")
    assert r.returncode == 0, r.stderr
    for m in ("raytraced", "shadowmap", "volume_zfail"):
        a = np.asarray(bpy.data.images.load(str(tmp_path / "shadow_button" / f"{m}_mask.png")).pixels[:])
        b = np.asarray(bpy.data.images.load(str(tmp_path / "shadow_script" / f"{m}_mask.png")).pixels[:])
        assert a.shape == b.shape and np.array_equal(a, b), m


def test_panels_scripts_and_options_share_one_declaration():
    """Every panel property and every script argument comes from its job's options class: same defaults, same
    limits, same choices."""
    import importlib.util
    from addon.bake.options import BakeOptions
    from addon.core import options as core_options
    from addon.lab.options import (EnvmapOptions, RadiosityOptions, RaytraceOptions, ReflectionOptions,
                                   ShadowOptions, SSAOOptions)
    from addon.nodes.options import ShadingOptions
    s = bpy.context.scene.illumination
    groups = {BakeOptions: s.lightmaps, SSAOOptions: s.ssao, ShadowOptions: s.shadows, ShadingOptions: s.shading,
              EnvmapOptions: bpy.ops.illumination.envmap_irradiance.get_rna_type(),
              RadiosityOptions: bpy.ops.illumination.radiosity.get_rna_type(),
              ReflectionOptions: s.reflections, RaytraceOptions: s.raytrace}
    for cls, group in groups.items():
        rna = group.bl_rna if hasattr(group, "bl_rna") else group
        for name, kind, default, spec in core_options.specs(cls):
            if not spec.ui:
                assert name not in rna.properties, (cls.__name__, name)
                continue
            p = rna.properties[name]
            assert p.name == spec.label, (cls.__name__, name)
            if spec.choices:
                items = {i.identifier for i in p.enum_items}
                assert items <= set(core_options.choice_ids(spec)), (cls.__name__, name)
                continue
            if default is not None and not (cls is BakeOptions and name in ("resolution", "max_resolution")):
                assert p.default == pytest.approx(default, rel=1e-6), (cls.__name__, name, p.default, default)
            if kind in (int, float) and spec.minimum is not None:
                assert p.hard_min == pytest.approx(spec.minimum), (cls.__name__, name)
    scripts = {"bake.py": BakeOptions, "ssao.py": SSAOOptions, "shadows.py": ShadowOptions,
               "envmap.py": EnvmapOptions, "radiosity.py": RadiosityOptions, "reflections.py": ReflectionOptions,
               "raytrace.py": RaytraceOptions}
    for name, cls in scripts.items():
        spec_ = importlib.util.spec_from_file_location(f"il_{name}", os.path.join(ROOT, "scripts", name))
        mod = importlib.util.module_from_spec(spec_)
        spec_.loader.exec_module(mod)
        args = mod.build_parser().parse_args(["--out", "x"] + (["--objects", "A"] if name == "bake.py" else []))
        sys.path.insert(0, os.path.join(ROOT, "scripts"))
        import _cli
        assert _cli.options_from(cls, args) == cls().validate(), name

