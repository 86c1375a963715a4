"""Cache of generated light-map layouts, so that a mesh is unwrapped once: in memory within a run (meshes with the
same geometry, linked duplicates) and on disk in the output folder (``<out>/.il-uv-cache/<digest hex>.uv``) for
reruns and resumed bakes.

The key is a digest of everything the layout depends on: per object its mesh (vertex positions, loops' vertices, faces'
first loops and corner counts: what the unwrappers see, and the loop order the UVs come back in), its evaluated mesh
(the modifiers' result; for a mesh only subdivided, ``blender.scene.subdivided_only``, the modifiers' settings instead,
and nothing more for one without modifiers, ``blender.scene.unmodified``,
which need no evaluation), the metric MᵀM of its world matrix (world area, hence the side chosen from a texel density;
the matrix itself for an atlas; both to 6 digits), the stretch its unwrap copy gets (:class:`unwrap_copy.Stretches`),
for a single mesh the UVs of its own layers (``uv.own_layers``: its layout may be their charts), and the layout
options (margin, resolution, texel density, maximum resolution, fixed sizes, atlas), :data:`LAYOUT_VERSION` and Blender's version (the unwrappers may change). An entry
is :data:`MAGIC`, a JSON head on one line (the side, margin and unwrapper, each object's loop count and the window the
layout was carried into: width, height and the side it was cut from; 0 0 0 for none), a newline, then each object's
UVs (little-endian float32, its loop order; one block for all, read at once: an eighth of the time of an npz's two
members); a file that cannot be read, or whose UVs do not match the meshes (count, finite values inside the unit
square), is ignored and rebuilt. Files are written (atomically) only after a map of the run is written,
never outside the output folder, named by the digest only; beyond :attr:`UVCache.MAX_BYTES` in all the least recently
used are removed.
"""
import contextlib
import dataclasses
import hashlib
import json
import os
import re

import bpy
import numpy as np

from ..blender.digest import rna_digest
from ..blender.scene import corner_vertices, face_sizes, face_starts, from_its_mesh, positions
from ..core.io.files import prune_least_recent, write_bytes
from .unwrap_copy import Stretches

LAYOUT_VERSION = 16
"""Raised whenever the layout search (uv.py, unwrap.py) changes what it makes for the same input."""
DIR = ".il-uv-cache"
MAGIC = b"IL light-map UVs 1\n"
SUFFIX = ".uv"
_SLACK = 1e-4
_ENTRY = re.compile(r"^[0-9a-f]{40}\.uv$")
_BEFORE = re.compile(r"^[0-9a-f]{40}\.npz$")
"""An entry of the format before MAGIC: never read, removed when a run writes an entry."""


@dataclasses.dataclass
class Entry:
    """A generated layout: per object its "Lightmap" UVs (flat float32, 2 per loop), the side it was made for,
    the margin in texels, the unwrapper, the side asked before it was enlarged (0: not enlarged), the window
    (width, height, side cut from) the layout was carried into (None: the square)."""
    uvs: list
    side: int
    margin: float
    unwrap: str
    enlarged_from: int = 0
    window: tuple = None
    corners: tuple = None
    """Per object, :func:`corner_digest` of its mesh's corners in the order the UVs follow: the order the bake held
    them in, which the key hashes. A mesh whose normals the bake flips (inside out: ``SavedState.flip_normals``) has
    them reversed then (:func:`flip_order`), so :func:`file_layout` matches the file's mesh against both orders.
    None in entries written before it."""


def flip_order(me):
    """The corner permutation of ``mesh.flip_normals()`` on mesh ``me``: each face's first corner kept, the rest
    reversed (its own inverse)."""
    starts = face_starts(me)
    sizes = face_sizes(me, starts)
    first = np.repeat(starts, sizes)
    k = np.arange(len(first)) - first
    return np.where(k == 0, first, first + np.repeat(sizes, sizes) - k)


def flip_corners(me, uv):
    """``uv`` (flat, 2 per corner of mesh ``me``) with each face's corners in the order ``mesh.flip_normals()`` gives
    them. The same call turns them back."""
    return np.asarray(uv).reshape(-1, 2)[flip_order(me)].ravel()


def corner_digest(vertices):
    """Hex digest of a mesh's corner vertex indices in the given order."""
    return hashlib.blake2b(np.asarray(vertices, np.int64).tobytes(), digest_size=16).hexdigest()


def corners_of(meshes):
    """:attr:`Entry.corners` of ``meshes`` as they are now."""
    return tuple(corner_digest(corner_vertices(me)) for me in meshes)


def _arrays(me):
    starts = face_starts(me)
    return positions(me), corner_vertices(me), starts, face_sizes(me, starts)


