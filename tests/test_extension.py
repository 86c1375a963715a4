"""The extension zip, built by Blender's own builder, installs and enables as users install it."""
import os
import subprocess
import sys
import textwrap

import pytest

from conftest import ROOT, run_script

pytestmark = pytest.mark.both_versions

CHECK = textwrap.dedent("""
    import sys, bpy, addon_utils
    zip_path = sys.argv[1]
    bpy.ops.extensions.package_install_files(filepath=zip_path, repo="user_default", enable_on_install=True)
    module = "bl_ext.user_default.illumination_lab"
    assert module in {m.__name__ for m in addon_utils.modules()}, "not installed"
    assert addon_utils.check(module)[1], "not enabled"
    assert hasattr(bpy.types, "IL_PT_main") and hasattr(bpy.types.Scene, "illumination")
    assert "build_demo_scene" in dir(bpy.ops.illumination)
    import OpenEXR  # the bundled wheel
    addon_utils.disable(module)
    assert not hasattr(bpy.types, "IL_PT_main") and not hasattr(bpy.types.Scene, "illumination")
    addon_utils.enable(module)
    assert hasattr(bpy.types, "IL_PT_main")
    addon_utils.disable(module)
    print("EXTENSION-OK", bpy.app.version_string)
""")


def test_zip_builds_installs_enables_disables(tmp_path):
    built = run_script("build_extension.py", "--out", tmp_path / "dist")
    assert built.returncode == 0, built.stderr
    zip_path = built.stdout.strip().splitlines()[-1]
    assert os.path.isfile(zip_path)
    home = tmp_path / "home"
    home.mkdir()
    env = dict(os.environ, HOME=str(home), BLENDER_USER_RESOURCES=str(home / "blender"))
    # A Python without the venv's OpenEXR on its path would be the strictest check; the
    # extension's own site-packages must at least provide it.
    proc = subprocess.run([sys.executable, "-c", CHECK, zip_path], capture_output=True, text=True,
                          env=env, cwd=str(tmp_path), timeout=300)
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    assert "EXTENSION-OK" in proc.stdout
    assert (home / "blender").exists()
