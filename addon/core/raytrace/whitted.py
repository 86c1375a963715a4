"""Ray casting and Whitted ray tracing (seed 004, "Rendering con ray casting" and "Ray-tracing", eq. 2):

    I = I_a k_a + Σ_lights I (k_d n·l + k_s (n·h)^n) + k_s I_r + k_t I_t

traced as a wavefront: all rays of one depth at once, each carrying the product of the k_s / k_t factors
along its path (its ``weight``), so the recursion is a loop over depth. Ray casting is depth 0: the
primary ray, the local model at its first hit and shadow rays. Whitted adds, up to ``max_depth``
bounces, the mirror ray (k_s I_r) and the refracted ray (k_t I_t, Snell, total internal reflection sends
everything into I_r). Diffuse interreflection, area lights and sky light are left out, as in the notes.
"""
import time

import numpy as np

from . import optics
from ..brdf import dot

METHODS = ("raycast", "whitted")
#: Rays whose weight falls below this (all channels) are dropped. Each glass hit spawns two rays, so without it
#: the ray count doubles per bounce where both keep weight (near-critical angles, facets trapping light by total
#: internal reflection): 1.7 M rays at depth 64 on a 128² glass sphere with 1e-9. What is dropped is counted
#: (Stats.dropped_max: at most that share of a background's radiance is lost in a pixel).
MIN_WEIGHT = 1e-4


class Stats:
    """Counts of one render: primary, secondary (reflected and refracted) and shadow rays, seconds."""

    def __init__(self):
        self.primary = self.secondary = self.shadow = 0
        self.seconds = self.cpu_seconds = 0.0
        self.depth_reached = 0
        self.dropped_max = 0.0      # largest summed weight of rays dropped below MIN_WEIGHT in one pixel
        self.cut_mean = 0.0         # weight still travelling when max_depth stopped it, mean over pixels
        self.cut_max = 0.0

    @property
    def rays(self):
        return self.primary + self.secondary + self.shadow

    def as_dict(self):
        return {"rays": self.rays, "primary": self.primary, "secondary": self.secondary, "shadow": self.shadow,
                "seconds": self.seconds, "cpu_seconds": self.cpu_seconds, "depth_reached": self.depth_reached,
                "dropped_weight_max": self.dropped_max, "cut_weight_mean": self.cut_mean,
                "cut_weight_max": self.cut_max,
                "rays_per_second": self.rays / self.seconds if self.seconds > 0 else None}


def direct_light(scene, mat, p, n, ng, v, stats, kd=None):
    """Σ_lights I (local model) over the lights a shadow ray reaches (seed 004: the shadow ray from the hit point
    toward the light; anything in between, glass included, blocks it)."""
    out = np.zeros(p.shape)
    origin = p + ng * scene.epsilon
    for light in scene.lights:
        l, dist, I = light.sample(p)
        facing = (dot(n, l) > 0) & (dot(ng, l) > 0) & (np.abs(I).sum(-1) > 0)
        if not facing.any():
            continue
        idx = np.nonzero(facing)[0]
        stats.shadow += len(idx)
        blocked = scene.bvh.occluded(origin[idx], l[idx], dist[idx] - scene.epsilon, tmin=0.0)
        lit = idx[~blocked]
        out[lit] += mat.local(n[lit], l[lit], v[lit], I[lit], kd=None if kd is None else kd[lit])
    return out


def ambient_light(scene, mat, count):
    """I_a k_a (seed 004, eq. 1): the constant term standing in for indirect light."""
    return np.broadcast_to(scene.ambient * mat.ka, (count, 3))


#: Primary rays traced together (bounds the wavefront's memory: ~0.5 KB per ray and its BVH frontier).
BATCH = 1 << 16


def trace(scene, origins, dirs, method="whitted", max_depth=4, progress=None):
    """Radiance along each ray (N, 3) and :class:`Stats`, BATCH primary rays at a time. ``progress(message)`` is
    called once per depth of each batch (a callback that raises stops the render)."""
    if method not in METHODS:
        raise ValueError(f"unknown method {method!r}: one of {', '.join(METHODS)}")
    o = np.asarray(origins, np.float64).reshape(-1, 3)
    d = np.asarray(dirs, np.float64).reshape(-1, 3)
    t0, c0 = time.perf_counter(), time.process_time()
    images, total = [], Stats()
    for s in range(0, max(len(o), 1), BATCH):
        note = progress
        if progress is not None and len(o) > BATCH:
            note = (lambda m, s=s: progress(f"rays {s}-{min(s + BATCH, len(o))} of {len(o)}, {m}"))
        img, st = _trace_batch(scene, o[s:s + BATCH], d[s:s + BATCH], method, max_depth, note)
        images.append(img)
        total.primary += st.primary
        total.secondary += st.secondary
        total.shadow += st.shadow
        total.depth_reached = max(total.depth_reached, st.depth_reached)
        total.dropped_max = max(total.dropped_max, st.dropped_max)
        total.cut_max = max(total.cut_max, st.cut_max)
        total.cut_mean += st.cut_mean * st.primary
    total.cut_mean /= max(total.primary, 1)
    total.seconds = time.perf_counter() - t0
    total.cpu_seconds = time.process_time() - c0
    return (np.concatenate(images) if images else np.zeros((0, 3))), total


