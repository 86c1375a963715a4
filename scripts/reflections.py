"""Reflection lab: lat-long, cube and sphere maps against Cycles' ray-traced mirror on the same pixels.

    python scripts/reflections.py --scene nearby --methods latlong,cube,sphere,raytraced --out out/reflections
    python scripts/reflections.py FILE.blend --object Ball --methods latlong,cube --map-size 128 --out out/r
    blender -b FILE.blend -P scripts/reflections.py -- --object Ball --out out/r
"""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import _cli  # noqa: E402

from addon.lab.options import REFLECTION_SCENE_CHOICES, ReflectionOptions  # noqa: E402  (no bpy)


def main(args):
    import bpy
    from addon.core.errors import InputError
    from addon.lab import reflections
    out = os.path.abspath(args.out)
    o = _cli.options_from(ReflectionOptions, args)
    names = [c[0] for c in REFLECTION_SCENE_CHOICES]
    if args.scene:
        if args.blend:
            raise InputError("give either FILE.blend or --scene NAME, not both")
        if args.scene not in names:
            raise InputError(f"unknown scene {args.scene!r}: choose from {', '.join(names)}")
        result = reflections.run_builtin(args.scene, out, o)
    else:
        if not bpy.data.filepath and not args.blend:
            raise InputError("give a FILE.blend or --scene NAME (one of: " + ", ".join(names) + ")")
        result = reflections.compare(bpy.context.scene, out, o)
    print(f"reflections: report {result.path}")
    for m, e in result["methods"].items():
        print(f"  {m:10s} rmse {e['rmse']:.5f}  relative {e['relative_rmse']:.4f}  {e['seconds']:.3f} s")
    for row in result.get("distance_sweep", []):
        print(f"  capture point {row['distance']:.2f} m away: "
              + ", ".join(f"{k} {v:.4f}" for k, v in row.items() if k != "distance"))


def build_parser():
    p = _cli.parser("reflections.py", "Compare reflection-mapping methods with Cycles' mirror on the same pixels.")
    p.add_argument("--scene", metavar="NAME",
                   help="built-in scene: " + ", ".join(c[0] for c in REFLECTION_SCENE_CHOICES)
                   + " (instead of FILE.blend)")
    p.add_argument("--out", default="out/reflections", help="output folder (default: out/reflections)")
    _cli.add_options(p, ReflectionOptions)
    return p


if __name__ == "__main__":
    _cli.run(build_parser(), main)
