"""core.memo: a result is made once per input, a changed input (bytes, dtype or shape) is a new result, arrays come
back read-only and the least recently used results go first; a store on disk gives them to another process,
never unpickles, and drops what another version of the code made."""
import json
import os
import re

import numpy as np
import pytest

from addon.core import memo
from addon.core.memo import Memo, digest
from addon.core.seams import Seams


def test_a_result_is_made_once_per_input_and_again_for_any_change():
    made = []

    def area(tri, side):
        made.append(side)
        return np.full(3, tri.sum() * side)

    memo = Memo()
    tri = np.arange(6, dtype=np.float32).reshape(3, 2)
    first = memo.call(area, tri, 4)
    assert memo.call(area, tri.copy(), 4) is first and made == [4]
    with pytest.raises(ValueError):
        first[0] = 1.0
    memo.call(area, tri, 8)
    memo.call(area, tri.astype(np.float64), 4)
    memo.call(area, tri.reshape(2, 3), 4)
    changed = tri.copy()
    changed[0, 0] = np.nextafter(np.float32(0), np.float32(1))
    memo.call(area, changed, 4)
    assert made == [4, 8, 4, 4, 4]
    assert digest(tri, 4) != digest(tri, 4.0) and digest(tri, 4) == digest(tri.copy(), 4)


def test_the_least_recently_used_results_are_dropped_first():
    memo = Memo(kept=2, max_bytes=1 << 20)
    memo.get(b"a", lambda: 1)
    memo.get(b"b", lambda: 2)
    memo.get(b"a", lambda: 0)          # used again: b is now the oldest
    memo.get(b"c", lambda: 3)
    assert list(memo.items) == [b"a", b"c"]
    memo = Memo(kept=10, max_bytes=1000)
    memo.get(b"x", lambda: np.zeros(100))
    memo.get(b"y", lambda: np.zeros(100))
    assert list(memo.items) == [b"y"] and memo.bytes == 800



def _counted(made):
    def shells(co, k):
        made.append(k)
        return np.arange(len(co)) * k, float(k) / 3, [k, "k"]
    return shells


def _one_pack(folder, fn, *args):
    """(fn(*args), the pack a store in ``folder`` wrote for it, its index, its blob)."""
    writer = Memo()
    with writer.stored(folder) as store:
        result = writer.call(fn, *args)
        store.flush()
    (pack,) = folder.iterdir()
    with np.load(pack, allow_pickle=False) as z:
        return result, pack, json.loads(str(z["index"])), z["blob"]


def test_a_store_gives_another_process_the_same_figures(tmp_path, monkeypatch):
    made = []
    shells = _counted(made)
    co = np.ones((5, 3), np.float32)
    seams = Seams(np.zeros((2, 2, 2)), np.ones((2, 2, 2)), np.zeros((2, 2)), np.ones((2, 2)), creases=3)
    writer = Memo()
    with writer.stored(tmp_path) as store:
        first = writer.call(shells, co, 2)
        writer.get(b"seams", lambda: seams)
        writer.get(b"dict", lambda: {"not": "stored"})           # neither numbers nor arrays: not kept
        store.flush()
    packs = os.listdir(tmp_path)
    assert len(packs) == 1 and re.fullmatch(r"[0-9a-f]{32}\.npz", packs[0])
    reader = Memo()                                               # a new process: an empty memo
    with reader.stored(tmp_path):
        again = reader.call(shells, co, 2)
        kept = reader.get(b"seams", lambda: None)
        assert reader.get(b"dict", lambda: "made") == "made"
    assert made == [2]
    assert np.array_equal(again[0], first[0]) and again[0].dtype == first[0].dtype and again[1:] == first[1:]
    with pytest.raises(ValueError):
        again[0][0] = 1                                           # read-only, as a figure made here
    assert isinstance(kept, Seams) and kept.creases == 3
    assert all(np.array_equal(getattr(kept, k), getattr(seams, k)) for k in ("a", "b", "a_in", "b_in"))
    monkeypatch.setattr(memo, "code_digest", lambda: b"other code")   # the code that made them changed
    other = Memo()
    with other.stored(tmp_path):
        other.call(shells, co, 2)
    assert made == [2, 2]


def test_a_store_ignores_packs_it_cannot_read_and_keeps_the_newest(tmp_path, monkeypatch):
    made = []
    shells = _counted(made)
    co = np.ones((4, 3), np.float32)
    _, pack, index, blob = _one_pack(tmp_path, shells, co, 1)
    for spec, refs in index.values():
        refs[0][1] = "|S8"                                         # bytes a view would give: not a figure's dtype
    np.savez(pack, index=np.array(json.dumps(index)), blob=blob)
    (tmp_path / ("0" * 32 + ".npz")).write_bytes(b"PK\x03\x04 not a zip")
    reader = Memo()
    with reader.stored(tmp_path):
        value = reader.call(shells, co, 1)                        # an object array is never unpickled: made again
    assert made == [1, 1] and np.array_equal(value[0], np.arange(4))
    monkeypatch.setattr(memo.Store, "MAX_PACKS", 2)
    for path in tmp_path.iterdir():
        os.utime(path, (10**9, 10**9))
    for k in range(2, 6):
        before = set(tmp_path.iterdir())
        m = Memo()
        with m.stored(tmp_path) as store:
            m.call(shells, co, k)
            store.flush()
        for path in set(tmp_path.iterdir()) - before:             # packs written one second apart
            os.utime(path, (10**9 + k, 10**9 + k))
    assert len(list(tmp_path.iterdir())) == 2
    reader = Memo()
    with reader.stored(tmp_path):
        for k in (5, 4):
            reader.call(shells, co, k)
    assert made == [1, 1, 2, 3, 4, 5]                             # the two newest packs are kept
    newest = max(tmp_path.iterdir(), key=os.path.getmtime)
    monkeypatch.setattr(memo.Store, "MAX_BYTES", newest.stat().st_size + 1)
    m = Memo()
    with m.stored(tmp_path) as store:
        m.call(shells, co, 5)                                     # reads the newest pack: kept
        store.flush()
    assert list(tmp_path.iterdir()) == [newest]                   # the other is over the bytes allowed