def key(objects, depsgraph, options, together=False, linears=None):
    """Hex digest of the layout of ``objects`` made with ``options`` and the stretches ``linears`` of their unwrap
    copies (:meth:`unwrap_copy.Stretches.of`; see the module docstring)."""
    h = hashlib.blake2b(digest_size=20)
    h.update(repr((LAYOUT_VERSION, tuple(bpy.app.version), float(options.margin), options.texel_density,
                   int(options.resolution), int(options.max_resolution), bool(together))).encode())
    for o, lin in zip(objects, linears or [None] * len(objects)):
        sizes = options.sizes.get(o.name) if options.sizes else None
        m = np.array(o.matrix_world, float)[:3, :3]
        h.update(repr((tuple(sizes) if sizes else None, _rounded(m if together else m.T @ m),
                       None if lin is None else (_rounded(lin), tuple(f"{v:.4g}" for v in np.linalg.eigvalsh(lin))))
                      ).encode())
        if from_its_mesh(o):            # the mesh and the settings give the evaluated mesh: it is not read
            meshes = (o.data,)
            for mod in o.modifiers:
                if mod.show_viewport or mod.show_render:
                    rna_digest(h, mod)
        else:
            meshes = (o.data, o.evaluated_get(depsgraph).data)
        for me in meshes:
            for a in _arrays(me):
                h.update(np.int64(a.size).tobytes())
                h.update(a.tobytes())
        if not together:                  # a single mesh's layout may be its own layers' charts
            from .uv import own_uvs
            h.update(own_uvs(o.data))
    return h.hexdigest()


def _rounded(a):
    """``a`` to 6 digits of its largest entry (a rotation's float32 round-off in MᵀM is below that)."""
    scale = float(np.abs(a).max()) or 1.0
    return f"{scale:.6g}", tuple(float(x) for x in np.round(a / scale, 6).ravel() + 0.0)


