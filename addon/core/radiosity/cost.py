"""Cost of a solve: refuse what cannot finish before allocating anything (patch count, memory, seconds)."""
from dataclasses import dataclass

import numpy as np

from ..budget import memory_budget
from ..errors import InputError
from ..budget import format_bytes, format_count, format_seconds
from .form_factors import NEAR_PEAK_BYTES
from .patches import longest_edge
from .subdivision import MAX_LEVELS, planned_patches_per_round


# Peak memory of a solve with N patches, per patch pair: measured with tracemalloc on the Cornell box at
# N = 7104: form factors with the visibility matrix alive 21.3 B (F float64, V bool and their temporaries),
# near pairs beside F 11.6 B (found block by block), a solve 8.0 B, the emitter split mask 8.8 B; plus bounded
# chunks. Rounded up. F is float32 since (4 B a pair less) and the near pairs are found cluster by cluster: an
# upper bound now, not remeasured.
BYTES_PER_PAIR = 24.0
OVERHEAD_BYTES = 600e6                  # Blender, numpy and the chunked temporaries
# Seconds per patch pair (visibility + form factor + the three solvers of the convergence chart), measured on
# the 2-core reference machine by scripts/bench_radiosity.py (docs/envmap-radiosity.md): with the face test
# (core.radiosity.visibility.visibility_faces) and the visible pairs' form factors once, and with a BVH ray a
# pair (scenes with more blocking faces than lab.radiosity.MAX_OCCLUDERS). Measured: the solve 0.23 CPU-µs a
# pair (15,331 patches, 53.6 s including the near field; 0.15 since the culled face test and float32 F: 36.2 CPU
# s), the convergence chart's progressive solver about 0.8 µs a pair (3,216 patches, 8.5 s); the BVH path 4 µs a
# pair as before (a ray 4.7 µs on the candidates).
SECONDS_PER_PAIR = 1e-6
SECONDS_PER_PAIR_BVH = 4e-6
# The near field (:class:`core.radiosity.gather.NearField`): element form factors of the near pairs, stored as
# float32 (4 B each), a visibility ray per receiving texel and source; made in chunks below NEAR_PEAK_BYTES.
# Measured: 1,190 a patch on the imported Cornell box (1,453 patches, the light's back in 8 x 8 elements), 590 on
# the built-in one (1,156), 300 on the corpus' emissive.blend (4,094); about 1 µs each with the rays.
NEAR_EVALS_PER_PATCH = 3000
SECONDS_PER_NEAR_EVAL = 1e-6
MAX_SECONDS = 3600.0


@dataclass
class Cost:
    """Estimated size of a solve: patches, peak bytes, seconds."""
    patches: float
    bytes: float
    seconds: float


def solve_cost(n, seconds_per_pair=None):
    """:class:`Cost` of solving ``n`` patches: N² form factors and visibility, plus the near field's bounded
    work (NEAR_EVALS_PER_PATCH element form factors a patch, kept; NEAR_PEAK_BYTES at most while made)."""
    n = float(n)
    per = SECONDS_PER_PAIR if seconds_per_pair is None else seconds_per_pair
    return Cost(n, BYTES_PER_PAIR * n * n + OVERHEAD_BYTES + NEAR_PEAK_BYTES + 4 * NEAR_EVALS_PER_PATCH * n,
                per * n * n + SECONDS_PER_NEAR_EVAL * NEAR_EVALS_PER_PATCH * n)


def adaptive_cost(patches, max_edge, adaptive=0, seconds_per_pair=None):
    """:class:`Cost` of a solve and its ``adaptive`` rounds at their worst case
    (:func:`core.radiosity.subdivision.planned_patches_per_round`): patches of the last round, seconds summed over
    the rounds, bytes of the largest round beside the previous round's form factors (as each round is checked)."""
    ns = planned_patches_per_round(patches, max_edge, adaptive)
    costs = [solve_cost(n, seconds_per_pair) for n in ns]
    peak = max(c.bytes + (BYTES_PER_PAIR * ns[i - 1] ** 2 if i else 0.0) for i, c in enumerate(costs))
    return Cost(ns[-1], peak, sum(c.seconds for c in costs))


