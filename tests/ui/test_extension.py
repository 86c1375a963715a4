"""The extension zip, built by Blender's own builder, installs and enables as users install it, and its
main buttons work with what Blender's Python offers: numpy plus the bundled OpenEXR wheel, no scipy, no
matplotlib."""
import json
import os
import subprocess
import sys
import textwrap

import pytest

from conftest import run_script

pytestmark = pytest.mark.both_versions

CHECK = textwrap.dedent("""
    import glob, importlib, importlib.machinery, json, os, sys
    import bpy, addon_utils
    zip_path, out = sys.argv[1], sys.argv[2]
    assert "OpenEXR" not in sys.modules and "addon" not in sys.modules
    sys.modules["scipy"] = None        # a real Blender has neither: importing them must not be needed
    sys.modules["matplotlib"] = None
    # Blender's own Python has no OpenEXR either: the wheel the extension bundles is the only one found.
    # (The bpy module's venv has a copy earlier on sys.path than the extensions' site-packages.)
    wheels = os.path.join(bpy.utils.user_resource("EXTENSIONS"), ".local", "lib",
                          "python{}.{}".format(*sys.version_info[:2]), "site-packages")

    class BundledWheelsOnly:
        @staticmethod
        def find_spec(name, path=None, target=None):
            if name.partition(".")[0] not in ("OpenEXR", "Imath"):
                return None
            spec = importlib.machinery.PathFinder.find_spec(name, [wheels] if path is None else path)
            if spec is None:
                raise ModuleNotFoundError(name + " is not among the extension's wheels", name=name)
            return spec

    sys.meta_path.insert(0, BundledWheelsOnly)
    bpy.ops.extensions.package_install_files(filepath=zip_path, repo="user_default", enable_on_install=True)
    module = "bl_ext.user_default.illumination_lab"
    assert module in {m.__name__ for m in addon_utils.modules()}, "not installed"
    assert addon_utils.check(module)[1], "not enabled"
    assert hasattr(bpy.types, "IL_PT_main") and hasattr(bpy.types.Scene, "illumination")
    assert "build_demo_scene" in dir(bpy.ops.illumination)

    # OpenEXR comes from the wheel Blender installed into the extensions' own site-packages
    import OpenEXR
    assert os.path.realpath(OpenEXR.__file__).startswith(os.path.realpath(wheels) + os.sep), OpenEXR.__file__
    assert sys.modules[module + ".addon.ui.envmap"].IL_OT_radiosity.is_registered   # the installed copy's
    assert not sys.modules["matplotlib"] and not sys.modules["scipy"]
    assert not importlib.import_module(module + ".addon.core.charts").available()

    ops = bpy.ops.illumination

    def press(op, **props):
        result = op(**props)
        assert result == {"FINISHED"}, (op.idname(), result)
        print("PRESSED", op.idname(), flush=True)

    # demo scene, node groups, a shading model on the sphere
    press(ops.build_demo_scene)
    scene = bpy.context.scene
    assert scene.name.startswith("IL Demo"), scene.name
    press(ops.add_node_groups)
    sphere = next(o for o in scene.objects if o.get("il_demo_role") == "Sphere")
    for o in scene.objects:
        o.select_set(o == sphere)
    bpy.context.view_layer.objects.active = sphere
    press(ops.assign_shading_model, model="COOK_TORRANCE")
    assert sphere.active_material is not None and sphere.active_material.name.startswith("IL")

    # AO + irradiance light maps at 16², margin 2 (the dilation runs)
    lm = scene.illumination.lightmaps
    lm.output_dir, lm.resolution, lm.samples, lm.bounces, lm.margin = os.path.join(out, "lightmaps"), 16, 4, 1, 2
    lm.maps = {"ao", "irradiance"}
    press(ops.bake_lightmaps)
    exrs = glob.glob(os.path.join(out, "lightmaps", "*.exr"))
    assert len(exrs) == 2, exrs
    assert OpenEXR.File(exrs[0]).header()["dataWindow"][1][0] == 15

    # radiosity on the Cornell box, coarse patches, no comparison bake: the chart is skipped
    press(ops.build_cornell_box)
    press(ops.radiosity, output_dir=os.path.join(out, "radiosity"), solver="gauss_seidel", max_edge=1.0, compare=False)
    with open(os.path.join(out, "radiosity", "radiosity_report.json")) as f:
        rep = json.load(f)
    assert rep["chart"] is None and rep["patches"] > 10 and not glob.glob(os.path.join(out, "radiosity", "*.png"))
    assert os.path.isfile(os.path.join(out, "radiosity", "radiosity_convergence.csv"))

    # SSAO comparison of the numpy methods at 16 px
    bpy.context.scene.illumination.ssao.resolution = 16
    press(ops.ssao_build_scene)
    s = bpy.context.scene.illumination.ssao
    s.methods = {"crytek", "hemisphere", "hbao", "gtao"}
    s.samples, s.reference_samples, s.output_dir = 2, 4, os.path.join(out, "ssao")
    press(ops.ssao_compare)
    assert set(json.loads(s.last_report)) == {"crytek", "hemisphere", "hbao", "gtao"}

    # shadow comparison of the numpy methods at 16 px
    bpy.context.scene.illumination.shadows.resolution = 16
    press(ops.build_shadow_scene)
    st = bpy.context.scene.illumination.shadows
    st.methods = {"planar", "shadowmap", "volume_zpass", "volume_zfail"}
    st.shadowmap_size, st.output_dir = 64, os.path.join(out, "shadows")
    press(ops.run_shadow_comparison)
    assert os.path.isfile(st.last_report), st.last_report

    assert "scipy" not in sys.modules or sys.modules["scipy"] is None
    assert "matplotlib" not in sys.modules or sys.modules["matplotlib"] is None
    addon_utils.disable(module)
    assert not hasattr(bpy.types, "IL_PT_main") and not hasattr(bpy.types.Scene, "illumination")
    addon_utils.enable(module)
    assert hasattr(bpy.types, "IL_PT_main")
    addon_utils.disable(module)
    print("EXTENSION-OK", bpy.app.version_string)
""")

