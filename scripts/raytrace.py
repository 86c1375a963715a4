"""Ray casting and Whitted ray tracing of the scene camera (seed 004), pixel-aligned with Cycles.

    python scripts/raytrace.py --scene glass --method whitted --max-depth 4 --out out/raytrace
    python scripts/raytrace.py FILE.blend --method raycast --out out/rc --resolution 128
    blender -b FILE.blend -P scripts/raytrace.py -- --method whitted --max-depth 8 --out out/rt

Writes <out>/<method>.exr (RGB radiance) and <out>/raytrace_report.json; with the Cycles comparison (default)
also cycles.exr (Cycles with Whitted's light paths), cycles_full.exr (the scene's own bounces) and missing.exr
(cycles_full - <method>: what Whitted leaves out).
"""
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import _cli  # noqa: E402

from addon.lab.options import RAYTRACE_SCENE_CHOICES, RaytraceOptions  # noqa: E402  (no bpy)


def main(args):
    import bpy
    from addon.core.errors import InputError
    from addon.lab import raytrace
    out = os.path.abspath(args.out)
    o = _cli.options_from(RaytraceOptions, args)
    if args.scene:
        if args.blend:
            raise InputError("give either FILE.blend or --scene NAME, not both")
        names = [c[0] for c in RAYTRACE_SCENE_CHOICES]
        if args.scene not in names:
            raise InputError(f"unknown scene '{args.scene}': one of {', '.join(names)}")
        result = raytrace.run_builtin(args.scene, out, o)
    else:
        if not bpy.data.filepath and not args.blend:
            raise InputError("give a FILE.blend or --scene NAME (one of: "
                             + ", ".join(c[0] for c in RAYTRACE_SCENE_CHOICES) + ")")
        result = raytrace.run(bpy.context.scene, out, o)
    r = result.report
    print(f"raytrace: report {result.path}")
    depth = f" depth {r['max_depth']}" if r["method"] == "whitted" else ""
    print(f"  {r['method']}{depth}: {r['rays']} rays in {r['seconds']:.3f} s "
          f"({r['rays_per_second']:.0f} rays/s)")
    if r["rmse_vs_cycles"] is not None:
        c, m = r["cycles"], r["missing"]
        print(f"  RMSE vs Cycles (same light paths) {r['rmse_vs_cycles']:.4g} (relative "
              f"{r['relative_rmse_vs_cycles'] or 0:.4g}); Cycles noise {c['noise_rmse']:.3g}")
        print(f"  missing vs Cycles with all its bounces: {100 * m['fraction']:.1f} % of the light (missing.exr)")
    for note in r["left_out"]:
        print(f"  note: {note}")


def build_parser():
    p = _cli.parser("raytrace.py", "Ray casting or Whitted ray tracing of the scene camera, compared with Cycles.")
    p.add_argument("--scene", metavar="NAME",
                   help="built-in scene: " + ", ".join(c[0] for c in RAYTRACE_SCENE_CHOICES)
                   + " (instead of FILE.blend)")
    p.add_argument("--out", default="out/raytrace", help="output folder (default: out/raytrace)")
    _cli.add_options(p, RaytraceOptions)
    return p


if __name__ == "__main__":
    _cli.run(build_parser(), main)