def smallest_edge_that_fits(patches, memory, max_seconds=MAX_SECONDS, seconds_per_pair=None, adaptive=0):
    """The smallest max_edge whose estimated solve (with ``adaptive`` rounds at their worst case) fits in
    ``memory`` bytes and ``max_seconds`` (None when even the unsplit faces do not fit)."""
    def fits(e):
        c = adaptive_cost(patches, e, adaptive, seconds_per_pair)
        return c.bytes <= memory and c.seconds <= max_seconds
    hi = float(longest_edge(patches.corners).max()) * 1.0000001
    if not fits(hi):
        return None
    lo = hi / 2 ** MAX_LEVELS
    if fits(lo):
        return lo
    for _ in range(60):
        mid = np.sqrt(lo * hi)
        lo, hi = (lo, mid) if fits(mid) else (mid, hi)
    return hi


def check_cost(patches, max_edge, memory=None, max_seconds=MAX_SECONDS, option="--max-edge", seconds_per_pair=None,
               adaptive=0):
    """Estimate the solve of ``patches`` split to ``max_edge`` (an upper bound: :func:`core.radiosity.subdivision.planned_patches`) and
    refuse (InputError, one line naming the
    limit and the smallest edge that fits) what needs more than ``memory`` bytes (default: the memory
    a job may plan to use, core.budget) or more than ``max_seconds``. With ``adaptive`` rounds the estimate is
    their worst case (:func:`adaptive_cost`) and the refusal names the largest --adaptive that fits at this edge
    and the smallest edge that fits with these rounds. Returns the :class:`Cost`."""
    memory = memory_budget() if memory is None else memory
    per = SECONDS_PER_PAIR if seconds_per_pair is None else seconds_per_pair
    adaptive = int(adaptive)
    cost = adaptive_cost(patches, max_edge, adaptive, per)
    over_mem = memory is not None and cost.bytes > memory
    over_time = max_seconds is not None and cost.seconds > max_seconds
    if not (over_mem or over_time):
        return cost
    mem = memory if memory is not None else float("inf")
    secs = max_seconds if max_seconds is not None else float("inf")
    best = smallest_edge_that_fits(patches, mem, secs, per, adaptive)
    limits = " and ".join(x for x in (f"{format_bytes(mem)} of usable memory" if memory is not None else "",
                                      f"{format_seconds(secs)} (at {per * 1e6:g} µs a patch pair)"
                                      if max_seconds is not None else "") if x)
    if adaptive:
        rounds = [a for a in range(adaptive) if (lambda c: c.bytes <= mem and c.seconds <= secs)(
            adaptive_cost(patches, max_edge, a, per))]
        largest = (f"the largest --adaptive that fits with {option} {max_edge:g} in {limits} is {rounds[-1]}"
                   if rounds else f"no --adaptive fits with {option} {max_edge:g} in {limits}")
        edge = (f"the smallest {option} that fits with --adaptive {adaptive} is {best:.2g}" if best is not None
                else f"no {option} fits with --adaptive {adaptive}")
        raise InputError(f"--adaptive {adaptive} with {option} {max_edge:g} gives up to ~{format_count(cost.patches)} "
                         f"patches (every adaptive round splitting every patch it may) needing "
                         f"{format_bytes(cost.bytes)} and about {format_seconds(cost.seconds)}; {largest}; {edge}")
    hint = (f"the smallest edge that fits in {limits} is {best:.2g}" if best is not None
            else f"even the unsplit faces do not fit in {limits}: simplify the scene")
    need = f"needing {format_bytes(cost.bytes)}" + (f" and about {format_seconds(cost.seconds)}" if over_time else "")
    raise InputError(f"{option} {max_edge:g} gives ~{format_count(cost.patches)} patches {need}; {hint}")
