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

Layout (issue 14): per chunk of :data:`CHUNK` pixel-samples, coordinates as separate float32 planes
with pixels on the last axis, depth lookups as flat gathers (core.ssao.gbuffer.lookup_at); every
floating-point operation and its order is the plain implementation's (tests/core/ssao/seed_ssao.py),
so the images are the same.
"""
import time

import numpy as np

from .. import budget
from ..errors import InputError
from .blur import depth_aware_blur
from .gbuffer import depth_from_lookup, lookup_at, pixels_per_metre, positions_at, project
from .samplers import ball_from_uniform, hemisphere_from_uniform, orthonormal_basis, split_samples


#: The numpy methods of this module.
METHODS = ("crytek", "hemisphere", "hbao", "gtao")
#: Every method the SSAO lab compares (the last two are Blender's own renders).
ALL_METHODS = METHODS + ("eevee", "workbench")

#: Pixel-samples per draw of random numbers. Fixed, so that a seed gives the same image whatever
#: :data:`CHUNK` is.
RNG_BLOCK = 1 << 18
#: Pixel-samples computed at once: each float32 temporary is 512 KiB, so a chunk's working set stays
#: in the caches (1 MiB L2 per core, 32 MiB L3 here) while numpy's per-call overhead stays small
#: (measured at 512², 16 samples: 2^17 best, 2^15 and 2^18 5-15 % slower).
CHUNK = 1 << 17


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


def _chunks(n, per_item, budget=None):
    """Slices of ``range(n)`` so that ``rows * per_item`` stays within ``budget`` (:data:`CHUNK`) elements."""
    step = max(1, (CHUNK if budget is None else budget) // max(1, per_item))
    return [slice(i, min(n, i + step)) for i in range(0, n, step)]


def _blocks(n, per_item):
    """(block, chunks): the :data:`RNG_BLOCK` slices of ``range(n)``, each with its :data:`CHUNK` slices
    relative to the block's start."""
    for block in _chunks(n, per_item, RNG_BLOCK):
        yield block, _chunks(block.stop - block.start, per_item)


def _sample_major(u):
    """Uniforms drawn (pixels, samples, k) as a (samples, pixels, k) view whose k planes are contiguous,
    so per-pixel operands broadcast along whole rows."""
    return np.ascontiguousarray(u.transpose(2, 1, 0)).transpose(1, 2, 0)


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
    pos = gb.position[gb.mask].T.copy()
    out = np.empty(pos.shape[1], np.float32)
    r = np.float32(radius)
    for block, chunks in _blocks(pos.shape[1], samples):
        u = rng.random((block.stop - block.start, samples, 3), dtype=np.float32)
        p_block = pos[:, block]
        for sl in chunks:                                       # (samples, pixels) from here on
            p = p_block[:, sl]
            sx, sy, sz = ball_from_uniform(_sample_major(u[sl]))
            sx *= r
            sx += p[0]
            sy *= r
            sy += p[1]
            sz *= r
            sz += p[2]
            x, y, w = project(sx, sy, sz, gb.proj, gb.width, gb.height)
            v, on = lookup_at(gb, x, y)
            d = depth_from_lookup(gb, v)
            z = np.negative(sz, out=sz)
            visible = z < d
            visible |= ~on
            visible |= w <= 0
            if range_check:
                z -= d
                visible |= z > radius
            out[block][sl] = np.count_nonzero(visible, axis=0) / samples
    return _scatter(gb, out)