def test_a_run_writes_one_pack_once_allowed_and_keeps_the_packs_it_reads(tmp_path, monkeypatch):
    made = []
    shells = _counted(made)
    co = np.ones((3, 3), np.float32)
    monkeypatch.setattr(memo.Store, "MAX_PACKS", 1)
    run = Memo()
    with run.stored(tmp_path) as store:
        run.call(shells, co, 0)
        assert os.listdir(tmp_path) == []                            # nothing before a map is written
        for k in range(1, 70):                                       # a report merge after every map
            run.call(shells, co, k)
            store.flush()
    assert len(os.listdir(tmp_path)) == 1
    second = Memo()
    with second.stored(tmp_path) as store:
        second.call(shells, co, 0)                                   # read from the first run's pack
        second.call(shells, co, 70)
        store.flush()
    assert len(os.listdir(tmp_path)) == 2                            # the pack it read is not pruned
    reader = Memo()
    with reader.stored(tmp_path):
        for k in range(71):
            reader.call(shells, co, k)
    assert made == list(range(71))
    unused = Memo()
    with unused.stored(tmp_path) as store:                           # a run that writes no map writes nothing
        unused.call(shells, co, 99)
    assert len(os.listdir(tmp_path)) == 2 and made[-1] == 99


def test_a_figure_whose_arrays_lie_past_the_end_of_its_pack_is_made_again(tmp_path):
    made = []
    shells = _counted(made)
    co = np.ones((6, 3), np.float32)
    first, pack, index, blob = _one_pack(tmp_path, shells, co, 7)
    assert blob.dtype == np.uint8 and len(blob) >= co.shape[0] * 8       # the arrays' bytes
    for cut in (blob[:len(blob) // 2],                                      # arrays past the end
                blob.view(np.int8)):                                        # a blob that is not bytes (the same ones)
        np.savez(pack, index=np.array(json.dumps(index)), blob=cut)
        reader = Memo()
        with reader.stored(tmp_path):
            again = reader.call(shells, co, 7)
        assert np.array_equal(again[0], first[0])
    assert made == [7, 7, 7]


def test_packs_whose_index_is_not_a_mapping_or_pickled_are_ignored_and_scalars_stay_scalars(tmp_path):
    def figure(co, k):
        return np.float64(co.sum()) / 3, np.int32(k), np.arange(k)

    co = np.ones((2, 3), np.float32)
    first, pack, index, blob = _one_pack(tmp_path, figure, co, 4)
    np.savez(tmp_path / ("1" * 32 + ".npz"), index=np.array(json.dumps([[1]])), blob=blob)
    np.savez(tmp_path / ("2" * 32 + ".npz"), index=np.array([index], object), blob=blob)   # pickled: never loaded
    reader = Memo()
    with reader.stored(tmp_path):
        again = reader.call(figure, co, 4)
    assert type(again[0]) is np.float64 and type(again[1]) is np.int32 and np.ndim(again[0]) == 0
    assert again[0] == first[0] and again[1] == 4 and np.array_equal(again[2], np.arange(4))
    for spec, refs in index.values():
        refs[0][0] = -16                                            # an offset before the blob
    np.savez(pack, index=np.array(json.dumps(index)), blob=blob)
    other = Memo()
    with other.stored(tmp_path):
        assert other.call(figure, co, 4)[0] == first[0]            # made again, not read from before the blob


def test_a_figure_reaches_the_store_once_also_when_made_unstored_first_or_in_an_earlier_bake(tmp_path):
    """Store.keep: a figure made unstored (a trial layout's) and then asked for stored is written, and a second bake
    in the same session writes only its new figures, not those its memo remembers from the first."""
    made = []
    shells = _counted(made)
    co = np.ones((2, 3), np.float32)
    session = Memo()
    with session.stored(tmp_path) as store:
        session.call(shells, co, 1, stored=False)
        session.call(shells, co, 1)
        store.flush()
    reader = Memo()
    with reader.stored(tmp_path):
        reader.call(shells, co, 1)
    assert made == [1]                                              # read from the pack, not made
    first = set(tmp_path.iterdir())
    with session.stored(tmp_path) as store:
        session.call(shells, co, 1)                                 # remembered, and in the folder's pack
        session.call(shells, co, 2)
        store.flush()
    (second,) = set(tmp_path.iterdir()) - first
    with np.load(second, allow_pickle=False) as z:
        assert len(json.loads(str(z["index"]))) == 1                # the new figure only
    assert made == [1, 2]


def test_a_pack_written_during_a_run_is_read_back_by_the_same_store(tmp_path, monkeypatch):
    """A store writes a pack when its figures pass PENDING_BYTES (compressed on disk, its bytes kept as they are): a
    figure dropped from memory since is read back from it, not made again."""
    monkeypatch.setattr(memo.Store, "PENDING_BYTES", 0)
    made = []
    shells = _counted(made)
    co = np.ones((300, 3), np.float32)
    run = Memo(kept=1)
    with run.stored(tmp_path) as store:
        store.flush()
        first = run.call(shells, co, 2)
        assert len(os.listdir(tmp_path)) == 1               # written at once
        run.call(shells, co, 3)                              # drops the first from memory
        again = run.call(shells, co, 2)
    assert made == [2, 3] and np.array_equal(again[0], first[0]) and again[1:] == first[1:]