def _trace_batch(scene, origins, dirs, method, max_depth, progress):
    """:func:`trace` of one batch of primary rays: the wavefront, one depth per pass."""
    depth_limit = 0 if method == "raycast" else int(max_depth)
    t0, c0 = time.perf_counter(), time.process_time()
    o = np.asarray(origins, np.float64).reshape(-1, 3)
    d = np.asarray(dirs, np.float64).reshape(-1, 3)
    d = d / np.linalg.norm(d, axis=-1, keepdims=True)
    n_rays = len(o)
    image = np.zeros((n_rays, 3))
    weight = np.ones((n_rays, 3))
    pixel = np.arange(n_rays)
    stats = Stats()
    stats.primary = n_rays
    tmin = np.zeros(n_rays)
    dropped = np.zeros(n_rays)
    cut = np.zeros(n_rays)
    for depth in range(depth_limit + 1):
        if progress is not None:
            progress(f"depth {depth}: {len(o)} rays")
        if not len(o):
            break
        stats.depth_reached = depth
        t, tri = scene.bvh.closest(o, d, tmin=tmin)
        miss = tri < 0
        np.add.at(image, pixel[miss], weight[miss] * scene.background)
        hit = ~miss
        o, d, t, tri, weight, pixel = o[hit], d[hit], t[hit], tri[hit], weight[hit], pixel[hit]
        p = o + t[:, None] * d
        ng = scene.face_normals[tri]
        ns = scene.shading_normal(tri, p)
        spawned = []
        for m in np.unique(scene.material_index[tri]):
            sel = scene.material_index[tri] == m
            mat = scene.materials[m]
            radiance, rays = shade(scene, mat, p[sel], d[sel], ng[sel], ns[sel], stats,
                                   spawn=depth < depth_limit, tri=tri[sel])
            if depth == depth_limit and mat.specular_only:
                np.add.at(cut, pixel[sel], weight[sel].max(-1))
            np.add.at(image, pixel[sel], weight[sel] * radiance)
            w_sel, px_sel = weight[sel], pixel[sel]
            for k, ro, rd, rw in rays:
                spawned.append((ro, rd, w_sel[k] * rw, px_sel[k]))
        if not spawned:
            o = np.zeros((0, 3))
            break
        o = np.concatenate([s[0] for s in spawned])
        d = np.concatenate([s[1] for s in spawned])
        weight = np.concatenate([s[2] for s in spawned])
        pixel = np.concatenate([s[3] for s in spawned])
        keep = weight.max(-1) > MIN_WEIGHT
        np.add.at(dropped, pixel[~keep], weight[~keep].max(-1))
        o, d, weight, pixel = o[keep], d[keep], weight[keep], pixel[keep]
        tmin = np.zeros(len(o))
        stats.secondary += len(o)
    stats.dropped_max = float(dropped.max()) if n_rays else 0.0
    stats.cut_mean, stats.cut_max = (float(cut.mean()), float(cut.max())) if n_rays else (0.0, 0.0)
    stats.seconds = time.perf_counter() - t0
    stats.cpu_seconds = time.process_time() - c0
    return image, stats


def shade(scene, mat, p, d, ng, ns, stats, spawn=True, tri=None):
    """Local radiance at hits of one material and the secondary rays [(which hits, origins, dirs, weight factor)];
    ``tri``: the hit triangles (a textured k_d is read through their UVs)."""
    count = len(p)
    v = -d
    if not mat.specular_only:
        # two-sided like Cycles: a surface seen from its back is lit as its front
        back = dot(ng, d) > 0
        ng = np.where(back[:, None], -ng, ng)
        ns = np.where(back[:, None], -ns, ns)
        kd = None if tri is None else scene.albedo(mat, tri, p)
        radiance = ambient_light(scene, mat, count) + direct_light(scene, mat, p, ns, ng, v, stats, kd)
        return radiance + np.asarray(mat.emission), []
    radiance = np.broadcast_to(np.asarray(mat.emission, np.float64), (count, 3)).copy()
    if not spawn:
        return radiance, []
    eps = scene.epsilon
    if mat.mirror is not None:
        side = np.where((dot(ng, d) > 0)[:, None], -1.0, 1.0)
        n = ns * side
        cos_i = np.clip(-dot(n, d), 0.0, 1.0)
        ks = optics.fresnel_conductor(cos_i, mat.mirror)
        return radiance, [(np.arange(count), p + ng * side * eps, optics.reflect_dir(d, n), ks)]
    n_geo_side = np.where((dot(ng, d) < 0)[:, None], ng, -ng)
    n, eta, ks, kt, tir = optics.glass_split(d, ng, mat.ior, n_shade=ns)
    r = optics.reflect_dir(d, n)
    t, _ = optics.refract_dir(d, n, eta)
    rays = [(np.arange(count), p + n_geo_side * eps, r, np.repeat(ks[:, None], 3, 1))]
    through = np.nonzero(~tir)[0]
    if len(through):
        kt_rgb = kt[through, None] * np.asarray(mat.tint, np.float64)
        rays.append((through, p[through] - n_geo_side[through] * eps, t[through], kt_rgb))
    return radiance, rays
