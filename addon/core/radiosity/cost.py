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
# Seconds of a solve of N patches (after the subdivision near emitters), an upper bound calibrated against the
# report's per-phase timings (scripts/radiosity.py --no-compare) on the 2 cores shared with other jobs, where
# the same solve takes 2-3 times what it takes on a quiet machine (docs/envmap-radiosity.md): 1,156 patches
# (built-in box) 2.2 s; 1,453 and 3,172 (imported box) 4.9 and 11.5 s, of which near emitters, near field and
# texel gather 3.9 and 9.3 s (2.9 ms a patch); 8,512 (built-in) 24.9 s, of which visibility and form factors
# 15.2 s (2.1e-7 s a pair), the Jacobi sweeps 3.0 s and the texel gather 2.2 s. The BVH path casts a ray a
# pair (4.7 µs measured on the candidates).
SECONDS_FIXED = 1.5
SECONDS_PER_PATCH = 2.5e-3
SECONDS_PER_PAIR = 2.5e-7
SECONDS_PER_PAIR_BVH = 4e-6
# The solvers beyond Jacobi's sweeps (a Gauss-Seidel sweep is a row loop, a progressive shot costs a few
# N-vectors): Gauss-Seidel 10-12 sweeps, 0.29 s at 1,156 patches; progressive refinement 6-9 N shots, 3.5 s at
# 1,156 patches, 18 s at 8,479 (quiet machine).
SOLVER_SECONDS_PER_PATCH = {"jacobi": 0.0, "gauss_seidel": 2.5e-4, "progressive": 3e-3}
SOLVER_SECONDS_PER_PAIR = {"jacobi": 0.0, "gauss_seidel": 3e-8, "progressive": 2e-7}
# The near field (:class:`core.radiosity.gather.NearField`): element form factors of the near pairs, stored as
# float32 (4 B each); made in chunks below NEAR_PEAK_BYTES. Measured: 1,190 a patch on the imported Cornell box
# (1,453 patches, the light's back in 8 x 8 elements), 590 on the built-in one (1,156), 300 on the corpus'
# emissive.blend (4,094).
NEAR_EVALS_PER_PATCH = 3000
MAX_SECONDS = 3600.0


@dataclass
class Cost:
    """Estimated size of a solve: patches, peak bytes, seconds."""
    patches: float
    bytes: float
    seconds: float


def solver_seconds(n, solver="jacobi"):
    """Seconds ``solver`` takes beyond a Jacobi solve (SOLVER_SECONDS_PER_PATCH, SOLVER_SECONDS_PER_PAIR)."""
    n = float(n)
    return SOLVER_SECONDS_PER_PATCH[solver] * n + SOLVER_SECONDS_PER_PAIR[solver] * n * n


def solve_cost(n, seconds_per_pair=None, solver="jacobi", compare_solvers=False):
    """:class:`Cost` of solving ``n`` patches (an upper bound): N² form factors and visibility, the near field's
    bounded work (NEAR_EVALS_PER_PATCH element form factors a patch, kept; NEAR_PEAK_BYTES at most while made),
    ``solver``, and with ``compare_solvers`` the other solvers of the convergence chart on the same F."""
    n = float(n)
    per = SECONDS_PER_PAIR if seconds_per_pair is None else seconds_per_pair
    extra = sum(solver_seconds(n, s) for s in SOLVER_SECONDS_PER_PAIR if compare_solvers or s == solver)
    return Cost(n, BYTES_PER_PAIR * n * n + OVERHEAD_BYTES + NEAR_PEAK_BYTES + 4 * NEAR_EVALS_PER_PATCH * n,
                SECONDS_FIXED + SECONDS_PER_PATCH * n + per * n * n + extra)


def adaptive_cost(patches, max_edge, adaptive=0, seconds_per_pair=None, solver="jacobi", compare_solvers=False):
    """:class:`Cost` of a solve and its ``adaptive`` rounds at their worst case
    (:func:`core.radiosity.subdivision.planned_patches_per_round`): patches of the last round, seconds summed over
    the rounds, bytes of the largest round beside the previous round's form factors (as each round is checked)."""
    ns = planned_patches_per_round(patches, max_edge, adaptive)
    costs = [solve_cost(n, seconds_per_pair, solver, compare_solvers and i == len(ns) - 1) for i, n in enumerate(ns)]
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
               adaptive=0, solver="jacobi", compare_solvers=False):
    """Estimate the solve of ``patches`` split to ``max_edge`` (an upper bound: :func:`core.radiosity.subdivision.planned_patches`) and
    refuse (InputError, one line naming the
    limit and the smallest edge that fits) what needs more than ``memory`` bytes (default: the memory
    a job may plan to use, core.budget) or more than ``max_seconds``. With ``adaptive`` rounds the estimate is
    their worst case (:func:`adaptive_cost`) and the refusal names the largest --adaptive that fits at this edge
    and the smallest edge that fits with these rounds. Returns the :class:`Cost`."""
    memory = memory_budget() if memory is None else memory
    per = SECONDS_PER_PAIR if seconds_per_pair is None else seconds_per_pair
    adaptive = int(adaptive)
    cost = adaptive_cost(patches, max_edge, adaptive, per, solver, compare_solvers)
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
