"""Screen-space ambient occlusion methods on a G-buffer, vectorised numpy.

Every method returns k_A in [0, 1] with the meaning of seed 003 (REFERENCE.md
§1): the cosine-weighted fraction of the hemisphere NOT blocked within the
radius, 1 = fully open. Seed 000 writes AO = 1 - (1/|S|) Σ V(p) (the occluded
fraction); here k_A = 1 - AO (REFERENCE.md §6).

Methods (REFERENCE.md §4):
- :func:`crytek`: sphere kernel, seed 000's depth test (Mittring 2007);
- :func:`hemisphere`: normal-oriented hemisphere with bias and range check
  (Chapman 2013 style);
- :func:`hbao`: horizon-based AO (Bavoil & Sainz 2008), uniform measure with
  distance attenuation;
- :func:`gtao`: ground-truth AO (Jimenez et al. 2016), horizon per slice and
  the cosine-weighted inner integral solved analytically;
- :func:`core.ssao.blur.depth_aware_blur`: optional bilateral blur guided by depth and normal.
"""
import time

import numpy as np

from .. import budget
from ..errors import InputError
from .blur import depth_aware_blur
from .gbuffer import depth_at, pixels_per_metre, position_at, view_to_pixels, view_vectors
from .samplers import cosine_hemisphere, orthonormal_basis, split_samples, uniform_ball


#: The numpy methods of this module.
METHODS = ("crytek", "hemisphere", "hbao", "gtao")
#: Every method the SSAO lab compares (the last two are Blender's own renders).
ALL_METHODS = METHODS + ("eevee", "workbench")


def _check(radius, samples):
    if not np.isfinite(radius) or radius <= 0:
        raise InputError(f"radius must be positive, got {radius}")
    if int(samples) != samples or samples <= 0:
        raise InputError(f"samples must be a positive integer, got {samples}")


def _scatter(gb, values):
    """Per-geometry-pixel values -> (H, W) image, sky = 1 (open), float32."""
    out = np.ones(gb.depth.shape, np.float32)
    out[gb.mask] = values
    return out


