"""addon/core imports with bpy and mathutils made unimportable."""
import os
import pkgutil
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def test_every_core_module_imports_without_bpy():
    names = [m.name for m in pkgutil.iter_modules([os.path.join(ROOT, "addon", "core")])]
    code = ("import sys; sys.modules['bpy'] = None; sys.modules['mathutils'] = None; "
            "sys.modules['bmesh'] = None; import importlib; "
            + "; ".join(f"importlib.import_module('addon.core.{n}')" for n in names))
    proc = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    assert "exr" in names