def range_weight(radius, dz):
    """Range check of the hemisphere method: smoothstep(0, 1, r / |z_p - d(s)|) (Chapman 2013)."""
    t = np.clip(radius / np.maximum(np.abs(dz), 1e-12), 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


def _range_weight_inplace(radius, dz):
    """:func:`range_weight` overwriting ``dz`` (float32, same operations)."""
    t = np.abs(dz, out=dz)
    np.maximum(t, 1e-12, out=t)
    np.divide(radius, t, out=t)
    np.minimum(t, 1.0, out=t)                      # r/|dz| > 0: clip(t, 0, 1) = min(t, 1)
    s = 2.0 * t
    np.subtract(3.0, s, out=s)
    t *= t
    t *= s
    return t


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
    pos, nrm = gb.position[gb.mask].T.copy(), gb.normal[gb.mask]
    out = np.empty(pos.shape[1], np.float32)
    r = np.float32(radius)
    for block, chunks in _blocks(pos.shape[1], samples):
        m = block.stop - block.start
        u = rng.random((m, samples, 2), dtype=np.float32)
        u_lam = rng.random((m, samples, 1), dtype=np.float32)
        p_block, n_block = pos[:, block], nrm[block]
        for sl in chunks:                                       # (samples, pixels) from here on
            p, n = p_block[:, sl], n_block[sl]
            t, b = orthonormal_basis(n)
            frame = [f.T.copy() for f in (t, b, n)]             # (3, pixels) each
            lx, ly, lz = hemisphere_from_uniform(_sample_major(u[sl]))
            lam = _sample_major(u_lam[sl])[..., 0] ** 2
            lam *= 0.9
            lam += 0.1
            lam *= r
            lx *= lam
            ly *= lam
            lz *= lam
            s = []
            for k in range(3):                                  # s = ((p + lx t) + ly b) + lz n
                c = lx * frame[0][k]
                c += p[k]
                np.multiply(ly, frame[1][k], out=lam)
                c += lam
                np.multiply(lz, frame[2][k], out=lam)
                c += lam
                s.append(c)
            x, y, w = project(*s, gb.proj, gb.width, gb.height)
            v, on = lookup_at(gb, x, y)
            d = depth_from_lookup(gb, v)
            z = np.negative(s[2], out=s[2])
            z -= bias
            occluded = d < z
            occluded &= on
            occluded &= w > 0
            if range_check:
                dz = np.subtract(-p[2], d, out=z)
                weight = _range_weight_inplace(radius, dz)
                weight *= occluded
                out[block][sl] = 1.0 - weight.T.copy().mean(axis=1)   # the per-pixel sum's order
            else:
                out[block][sl] = 1.0 - occluded.mean(axis=0)
    return _scatter(gb, out)


def _dot(a, b):
    """a·b of coordinate triples, (a0 b0 + a1 b1) + a2 b2 (the order of numpy's sum over a last axis of 3)."""
    d = a[0] * b[0]
    d += a[1] * b[1]
    d += a[2] * b[2]
    return d


def _horizon_search(gb, radius, samples, seed, slices=None, steps=None):
    """Yield per chunk: slice frame and per-sample horizon vectors of both sides.

    For each pixel: slice angles ψ_k = (k + u)π/S (stratified, random per pixel),
    screen direction (cos ψ, sin ψ), steps at (j + u')/N of the projected radius
    on both sides; the sample's view position S gives H = S - p, kept when
    0 < |H| <= r (AO distance) and on screen and not sky.
    Sample positions are sub-pixel (:func:`core.ssao.gbuffer.position_at`), so H lies in the slice
    plane. Yields: chunk slice, |n_p| and γ (S, m), and for each side cos(H, v) (-inf when invalid)
    and |H|, both (N, S, m). Pixels are the last axis, so every operation runs along contiguous rows.
    """
    _check(radius, samples)
    if slices is None or steps is None:
        s0, n0 = split_samples(samples)
        slices, steps = slices or s0, steps or n0
    # Python scalars: a NumPy float64/int64 here would turn the float32 planes float64 under NEP 50 (NumPy 2)
    radius, slices, steps = float(radius), int(slices), int(steps)
    rng = np.random.default_rng(seed)
    ys, xs = (a.astype(np.float32) for a in np.nonzero(gb.mask))
    pos, nrm = gb.position[gb.mask].T.copy(), gb.normal[gb.mask].T.copy()           # (3, pixels)
    scale = pixels_per_metre(gb, gb.depth[gb.mask]) * radius
    step_index = np.arange(steps, dtype=np.float32)[:, None, None]
    slice_index = np.arange(slices, dtype=np.float32)[:, None]
    for block, chunks in _blocks(pos.shape[1], slices * steps * 2):
        m_block = block.stop - block.start
        u_psi = rng.random((m_block, 1), dtype=np.float32)[:, 0]
        u_step = rng.random((m_block, 1, 1), dtype=np.float32)[:, 0, 0]
        for rel in chunks:
            sl = slice(block.start + rel.start, block.start + rel.stop)
            p, n = pos[:, sl], nrm[:, sl]
            if gb.perspective:                                                 # v = -p/|p|
                length = np.sqrt(_dot(p, p))
                np.maximum(length, 1e-12, out=length)
                v = [np.negative(pk) / length for pk in p]
            else:
                v = [np.zeros(p.shape[1], np.float32)] * 2 + [np.ones(p.shape[1], np.float32)]
            psi = (slice_index + u_psi[rel]) * (np.pi / slices)                     # (S, m)
            c, s_ = np.cos(psi), np.sin(psi)                                    # screen direction, y down
            d3 = (c, -s_)                                                       # view space, y up; z = 0
            dot = d3[0] * v[0]
            dot += d3[1] * v[1]
            t = [d3[0] - dot * v[0], d3[1] - dot * v[1], 0.0 - dot * v[2]]
            length = np.sqrt(_dot(t, t))
            np.maximum(length, 1e-12, out=length)
            for tk in t:
                tk /= length
            axis = [v[1] * t[2] - v[2] * t[1], v[2] * t[0] - v[0] * t[2], v[0] * t[1] - v[1] * t[0]]
            dot = _dot(n[:, None, :], axis)
            n_p = [n[k] - dot * axis[k] for k in range(3)]                      # normal in the slice plane
            n_len = np.sqrt(_dot(n_p, n_p))
            gamma = np.arctan2(_dot(n_p, t), _dot(n_p, v))
            frac = (step_index + u_step[rel]) / steps                               # (N, 1, m)
            off = scale[sl] * frac                                                  # pixels
            dx, dy = c * off, s_ * off                                              # (N, S, m)
            x0, y0 = xs[sl], ys[sl]
            sides = []
            for qx, qy in ((dx + x0, dy + y0), (np.subtract(x0, dx, out=dx), np.subtract(y0, dy, out=dy))):
                hx, hy, hz, valid = positions_at(gb, qx, qy)                     # in the slice plane
                hx -= p[0]
                hy -= p[1]
                hz -= p[2]
                cos_h = _dot((hx, hy, hz), v)
                hx *= hx
                hy *= hy
                hz *= hz
                hx += hy
                hx += hz
                dist = np.sqrt(hx, out=hx)
                valid &= dist > 1e-6 * radius
                valid &= dist <= radius
                cos_h /= np.maximum(dist, 1e-12, out=hy)
                np.copyto(cos_h, -np.inf, where=~valid)
                sides.append((cos_h, dist))
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
        c2 = np.fmax(np.max(c2, axis=0), -1.0)
        c1 = np.fmax(np.max(c1, axis=0), -1.0)
        h2 = np.minimum(np.arccos(np.clip(c2, -1, 1)), gamma + np.pi / 2)
        h1 = np.maximum(-np.arccos(np.clip(c1, -1, 1)), gamma - np.pi / 2)
        k = (n_len * (gtao_inner(h1, gamma) + gtao_inner(h2, gamma))).T.copy()        # (m, S)
        if normalise:
            k_open = n_len * (gtao_inner(gamma - np.pi / 2, gamma) + gtao_inner(gamma + np.pi / 2, gamma))
            k_open = k_open.T.copy()
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
    radius = float(radius)                          # weak Python scalar with float32 distances (NEP 50)
    out = np.empty(int(gb.mask.sum()), np.float32)
    for sl, n_len, gamma, sides in _horizon_search(gb, radius, samples, seed, slices, steps):
        occ = np.zeros(gamma.shape, np.float32)
        for (cos_h, dist), sin_t in zip(sides, (-np.sin(gamma), np.sin(gamma))):
            best = sin_t.astype(np.float32)
            wgt = hbao_attenuation(dist, radius) if attenuation else None
            for j in range(len(cos_h)):
                sh = cos_h[j]
                rise = np.maximum(sh - best, 0.0)           # an invalid step (-inf) never rises
                rising = rise > 0
                if wgt is not None:
                    rise *= wgt[j]
                occ += rise
                np.copyto(best, sh, where=rising)
        out[sl] = np.clip(1.0 - occ.T.copy().mean(axis=1) / 2.0, 0.0, 1.0)
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