def _chunks(n, per_item, budget=1 << 18):
    """Slices of ``range(n)`` so that ``rows * per_item`` stays within ``budget`` elements."""
    step = max(1, budget // max(1, per_item))
    return [slice(i, min(n, i + step)) for i in range(0, n, step)]


# --------------------------------------------------------------------------- methods

def crytek(gb, radius, samples, seed=0, range_check=False):
    """Sphere kernel (Mittring 2007; seed 000): k_A = (1/|S|) Σ_{s∈S} V(s), V(s) = [z(s) < d(s)].

    S: ``samples`` points uniform in the ball of radius r around the pixel's
    position; z(s) the sample's view depth, d(s) the depth buffer where s
    projects. Off-screen samples count as visible. A flat open surface reads
    about 0.5: half the ball lies behind it (seed 003). With ``range_check`` a
    depth-buffer surface more than r in front of the sample does not occlude.
    """
    _check(radius, samples)
    rng = np.random.default_rng(seed)
    pos = gb.position[gb.mask]
    out = np.empty(len(pos), np.float32)
    for sl in _chunks(len(pos), samples):
        p = pos[sl][:, None, :]
        s = p + np.float32(radius) * uniform_ball(rng, (len(p), samples))
        x, y, w = view_to_pixels(s, gb.proj, gb.width, gb.height)
        d, on = depth_at(gb, x, y)
        z = -s[..., 2]
        visible = (z < d) | ~on | (w <= 0)
        if range_check:
            visible |= (z - d) > radius
        out[sl] = visible.mean(axis=1)
    return _scatter(gb, out)


def range_weight(radius, dz):
    """Range check of the hemisphere method: smoothstep(0, 1, r / |z_p - d(s)|) (Chapman 2013)."""
    t = np.clip(radius / np.maximum(np.abs(dz), 1e-12), 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


def hemisphere(gb, radius, samples, seed=0, bias=None, range_check=True):
    """Normal-oriented hemisphere: k_A = 1 - (1/N) Σ_i [d(s_i) < z(s_i) - bias] · w_i.

    s_i = p + r λ_i ω_i with ω_i cosine-distributed about the normal (so the
    estimate carries the cos θ weight of k_A) and λ_i = 0.1 + 0.9 u² (samples
    gather near p, Chapman 2013); w_i the range check :func:`range_weight`
    (1 without it). ``bias`` (default 0.025 r) stops a surface occluding itself.
    """
    _check(radius, samples)
    bias = 0.025 * radius if bias is None else float(bias)
    rng = np.random.default_rng(seed)
    pos, nrm = gb.position[gb.mask], gb.normal[gb.mask]
    out = np.empty(len(pos), np.float32)
    for sl in _chunks(len(pos), samples):
        p, n = pos[sl], nrm[sl]
        t, b = orthonormal_basis(n)
        local = cosine_hemisphere(rng, (len(p), samples))
        lam = 0.1 + 0.9 * rng.random((len(p), samples, 1), dtype=np.float32) ** 2
        local = local * (np.float32(radius) * lam)
        s = (p[:, None, :] + local[..., :1] * t[:, None, :] + local[..., 1:2] * b[:, None, :]
             + local[..., 2:] * n[:, None, :])
        x, y, w = view_to_pixels(s, gb.proj, gb.width, gb.height)
        d, on = depth_at(gb, x, y)
        occluded = (d < -s[..., 2] - bias) & on & (w > 0)
        weight = range_weight(radius, -p[:, None, 2] - d) if range_check else 1.0
        out[sl] = 1.0 - (occluded * weight).mean(axis=1)
    return _scatter(gb, out)


def _horizon_search(gb, radius, samples, seed, slices=None, steps=None):
    """Yield per chunk: slice frame and per-sample horizon vectors of both sides.

    For each pixel: slice angles ψ_k = (k + u)π/S (stratified, random per pixel),
    screen direction (cos ψ, sin ψ), steps at (j + u')/N of the projected radius
    on both sides; the sample's view position S gives H = S - p, kept when
    0 < |H| <= r (AO distance) and on screen and not sky.
    Sample positions are sub-pixel (:func:`core.ssao.gbuffer.position_at`), so H lies in the slice
    plane. Yields: chunk slice, |n_p|, γ, and for each side cos(H, v) (nan when
    invalid) and |H|.
    """
    _check(radius, samples)
    if slices is None or steps is None:
        s0, n0 = split_samples(samples)
        slices, steps = slices or s0, steps or n0
    rng = np.random.default_rng(seed)
    ys, xs = (a.astype(np.float32) for a in np.nonzero(gb.mask))
    pos, nrm = gb.position[gb.mask], gb.normal[gb.mask]
    scale = pixels_per_metre(gb, gb.depth[gb.mask]) * radius
    for sl in _chunks(len(pos), slices * steps * 2):
        p, n = pos[sl], nrm[sl]
        m = len(p)
        v = view_vectors(gb, p)
        psi = (np.arange(slices, dtype=np.float32)[None, :] + rng.random((m, 1), dtype=np.float32)) * (np.pi / slices)
        c, s_ = np.cos(psi), np.sin(psi)                                   # (m, S) screen direction, y down
        d3 = np.stack([c, -s_, np.zeros_like(c)], -1)                      # view space, y up
        vv = v[:, None, :]
        t = d3 - np.sum(d3 * vv, -1, keepdims=True) * vv
        t /= np.maximum(np.linalg.norm(t, axis=-1, keepdims=True), 1e-12)
        axis = np.cross(vv, t)                                             # slice plane normal
        nn = n[:, None, :]
        n_p = nn - np.sum(nn * axis, -1, keepdims=True) * axis
        n_len = np.linalg.norm(n_p, axis=-1)
        gamma = np.arctan2(np.sum(n_p * t, -1), np.sum(n_p * vv, -1))
        jitter = rng.random((m, 1, 1), dtype=np.float32)
        frac = (np.arange(steps, dtype=np.float32)[None, None, :] + jitter) / steps   # (m, 1, N)
        off = scale[sl, None, None] * frac                                             # pixels
        sides = []
        for sign in (1.0, -1.0):
            qx = xs[sl, None, None] + sign * c[..., None] * off
            qy = ys[sl, None, None] + sign * s_[..., None] * off
            spos, valid = position_at(gb, qx, qy)
            hv = spos - p[:, None, None, :]                                 # (m, S, N, 3) in the slice plane
            dist = np.linalg.norm(hv, axis=-1)
            valid &= (dist > 1e-6 * radius) & (dist <= radius)
            cos_h = np.sum(hv * vv[:, :, None, :], -1) / np.maximum(dist, 1e-12)
            sides.append((np.where(valid, cos_h, np.nan), dist))
        yield sl, n_len, gamma, sides


def gtao_inner(h, gamma):
    """Cosine-weighted inner integral of one side (Jimenez et al. 2016, eq. 10):
    â(h, γ) = ¼(-cos(2h - γ) + cos γ + 2h sin γ) = ∫_0^h cos(φ - γ)|sin φ| dφ."""
    return 0.25 * (-np.cos(2.0 * h - gamma) + np.cos(gamma) + 2.0 * h * np.sin(gamma))


def gtao(gb, radius, samples, seed=0, slices=None, steps=None, normalise=True):
    """GTAO: k_A = mean over slices of |n_p| (â(h1, γ) + â(h2, γ)) (Jimenez et al. 2016).

    h2 = +acos(max cos(H, v)) on the +side, h1 = -acos(...) on the -side, each
    clamped to the hemisphere: h2 <= γ + π/2, h1 >= γ - π/2; γ the angle of the
    normal projected into the slice (n_p) from the view vector v. Exact for a
    height field within the AO distance r. The slice mean is unbiased over
    random slice angles, but a few slices scatter it around 1 on an open
    surface; with ``normalise`` it is divided by the same slices' open value
    Σ|n_p|(â(γ-π/2) + â(γ+π/2)) (a ratio estimator: an open surface reads
    exactly 1, and it converges to the same k_A as slices grow, since that
    mean tends to 1).
    """
    out = np.empty(int(gb.mask.sum()), np.float32)
    for sl, n_len, gamma, sides in _horizon_search(gb, radius, samples, seed, slices, steps):
        (c2, _), (c1, _) = sides
        with np.errstate(all="ignore"):
            c2 = np.fmax(np.nanmax(np.where(np.isnan(c2), -1.0, c2), -1), -1.0)
            c1 = np.fmax(np.nanmax(np.where(np.isnan(c1), -1.0, c1), -1), -1.0)
        h2 = np.minimum(np.arccos(np.clip(c2, -1, 1)), gamma + np.pi / 2)
        h1 = np.maximum(-np.arccos(np.clip(c1, -1, 1)), gamma - np.pi / 2)
        k = n_len * (gtao_inner(h1, gamma) + gtao_inner(h2, gamma))
        if normalise:
            k_open = n_len * (gtao_inner(gamma - np.pi / 2, gamma) + gtao_inner(gamma + np.pi / 2, gamma))
            out[sl] = np.clip(k.sum(axis=1) / np.maximum(k_open.sum(axis=1), 1e-12), 0.0, 1.0)
        else:
            out[sl] = np.clip(k.mean(axis=1), 0.0, 1.0)
    return _scatter(gb, out)


def hbao_attenuation(dist, radius):
    """HBAO's distance attenuation W(r) = 1 - r²/R² (Bavoil & Sainz 2008)."""
    return np.clip(1.0 - (dist / radius) ** 2, 0.0, 1.0)


def hbao(gb, radius, samples, seed=0, slices=None, steps=None, attenuation=True):
    """HBAO: k_A = 1 - (1/N_d) Σ_θ Σ_j W(r_j) (sin h_j - sin h_{j-1})⁺ (Bavoil & Sainz 2008).

    Per direction θ (each side of a slice) elevations are measured from the plane
    perpendicular to the view vector: the tangent's sin t = ∓sin γ starts the
    running horizon, each step that raises it adds W times the rise in sin h.
    This is the uniform (not cosine-weighted) measure of the paper.
    """
    out = np.empty(int(gb.mask.sum()), np.float32)
    for sl, n_len, gamma, sides in _horizon_search(gb, radius, samples, seed, slices, steps):
        occ = np.zeros(gamma.shape, np.float32)
        for (cos_h, dist), sin_t in zip(sides, (-np.sin(gamma), np.sin(gamma))):
            best = sin_t.astype(np.float32)
            for j in range(cos_h.shape[-1]):
                sh = cos_h[..., j]
                rise = np.where(np.isnan(sh), 0.0, np.maximum(sh - best, 0.0))
                wgt = hbao_attenuation(dist[..., j], radius) if attenuation else 1.0
                occ += rise * wgt
                best = np.where(rise > 0, sh, best)
        out[sl] = np.clip(1.0 - occ.mean(axis=1) / 2.0, 0.0, 1.0)
    return _scatter(gb, out)


_FUNCS = {"crytek": crytek, "hemisphere": hemisphere, "hbao": hbao, "gtao": gtao}


def check_method(name):
    """The function of the numpy method ``name`` (InputError for any other name)."""
    if name not in _FUNCS:
        raise InputError(f"unknown SSAO method '{name}' (choose from {', '.join(METHODS)})")
    return _FUNCS[name]


def run_method(name, gb, radius, samples, blur=False, seed=0, **params):
    """Run one method by name; return ``(k_A image, seconds, params)`` (blur included in the time)."""
    func = check_method(name)
    _check(radius, samples)
    t0 = time.perf_counter()
    k = func(gb, radius, samples, seed=seed, **params)
    if blur:
        k = depth_aware_blur(gb, k)
    seconds = time.perf_counter() - t0
    used = {"radius": float(radius), "samples": int(samples), "blur": bool(blur), "seed": int(seed), **params}
    if name in ("hbao", "gtao"):
        s0, n0 = split_samples(samples)
        used.setdefault("slices", params.get("slices") or s0)
        used.setdefault("steps", params.get("steps") or n0)
    if name == "hemisphere":
        used["bias"] = used.get("bias") if used.get("bias") is not None else 0.025 * radius
    return k, seconds, used
