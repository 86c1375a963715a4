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


def main(args):
    import bpy
    from addon.core.errors import InputError
    from addon.lab import shadow_scenes, shadows
    out = os.path.abspath(args.out)
    if args.sweeps:
        result = shadows.sweeps(out, quick=args.quick)
        print(f"shadows: {len(result['charts'])} charts and {len(result['tables'])} tables in {out}")
        return
    methods = shadows.parse_methods(args.methods)
    params = dict(resolution=args.resolution, shadowmap_size=args.shadowmap_size, bias=args.bias,
                  slope_bias=args.slope_bias, pcf=args.pcf, receiver=args.receiver, samples=args.samples)
    if args.scene:
        if args.blend:
            raise InputError("give either FILE.blend or --scene NAME, not both")
        report = shadows.compare_builtin(args.scene, args.light_type, methods, out, keep=False, **params)
    else:
        if not bpy.data.filepath and not args.blend:
            raise InputError("give a FILE.blend or --scene NAME (one of: " + ", ".join(shadow_scenes.SCENES) + ")")
        report = shadows.compare(bpy.context.scene, args.light, methods, out, **params)
    print(f"shadows: report {report['report']}")
    for m, e in report["methods"].items():
        print(f"  {m:13s} error {e['error']:.4f} (false shadow {e['false_shadow']:.4f}, "
              f"false light {e['false_light']:.4f})  {e['seconds']:.3f} s")


def build_parser():
    p = _cli.parser("shadows.py", "Compare shadow methods with a ray-traced reference on the same pixels.")
    p.add_argument("--scene", choices=None, metavar="NAME",
                   help="built-in scene: sphere, stairs, acne, plate, inside (instead of FILE.blend)")
    p.add_argument("--light", default="Light", help="name of the light object (default: Light)")
    p.add_argument("--light-type", default="sun", metavar="KIND",
                   help="light of a built-in scene: sun, point or spot (default: sun)")
    p.add_argument("--methods", default="raytraced,planar,shadowmap,volume_zpass,volume_zfail",
                   help="comma-separated: raytraced, planar, shadowmap, volume_zpass, volume_zfail, eevee, workbench")
    p.add_argument("--out", default="out/shadows", help="output folder (default: out/shadows)")
    p.add_argument("--resolution", type=int, default=128, help="render width in pixels (default 128)")
    p.add_argument("--shadowmap-size", type=int, default=1024, help="shadow-map size N (N x N, default 1024)")
    p.add_argument("--bias", type=float, default=0.01, help="constant shadow-map bias in metres (default 0.01)")
    p.add_argument("--slope-bias", type=float, default=2.0,
                   help="slope-scaled bias in texels: adds B x texel size x tan(theta) (default 2)")
    p.add_argument("--pcf", type=int, default=1, help="PCF kernel size K, odd (default 1 = no filtering)")
    p.add_argument("--receiver", default=None, help="plane object for planar shadows (default: Floor)")
    p.add_argument("--samples", type=int, default=1, help="Cycles samples of the reference (default 1)")
    p.add_argument("--sweeps", action="store_true", help="run the sweeps and charts instead of one comparison")
    p.add_argument("--quick", action="store_true", help="with --sweeps: small sizes (well under a minute)")
    return p


if __name__ == "__main__":
    _cli.run(build_parser(), main)
