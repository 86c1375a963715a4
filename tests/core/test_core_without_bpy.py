"""addon/core imports with bpy and mathutils made unimportable: every module, subpackages included."""
import os
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def core_modules():
    """Dotted names under addon.core ("io.exr", "ssao.methods", ...), packages included."""
    base = os.path.join(ROOT, "addon", "core")
    names = []
    for folder, dirs, files in os.walk(base):
        dirs[:] = sorted(d for d in dirs if not d.startswith(("_", ".")))
        rel = os.path.relpath(folder, base)
        prefix = "" if rel == "." else rel.replace(os.sep, ".") + "."
        for f in sorted(files):
            if f.endswith(".py"):
                stem = f[:-3]
                names.append(prefix[:-1] if stem == "__init__" and prefix else prefix + stem)
    return [n for n in names if n != "__init__"]


def test_every_core_module_imports_without_bpy():
    names = core_modules()
    code = ("import sys; sys.modules['bpy'] = None; sys.modules['mathutils'] = None; "
            "sys.modules['bmesh'] = None; import importlib; "
            + "; ".join(f"importlib.import_module('addon.core.{n}')" for n in names))
    proc = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    assert "io.exr" in names
