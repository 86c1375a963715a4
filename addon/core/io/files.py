"""Output files: folders checked before any work, files written to a temporary name beside the target, then renamed."""
import contextlib
import json
import math
import os
import re
import secrets
import socket
import tempfile
import time

from ..errors import ILError, InputError


def check_output_dir(out):
    """Return ``out`` as an absolute path if it is named (not empty), is a folder or can be created as one,
    and is writable; raise InputError otherwise. Nothing is created: a probe file is made and removed in the folder or
    its nearest existing parent (permission bits alone say nothing for root or read-only mounts)."""
    if not os.fspath(out).strip():
        raise InputError("no output folder given (an empty one would write into the current folder)")
    out = os.path.abspath(os.fspath(out))
    if os.path.exists(out) and not os.path.isdir(out):
        raise InputError(f"output folder is a file: {out}")
    probe = out
    while not os.path.exists(probe):
        parent = os.path.dirname(probe)
        if parent == probe:
            break
        probe = parent
    if not os.path.isdir(probe):
        raise InputError(f"output folder cannot be created: {out} ({probe} is a file)")
    _check_name_lengths(out, probe)
    try:
        fd, tmp = tempfile.mkstemp(prefix=".il_probe_", dir=probe)
    except OSError as e:
        raise InputError(f"output folder cannot be written: {out} ({probe}: {e.strerror})") from None
    os.close(fd)
    os.remove(tmp)
    return out


#: Room kept in a path for the names written inside the output folder (<object>_<map>.exr and the like).
FILE_NAME_ROOM = 128


def _check_name_lengths(out, existing):
    """InputError when a folder still to be made under ``existing`` has a name longer than the file system
    takes, or ``out`` leaves less than FILE_NAME_ROOM bytes of the longest path for the files in it."""
    try:
        name_max = os.pathconf(existing, "PC_NAME_MAX")
        path_max = os.pathconf(existing, "PC_PATH_MAX")
    except (AttributeError, ValueError, OSError):
        name_max, path_max = 255, 4096
    for part in os.path.relpath(out, existing).split(os.sep):
        if part != os.curdir and len(os.fsencode(part)) > name_max:
            raise InputError(f"output folder name too long for the file system ({len(os.fsencode(part))} bytes, "
                             f"at most {name_max}): {part[:40]}...")
    if len(os.fsencode(out)) + FILE_NAME_ROOM > path_max:
        raise InputError(f"output folder path too long: {len(os.fsencode(out))} bytes leave no room for its "
                         f"files (at most {path_max - FILE_NAME_ROOM})")


@contextlib.contextmanager
def atomic_path(path):
    """Yield a temporary path in the target's folder (``.<stem>.<host>-<pid>.<random>.tmp<ext>``: see
    :func:`remove_stale_temporaries`); on success rename it onto ``path``. The temporary is named in ``_LIVE``
    before it is created and until it is gone, for :func:`remove_own_temporaries`."""
    path = os.fspath(path)
    folder = os.path.dirname(os.path.abspath(path))
    os.makedirs(folder, exist_ok=True)
    stem, ext = os.path.splitext(os.path.basename(path))
    tmp = None
    try:
        while True:
            tmp = os.path.join(folder, f".{stem}.{_OWNER}.{secrets.token_hex(4)}.tmp{ext}")
            _LIVE.add(tmp)
            try:
                os.close(os.open(tmp, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o600))
                break
            except FileExistsError:
                _LIVE.discard(tmp)
        yield tmp
        os.chmod(tmp, 0o666 & ~_umask())
        os.replace(tmp, path)
    finally:
        if tmp is not None:
            if os.path.exists(tmp):
                os.remove(tmp)
            _LIVE.discard(tmp)


_LIVE = set()


