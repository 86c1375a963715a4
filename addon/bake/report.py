"""bake_report.json: merging a run's entries under a folder lock, shard parts, the summary line and the progress
line's tracker."""
import contextlib
import json
import os
import time

import bpy

from ..core import errors
from ..core.errors import InputError
from ..core.io.files import write_json
from ..core.result import JobResult


REPORT = "bake_report.json"


SHARD_REPORT = "bake_report.shard-{k}-of-{n}.json"


class Tracker:
    """Objects and texels done of a level bake (``plan``: :class:`plan.Target`), the elapsed time and the ETA from
    the texels per second so far."""

    def __init__(self, plan, maps, unchanged, options):
        self.t0 = time.perf_counter()
        self.texels = {}
        for target in plan:
            for m in maps:
                if m not in unchanged.get(target.name, ()):
                    self.texels[(target.name, m)] = target.texels
        self.total = sum(self.texels.values())
        self.objects = {name for name, _ in self.texels}
        self.finished, self.texels_done, self.objects_done = set(), 0, set()

    def done(self, name, m):
        key = (name, m)
        if key in self.texels and key not in self.finished:
            self.finished.add(key)
            self.texels_done += self.texels[key]
            if all((name, k) in self.finished for n, k in self.texels if n == name):
                self.objects_done.add(name)

    def line(self):
        elapsed = time.perf_counter() - self.t0
        rate = self.texels_done / elapsed if elapsed > 0 and self.texels_done else 0.0
        eta = f"{(self.total - self.texels_done) / rate:.0f} s" if rate else "?"
        text = (f" | objects {len(self.objects_done)}/{len(self.objects)}, texels {self.texels_done}/{self.total}, "
                f"{elapsed:.1f} s, ETA {eta}")
        try:
            if not bpy.app.background and bpy.context.workspace is not None:
                bpy.context.workspace.status_text_set(f"Light maps:{text[2:]}")
        except (AttributeError, RuntimeError):
            pass
        return text

    def final(self, report):
        try:
            if not bpy.app.background and bpy.context.workspace is not None:
                bpy.context.workspace.status_text_set(None)
        except (AttributeError, RuntimeError):
            pass
        elapsed = time.perf_counter() - self.t0
        return f" ({self.texels_done} texels in {elapsed:.1f} s, {self.texels_done / max(elapsed, 1e-9):.0f} texels/s)"


def merge_reports(folder):
    """Join the shard report parts (bake_report.shard-K-of-N.json) of ``folder`` into its bake_report.json; return
    a JobResult. The report's entries stay and the parts' update them (per object and map); "skipped" and
    "unchanged" are the parts' unions, "seconds" their sum. Only the parts of the latest split (the N of the newest
    part) are joined; parts of other splits and missing shares are named in a warning. A part (or report) that
    cannot be read is moved aside (:func:`_aside`) with a warning and the rest merged."""
    import re
    pattern = re.compile(r"bake_report\.shard-(\d+)-of-(\d+)\.json")
    found = {}
    for entry in sorted(os.listdir(folder)) if os.path.isdir(folder) else []:
        match = pattern.fullmatch(entry)
        if match:
            found[os.path.join(folder, entry)] = (int(match.group(1)), int(match.group(2)))
    if not found:
        raise InputError(f"no shard reports (bake_report.shard-K-of-N.json) in {folder}")
    n = found[max(found, key=lambda p: (os.path.getmtime(p), found[p][1]))][1]
    stale = sorted(os.path.basename(p) for p, (_, m) in found.items() if m != n)
    if stale:
        errors.warn(f"ignored the parts of an earlier split (the latest has {n} shares): " + ", ".join(stale))
    parts = sorted((p for p, (_, m) in found.items() if m == n), key=lambda p: found[p][0])
    missing = sorted(set(range(1, n + 1)) - {found[p][0] for p in parts})
    if missing:
        errors.warn(f"no report part of shard(s) {', '.join(f'{k}/{n}' for k in missing)} in {folder}: "
                    "their maps are not in the merged report")
    path = os.path.join(folder, REPORT)
    with report_lock(folder):
        old = _load_report(path, "a new report started") or {}
        merged = {"objects": old.get("objects", {}), "skipped": {}, "unchanged": {}, "failed": {}, "seconds": 0.0,
                  "shards": []}
        joined = []
        for part_path in parts:
            part = _load_report(part_path, "merged without it")
            if part is None:
                continue
            joined.append(part)
            for obj, maps in part.get("objects", {}).items():
                merged["objects"].setdefault(obj, {}).update(maps)
            merged["skipped"].update(part.get("skipped", {}))
            for obj, maps in part.get("unchanged", {}).items():
                have = merged["unchanged"].setdefault(obj, [])
                have.extend(m for m in maps if m not in have)
            merged["seconds"] += float(part.get("seconds", 0.0))
            merged["shards"].append(os.path.basename(part_path))
            merged["blender_version"] = part.get("blender_version")
        if not joined:
            raise InputError(f"no readable shard reports (bake_report.shard-K-of-N.json) in {folder}")
        named = {obj for part in joined for obj in part.get("objects", {})}
        merged["failed"] = {k: v for k, v in old.get("failed", {}).items() if k not in named}
        for part in joined:
            merged["failed"].update(part.get("failed", {}))
        write_json(path, merged)
    return JobResult(merged, path, summary(merged) + f" ({len(joined)} shard reports merged)")


