"""The SSAO methods as they were before issue 14 (commit 813ff01): the plain (..., 3)-array numpy
implementation, kept verbatim as the oracle the fast one in core.ssao must reproduce.

Only the imports changed (everything lives in this module) and the G-buffer's cached properties are
computed here (``_lookup``, ``_perspective``), so nothing of the code under test is used.
"""
import numpy as np

from addon.core.camera import SKY_DEPTH, ndc_to_pixels, pixels_to_ndc
from addon.core.errors import InputError


def _perspective(gb):
    return abs(gb.proj[3, 2]) > 0.5


def _lookup(gb):
    d = gb.depth.astype(np.float32)
    return (np.float32(1.0) / d) if _perspective(gb) else d


# --------------------------------------------------------------------------- gbuffer.py

def view_to_pixels(points, proj, width, height):
    """(..., 3) view points -> pixel x, y (row 0 at top) and clip w (> 0 in front of a perspective camera).

    x = (ndc_x + 1) W/2 - 1/2, y = (1 - ndc_y) H/2 - 1/2 with ndc = clip.xyz / clip.w.
    """
    p = proj.astype(np.float32)
    px, py, pz = points[..., 0], points[..., 1], points[..., 2]
    w = p[3, 0] * px + p[3, 1] * py + p[3, 2] * pz + p[3, 3]
    safe = np.where(w > 1e-6, w, np.float32(1.0))
    ndc_x = (p[0, 0] * px + p[0, 1] * py + p[0, 2] * pz + p[0, 3]) / safe
    ndc_y = (p[1, 0] * px + p[1, 1] * py + p[1, 2] * pz + p[1, 3]) / safe
    x, y = ndc_to_pixels(ndc_x, ndc_y, width, height)
    return x, y, w


def pixels_per_metre(gb, depth):
    """Screen-space scale at view depth z: f/z pixels per metre (perspective), f (orthographic).

    f = (P00 W/2 + P11 H/2)/2, the mean focal length in pixels, in float32 like the depth (the dtype
    NumPy 1's value-based casting gave f/z; NEP 50 would make it float64).
    """
    f = np.float32(0.25 * (gb.proj[0, 0] * gb.width + gb.proj[1, 1] * gb.height))
    return f / depth if _perspective(gb) else np.full_like(depth, f)


def view_vectors(gb, pos):
    """Unit vectors from the surface toward the camera: -p/|p| (perspective) or +Z (orthographic)."""
    if _perspective(gb):
        return -pos / np.maximum(np.linalg.norm(pos, axis=-1, keepdims=True), 1e-12)
    return np.broadcast_to(np.array([0, 0, 1], np.float32), pos.shape)


def depth_at(gb, x, y):
    """Depth buffer at sub-pixel positions; returns (depth, on_screen).

    Bilinear in 1/z for a perspective camera (1/z is affine in screen space on a
    plane, so planes are reconstructed exactly), in z for an orthographic one.
    Off-screen positions return SKY_DEPTH and on_screen False.
    """
    h, w = gb.depth.shape
    on = (x >= -0.5) & (x <= w - 0.5) & (y >= -0.5) & (y <= h - 0.5)
    xc = np.clip(x, 0.0, w - 1.0)
    yc = np.clip(y, 0.0, h - 1.0)
    x0 = np.minimum(np.floor(xc).astype(np.int32), w - 2 if w > 1 else 0)
    y0 = np.minimum(np.floor(yc).astype(np.int32), h - 2 if h > 1 else 0)
    fx = (xc - x0).astype(np.float32)
    fy = (yc - y0).astype(np.float32)
    x1 = np.minimum(x0 + 1, w - 1)
    y1 = np.minimum(y0 + 1, h - 1)
    q = _lookup(gb)
    top = q[y0, x0] * (1 - fx) + q[y0, x1] * fx
    bot = q[y1, x0] * (1 - fx) + q[y1, x1] * fx
    v = top * (1 - fy) + bot * fy
    if _perspective(gb):
        d = 1.0 / np.maximum(v, np.float32(1.0 / SKY_DEPTH))
    else:
        d = v
    return np.where(on, d, np.float32(SKY_DEPTH)), on