def remove_own_temporaries():
    """Remove the temporaries of :func:`atomic_path` this process still has on disk: a Ctrl-C that lands inside
    its clean-up leaves one. Call when the process stops on an error; returns the paths removed."""
    removed = []
    for tmp in sorted(_LIVE):
        with contextlib.suppress(OSError):
            os.remove(tmp)
            removed.append(tmp)
        _LIVE.discard(tmp)
    return removed


_HOST = re.sub(r"[^A-Za-z0-9-]", "-", socket.gethostname()) or "host"
_OWNER = f"{_HOST}-{os.getpid()}"
_TEMPORARY = re.compile(r"^\..+\.(?P<host>[A-Za-z0-9-]+)-(?P<pid>\d+)\.[^.]+\.tmp(\.[A-Za-z0-9]+)?$")


#: A temporary younger than this is never removed: a writer holds one for seconds, and host and PID alone do
#: not tell processes apart across PID namespaces (containers that share a host name and a folder).
STALE_AFTER = 120.0


def remove_stale_temporaries(folder, now=None):
    """Remove the temporary files :func:`atomic_path` left in ``folder`` when its process was killed (SIGKILL,
    power loss): those of this host whose process is gone and that are older than STALE_AFTER seconds. Another
    host's (a farm sharing the folder) and a live process's stay. Returns the names removed."""
    removed = []
    try:
        names = os.listdir(folder)
    except OSError:
        return removed
    now = time.time() if now is None else now
    for name in names:
        m = _TEMPORARY.match(name)
        if not m or m["host"] != _HOST or _alive(int(m["pid"])):
            continue
        with contextlib.suppress(OSError):
            if now - os.path.getmtime(os.path.join(folder, name)) < STALE_AFTER:
                continue
        with contextlib.suppress(OSError):
            os.remove(os.path.join(folder, name))
            removed.append(name)
    return removed


def _alive(pid):
    if os.name == "nt":                           # os.kill(pid, 0) there sends CTRL_C_EVENT: assume alive
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OSError, OverflowError):
        return True
    return True


def _umask():
    mask = os.umask(0)
    os.umask(mask)
    return mask


def write_json(path, data):
    """Write ``data`` as indented JSON, atomically; a NaN or infinite number is refused (ILError naming
    the file and the key) before anything is written."""
    try:
        text = json.dumps(data, indent=2, sort_keys=False, allow_nan=False)   # one string: json.dump writes each token
    except ValueError:
        where = non_finite(data)
        if where:
            raise ILError(f"not writing {path}: non-finite number at {where}") from None
        raise
    with atomic_path(path) as tmp:
        with open(tmp, "w", encoding="utf-8") as f:
            f.write(text + "\n")


def non_finite(data, where=""):
    """The key path ("methods.gtao.rmse") of the first NaN or infinite float in nested dicts/lists, or ""."""
    if isinstance(data, float):
        return "" if math.isfinite(data) else (where or "top level") + f" ({data})"
    if isinstance(data, dict):
        items = data.items()
    elif isinstance(data, (list, tuple)):
        items = enumerate(data)
    else:
        return ""
    for key, value in items:
        found = non_finite(value, f"{where}.{key}" if where else str(key))
        if found:
            return found
    return ""


def write_bytes(path, data):
    """Write ``data`` bytes, atomically."""
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as f:
            f.write(data)


def prune_least_recent(paths, keep=frozenset(), max_files=math.inf, max_bytes=math.inf):
    """Remove files of ``paths``, the least recently modified first and never one in ``keep``, until at most
    ``max_files`` of them hold at most ``max_bytes`` in all (a file that cannot be read or removed is left)."""
    files = []
    for path in paths:
        with contextlib.suppress(OSError):
            st = os.stat(path)
            files.append((st.st_mtime, st.st_size, path))
    count, total = len(files), sum(size for _, size, _ in files)
    for _, size, path in sorted(files):
        if count <= max_files and total <= max_bytes:
            break
        if path in keep:
            continue
        with contextlib.suppress(OSError):
            os.remove(path)
            count, total = count - 1, total - size