BUTTONS = ("build_demo_scene", "add_node_groups", "assign_shading_model", "bake_lightmaps", "build_cornell_box",
           "radiosity", "ssao_build_scene", "ssao_compare", "build_shadow_scene", "run_shadow_comparison")


def test_zip_installs_and_its_buttons_work_without_scipy_and_matplotlib(tmp_path):
    built = run_script("build_extension.py", "--out", tmp_path / "dist")
    assert built.returncode == 0, built.stderr
    zip_path = built.stdout.strip().splitlines()[-1]
    assert os.path.isfile(zip_path)
    import zipfile
    names = zipfile.ZipFile(zip_path).namelist()
    assert not [n for n in names if n.split("/")[0] in ("web", "tests", "scripts", "out", "node_modules")], names
    home = tmp_path / "home"
    home.mkdir()
    out = tmp_path / "out"
    env = dict(os.environ, HOME=str(home), BLENDER_USER_RESOURCES=str(home / "blender"))
    proc = subprocess.run([sys.executable, "-c", CHECK, zip_path, str(out)], capture_output=True, text=True,
                          env=env, cwd=str(tmp_path), timeout=300)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    assert "EXTENSION-OK" in proc.stdout
    pressed = [line.split()[1] for line in proc.stdout.splitlines() if line.startswith("PRESSED")]
    assert pressed == [f"ILLUMINATION_OT_{b}" for b in BUTTONS]
    assert proc.stdout.count("matplotlib is needed for charts") == 1      # the radiosity button's one warning
    assert (home / "blender").exists()
    with open(out / "lightmaps" / "bake_report.json") as f:
        assert json.load(f)["objects"]