def position_at(gb, x, y):
    """View-space surface position at sub-pixel (x, y): the pixel's view ray scaled to :func:`depth_at`.

    Perspective: X = z (x_ndc + P02)/P00, Y = z (y_ndc + P12)/P11, Z = -z;
    orthographic: X = (x_ndc - P03)/P00, Y = (y_ndc - P13)/P11. Points along a
    screen line through a pixel stay in the plane through the eye containing
    that pixel's ray (GTAO's slice). Returns (positions, valid) where valid =
    on screen and not sky.
    """
    d, on = depth_at(gb, x, y)
    p = gb.proj.astype(np.float32)     # float32 as NumPy 1's value-based casting read P's scalars here
    ndc_x, ndc_y = pixels_to_ndc(x, y, gb.width, gb.height)
    if _perspective(gb):
        px = d * ((ndc_x + p[0, 2]) / p[0, 0])
        py = d * ((ndc_y + p[1, 2]) / p[1, 1])
    else:
        px = (ndc_x - p[0, 3]) / p[0, 0]
        py = (ndc_y - p[1, 3]) / p[1, 1]
    pos = np.stack([px, py, -d], -1).astype(np.float32)
    return pos, on & (d < 0.5 * SKY_DEPTH)


# --------------------------------------------------------------------------- samplers.py

def orthonormal_basis(n):
    """Tangent frame (t, b) of unit normals n (Duff et al. 2017, branchless, no singularity)."""
    sign = np.where(n[..., 2] >= 0, 1.0, -1.0).astype(np.float32)
    a = -1.0 / (sign + n[..., 2])
    b = n[..., 0] * n[..., 1] * a
    t = np.stack([1.0 + sign * n[..., 0] ** 2 * a, sign * b, -sign * n[..., 0]], -1)
    bb = np.stack([b, sign + n[..., 1] ** 2 * a, -n[..., 1]], -1)
    return t.astype(np.float32), bb.astype(np.float32)


def uniform_ball(rng, shape):
    """Points uniform in the unit ball: direction uniform on the sphere, radius u^(1/3)."""
    u = rng.random(shape + (3,), dtype=np.float32)
    z = 2.0 * u[..., 0] - 1.0
    phi = 2.0 * np.pi * u[..., 1]
    s = np.sqrt(np.maximum(0.0, 1.0 - z * z))
    r = np.cbrt(u[..., 2])
    return np.stack([s * np.cos(phi) * r, s * np.sin(phi) * r, z * r], -1)


def cosine_hemisphere(rng, shape):
    """Cosine-weighted unit directions about +Z (Malley: uniform disk lifted), pdf = cosθ/π."""
    u = rng.random(shape + (2,), dtype=np.float32)
    r = np.sqrt(u[..., 0])
    phi = 2.0 * np.pi * u[..., 1]
    return np.stack([r * np.cos(phi), r * np.sin(phi), np.sqrt(np.maximum(0.0, 1.0 - u[..., 0]))], -1)


def split_samples(samples):
    """Horizon methods: ``samples`` lookups = slices x 2 sides x steps; slices ~ sqrt(samples/2)."""
    slices = max(1, int(np.sqrt(samples / 2.0)))
    steps = max(1, int(samples) // (2 * slices))
    return slices, steps


# --------------------------------------------------------------------------- blur.py

def depth_aware_blur(gb, k_a, size=2, depth_sigma=0.05, normal_power=8.0):
    """Bilateral blur over a (2·size+1)² window, geometry pixels only:
    k'(p) = Σ_q w_q k(q) / Σ_q w_q, w_q = exp(-((z_q - z_p)/(σ z_p))²) · max(0, n_p·n_q)^P.

    Weights vanish across depth discontinuities and creases, so occlusion does
    not bleed between objects; sky pixels keep 1.
    """
    h, w = k_a.shape
    pad = size
    kp = np.pad(np.where(gb.mask, k_a, 0.0).astype(np.float32), pad, mode="edge")
    zp = np.pad(gb.depth, pad, mode="edge")
    mp = np.pad(gb.mask, pad, mode="constant")
    np_ = np.pad(gb.normal, ((pad, pad), (pad, pad), (0, 0)), mode="edge")
    acc = np.zeros((h, w), np.float32)
    wsum = np.zeros((h, w), np.float32)
    z0, n0 = gb.depth, gb.normal
    for dy in range(-size, size + 1):
        for dx in range(-size, size + 1):
            sl = (slice(pad + dy, pad + dy + h), slice(pad + dx, pad + dx + w))
            rel = (zp[sl] - z0) / (depth_sigma * np.maximum(z0, 1e-6))
            cosn = np.maximum(np.sum(np_[sl] * n0, -1), 0.0)
            wq = np.exp(-rel * rel) * cosn ** normal_power * mp[sl]
            acc += wq * kp[sl]
            wsum += wq
    out = np.where(gb.mask & (wsum > 0), acc / np.maximum(wsum, 1e-12), k_a)
    return np.where(gb.mask, out, 1.0).astype(np.float32)


# --------------------------------------------------------------------------- methods.py

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
            sides.append((np.where(valid, cos_h, np.float32(np.nan)), dist))
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


FUNCS = {"crytek": crytek, "hemisphere": hemisphere, "hbao": hbao, "gtao": gtao}
