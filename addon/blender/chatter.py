"""Blender's own console output (``Info: Baking map saved to internal image...``, ``Read blend:``, Mesa's EGL
messages) kept off the scripts' stdout and stderr, which carry the project's lines only (no bpy, no numpy).

Blender writes through C stdio on file descriptors 1 and 2, below Python's ``sys.stdout``: inside
:func:`captured` both descriptors point at a temporary file; the last lines are kept for a failure report
(:func:`tail`). Only scripts turn it on (:func:`enable`); inside Blender's UI the console stays as it is.
"""
import collections
import contextlib
import ctypes
import os
import sys
import tempfile

KEPT_LINES = 200
_lines = collections.deque(maxlen=KEPT_LINES)
_enabled = False


def enable():
    """Capture Blender's output in :func:`captured` blocks from now on (batch scripts)."""
    global _enabled
    _enabled = True


def _flush_c_stdio():
    try:
        ctypes.CDLL(None).fflush(None)
    except (OSError, AttributeError, TypeError):     # no C library handle (Windows): Python's own flush only
        pass


@contextlib.contextmanager
def captured(always=False):
    """Point descriptors 1 and 2 at a temporary file for the block (when enabled, or ``always``); keep its last
    lines."""
    if not (_enabled or always):
        yield
        return
    for stream in (sys.stdout, sys.stderr):
        stream.flush()
    _flush_c_stdio()
    saved = [os.dup(1), os.dup(2)]
    with tempfile.TemporaryFile() as log:
        try:
            os.dup2(log.fileno(), 1)
            os.dup2(log.fileno(), 2)
            yield
        finally:
            _flush_c_stdio()
            os.dup2(saved[0], 1)
            os.dup2(saved[1], 2)
            for fd in saved:
                os.close(fd)
            log.seek(0)
            _lines.extend(log.read().decode("utf-8", "replace").splitlines())


def silence_rest():
    """Point descriptors 1 and 2 at the null device for the rest of the process, after a script's last line: what
    the bpy module prints as the process ends (bpy 4.5's "Error: Not freed memory blocks" on stdout after a file
    saved by a newer Blender) stays off the script's output. Only where nothing else runs after the script (not
    inside ``blender -b``, where a later ``-P`` script still prints). Kept with IL_DEBUG."""
    if not _enabled or os.environ.get("IL_DEBUG"):
        return
    for stream in (sys.stdout, sys.stderr):
        stream.flush()
    _flush_c_stdio()
    null = os.open(os.devnull, os.O_WRONLY)
    os.dup2(null, 1)
    os.dup2(null, 2)
    os.close(null)


def tail():
    """The last captured lines of Blender's output (at most KEPT_LINES)."""
    return list(_lines)
