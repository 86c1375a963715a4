"""Cost bounds: a job's estimated bytes and seconds checked before it starts (no bpy, no numpy).

``check(option, value, cost, lo)`` refuses a value whose ``cost(value) -> (bytes, seconds)`` does not
fit in :func:`memory_budget` bytes and :data:`MAX_SECONDS`, with one line naming the largest value
that fits (cost grows with the value). The per-unit figures each caller uses were measured on a
2-core machine (README "Limits"); they are upper estimates, not promises.
"""
import os

from .errors import InputError

#: Longest job a lab accepts (seconds of estimated work).
MAX_SECONDS = 2 * 3600.0
#: Share of the available memory a job may plan to use.
MEMORY_SHARE = 0.75


def available_bytes():
    """Memory available to a new allocation: MemAvailable (Linux), else physical memory, else 8 GiB."""
    try:
        with open("/proc/meminfo", encoding="ascii") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (AttributeError, OSError, ValueError):
        return 8 << 30


def memory_budget():
    """Bytes a job may plan to use: :data:`MEMORY_SHARE` of :func:`available_bytes`."""
    return int(MEMORY_SHARE * available_bytes())


def fits(cost, value, memory=None, seconds=MAX_SECONDS):
    """True when ``cost(value) = (bytes, seconds)`` is within ``memory`` (default: the budget) and ``seconds``."""
    need_b, need_s = cost(value)
    return need_b <= (memory_budget() if memory is None else memory) and need_s <= seconds


def largest(cost, lo, hi, memory=None, seconds=MAX_SECONDS):
    """The largest integer v in [lo, hi] that :func:`fits` (cost non-decreasing in v), or None."""
    memory = memory_budget() if memory is None else memory
    if hi < lo or not fits(cost, lo, memory, seconds):
        return None
    while lo < hi:
        mid = (lo + hi + 1) // 2
        if fits(cost, mid, memory, seconds):
            lo = mid
        else:
            hi = mid - 1
    return lo


def check(option, value, cost, lo=1, what="", multiple=1):
    """Raise InputError unless ``cost(value)`` fits; the message names the largest ``option`` that does
    (a multiple of ``multiple``, for options that must be even).

    ``what`` says what the other settings are ("at 128x128 pixels").
    """
    memory = memory_budget()
    need_b, need_s = cost(value)
    if need_b <= memory and need_s <= MAX_SECONDS:
        return value
    best = largest(cost, lo, int(value) - 1, memory)
    if best is not None:
        best -= best % multiple
        best = best if best >= lo else None
    if need_b > memory:
        reason = f"needs about {format_bytes(need_b)} of memory ({format_bytes(memory)} usable here)"
    else:
        reason = f"would take about {format_seconds(need_s)} (limit {format_seconds(MAX_SECONDS)})"
    hint = (f"the largest {option} that fits is {best}" if best is not None
            else f"no {option} fits: reduce the other sizes")
    raise InputError(f"{option} {value}{' ' + what if what else ''} {reason}: {hint}")


def format_bytes(n):
    """1536 -> '1.5 KiB'."""
    n = float(n)
    for unit in ("B", "KiB", "MiB", "GiB", "TiB", "PiB", "EiB"):
        if n < 1024 or unit == "EiB":
            return f"{n:.3g} {unit}"
        n /= 1024


def format_count(n):
    """2.1M style."""
    for unit, f in (("", 1), ("k", 1e3), ("M", 1e6), ("G", 1e9), ("T", 1e12)):
        if n < 1000 * f or unit == "T":
            return f"{n / f:.3g}{unit}"


def format_seconds(s):
    """90 -> '1.5 min'."""
    if s < 120:
        return f"{s:.3g} s"
    if s < 7200:
        return f"{s / 60:.3g} min"
    if s < 48 * 3600:
        return f"{s / 3600:.3g} h"
    return f"{s / 86400:.3g} days"
