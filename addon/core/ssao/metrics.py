"""Errors of an SSAO image against a reference: RMSE and bias over geometry pixels, silhouettes, reference noise."""
import numpy as np


# --------------------------------------------------------------------------- metrics

def behind_silhouette(gb, jump, reach=3):
    """Geometry pixels p with a pixel q within ``reach`` px (square window) in front of them by more
    than ``jump`` metres: z_q < z_p - jump. Where halos at depth discontinuities show."""
    h, w = gb.depth.shape
    zp = np.pad(gb.depth, reach, mode="edge")
    near = np.full((h, w), np.inf, np.float32)
    for dy in range(-reach, reach + 1):
        for dx in range(-reach, reach + 1):
            near = np.minimum(near, zp[reach + dy:reach + dy + h, reach + dx:reach + dx + w])
    return gb.mask & (near < gb.depth - jump)


def error_metrics(k_a, reference, mask):
    """Over geometry pixels only: RMSE = √mean((k - k_ref)²), bias = mean(k - k_ref), mean = mean(k)."""
    mask = np.asarray(mask, bool)
    if not mask.any():
        return {"rmse": float("nan"), "bias": float("nan"), "mean": float("nan"), "pixels": 0}
    d = np.asarray(k_a, np.float64)[mask] - np.asarray(reference, np.float64)[mask]
    return {"rmse": float(np.sqrt(np.mean(d * d))), "bias": float(np.mean(d)),
            "mean": float(np.mean(np.asarray(k_a, np.float64)[mask])), "pixels": int(mask.sum())}


def reference_noise(reference, samples, mask):
    """RMS standard error of a binary-visibility AO estimate with N cosine rays:
    σ = √(k(1 - k)/N) per pixel (REFERENCE.md §3), root-mean-square over the mask; max 0.5/√N."""
    k = np.clip(np.asarray(reference, np.float64)[np.asarray(mask, bool)], 0.0, 1.0)
    if k.size == 0:
        return 0.0
    return float(np.sqrt(np.mean(k * (1.0 - k) / samples)))
