"""Solvers of the discrete radiosity equation (seed 004; Goral et al. 1984; Cohen et al. 1988):

    B_i = E_i + ρ_i Σ_j F_ij B_j

per colour channel: B_i radiosity (exitance, W/m²), E_i emitted exitance (π L_e
for a Lambertian emitter of radiance L_e), ρ_i diffuse albedo. The irradiance
arriving on patch i is H_i = Σ_j F_ij B_j (what a Cycles irradiance bake
measures: E = π × DIFFUSE bake, REFERENCE.md §1).
"""
import time
from dataclasses import dataclass

import numpy as np

from ..errors import InputError


@dataclass
class Solution:
    """B (N, 3) radiosity in W/m²; ``residuals``: relative residual |E + ρFB − B|/|E| after each iteration."""
    B: np.ndarray
    solver: str
    iterations: int
    residuals: list
    seconds: float
    converged: bool


PRODUCT_BLOCK_BYTES = 4_000_000     # rows of a float32 F multiplied while in cache


def product(F, B):
    """F B in float64; a float32 F (core.radiosity.form_factors.visible_form_factors' storage) is multiplied
    as float32, B rounded to it (relative 6e-8, far below any tolerance here): half the memory traffic, no
    float64 copy of F. With several columns, F is read once: a block of its rows (PRODUCT_BLOCK_BYTES, in
    cache) times each column in turn (a matrix-vector product each: about 2.5 times faster than one
    matrix-matrix product of 3 columns, which runs below the memory bandwidth)."""
    if F.dtype != np.float32:
        return F @ B
    B = np.asarray(B, np.float32)
    if B.ndim == 1 or B.shape[1] == 1:
        return (F @ B).astype(np.float64)
    cols = [np.ascontiguousarray(B[:, k]) for k in range(B.shape[1])]
    out = np.empty((len(F), B.shape[1]))
    rows = max(8, PRODUCT_BLOCK_BYTES // max(4 * F.shape[1], 1))
    for s in range(0, len(F), rows):
        blk = F[s:s + rows]
        for k, b in enumerate(cols):
            out[s:s + rows, k] = blk @ b
    return out


def residual(F, rho, E, B, FB=None):
    """Relative residual of the radiosity equation: ‖E + ρ ∘ (F B) − B‖ / ‖E‖ (``FB`` = F B if already known)."""
    FB = product(F, B) if FB is None else FB
    return float(np.linalg.norm(E + rho * FB - B) / max(np.linalg.norm(E), 1e-300))


def _check(F, rho, E):
    F = F if isinstance(F, np.ndarray) and F.dtype == np.float32 else np.asarray(F, np.float64)
    rho, E = (np.asarray(a, np.float64) for a in (rho, E))
    if F.ndim != 2 or F.shape[0] != F.shape[1] or E.shape != rho.shape or E.shape[0] != F.shape[0]:
        raise InputError(f"shapes do not match: F {F.shape}, rho {rho.shape}, E {E.shape}")
    if not np.any(E):
        raise InputError("nothing emits light: every E_i is 0")
    return F, rho, E


def solve_direct(F, rho, E):
    """B = (I − diag(ρ) F)⁻¹ E per channel (the reference answer)."""
    F, rho, E = _check(F, rho, E)
    t = time.perf_counter()
    n = len(F)
    B = np.stack([np.linalg.solve(np.eye(n) - rho[:, c, None] * F, E[:, c]) for c in range(E.shape[1])], axis=1)
    return Solution(B, "direct", 1, [residual(F, rho, E, B)], time.perf_counter() - t, True)


def solve_jacobi(F, rho, E, tol=1e-6, max_iter=10000, progress=None):
    """Jacobi: B^{k+1} = E + ρ ∘ (F B^k) from B⁰ = E; iteration k adds the k-th bounce. ``progress(sweep,
    residual)`` after each sweep."""
    F, rho, E = _check(F, rho, E)
    t = time.perf_counter()
    B, res = E.copy(), []
    FB = product(F, B)
    for k in range(1, max_iter + 1):
        B = E + rho * FB
        FB = product(F, B)                            # the residual's product is the next sweep's
        res.append(residual(F, rho, E, B, FB))
        if progress:
            progress(k, res[-1])
        if res[-1] < tol:
            break
    return Solution(B, "jacobi", len(res), res, time.perf_counter() - t, res[-1] < tol)


def solve_gauss_seidel(F, rho, E, tol=1e-6, max_iter=10000, progress=None):
    """Gauss-Seidel: one sweep updates every B_i in place, in order, with the newest B_j:

        B_i ← (E_i + ρ_i Σ_{j≠i} F_ij B_j) / (1 − ρ_i F_ii)

    i.e. (I − D − L) B^{k+1} = E + U B^k with ρF = L + D + U (strictly lower, diagonal,
    strictly upper); F_ii = 0 for flat patches. ``progress(sweep, residual)`` after each sweep.
    """
    F, rho, E = _check(F, rho, E)
    t = time.perf_counter()
    B, res = E.copy(), []
    diag = np.diag(F).copy()
    scale = rho / (1.0 - rho * diag[:, None])    # ρ_i / (1 − ρ_i F_ii), per channel
    base = E / (1.0 - rho * diag[:, None])
    for k in range(1, max_iter + 1):
        for i in range(len(F)):
            B[i] = base[i] + scale[i] * (F[i] @ B - diag[i] * B[i])
        res.append(residual(F, rho, E, B))
        if progress:
            progress(k, res[-1])
        if res[-1] < tol:
            break
    return Solution(B, "gauss_seidel", len(res), res, time.perf_counter() - t, res[-1] < tol)


def solve_progressive(F, rho, E, area, tol=1e-6, max_iter=None, record_every=None, progress=None):
    """Progressive refinement (Cohen et al. 1988): shoot the patch with the most unshot power ΔB_i A_i;
    every j receives ΔB_j += ρ_j F_ji ΔB_i. One iteration = one shot.

    Stops when the unshot power is below ``tol`` times the emitted power; the
    residual equals ‖ρ ∘ F ΔB‖/‖E‖, recorded every ``record_every`` shots (``progress(shots, residual)`` then).
    """
    F, rho, E = _check(F, rho, E)
    area = np.asarray(area, np.float64)
    t = time.perf_counter()
    n = len(F)
    max_iter = max_iter or 200 * n
    record_every = record_every or max(1, n // 10)
    B, dB = E.copy(), E.copy()
    total = float((E.sum(axis=1) * area).sum())
    power = dB.sum(axis=1) * area
    res, shots, done = [], 0, False
    nE = max(np.linalg.norm(E), 1e-300)
    for shots in range(1, max_iter + 1):
        i = int(np.argmax(power))
        shoot = dB[i].copy()
        gain = rho * (F[:, i, None] * shoot[None, :])
        B += gain
        dB += gain
        dB[i] = 0.0
        power = dB.sum(axis=1) * area
        if shots % record_every == 0 or power.sum() <= tol * total:
            res.append(float(np.linalg.norm(rho * product(F, dB)) / nE))
            if progress:
                progress(shots, res[-1])
        if power.sum() <= tol * total:
            done = True
            break
    return Solution(B, "progressive", shots, res, time.perf_counter() - t, done)


SOLVERS = ("jacobi", "gauss_seidel", "progressive")


def solve(F, rho, E, area, solver="jacobi", tol=1e-6, max_iter=None, progress=None):
    """Dispatch by name: jacobi, gauss_seidel, progressive (or direct); ``progress(iteration, residual)`` per
    sweep or per recorded block of shots."""
    if solver == "jacobi":
        return solve_jacobi(F, rho, E, tol, max_iter or 10000, progress)
    if solver == "gauss_seidel":
        return solve_gauss_seidel(F, rho, E, tol, max_iter or 10000, progress)
    if solver == "progressive":
        return solve_progressive(F, rho, E, area, tol, max_iter, progress=progress)
    if solver == "direct":
        return solve_direct(F, rho, E)
    raise InputError(f"unknown solver {solver!r}; choose from {', '.join(SOLVERS)}")


def irradiance(F, B):
    """Incident irradiance H_i = Σ_j F_ij B_j (W/m²): what a white Lambertian patch receives."""
    return product(F, B)
