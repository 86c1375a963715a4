"""Bake AO and irradiance light maps with Cycles (CPU); the .blend on disk is never modified.

    python scripts/bake.py scene.blend --objects Floor Box --maps ao irradiance --out out/maps
    blender -b scene.blend -P scripts/bake.py -- --objects Floor --maps ao --out out/maps --target-error 0.01
"""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import _cli  # noqa: E402


def main(args):
    import bpy
    from addon.bake import BakeOptions, bake_lightmaps
    from addon.core.errors import InputError
    options = _cli.options_from(BakeOptions, args)
    objects = []
    for name in args.objects:
        obj = bpy.data.objects.get(name)
        if obj is None:
            raise InputError(f"no object named '{name}' in the file")
        objects.append(obj)
    result = bake_lightmaps(objects, options.maps, os.path.abspath(args.out), options, scene=bpy.context.scene)
    for obj, maps in result["objects"].items():
        for m, e in maps.items():
            err = e["estimated_error"]
            err = "n/a" if err is None else f"{err:.4g}"
            kind = e["error_estimate"].split(":")[0] + (", before denoising" if e.get("denoised") else "")
            print(f"{obj} {m}: {e['file']} {e['resolution'][0]}x{e['resolution'][1]} "
                  f"{e['samples']} samples {e['seconds']:.2f} s est. error {err} ({kind})")
    print(result.summary)
    print(f"report: {result.path}")


def build_parser():
    from addon.bake.options import BakeOptions
    p = _cli.parser("bake.py", "Bake ambient-occlusion and irradiance light maps with Cycles on the CPU.")
    p.add_argument("--objects", nargs="+", required=True, metavar="NAME", help="mesh objects to bake")
    p.add_argument("--out", required=True, help="output folder")
    return _cli.add_options(p, BakeOptions)


if __name__ == "__main__":
    _cli.run(build_parser(), main)
