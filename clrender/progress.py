"""Progress of slow one-time work: OpenCL program builds, first kernel launches, the device probe.

A cold machine compiles clrender's kernels once (seconds each on PoCL; cached afterwards). That
must never look like a hang: every such stage reports through the `clrender` logger (INFO when it
starts and ends, DEBUG per item), and the CLI adds a tqdm bar on stderr (`show_bars(True)`; `-q`
leaves it off). A bar appears only after `BAR_DELAY_S`, so a warm start shows nothing.

    with progress.stage("building OpenCL programs", total=12, device="pocl 3.1: cpu") as s:
        for name in names:
            build(name); s.advance(name)
"""
from __future__ import annotations

import logging
import sys
import threading
import time
from contextlib import contextmanager
from typing import Iterator, Optional

log = logging.getLogger("clrender")
BAR_DELAY_S = 1.0
_bars = False
_lines = None               # a stream that gets "total N" / "progress ITEM" lines (the probe child's stdout)
_active: list = []          # open stages, innermost last: a nested build reports into its stage


def show_bars(enabled: bool) -> None:
    """Draw a tqdm bar on stderr for stages that last longer than BAR_DELAY_S (the CLI's choice)."""
    global _bars
    _bars = bool(enabled)


def report_lines(stream) -> None:
    """Also write each stage's total and items as lines to `stream` (the probe child reports to its
    parent this way: clrender/device/probe.py)."""
    global _lines
    _lines = stream


def emit(text: str) -> None:
    """A fact for the parent of a line-reporting process (e.g. a build and its seconds)."""
    _line(text)


def _line(text: str) -> None:
    if _lines is not None:
        _lines.write(text + "\n")
        _lines.flush()


class Stage:
    """One stage of one-time work: `total` items (None: unknown), advanced one by one."""

    def __init__(self, what: str, total: Optional[int], device: str = ""):
        self.what, self.total, self.device = what, total, device
        self.done = 0
        self.started = time.perf_counter()
        self.bar = None
        if _bars:
            from tqdm import tqdm
            label = (f"{what} for {device}" if device else what) + " (first run only, cached afterwards)"
            self.bar = tqdm(total=total, desc=label, unit="", file=sys.stderr, delay=BAR_DELAY_S, leave=False,
                            dynamic_ncols=True, bar_format="{desc}: {n_fmt}/{total_fmt} [{elapsed}<{remaining}] {postfix}")
        self._stop = threading.Event()
        if self.bar is not None:      # the clock keeps moving while one long compile runs
            threading.Thread(target=self._tick, daemon=True).start()
        log.info("%s%s%s (first run only, cached afterwards)", what, f" for {device}" if device else "",
                 f": {total}" if total else "")
        if total:
            _line(f"total {total}")

    def add_total(self, n: int) -> None:
        """More items than first counted (work found on the way, e.g. shadow-map programs)."""
        if n <= 0:
            return
        self.total = (self.total or 0) + n
        _line(f"total {self.total}")
        if self.bar is not None:
            self.bar.total = self.total
            if self._shown():
                self.bar.refresh()

    def advance(self, item: str = "", n: int = 1) -> None:
        self.done += n
        log.debug("%s: %s (%d%s)", self.what, item, self.done, f"/{self.total}" if self.total else "")
        _line(f"progress {item}")
        if self.bar is not None:
            if item:
                self.bar.set_postfix_str(_short(item), refresh=False)
            self.bar.update(n)

    def note(self, item: str) -> None:
        """Name what is being worked on now (before it is done)."""
        if self.bar is not None:
            self.bar.set_postfix_str(_short(item), refresh=self._shown())

    def _shown(self) -> bool:
        """tqdm's `delay` holds the bar back only until something forces a refresh: not before."""
        return time.perf_counter() - self.started >= BAR_DELAY_S

    def _tick(self) -> None:
        while not self._stop.wait(1.0):
            if self._shown():
                self.bar.refresh()

    def close(self) -> None:
        self._stop.set()
        if self.bar is not None:
            self.bar.close()
        log.info("%s: %d done in %.1f s", self.what, self.done, time.perf_counter() - self.started)


def _short(item: str) -> str:
    """The bar names a program by its file (its -D defines are in the debug log)."""
    return item.split(" ", 1)[0] if ".cl " in item else item


@contextmanager
def stage(what: str, total: Optional[int] = None, device: str = "") -> Iterator[Stage]:
    s = Stage(what, total, device)
    _active.append(s)
    try:
        yield s
    finally:
        _active.remove(s)
        s.close()


def current() -> Optional[Stage]:
    """The innermost open stage, if any (a build outside any stage opens its own)."""
    return _active[-1] if _active else None
