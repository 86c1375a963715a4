"""Bake AO and irradiance light maps with Cycles (CPU); the .blend on disk is never modified.

    python scripts/bake.py scene.blend --objects Floor Box --maps ao irradiance --out out/maps
    blender -b scene.blend -P scripts/bake.py -- --objects Floor --maps ao --out out/maps --target-error 0.01
"""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import _cli  # noqa: E402
from addon.core.lightmap import MAX_RESOLUTION  # noqa: E402  (numpy only, no bpy)


def main(args):
    import bpy
    from addon.bake import BakeOptions, bake_lightmaps, summary
    from addon.core.errors import InputError
    scene = bpy.context.scene
    objects = []
    for name in args.objects:
        obj = bpy.data.objects.get(name)
        if obj is None:
            raise InputError(f"no object named '{name}' in the file")
        objects.append(obj)
    options = BakeOptions(
        resolution=args.resolution if args.resolution is not None else 256, texel_density=args.texel_density,
        max_resolution=args.max_resolution, samples=args.samples, target_error=args.target_error,
        ao_distance=args.ao_distance, bounces=args.bounces, margin=args.margin, denoise=args.denoise,
        uv_layer=args.uv_layer, target=args.target, atlas=args.atlas, overwrite=args.overwrite, seed=args.seed)
    report = bake_lightmaps(objects, args.maps, os.path.abspath(args.out), options, scene=scene)
    for obj, maps in report["objects"].items():
        for m, e in maps.items():
            err = e["estimated_error"]
            err = "n/a" if err is None else f"{err:.4g}"
            kind = e["error_estimate"].split(":")[0] + (", before denoising" if e.get("denoised") else "")
            print(f"{obj} {m}: {e['file']} {e['resolution'][0]}x{e['resolution'][1]} "
                  f"{e['samples']} samples {e['seconds']:.2f} s est. error {err} ({kind})")
    print(summary(report))
    print(f"report: {report['report']}")


def build_parser():
    p = _cli.parser("bake.py", "Bake ambient-occlusion and irradiance light maps with Cycles on the CPU.")
    p.add_argument("--objects", nargs="+", required=True, metavar="NAME", help="mesh objects to bake")
    p.add_argument("--maps", nargs="+", default=["ao"], choices=["ao", "irradiance"], help="maps (default ao)")
    p.add_argument("--out", required=True, help="output folder")
    size = p.add_mutually_exclusive_group()
    size.add_argument("--resolution", type=_cli.number(int, 1, MAX_RESOLUTION),
                      help="map side in texels (default 256; the machine's memory may allow less, see README)")
    size.add_argument("--texel-density", type=_cli.number(float, above=0), metavar="T",
                      help="texels per metre (side capped)")
    p.add_argument("--max-resolution", type=_cli.number(int, 1, MAX_RESOLUTION), default=4096,
                   help="cap for --texel-density (default 4096)")
    quality = p.add_mutually_exclusive_group()
    quality.add_argument("--samples", type=_cli.number(int, 1, 1 << 20), default=64, help="Cycles samples (default 64)")
    quality.add_argument("--target-error", type=_cli.number(float, above=0), metavar="E",
                         help="RMS error wanted; samples chosen from a pilot bake's variance")
    p.add_argument("--ao-distance", type=_cli.number(float, above=0), default=10.0, metavar="D",
                   help="AO ray length in m (default 10)")
    p.add_argument("--bounces", type=_cli.number(int, 0, 1024), default=3, metavar="K",
                   help="diffuse bounces of irradiance (default 3)")
    p.add_argument("--margin", type=_cli.number(int, 0, 1024), default=4, metavar="PX",
                   help="dilation in texels (default 4)")
    p.add_argument("--denoise", action="store_true", help="Blender's denoiser on the image maps")
    p.add_argument("--uv-layer", metavar="NAME", help="existing UV layer used as it is (default: generate 'Lightmap')")
    p.add_argument("--target", choices=["image", "vertex"], default="image", help="image maps or vertex colours")
    p.add_argument("--atlas", action="store_true", help="one shared map for all objects")
    p.add_argument("--seed", type=_cli.number(int, 0, 2 ** 31 - 1), default=0, help="Cycles seed")
    p.add_argument("--overwrite", action="store_true", help="replace existing output files")
    return p


if __name__ == "__main__":
    _cli.run(build_parser(), main)
