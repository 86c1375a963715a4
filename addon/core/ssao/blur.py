"""Depth- and normal-aware bilateral blur of a k_A image."""
import numpy as np


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
