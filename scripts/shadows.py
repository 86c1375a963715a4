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

from addon.core.shadow.depth_map import MAX_RESOLUTION, MAX_SIZE  # noqa: E402  (numpy only)


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
    if not report["meaningful"]:
        print("  the reference has no lit or no shadowed pixel: the errors below mean nothing")
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
    p.add_argument("--resolution", type=_cli.number(int, 8, MAX_RESOLUTION), default=128,
                   help=f"render width in pixels, 8..{MAX_RESOLUTION} (default 128; memory is checked first)")
    p.add_argument("--shadowmap-size", type=_cli.number(int, 2, MAX_SIZE), default=1024,
                   help=f"shadow-map size N (N x N), 2..{MAX_SIZE} (default 1024; memory is checked first)")
    p.add_argument("--bias", type=_cli.number(float, 0), default=0.01,
                   help="constant shadow-map bias in metres (default 0.01)")
    p.add_argument("--slope-bias", type=_cli.number(float, 0), default=2.0,
                   help="slope-scaled bias in texels: adds B x texel size x tan(theta) (default 2)")
    p.add_argument("--pcf", type=_cli.number(int, 1, 15), default=1,
                   help="PCF kernel size K, odd, 1..15 (default 1 = no filtering)")
    p.add_argument("--receiver", default=None, help="plane object for planar shadows (default: Floor)")
    p.add_argument("--samples", type=_cli.number(int, 1, 4096), default=1,
                   help="Cycles samples of the reference, 1..4096 (default 1)")
    p.add_argument("--sweeps", action="store_true", help="run the sweeps and charts instead of one comparison")
    p.add_argument("--quick", action="store_true", help="with --sweeps: small sizes (well under a minute)")
    return p


if __name__ == "__main__":
    _cli.run(build_parser(), main)