class UVCache:
    """Layouts by :func:`key`: ``memory`` for this run, ``folder`` (None: memory only) across runs. Entries beyond
    MAX_BYTES in all are removed when a run writes one, the least recently written or read first, never one the
    run wrote or read."""

    MAX_BYTES = 1 << 30

    def __init__(self, folder=None):
        self.folder = folder
        self.memory, self.pending = {}, {}
        self.used = set()     # entry files this run read or wrote
        self.settled = {}     # mesh pointer -> the layout (uv._Made, None: a layer reused) this run gave the mesh
        self.stretches = Stretches()      # the unwrap copies' stretches in this run

    def path(self, digest):
        return os.path.join(self.folder, f"{digest}{SUFFIX}")

    def get(self, digest, meshes):
        """The :class:`Entry` of ``digest`` whose UVs fit ``meshes`` (one per object), or None."""
        entry = self.memory.get(digest)
        if entry is None and self.folder is not None:
            entry = _read(self.path(digest))
            if entry is not None:
                self.used.add(self.path(digest))
                with contextlib.suppress(OSError):
                    os.utime(self.path(digest))             # read now: the most recently used
        if entry is None or not _fits(entry, meshes):
            return None
        self.memory[digest] = entry
        return entry

    def put(self, digest, entry):
        """Keep ``entry`` under ``digest``, written by :meth:`flush` unless the folder holds it already."""
        held = self.folder is not None and digest not in self.pending and _same(self._held(digest), entry)
        self.memory[digest] = entry
        if self.folder is None:
            return
        if held:
            self.used.add(self.path(digest))
            with contextlib.suppress(OSError):
                os.utime(self.path(digest))             # used now: the most recently used
            return
        self.pending[digest] = entry

    def _held(self, digest):
        """The entry the folder holds under ``digest`` (as this run read or wrote it, else as on disk), or None."""
        path = self.path(digest)
        return self.memory.get(digest) if path in self.used else _read(path)

    def flush(self):
        """Write the entries made since the last flush (a failed write is dropped: the cache is an optimisation), then
        remove the entries beyond MAX_BYTES."""
        if not self.pending:
            return
        while self.pending:
            digest, entry = self.pending.popitem()
            head = {"side": int(entry.side), "margin": float(entry.margin), "unwrap": entry.unwrap,
                    "enlarged_from": int(entry.enlarged_from), "window": list(entry.window or (0, 0, 0)),
                    "loops": [len(uv) // 2 for uv in entry.uvs]}
            if entry.corners:
                head["corners"] = list(entry.corners)
            uv = np.concatenate([np.asarray(uv, "<f4") for uv in entry.uvs] or [np.zeros(0, "<f4")])
            try:
                write_bytes(self.path(digest), MAGIC + json.dumps(head).encode() + b"\n" + uv.tobytes())
                self.used.add(self.path(digest))
            except OSError:
                pass
        self._prune()

    def _prune(self):
        try:
            names = os.listdir(self.folder)
        except OSError:
            return
        for name in filter(_BEFORE.match, names):
            with contextlib.suppress(OSError):
                os.remove(os.path.join(self.folder, name))
        prune_least_recent([os.path.join(self.folder, n) for n in names if _ENTRY.match(n)], self.used,
                           max_bytes=self.MAX_BYTES)


def cached_entry(folder, ref):
    """The path of the UV cache entry ``ref`` = [key, index] (a report entry's "uv_cache") names in output folder
    ``folder`` when it is there, else None (``ref`` comes from a file: it names an entry of the cache or nothing)."""
    if not (isinstance(ref, list) and len(ref) == 2 and isinstance(ref[0], str) and re.fullmatch("[0-9a-f]{40}", ref[0])
            and type(ref[1]) is int):
        return None
    path = os.path.join(folder, DIR, ref[0] + SUFFIX)
    return path if os.path.isfile(path) else None


def layout_of(folder, ref, loops):
    """The UVs (flat float32, 2 per loop) of one object of a layout in the UV cache of output folder ``folder``: the
    entry :func:`cached_entry` finds, holding ``loops`` finite UVs in the unit square for object ``ref[1]``; None
    otherwise. On the corners in the order the bake held them (:attr:`Entry.corners`): :func:`file_layout` for a
    mesh of the file."""
    return _entry_uv(folder, ref, loops)[0]


def file_layout(folder, ref, obj, scene):
    """:func:`layout_of` with its UVs on ``obj``'s corners as the file holds them now (what Export and Preview write
    into the file's mesh): as stored when the entry's :attr:`Entry.corners` are the mesh's, turned by
    :func:`flip_corners` when they are the mesh's flipped (the bake turned it outward; the file's is still inside
    out), None when neither (edited since). An entry written before ``corners`` is turned when the bake would flip
    the mesh now (``orientation.check``: every closed part inside out)."""
    uv, corners = _entry_uv(folder, ref, len(obj.data.loops))
    if uv is None:
        return None
    me = obj.data
    if corners is None:
        from .orientation import empty_inward_shells
        return flip_corners(me, uv) if empty_inward_shells(scene, obj)[0] == 1.0 else uv
    now = corner_vertices(me)
    if corner_digest(now) == corners[ref[1]]:
        return uv
    return flip_corners(me, uv) if corner_digest(now[flip_order(me)]) == corners[ref[1]] else None


def _entry_uv(folder, ref, loops):
    path = cached_entry(folder, ref)
    entry = _read(path) if path else None
    if entry is None or not 0 <= ref[1] < len(entry.uvs) or not _uv_fits(entry.uvs[ref[1]], loops):
        return None, None
    return entry.uvs[ref[1]], entry.corners


def _read(path):
    try:
        with open(path, "rb") as f:
            data = f.read()
        if not data.startswith(MAGIC):
            return None
        line = data.index(b"\n", len(MAGIC))
        head = json.loads(data[len(MAGIC):line])
        flat = np.frombuffer(data, "<f4", offset=line + 1).astype(np.float32)
        ends = np.cumsum([2 * int(n) for n in head["loops"]])
        if len(ends) and ends[-1] != len(flat) or not len(ends) and len(flat):
            return None
        window = tuple(int(x) for x in head["window"])
        return Entry(np.split(flat, ends[:-1]) if len(ends) else [], int(head["side"]), float(head["margin"]),
                     str(head["unwrap"]), int(head["enlarged_from"]), window if all(window) else None,
                     _corners(head.get("corners"), len(ends)))
    except Exception:      # missing, truncated, not an entry, a field missing or of another kind: rebuilt
        return None


def _corners(value, objects):
    """The head's "corners" (one hex digest per object), or None when absent or not that."""
    if not isinstance(value, list) or len(value) != objects or not all(isinstance(v, str) for v in value):
        return None
    return tuple(value)


def _same(a, b):
    """Entries ``a`` and ``b`` hold the same layout (fields and UVs); False for None."""
    if a is None or b is None:
        return False
    fields = lambda e: (e.side, e.margin, e.unwrap, e.enlarged_from, tuple(e.window or ()), e.corners)
    return (fields(a) == fields(b) and len(a.uvs) == len(b.uvs)
            and all(np.array_equal(x, y) for x, y in zip(a.uvs, b.uvs)))


def _fits(entry, meshes):
    """The entry's arrays match the meshes: one float32 array of 2 × loops finite UVs in the unit square each,
    a positive side and margin, a window (if any) of three positive sides no wider than the side it was cut from."""
    from .unwrap import UNWRAPPERS
    if len(entry.uvs) != len(meshes) or entry.side < 1 or not entry.margin > 0 or entry.unwrap not in UNWRAPPERS:
        return False
    if entry.window is not None and (len(entry.window) != 3 or min(entry.window) < 1
                                     or max(entry.window[:2]) > entry.window[2]):
        return False
    return all(_uv_fits(uv, len(me.loops)) for uv, me in zip(entry.uvs, meshes))


def _uv_fits(uv, loops):
    """``uv`` is float32, 2 × ``loops`` finite UVs inside the unit square (to _SLACK)."""
    return (uv.dtype == np.float32 and uv.shape == (2 * int(loops),) and bool(np.isfinite(uv).all())
            and not (len(uv) and (uv.min() < -_SLACK or uv.max() > 1 + _SLACK)))
