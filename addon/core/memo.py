"""Results of costly pure functions of arrays, remembered for the process by a digest of their inputs.

A rerun of a bake in the same session (the UI, a benchmark) asks again for figures of layouts and meshes that did
not change: their overlap, seams, inward shells and chart counts. The key is the bytes, dtype and shape of every
input array (and the repr of the other inputs), so a changed input is a new key, never a stale result. Results
are returned as they were made: numpy arrays among them (in tuples, lists and dataclasses) are made read-only.
"""
import collections
import dataclasses
import hashlib

import numpy as np


def digest(*parts):
    """16-byte blake2b of ``parts``: arrays by dtype, shape and bytes, anything else by its repr."""
    h = hashlib.blake2b(digest_size=16)
    for p in parts:
        if isinstance(p, np.ndarray):
            a = np.ascontiguousarray(p)
            h.update(repr((a.dtype.str, a.shape)).encode())
            h.update(a.tobytes())
        else:
            h.update(repr(p).encode())
        h.update(b"|")
    return h.digest()


def _parts(value):
    if isinstance(value, (tuple, list)):
        return value
    if dataclasses.is_dataclass(value):
        return [getattr(value, f.name) for f in dataclasses.fields(value)]
    return ()


def _nbytes(value):
    if isinstance(value, np.ndarray):
        return value.nbytes
    return 64 + sum(_nbytes(v) for v in _parts(value))


def _frozen(value):
    if isinstance(value, np.ndarray):
        value.flags.writeable = False
    for v in _parts(value):
        _frozen(v)
    return value


class Memo:
    """At most ``kept`` results and ``max_bytes`` of arrays (the newest result is kept even when larger), least
    recently used dropped first."""

    def __init__(self, kept=1024, max_bytes=64 << 20):
        self.kept, self.max_bytes = kept, max_bytes
        self.items = collections.OrderedDict()
        self.bytes = 0

    def get(self, key, make):
        """The result remembered for ``key`` (a :func:`digest`), else ``make()`` remembered."""
        if key in self.items:
            self.items.move_to_end(key)
            return self.items[key]
        value = _frozen(make())
        self.items[key] = value
        self.bytes += _nbytes(value)
        while len(self.items) > 1 and (len(self.items) > self.kept or self.bytes > self.max_bytes):
            _, old = self.items.popitem(last=False)
            self.bytes -= _nbytes(old)
        return value

    def clear(self):
        self.items.clear()
        self.bytes = 0

    def call(self, fn, *args):
        """``fn(*args)``, remembered by ``fn``'s qualified name and a :func:`digest` of ``args``."""
        return self.get(digest(fn.__module__, fn.__qualname__, *args), lambda: fn(*args))


FIGURES = Memo()
"""The process's memo of figures the bake derives from meshes and layouts (overlap, seams, shells, charts)."""
