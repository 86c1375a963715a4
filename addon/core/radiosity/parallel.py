"""Chunks of numpy work on both cores: numpy releases the GIL inside its loops, so two threads evaluating
independent chunks (form factors) run side by side."""
import collections
import os
from concurrent.futures import ThreadPoolExecutor

WORKERS = min(2, os.cpu_count() or 1)


def ordered_map(fn, items, workers=None):
    """fn(item) for every item, yielded in order, computed by up to ``workers`` threads (default WORKERS) at
    most 2 workers' worth of items ahead of the consumer (bounded memory). Leaving the loop early (an
    exception, Ctrl-C) cancels the items not started and waits only for the running ones."""
    workers = WORKERS if workers is None else workers
    items = iter(items)
    if workers < 2:
        for x in items:
            yield fn(x)
        return
    ex = ThreadPoolExecutor(workers)
    try:
        pending = collections.deque(ex.submit(fn, x) for _, x in zip(range(2 * workers), items))
        while pending:
            r = pending.popleft().result()
            for x in items:
                pending.append(ex.submit(fn, x))
                break
            yield r
    finally:
        ex.shutdown(wait=True, cancel_futures=True)
