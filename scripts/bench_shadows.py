"""Shadow-lab performance figures, side by side with the issue's targets.

    python scripts/bench_shadows.py

1. numpy shadow-map lookup with 3x3 PCF: a 512x512 frame against a 2048x2048 map (target <= 0.5 s);
2. shadow volumes (silhouette, extrusion, z-fail stencil) for a 10k-triangle occluder in a
   512x512 frame (target <= 5 s);
3. per-method seconds of one comparison on the sphere scene at 256x256.
"""
import os
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import _cli  # noqa: E402


def main(args):
    from addon.core import shadow_map
    from addon.lab import shadow_scenes, shadows
    from addon.lab.shadow_session import Session
    from addon.blender.scene import remove_scene
    rows = []
    res = args.resolution
    shadow_map.check_cost(res, res, args.map_size, 1)
    scene = shadow_scenes.build("sphere", "sun", (res, res), segments=102, rings=50)   # 10 000 triangles
    try:
        with Session(scene, scene["il_shadow_light"], res) as s:
            s.render_reference()
            maps, render_s = s.depth_maps(args.map_size)
            r = s.receiver
            pts, nrm, tl = s.position[r], s.normal[r], s.to_light[r]
            best = min(_timed(lambda: shadow_map.lit_fraction(maps, pts, nrm, tl, 0.01, 2.0, 3)) for _ in range(3))
            rows.append((f"shadow-map lookup, 3x3 PCF, {res}^2 frame ({r.sum()} receiver px), {args.map_size}^2 map",
                         best, 0.5))
            rows.append((f"  (depth-map render by Cycles, {args.map_size}^2, not in the target)", render_s, None))
            t = time.perf_counter()
            volume, info = shadows.volume_inputs(s)
            shadows.volume_mask(s, volume, "zfail")
            rows.append((f"shadow volumes z-fail, {info['occluder_triangles']}-triangle occluder, {res}^2 frame",
                         time.perf_counter() - t, 5.0))
    finally:
        remove_scene(scene)
    with tempfile.TemporaryDirectory() as tmp:
        rep = shadows.compare_builtin("sphere", "sun", "raytraced,planar,shadowmap,volume_zpass,volume_zfail", tmp,
                                      resolution=256, shadowmap_size=2048)
    for m, e in rep["methods"].items():
        rows.append((f"comparison 256^2, {m} (error {e['error']:.4f})", e["seconds"], None))
    print(f"{'figure':92s} {'seconds':>9s} {'target':>8s}")
    for name, sec, target in rows:
        tgt = f"<= {target:g}" if target else ""
        flag = "" if target is None else ("  ok" if sec <= target else "  SLOW")
        print(f"{name:92s} {sec:9.3f} {tgt:>8s}{flag}")


def _timed(fn):
    t = time.perf_counter()
    fn()
    return time.perf_counter() - t


def build_parser():
    p = _cli.parser("bench_shadows.py", "Print the shadow lab's performance figures.", blend_file=False)
    p.add_argument("--resolution", type=_cli.number(int, 8, 8192), default=512, help="frame size (default 512)")
    p.add_argument("--map-size", type=_cli.number(int, 2, 16384), default=2048, help="shadow-map size (default 2048)")
    return p


if __name__ == "__main__":
    _cli.run(build_parser(), main)
