"""Export a scene with its baked light maps as glTF binary, through Blender's own glTF exporter; the .blend on disk
is never written.

    python scripts/export_lightmaps.py baked.blend --lightmaps out/maps --out out/scene.glb
    blender -b baked.blend -P scripts/export_lightmaps.py -- --lightmaps out/maps --out out/scene.glb

Each baked mesh carries its light-map UV layer as TEXCOORD_1, AO as the material's occlusionTexture (texCoord 1),
irradiance as the material extension MOZ_lightmap {"index", "texCoord": 1, "intensity"}: an 8-bit linear PNG of
E / max(E) with intensity = max(E) in W/m² (docs/lightmaps.md, "Export"). A batch bake does not save the .blend, so
open the copy it saved (bake.py --save-as): objects whose light-map UV layer is not in the file are named and
skipped. Only --out is written (a temporary file beside it, then moved into place).
"""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import _cli  # noqa: E402


def main(args):
    import bpy
    from addon.bake.gltf import encoding_error, export_glb
    from addon.core import errors
    from addon.core.errors import InputError
    if not args.glb:
        raise InputError("no output file given: --out FILE.glb")
    out = os.path.abspath(args.glb)
    if os.path.isfile(os.path.dirname(out)):
        raise InputError(f"--out: its output folder is a file: {os.path.dirname(out)}")
    if not out.lower().endswith(".glb"):
        raise InputError(f"--out: not a .glb file name: {out}")
    if not os.path.isdir(os.path.dirname(out)):
        raise InputError(f"--out: no such folder: {os.path.dirname(out)}")
    folder = os.path.abspath(args.lightmaps)
    if not os.path.isdir(folder):
        raise InputError(f"--lightmaps: no such folder: {folder}")
    try:
        import io_scene_gltf2  # noqa: F401
    except ImportError:
        raise InputError("Blender's glTF exporter (io_scene_gltf2) is not available in this Blender") from None
    result = export_glb(bpy.context.scene, folder, out)
    for line in result["notes"]:
        errors.warn(line)
    for name, maps in result["objects"].items():
        parts = []
        if "irradiance" in maps:
            e = maps["irradiance"]
            parts.append(f"irradiance intensity {e:.6g} W/m^2 (encoding error <= {encoding_error(e):.3g})")
        if "ao" in maps:
            parts.append("ao")
        print(f"{name}: " + ", ".join(parts))
    print(f"wrote {out}: {len(result['objects'])} object(s) with light maps on TEXCOORD_1")


if __name__ == "__main__":
    p = _cli.parser("export_lightmaps.py", __doc__.splitlines()[0])
    p.add_argument("--lightmaps", required=True, metavar="DIR", help="the bake's output folder (bake_report.json)")
    p.add_argument("--out", dest="glb", required=True, metavar="FILE.glb", help="the glTF binary to write")
    _cli.run(p, main)
