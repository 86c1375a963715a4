"""Results of costly pure functions of arrays, remembered for the process by a digest of their inputs, and on disk
beside a bake's maps (:class:`Store`).

A rerun of a bake asks again for figures of layouts and meshes that did not change: their overlap, seams, inward shells,
chart counts and the coverage masks of the layouts baked. The key is the bytes, dtype and shape of every input array
(and the repr of the other inputs), so a changed input is a new key, never a stale result. Results are returned as they
were made: numpy arrays among them (in tuples, lists and dataclasses) are made read-only.
"""
import collections
import contextlib
import dataclasses
import functools
import hashlib
import io
import json
import os
import re

import numpy as np

from .io.files import prune_least_recent, write_bytes


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

    store = None
    """A :class:`Store` while a bake keeps its figures on disk (:meth:`stored`), else None."""

    def get(self, key, make, stored=True):
        """The result remembered for ``key`` (a :func:`digest`), else the :attr:`store`'s, else ``make()``;
        remembered (in the store too unless ``stored`` is False)."""
        if key in self.items:
            self.items.move_to_end(key)
            if stored and self.store is not None:
                self.store.keep(key, self.items[key])     # made unstored first (a trial layout), now asked stored
            return self.items[key]
        value = self.store.get(key) if self.store is not None and stored else None
        if value is None:
            value = make()
            if self.store is not None and stored:
                self.store.add(key, value)
        value = _frozen(value)
        self.items[key] = value
        self.bytes += _nbytes(value)
        while len(self.items) > 1 and (len(self.items) > self.kept or self.bytes > self.max_bytes):
            _, old = self.items.popitem(last=False)
            self.bytes -= _nbytes(old)
        return value

    def clear(self):
        self.items.clear()
        self.bytes = 0

    def call(self, fn, *args, stored=True):
        """``fn(*args)``, remembered by ``fn``'s qualified name and a :func:`digest` of ``args`` (``stored``: also in
        the :attr:`store`)."""
        return self.get(digest(fn.__module__, fn.__qualname__, *args), lambda: fn(*args), stored)

    @contextlib.contextmanager
    def stored(self, folder):
        """A scope in which results are also looked up in, and added to, a :class:`Store` in ``folder``."""
        before, self.store = self.store, Store(folder)
        try:
            yield self.store
        finally:
            self.store.close()
            self.store = before


_STORABLE = {}


def storable(cls):
    """Class decorator: results of dataclass ``cls`` (fields of numbers and arrays) may be kept in a :class:`Store`."""
    _STORABLE[f"{cls.__module__}.{cls.__qualname__}"] = cls
    return cls


@functools.cache
def code_digest():
    """Digest of the add-on's Python sources and numpy's version: a stored figure is used only by the code that
    made it."""
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    h = hashlib.blake2b(np.__version__.encode(), digest_size=16)
    for folder, dirs, files in sorted(os.walk(root)):
        dirs.sort()
        for name in sorted(f for f in files if f.endswith(".py")):
            with open(os.path.join(folder, name), "rb") as f:
                h.update(name.encode() + b"|" + f.read())
    return h.digest()


def _encode(value, arrays):
    """A JSON-able description of ``value`` (numbers, strings, None, arrays, tuples, lists, :func:`storable`
    dataclasses), its arrays appended to ``arrays``; None when ``value`` holds anything else."""
    if isinstance(value, (np.ndarray, np.generic)):
        if np.asarray(value).dtype.kind not in "biuf":
            return None
        arrays.append(np.asarray(value))
        return {"a": len(arrays) - 1, "scalar": isinstance(value, np.generic)}
    if value is None or isinstance(value, (bool, int, str)):
        return {"v": value}
    if isinstance(value, float):
        return {"f": repr(value)}
    if isinstance(value, (tuple, list)):
        items = [_encode(v, arrays) for v in value]
        return None if None in items else {"t" if isinstance(value, tuple) else "l": items}
    name = f"{type(value).__module__}.{type(value).__qualname__}"
    if dataclasses.is_dataclass(value) and _STORABLE.get(name) is type(value):
        fields = [_encode(getattr(value, f.name), arrays) for f in dataclasses.fields(value)]
        return None if None in fields else {"d": name, "fields": fields}
    return None


def _decode(spec, arrays):
    if "v" in spec:
        return spec["v"]
    if "f" in spec:
        return float(spec["f"])
    if "a" in spec:
        a = arrays[spec["a"]]
        return a[()] if spec["scalar"] else a
    if "t" in spec or "l" in spec:
        items = [_decode(v, arrays) for v in spec.get("t", spec.get("l"))]
        return tuple(items) if "t" in spec else items
    return _STORABLE[spec["d"]](*(_decode(v, arrays) for v in spec["fields"]))


_PACK = re.compile(r"^[0-9a-f]{32}\.npz$")