def summary(report):
    """One line: what was baked and what was skipped, with the reason."""
    baked = ", ".join(f"{o} ({', '.join(maps)})" for o, maps in report["objects"].items()) or "nothing"
    line = f"baked {baked}"
    if report.get("unchanged"):
        line += f"; unchanged (skipped, inputs as baked) {sum(len(m) for m in report['unchanged'].values())} map(s): " \
                + ", ".join(f"{o} ({', '.join(m)})" for o, m in report["unchanged"].items())
    if report.get("skipped"):
        line += "; skipped " + "; ".join(f"{n} ({why})" for n, why in report["skipped"].items())
    if report.get("failed"):
        line += f"; FAILED {len(report['failed'])}: " + "; ".join(f"{n} ({why})" for n, why in report["failed"].items())
    return line


def merge_report(path, report):
    """Merge this run's entries into ``path`` under a lock on the folder (concurrent bakes of other objects
    into the same folder keep theirs); the top-level "seconds" is this run's. A report that cannot be read
    is kept aside under a new name, with a warning, never replaced silently."""
    with report_lock(os.path.dirname(path)):
        old = _load_report(path, "a new report started") or {}
        objects = old.get("objects", {})
        for name, maps in report["objects"].items():
            objects.setdefault(name, {}).update(maps)
        merged = {"objects": objects, "seconds": round(report["seconds"], 4),
                  "blender_version": bpy.app.version_string}
        failed = {k: v for k, v in old.get("failed", {}).items() if k not in report["objects"]}
        failed.update(report.get("failed", {}))
        if failed:
            merged["failed"] = failed
        for key in ("skipped", "unchanged"):           # the last run's, kept by the writes that do not say
            value = report[key] if key in report else old.get(key)
            if value:
                merged[key] = value
        write_json(path, merged)


def _shape_error(report):
    """Why ``report`` (parsed JSON) is not a bake report, or None."""
    if not isinstance(report, dict):
        return "not a JSON object"
    objects = report.get("objects", {})
    if not isinstance(objects, dict) or not all(isinstance(maps, dict) and all(isinstance(e, dict)
                                                                                for e in maps.values())
                                                 for maps in objects.values()):
        return '"objects" is not {object: {map: entry}}'
    for key in ("skipped", "failed", "unchanged"):
        if not isinstance(report.get(key, {}), dict):
            return f'"{key}" is not a JSON object'
    if not all(isinstance(m, list) for m in report.get("unchanged", {}).values()):
        return '"unchanged" is not {object: [map]}'
    if not isinstance(report.get("seconds", 0.0), (int, float)):
        return '"seconds" is not a number'
    return None


def _load_report(path, then):
    """The report in ``path``, None when there is none. One that cannot be read or is not a bake report is
    moved aside under a new name (:func:`_aside`) with a warning ending in ``then``, and None returned; call
    under :func:`report_lock`."""
    if not os.path.exists(path):
        return None
    try:
        with open(path, encoding="utf-8") as f:
            report = json.load(f)
        why = _shape_error(report)
        if why:
            raise ValueError(why)
        return report
    except (OSError, ValueError) as e:
        aside = _aside(path)
        os.replace(path, aside)
        errors.warn(f"{path} could not be read ({e}): kept as {aside}, {then}")
        return None


def entry_file(folder, entry):
    """The map file of a report entry: the file named as its "file" (a path written by the bake, / or \\
    separated) in ``folder`` itself, the folder as given (also copied or moved: a copy's report still names the
    original's paths), never a file elsewhere; None when it is not there or "file" is not a path."""
    name = entry.get("file") if isinstance(entry, dict) else None
    if not isinstance(name, str):
        return None
    base = name.replace("\\", "/").rsplit("/", 1)[-1]
    if base in ("", ".", ".."):
        return None
    path = os.path.join(folder, base)
    return path if os.path.isfile(path) else None


def read_objects(path):
    """The "objects" of the report in ``path`` as it is; {} when it is missing or unreadable (nothing moved)."""
    try:
        with open(path, encoding="utf-8") as f:
            report = json.load(f)
    except (OSError, ValueError):
        return {}
    return report.get("objects", {}) if _shape_error(report) is None else {}


def _aside(path):
    stem, ext = os.path.splitext(path)
    n = 1
    while os.path.exists(f"{stem}.unreadable-{n}{ext}"):
        n += 1
    return f"{stem}.unreadable-{n}{ext}"


@contextlib.contextmanager
def report_lock(folder):
    """Exclusive lock of ``folder`` for one report merge: ``flock`` on the folder itself (POSIX, no lock
    file left behind); on Windows ``msvcrt.locking`` on a ``.bake_report.lock`` file in the folder."""
    os.makedirs(folder, exist_ok=True)
    try:
        import fcntl
    except ImportError:
        fcntl = None
    if fcntl is not None:
        fd = os.open(folder, os.O_RDONLY)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX)
            yield
        finally:
            os.close(fd)              # closing releases the lock
        return
    import msvcrt
    with open(os.path.join(folder, ".bake_report.lock"), "a+b") as f:
        while True:
            try:
                msvcrt.locking(f.fileno(), msvcrt.LK_LOCK, 1)
                break
            except OSError:           # LK_LOCK gives up after 10 s: keep waiting
                continue
        try:
            yield
        finally:
            f.seek(0)
            msvcrt.locking(f.fileno(), msvcrt.LK_UNLCK, 1)
