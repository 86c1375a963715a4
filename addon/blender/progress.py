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
        """Report the step about to run (a pending Ctrl-C stops the job here)."""
        interrupt.checkpoint()
        if self.wm:
            self.wm.progress_update(self.done)
        else:
            t = time.perf_counter() - self.t0
            print(f"[{self.label} {self.done + 1}/{self.total} {t:6.1f}s] {message}", file=sys.stderr, flush=True)
        self.done += 1

    def note(self, message):
        """A line about the current step's progress on stderr in batch, without advancing (a pending Ctrl-C
        stops the job here)."""
        interrupt.checkpoint()
        if not self.wm:
            t = time.perf_counter() - self.t0
            print(f"[{self.label} {max(self.done, 1)}/{self.total} {t:6.1f}s]   {message}", file=sys.stderr, flush=True)

    def __exit__(self, *exc):
        Progress._open -= 1
        if self.wm:
            self.wm.progress_end()
        return False
