"""Samples of one map: the Cycles calls of a bake (halves, passes), their sums, target-error pairs, the error
estimate, denoising. numpy only: the calls themselves are a ``once(samples, seed) -> (values, mask)``."""
import dataclasses
import math

import numpy as np

from ..core import errors, lightmap
from . import cost
from .kinds import KINDS


ESTIMATES = {
    "binomial": "binomial bound: sqrt(mean k_A(1 - k_A)/N) per texel; Cycles' stratified sampler "
                "stays below it",
    "halves": "measured: RMS of the difference of two independent half bakes, halved",
    "pilots": "measured: pairs of independent bakes (a pilot first), each pair's error from its halves' "
              "difference, inverse-variance combined",
    "none": "not estimated: a single sample of a non-binary quantity",
}


ALPHA = 0.7        # err ∝ N^-α of Cycles' AO and irradiance bakes (measured; stratified sampling of a 2-D


MAX_PAIRS = 4      # pairs of bakes target_error may spend (pilot included)


DENOISED = "; noise of the map before denoising: the denoised map's error is lower (measured) but not estimated"


@dataclasses.dataclass
class BakeResult:
    """One baked map of one object group, in Blender's pixel order (row 0 at v = 0).

    values          (H, W) k_A or (H, W, 3) E in W/m² for images; {object: (V,) or (V, 3)} for vertices
    mask            (H, W) bool covered texels (images) / None (vertices)
    samples         total Cycles samples per texel (pilots included); pilot_samples: the pilots' share
    seconds         the whole map (bakes, read-back, denoising); cycles_seconds: inside the Cycles bake calls
    estimated_error RMS over covered texels, same units as values (NaN when not estimated)
    estimate        which estimate ``estimated_error`` is (one of ESTIMATES, plus DENOISED when denoised)
    capped          a target error missed within max_samples / MAX_PAIRS (:func:`warn_capped`)
    unlit           the warning line of a lit kind's map 0 everywhere (``write.check_lit``), else ""
    """
    values: object
    mask: object
    samples: int
    seconds: float
    estimated_error: float
    estimate: str
    pilot_samples: int = 0
    cycles_seconds: float = 0.0
    capped: bool = False
    unlit: str = ""


