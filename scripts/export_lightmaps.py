"""Export a scene with its baked light maps as glTF binary, through Blender's own glTF exporter; the .blend on disk
is never written.

    python scripts/export_lightmaps.py baked.blend --lightmaps out/maps --out out/scene.glb
    blender -b baked.blend -P scripts/export_lightmaps.py -- --lightmaps out/maps --out out/scene.glb

Each baked mesh carries its light-map UV layer as TEXCOORD_1, irradiance as the material extension MOZ_lightmap
{"index", "texCoord": 1, "intensity"}: an 8-bit linear PNG of E / max(E) with intensity = max(E) in W/m², AO as the
material's occlusionTexture (texCoord 1) where no irradiance was baked (E holds the occlusion already, and a client
multiplies the light map by the occlusion: --ao-with-irradiance exports both; docs/lightmaps.md, "Export"). A
batch bake does not save the .blend: the light-map UV layers it generated come from the bake folder's UV cache
(or open the copy bake.py --save-as wrote); objects whose layer is in neither are named and skipped. Only --out is
written (a temporary file beside it, then moved into place), and with --godot / --unity the engine files beside it,
named after it (docs/lightmaps.md, "Godot 4 and Unity"): STEM.lightmap.exr, .exr.import and STEM.lightmap.tres;
STEM.unity_lightmap_K.exr and STEM.unity.json.
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
    if os.path.isdir(out):
        raise InputError(f"--out: is a folder: {out}")
    if not os.path.isdir(os.path.dirname(out)):
        raise InputError(f"--out: no such folder: {os.path.dirname(out)}")
    folder = os.path.abspath(args.lightmaps)
    if not os.path.isdir(folder):
        raise InputError(f"--lightmaps: no such folder: {folder}")
    try:
        import io_scene_gltf2  # noqa: F401
    except ImportError:
        raise InputError("Blender's glTF exporter (io_scene_gltf2) is not available in this Blender") from None
    names, checked = [], None
    if args.godot or args.unity:
        from addon.bake.engines import engine_maps
        from addon.bake.gltf import Plan
        names = sorted(Plan(folder, bpy.context.scene).maps)
        if names:                                   # else export_glb says why nothing can be exported
            checked = engine_maps(bpy.context.scene, folder, names, args.godot, args.unity)
    result = export_glb(bpy.context.scene, folder, out, ao_with_irradiance=args.ao_with_irradiance)
    for line in result["notes"]:
        errors.warn(line)
    for name, maps in result["objects"].items():
        parts = []
        if "irradiance" in maps:
            e = maps["irradiance"]
            parts.append(f"irradiance intensity {e:.6g} W/m^2 (encoding error <= {encoding_error(e):.3g})")
        if "ao" in maps:
            parts.append("ao")
        if "directional" in maps:
            parts.append(f"directional e0 intensity {maps['directional']:.6g} W/m^2 (extras.il_directional)")
        print(f"{name}: " + ", ".join(parts))
    print(f"wrote {out}: {len(result['objects'])} object(s) with light maps on TEXCOORD_1")
    if args.godot or args.unity:
        from addon.bake.engines import write_engine_files
        exported = sorted(result["objects"])
        for path in write_engine_files(bpy.context.scene, folder, out, exported, args.godot, args.unity,
                                       checked if exported == names else None):
            print(f"wrote {path}")


if __name__ == "__main__":
    p = _cli.parser("export_lightmaps.py", " ".join(__doc__.split("\n\n")[0].split()))
    p.add_argument("--lightmaps", required=True, metavar="DIR", help="the bake's output folder (bake_report.json)")
    p.add_argument("--out", dest="glb", required=True, metavar="FILE.glb", help="the glTF binary to write")
    p.add_argument("--ao-with-irradiance", action="store_true",
                   help="also export AO as occlusionTexture on materials that carry irradiance (darkens twice)")
    p.add_argument("--godot", action="store_true",
                   help="also write the irradiance maps as a Godot 4 LightmapGIData with its Texture2DArray")
    p.add_argument("--unity", action="store_true",
                   help="also write the irradiance maps as Unity lightmaps (E/pi EXR) with each renderer's "
                        "lightmapIndex and lightmapScaleOffset")
    _cli.run(p, main)
