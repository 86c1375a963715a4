"""Build the installable extension zip with Blender's own builder (shipped in the bpy wheel).

    python scripts/build_extension.py --out dist

Downloads the OpenEXR wheels the manifest bundles (cp311 for Blender 4.5, cp313 for 5.1-5.3) into
./wheels first (pip's cache makes that a no-op after the first time).
"""
import glob
import importlib.util
import os
import re
import subprocess
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import _cli  # noqa: E402
from addon.core.errors import ILError  # noqa: E402

PLATFORM_TAGS = ("manylinux_2_28_x86_64", "win_amd64", "macosx_11_0_arm64")


def builder_path():
    """bpy/<version>/scripts/addons_core/bl_pkg/cli/blender_ext.py inside the installed bpy."""
    spec = importlib.util.find_spec("bpy")
    if spec is None or not spec.submodule_search_locations:
        raise ILError("the bpy module is not installed: run ./run build")
    hits = glob.glob(os.path.join(spec.submodule_search_locations[0], "*", "scripts", "addons_core",
                                  "bl_pkg", "cli", "blender_ext.py"))
    if not hits:
        raise ILError("Blender's extension builder (blender_ext.py) is not in this bpy")
    return hits[0]


def manifest_wheels():
    with open(os.path.join(_cli.ROOT, "blender_manifest.toml"), encoding="utf-8") as f:
        return re.findall(r'"\./(wheels/[^"]+\.whl)"', f.read())


def download_wheels():
    """Fetch every wheel the manifest names that is not in ./wheels yet."""
    for rel in manifest_wheels():
        path = os.path.join(_cli.ROOT, rel)
        if os.path.exists(path):
            continue
        name, version, python_tag = os.path.basename(rel).split("-")[:3]
        tag = next(t for t in PLATFORM_TAGS if t in rel)
        python_version = f"{python_tag[2]}.{python_tag[3:]}"      # cp313 -> 3.13
        cmd = [sys.executable, "-m", "pip", "download", "-q", "--disable-pip-version-check", "--no-deps",
               "--only-binary=:all:", "--python-version", python_version, "--platform", tag,
               "-d", os.path.dirname(path), f"{name}=={version}"]
        if subprocess.run(cmd).returncode != 0 or not os.path.exists(path):
            raise ILError(f"could not download {rel}")


def build(out):
    """Build into ``out``; return the zip's path."""
    download_wheels()
    os.makedirs(out, exist_ok=True)
    proc = subprocess.run([sys.executable, builder_path(), "build", "--source-dir", _cli.ROOT,
                           "--output-dir", out], capture_output=True, text=True)
    if proc.returncode != 0:
        last = (proc.stdout + proc.stderr).strip().splitlines()[-1:] or ["no output"]
        raise ILError(f"extension build failed: {last[0]}")
    zips = sorted(glob.glob(os.path.join(out, "illumination_lab-*.zip")), key=os.path.getmtime)
    if not zips:
        raise ILError("the extension builder wrote no zip")
    return zips[-1]


def main(args):
    print(build(os.path.abspath(args.out)))


def build_parser():
    p = _cli.parser("build_extension.py", "Build the extension zip.", blend_file=False)
    p.add_argument("--out", default="dist", help="output folder (default: dist)")
    return p


if __name__ == "__main__":
    _cli.run(build_parser(), main)