def fixed_calls(kind, options):
    """[(samples, seed)] of the Cycles calls of a fixed-sample map: two independent halves for a kind baked in
    ``halves`` (irradiance: its error is measured from their difference), one call otherwise."""
    n = int(options.samples)
    if KINDS[kind].halves and n >= 2:
        return [(n // 2, int(options.seed)), (n - n // 2, int(options.seed) + 1)]
    return [(n, int(options.seed))]


SEED_STRIDE = 2 * MAX_PAIRS
"""Seeds of the passes of one bake step by this: a map's bakes have seeds seed .. seed + 2 MAX_PAIRS - 1."""


def sample_passes(kind, samples, seed, texels, pace=None):
    """[(samples, seed)] of the Cycles calls of one bake of ``samples`` at ``seed`` over ``texels`` texels: that
    one call when it fits cost.PASS_SECONDS (:func:`cost.seconds`, as the progress line), else near-equal sample
    passes of at most :func:`cost.pass_samples`, seeds seed + j SEED_STRIDE, whose sample-weighted mean
    (:class:`PassSum`) is the bake; Ctrl-C (deferred inside a call) stops between them. ``pace``: the scene's
    :class:`cost.Speed`."""
    samples, seed = int(samples), int(seed)
    most = cost.pass_samples(texels, kind, pace)
    if samples <= most:
        return [(samples, seed)]
    k = -(-samples // most)
    return [(samples // k + (j < samples % k), (seed + j * SEED_STRIDE) % 2 ** 31) for j in range(k)]


class PassSum:
    """The sample-weighted mean of the passes of one bake of ``samples``, summed as they come (one pass's values
    held at a time); a single pass comes back as it is, and the mask is the first pass's."""

    def __init__(self, samples):
        self.samples, self.sum, self.mask, self.single = int(samples), None, None, None

    def add(self, values, mask, samples):
        if self.sum is None and self.single is None and samples == self.samples:
            self.single = values, mask
            return
        w = samples / self.samples
        if isinstance(values, dict):
            self.sum = {k: (self.sum[k] if self.sum else 0.0) + np.asarray(v, np.float64) * w for k, v in values.items()}
        elif self.sum is None:
            self.sum, self.mask = values.astype(np.float64) * w, mask
        else:
            self.sum += values * w

    def result(self):
        """(values, mask) of the whole bake."""
        if self.single is not None:
            return self.single
        return (self.sum if isinstance(self.sum, dict) else self.sum.astype(np.float32)), self.mask


def estimated(kind, options, parts):
    """(values, mask, samples, estimated error, estimate) of a fixed-sample map from its calls' (values, mask)
    (:func:`fixed_calls`): halves combined, error from their difference; else the kind's single-bake ``variance``
    (AO: the binomial bound), or not estimated."""
    n = int(options.samples)
    if len(parts) == 2:
        h = n // 2
        (a, mask), (b, _) = parts
        var = lightmap.per_sample_variance_pair(flat(a), flat(b), h, n - h, _flat_mask(mask, a))
        return _combine([a, b], [h, n - h]), mask, n, lightmap.expected_error(var, n), ESTIMATES["halves"]
    values, mask = parts[0]
    record = KINDS[kind]
    if record.variance is None:
        return values, mask, n, float("nan"), ESTIMATES[record.estimate]
    var = record.variance(flat(values), _flat_mask(mask, values))
    return values, mask, n, lightmap.expected_error(var, n), ESTIMATES[record.estimate]


def denoised(values, mask, kind, estimate):
    """(values, estimate) denoised: OIDN on the map (empty texels filled from the nearest covered one first),
    clipped to the kind's value_range (the denoiser's overshoot at edges put k_A above 1: Sponza's floors, 1,320 of
    4,940 texels, up to 1.022), the estimate + DENOISED; a kind the denoiser does not apply to (``denoise``
    False: signed SH coefficients) comes back as it is, with a warning."""
    if not KINDS[kind].denoise:
        errors.warn(f"denoise ignored for {kind} maps: the denoiser takes colours, not signed coefficients")
        return values, estimate
    return _denoise(values, mask, kind), estimate + DENOISED


def _denoise(values, mask, kind):
    filled, _ = lightmap.nearest_fill(values, mask)
    from .denoise import denoise
    lo, hi = KINDS[kind].value_range
    smooth = np.clip(denoise(filled), lo, hi)
    return np.where((mask[..., None] if values.ndim == 3 else mask), smooth, 0.0).astype(np.float32)


def bake_to_error(once, options):
    """Bake pairs until the RMS error meets ``options.target_error``; return (values, mask, samples, pilot, error).

    Every bake is one of a pair of independent bakes (different seeds) with the same samples; the RMS
    error of a pair's mean is measured from the difference of its halves
    (:func:`lightmap.per_sample_variance_pair`), and all pairs are combined with inverse-variance weights
    (:func:`lightmap.inverse_variance_weights`, 1/e² = Σ 1/e_i²), so the reported error is measured.
    The pilot pair has pilot_samples / 2 samples per bake; each next pair gets the samples predicted to
    bring the combination to the target, from err ∝ N^-α: α = ALPHA for the first prediction, then α
    measured between the last two pairs (:func:`lightmap.convergence_exponent`), rounded to the nearest
    power of two (Cycles' tabulated Sobol sequence is stratified best there: measured 16 samples beat 19,
    32 beat 28). Assuming independent samples (α = 1/2, N = σ²/E²) would bake several times too many
    samples with Cycles' stratified sampler.
    Up to MAX_PAIRS pairs and max_samples samples in all.
    """
    target = float(options.target_error)
    per, errors, parts, seed, mask = [], [], [], int(options.seed), None
    total = 0
    m = max(1, int(options.pilot_samples) // 2)
    while True:
        (a, mask_a), (b, _) = once(m, seed), once(m, seed + 1)
        seed, total = seed + 2, total + 2 * m
        mask = mask_a if mask is None else mask
        var = lightmap.per_sample_variance_pair(flat(a), flat(b), m, m, _flat_mask(mask, a))
        per.append(m)
        parts.append(_combine([a, b], [1, 1]))
        errors.append(lightmap.expected_error(var, 2 * m))
        weights, err = lightmap.inverse_variance_weights(errors)
        left = int(options.max_samples) - total
        if err <= target or len(per) == MAX_PAIRS or left < 2:
            break
        wanted = 1.0 / math.sqrt(1.0 / target ** 2 - 1.0 / err ** 2)     # error the next pair must reach
        alpha = ALPHA if len(per) == 1 else lightmap.convergence_exponent(errors[-2], per[-2], errors[-1], per[-1])
        m = lightmap.samples_for_error(errors[-1], per[-1], wanted, alpha, minimum=1, maximum=left // 2)
        m = min(2 ** round(math.log2(m)), left // 2)      # Cycles' Sobol sampler is best at powers of two
    return _combine(parts, weights), mask, total, 2 * per[0], err


def warn_capped(group, kind, samples, error, options):
    """True, with a warning naming the samples spent and the error reached, when the bake stopped at its sample
    bound (max_samples, MAX_PAIRS pairs) above ``options.target_error``."""
    if not error > float(options.target_error):
        return False
    errors.warn(f"'{group[0].name}' {kind}: target error {float(options.target_error):g} not reached: capped at "
                f"{samples} samples (at most {int(options.max_samples)} in {MAX_PAIRS} pairs of bakes), error "
                f"reached {error:.3g}")
    return True


def flat(values):
    if isinstance(values, dict):
        return np.concatenate([np.asarray(v, float).reshape(len(v), -1) for v in values.values()])
    return values


def _flat_mask(mask, values):
    if isinstance(values, dict):
        return np.ones(sum(len(v) for v in values.values()), bool)
    return mask


def _combine(parts, weights):
    """Weighted mean of independent bakes (image arrays or {object: vertex values})."""
    if isinstance(parts[0], dict):
        return {k: lightmap.combine([p[k] for p in parts], weights) for k in parts[0]}
    return lightmap.combine(parts, weights).astype(np.float32)
