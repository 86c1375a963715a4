"""Progress for long work: the window manager's progress in the UI, one line per step on stderr in batch."""
import sys
import time

import bpy

from . import interrupt


class Progress:
    """``with Progress("Baking", total) as p: p.step("Cube AO")`` -- ``step`` advances by one."""

    _open = 0  # nested progress (a bake inside a radiosity run) leaves the outer one's display alone

    def __init__(self, label, total):
        self.label, self.total, self.done = label, max(int(total), 1), 0
        self.t0 = time.perf_counter()
        wm = getattr(bpy.context, "window_manager", None)
        self.wm = wm if (wm is not None and not bpy.app.background and wm.windows) else None

    def __enter__(self):
        Progress._open += 1
        if self.wm and Progress._open > 1:
            self.wm = None
        if self.wm:
            self.wm.progress_begin(0, self.total)
        return self

    def step(self, message):
        """Report the step about to run (a pending Ctrl-C stops the job here); in the UI also in the status bar."""
        interrupt.checkpoint()
        if self.wm:
            self.wm.progress_update(self.done)
            _status(f"{self.label} {self.done + 1}/{self.total}: {message}")
        else:
            t = time.perf_counter() - self.t0
            print(f"[{self.label} {self.done + 1}/{self.total} {t:6.1f}s] {message}", file=sys.stderr, flush=True)
        self.done += 1

    def note(self, message, fraction=None):
        """A line about the current step's progress on stderr in batch, without advancing (a pending Ctrl-C
        stops the job here); in the UI the message in the status bar and, with ``fraction`` (of the current
        step done), the progress at done - 1 + fraction."""
        interrupt.checkpoint()
        if self.wm:
            if fraction is not None:
                self.wm.progress_update(max(self.done - 1, 0) + min(max(float(fraction), 0.0), 1.0))
            _status(f"{self.label}: {message}")
        else:
            t = time.perf_counter() - self.t0
            print(f"[{self.label} {max(self.done, 1)}/{self.total} {t:6.1f}s]   {message}", file=sys.stderr, flush=True)

    def __exit__(self, *exc):
        Progress._open -= 1
        if self.wm:
            self.wm.progress_end()
            _status(None)
        return False


def _status(text):
    """``text`` in the status bar of the context's workspace (None clears it); nothing without a workspace."""
    workspace = getattr(bpy.context, "workspace", None)
    if workspace is not None:
        workspace.status_text_set(text)
