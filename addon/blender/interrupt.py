"""Ctrl-C that stops a job at the next safe point (no bpy, no numpy).

A Blender call (a Cycles bake or render, a file load) runs C code that calls back into Python
(Cycles' engine methods, drivers); a KeyboardInterrupt raised inside such a callback is printed there
and swallowed, and the job runs on. Inside ``blender_call()`` a SIGINT only sets a flag; leaving the
outermost block raises KeyboardInterrupt in the job's own code, where its ``with`` blocks restore the
user's state. Outside those blocks Ctrl-C raises KeyboardInterrupt at once, as Python does.
"""
import contextlib
import signal
import threading

from . import chatter

_depth = 0
_pending = False


def _handler(signum, frame):
    global _pending
    if _depth:
        _pending = True
        return
    raise KeyboardInterrupt


def install():
    """Use the deferring SIGINT handler (batch scripts; a no-op outside the main thread)."""
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, _handler)


def checkpoint():
    """Raise KeyboardInterrupt if a Ctrl-C arrived during a Blender call and was not raised yet."""
    global _pending
    if _pending and not _depth:
        _pending = False
        raise KeyboardInterrupt


@contextlib.contextmanager
def blender_call():
    """Defer Ctrl-C until the Blender call inside the block returns, then raise it; Blender's console output
    of the call goes to :mod:`.chatter` (scripts)."""
    global _depth
    _depth += 1
    try:
        with chatter.captured() if _depth == 1 else contextlib.nullcontext():
            yield
    finally:
        _depth -= 1
    checkpoint()
