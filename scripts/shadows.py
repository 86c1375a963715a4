"""Shadow lab: planar, shadow map, shadow volumes, EEVEE and Workbench against ray-traced shadows.

    python scripts/shadows.py --scene sphere --light Light --methods raytraced,shadowmap,volume_zfail --out out/shadows
    python scripts/shadows.py FILE.blend --light Sun --methods planar,shadowmap --receiver Ground --out out/s
    blender -b FILE.blend -P scripts/shadows.py -- --light Sun --methods shadowmap --out out/s
    python scripts/shadows.py --sweeps --quick --out out/shadow_sweeps
"""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import _cli  # noqa: E402

from addon.lab.options import SHADOW_SCENE_CHOICES, ShadowOptions  # noqa: E402  (no bpy)


def main(args):
    import bpy
    from addon.core.errors import InputError
    from addon.lab import shadows
    from addon.lab.shadows import scenes as shadow_scenes
    out = os.path.abspath(args.out)
    if args.sweeps:
        from addon.lab.bench import shadows as bench_shadows
        result = bench_shadows.run(out, quick=args.quick)
        print(f"shadows: {len(result.charts)} charts and {len(result.tables)} tables in {out}")
        return
    o = _cli.options_from(ShadowOptions, args)
    if args.scene:
        if args.blend:
            raise InputError("give either FILE.blend or --scene NAME, not both")
        result = shadows.compare_builtin(args.scene, args.light_type, out, o)
    else:
        if not bpy.data.filepath and not args.blend:
            raise InputError("give a FILE.blend or --scene NAME (one of: " + ", ".join(shadow_scenes.SCENES) + ")")
        result = shadows.compare(bpy.context.scene, args.light, out, o)
    print(f"shadows: report {result.path}")
    if not result["meaningful"]:
        print("  the reference has no lit or no shadowed pixel: the errors below mean nothing")
    for m, e in result["methods"].items():
        print(f"  {m:13s} error {e['error']:.4f} (false shadow {e['false_shadow']:.4f}, "
              f"false light {e['false_light']:.4f})  {e['seconds']:.3f} s")
    for m, why in result.get("skipped", {}).items():
        print(f"  {m:13s} skipped: {why}")


def build_parser():
    p = _cli.parser("shadows.py", "Compare shadow methods with a ray-traced reference on the same pixels.")
    p.add_argument("--scene", choices=None, metavar="NAME",
                   help="built-in scene: " + ", ".join(c[0] for c in SHADOW_SCENE_CHOICES) + " (instead of FILE.blend)")
    p.add_argument("--light", default="Light", help="name of the light object (default: Light)")
    p.add_argument("--light-type", default="sun", metavar="KIND",
                   help="light of a built-in scene: sun, point or spot (default: sun)")
    p.add_argument("--out", default="out/shadows", help="output folder (default: out/shadows)")
    _cli.add_options(p, ShadowOptions)
    p.add_argument("--sweeps", action="store_true", help="run the sweeps and charts instead of one comparison")
    p.add_argument("--quick", action="store_true", help="with --sweeps: small sizes (well under a minute)")
    return p


if __name__ == "__main__":
    _cli.run(build_parser(), main)
