"""core.radiosity.parallel: chunks on two threads, in order, bounded, stoppable."""
import threading

import numpy as np

from addon.core.radiosity import form_factors, parallel, patches as rad_patches, subdivision, visibility
from addon.core import analytic


def test_ordered_map_yields_in_order_and_stops_early():
    started = []
    lock = threading.Lock()

    def fn(x):
        with lock:
            started.append(x)
        return np.full(1000, x).sum()              # numpy work (the GIL released)
    assert list(parallel.ordered_map(fn, range(50), workers=2)) == [1000 * x for x in range(50)]
    started.clear()
    for k, _ in enumerate(parallel.ordered_map(fn, range(1000), workers=2)):
        if k == 3:
            break
    assert len(started) <= 4 + 2 * 2                # at most 2 workers' worth ahead of the consumer


def test_threaded_form_factors_and_visibility_equal_one_thread(monkeypatch):
    base = rad_patches.patches_from_meshes(analytic.cornell_box())
    p = subdivision.subdivide_to_size(base, 0.2)
    out = {}
    for workers in (1, 2):
        monkeypatch.setattr(parallel, "WORKERS", workers)
        V = visibility.visibility_faces(p, visibility.occluders(base, p), leaf=8)
        out[workers] = V, form_factors.visible_form_factors(p, V, chunk_pairs=5000)
    assert np.array_equal(out[1][0], out[2][0]) and 0 < out[1][0].sum() < out[1][0].size
    assert np.array_equal(out[1][1], out[2][1])
