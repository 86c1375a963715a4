"""The two intersection engines on the same rays: the numpy BVH (core.raytrace.bvh) and Blender's
mathutils BVHTree (one Python call per ray). Rays per second of closest-hit queries and their agreement."""
import time

import numpy as np
from mathutils import Vector
from mathutils.bvhtree import BVHTree

#: Rays timed at most per engine (evenly spaced over the image's pixels).
MAX_RAYS = 4096


class BVHTreeEngine:
    """Blender's BVHTree behind core.raytrace's engine interface (``closest``, ``occluded``): one polygon per
    triangle, so its polygon index is the triangle index. A Python call per ray: 0.8-0.9 x the numpy BVH's
    closest-hit rate on full frames, faster on the small batches of a glass sphere's secondary rays
    (docs/raytrace.md)."""

    def __init__(self, tris):
        tris = np.asarray(tris, np.float64).reshape(-1, 3, 3)
        self.count = len(tris)
        self.tree = BVHTree.FromPolygons([Vector(v) for v in tris.reshape(-1, 3)],
                                         [(3 * i, 3 * i + 1, 3 * i + 2) for i in range(len(tris))],
                                         all_triangles=True, epsilon=0.0) if len(tris) else None

    def __len__(self):
        return self.count

    def closest(self, origins, dirs, tmin=0.0, tmax=np.inf):
        o = np.asarray(origins, np.float64).reshape(-1, 3)
        d = np.asarray(dirs, np.float64).reshape(-1, 3)
        n = len(o)
        tmin = np.broadcast_to(np.asarray(tmin, np.float64), n)
        tmax = np.broadcast_to(np.asarray(tmax, np.float64), n)
        t = np.array(tmax, np.float64, copy=True)
        tri = np.full(n, -1, np.int64)
        if self.tree is None:
            return t, tri
        cast = self.tree.ray_cast
        for i in range(n):
            start = o[i] + tmin[i] * d[i]
            dist = tmax[i] - tmin[i]
            _, _, index, hit = cast(Vector(start), Vector(d[i])) if not np.isfinite(dist) else \
                cast(Vector(start), Vector(d[i]), float(dist))
            if index is not None:
                t[i], tri[i] = hit + tmin[i], index
        return t, tri

    def occluded(self, origins, dirs, tmax, tmin=0.0):
        _, tri = self.closest(origins, dirs, tmin, tmax)
        return tri >= 0


ENGINES = {"bvhtree": BVHTreeEngine, "numpy": None}


def _timed(call):
    """(result, wall seconds, CPU seconds of this process): CPU time is what a loaded shared machine distorts least."""
    w, c = time.perf_counter(), time.process_time()
    out = call()
    return out, time.perf_counter() - w, time.process_time() - c


def compare(rt, origins, dirs):
    """{"numpy_bvh": {...}, "mathutils_bvhtree": {...}, "same_hits"}: build seconds, closest-hit rays per second of
    CPU time (and per wall second) on the same rays, and the share of rays both engines hit at the same distance."""
    from ...core.raytrace.bvh import BVH
    n = min(len(origins), MAX_RAYS)
    pick = np.linspace(0, len(origins) - 1, n).round().astype(np.int64)     # spread over the whole image
    o, d = origins[pick], dirs[pick]
    report = {"rays": int(n)}
    hits = {}
    for name, build in (("numpy_bvh", BVH), ("mathutils_bvhtree", BVHTreeEngine)):
        engine, b_wall, _ = _timed(lambda: build(rt.tris))
        (t, _), wall, cpu = _timed(lambda: engine.closest(o, d, tmin=0.0))
        hits[name] = t
        report[name] = {"build_seconds": b_wall, "seconds": wall, "cpu_seconds": cpu,
                        "rays_per_second": n / max(cpu, 1e-9), "rays_per_wall_second": n / max(wall, 1e-9)}
    a, b = hits["numpy_bvh"], hits["mathutils_bvhtree"]
    both = np.isfinite(a) & np.isfinite(b)
    a0, b0 = np.where(both, a, 0.0), np.where(both, b, 0.0)
    close = np.abs(a0 - b0) <= 1e-4 * np.maximum(1.0, b0)
    report["same_hits"] = float(np.mean((np.isfinite(a) == np.isfinite(b)) & close))
    return report
