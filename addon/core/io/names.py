"""File names from datablock names. Object, material and image names are user data from any file: they
become file names only through :func:`file_stems`."""
import hashlib
import re

from ..errors import ILError

_UNSAFE = re.compile(r"[^A-Za-z0-9._-]+")
_RESERVED = {"CON", "PRN", "AUX", "NUL", *(f"COM{i}" for i in range(10)), *(f"LPT{i}" for i in range(10))}
MAX_STEM = 96


def _sanitised(name):
    base = _UNSAFE.sub("_", name).lstrip("._-")[:MAX_STEM] or "_"
    return "_" + base if base.split(".")[0].upper() in _RESERVED else base


def _tagged(base, name):
    return f"{base}-{hashlib.blake2b(name.encode('utf-8', 'surrogatepass'), digest_size=4).hexdigest()}"


def file_stems(names):
    """``{name: stem}`` for a set of datablock names.

    Every stem is one plain path component (ASCII letters, digits, '.', '_', '-'; no leading dot or dash;
    not a reserved Windows device name; other characters become '_'), so ``os.path.join(out, stem + suffix)``
    stays inside ``out``, and stems are unique among ``names`` also where the file system ignores case. A
    name whose sanitised text (case folded) is its own keeps that text ("Back Wall" -> "Back_Wall"); names
    that sanitise alike each get '-' and 8 hex digits of their BLAKE2 hash after it. The same set gives the
    same stems in any order: pass every name that may be written in the same folder (e.g. all objects of the
    file), so that shards of one file agree.
    """
    names = sorted(set(names))
    groups = {}
    for name in names:
        groups.setdefault(_sanitised(name).casefold(), []).append(name)
    stems = {}
    for members in groups.values():
        for name in members:
            base = _sanitised(name)
            stems[name] = base if len(members) == 1 else _tagged(base, name)
    folded = [s.casefold() for s in stems.values()]
    if len(set(folded)) != len(folded):
        raise ILError("two datablock names give the same file name: rename one of them")
    return stems