class Store:
    """Figures kept in ``folder`` across processes: packs ``<digest of their keys>.npz`` of two arrays, ``index`` (JSON:
    each figure's spec and its arrays' offset, dtype and shape) and ``blob`` (their bytes, uncompressed: zlib level 1
    keeps a quarter of a level's batched triangles but inflates them at 300 MB/s, 0.1 s of a 207-object level's 2 s
    rerun outside Cycles; read once per pack, on its first use: one read instead of a zip member per array); numbers
    and arrays only, read back without pickle; a pack that cannot be read,
    or an entry that does not decode, is ignored and the figure made again. Keys are :func:`digest` s joined with
    :func:`code_digest`. The results added are written as one pack when the store closes, once a :meth:`flush` allowed
    it (a run writes its figures only after it wrote a map), or earlier when they pass PENDING_BYTES; then the packs
    beyond MAX_PACKS, and beyond MAX_BYTES in all (a 207-object level's triangles: 30 MB), are removed, the
    least recently written or read first, never one this store wrote or read."""

    MAX_PACKS = 64
    MAX_BYTES = 1 << 30
    PENDING_BYTES = 64 << 20

    def __init__(self, folder):
        self.folder = folder
        self.pending, self.pending_bytes = {}, 0
        self.allowed = False
        self.index = None            # hex key -> pack path
        self.open = {}               # pack path -> [np.lib.npyio.NpzFile, its blob once read]
        self.entries = {}            # pack path -> {hex key: [spec, [[offset, dtype, shape], ...]]}
        self.used = set()            # packs this store wrote or read

    def _key(self, key):
        return hashlib.blake2b(code_digest() + key, digest_size=16).hexdigest()

    def _packs(self):
        try:
            names = os.listdir(self.folder)
        except OSError:
            return []
        return [os.path.join(self.folder, n) for n in names if _PACK.match(n)]

    def _load(self):
        """Read the index of every pack in the folder, once (a pack that cannot be read is left out)."""
        if self.index is not None:
            return
        self.index = {}
        for path in self._packs():
            z = None
            try:
                z = np.load(path, allow_pickle=False)
                entries = json.loads(str(z["index"]))
                if not isinstance(entries, dict):
                    raise ValueError("a pack's index is not a mapping")
            except Exception:
                with contextlib.suppress(Exception):
                    z.close()
                continue
            self.open[path] = [z, None]
            self.index.update((k, path) for k in entries)
            self.entries[path] = entries

    def get(self, key):
        """The stored result of ``key``, or None."""
        self._load()
        k = self._key(key)
        path = self.index.get(k)
        if path is None:
            return None
        try:
            spec, refs = self.entries[path][k]
            value = _decode(spec, [self._array(path, *ref) for ref in refs])
        except Exception:
            return None
        self.used.add(path)
        return value

    def _array(self, path, offset, dtype, shape):
        """The array at ``offset`` of a pack's blob (read once per pack, on its first use)."""
        pack = self.open[path]
        if pack[1] is None:
            pack[1] = np.zeros(0, np.uint8)              # a blob that is not bytes holds no array
            blob = pack[0]["blob"]
            if blob.dtype != np.uint8 or blob.ndim != 1:
                raise ValueError("a pack's blob is not bytes")
            pack[1] = blob
        dtype = np.dtype(dtype)
        if dtype.kind not in "biuf":
            raise ValueError(f"not a figure's dtype: {dtype}")
        n = int(np.prod(shape, dtype=np.int64)) * dtype.itemsize
        data = pack[1][int(offset):int(offset) + n]
        if offset < 0 or len(data) != n:
            raise ValueError("an array past the end of its pack")
        return data.view(dtype).reshape(shape).copy()      # a copy: a small figure does not hold its pack's blob

    def keep(self, key, value):
        """:meth:`add` ``value`` unless the store holds ``key`` already (pending, or in a pack of the folder or one
        it wrote)."""
        self._load()
        k = self._key(key)
        if k not in self.pending and k not in self.index:
            self.add(key, value)

    def add(self, key, value):
        """Keep ``value`` for the next pack (nothing when it holds what a pack cannot)."""
        arrays = []
        spec = _encode(value, arrays)
        if spec is not None:
            self.pending[self._key(key)] = (spec, arrays)
            self.pending_bytes += sum(a.nbytes for a in arrays)
            if self.allowed and self.pending_bytes > self.PENDING_BYTES:
                self._write()

    def flush(self):
        """Allow the store to write its figures (a map of the run is written); those added so far are written when
        the store closes."""
        self.allowed = True

    def _write(self):
        """Write the pending results as one pack (a failed write is dropped: the store is an optimisation)."""
        if not self.pending:
            return
        self._load()                                   # the folder's packs before this one is written
        index, chunks, offset = {}, [], 0
        for k, (spec, arrays) in sorted(self.pending.items()):
            refs = []
            for a in arrays:
                a = np.asarray(a)                       # a 0-d array keeps its shape ()
                refs.append([offset, a.dtype.str, list(a.shape)])
                pad = -a.nbytes % 16                    # each array aligned in the blob
                chunks.append(a.tobytes() + bytes(pad))
                offset += a.nbytes + pad
            index[k] = [spec, refs]
        name = hashlib.blake2b("|".join(sorted(self.pending)).encode(), digest_size=16).hexdigest()
        path = os.path.join(self.folder, f"{name}.npz")
        blob = b"".join(chunks)
        buf = io.BytesIO()
        np.savez(buf, index=np.array(json.dumps(index)), blob=np.frombuffer(blob, np.uint8))
        self.pending, self.pending_bytes = {}, 0
        with contextlib.suppress(OSError):
            write_bytes(path, buf.getvalue())
            self.used.add(path)
        if path in self.open and self.open[path][0] is not None:
            self.open[path][0].close()                 # a pack of the same figures read before
        self.open[path], self.entries[path] = [None, np.frombuffer(blob, np.uint8)], index   # read back, not again
        self.index.update((k, path) for k in index)

    def _prune(self):
        for path in self.used:                       # read or written now: the most recently used
            with contextlib.suppress(OSError):
                os.utime(path)
        prune_least_recent(self._packs(), self.used, self.MAX_PACKS, self.MAX_BYTES)

    def close(self):
        """Write the pending results when allowed, prune, and close the packs read."""
        for z, _ in self.open.values():
            if z is not None:
                z.close()
        self.open, self.entries, self.index = {}, {}, None
        if self.allowed:
            self._write()
            self._prune()


FIGURES = Memo()
"""The process's memo of figures the bake derives from meshes and layouts (overlap, seams, shells, charts, coverage
masks)."""
