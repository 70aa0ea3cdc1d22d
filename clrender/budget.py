"""The memory budget's arithmetic: `Budget` (bytes one load may hold, thread-safe), the limit
(`CLRENDER_MAX_MEMORY`, else half of the physical memory), sizes and their text.

Below every layer, so the scene's own file codecs (clrender.scene.environment_files) check a header
against a budget without importing the loaders. The active load's Budget, shared by everything one
`load_scene` reads, is `clrender.loaders.budget.current()` (its docstring: what is charged and why).
"""
from __future__ import annotations

import os
import re
import threading
from typing import Optional

from clrender.errors import BudgetError

ENV = "CLRENDER_MAX_MEMORY"
DEFAULT_FRACTION = 0.5               # of the physical memory, without CLRENDER_MAX_MEMORY
FALLBACK_MEMORY = 8 << 30            # when the physical memory cannot be read
_UNITS = {"": 1, "K": 1 << 10, "M": 1 << 20, "G": 1 << 30, "T": 1 << 40}
_SIZE = re.compile(r"^\s*(\d+(?:\.\d*)?|\.\d+)\s*([KMGT]?)(?:I?B)?\s*$", re.I)
_PERCENT = re.compile(r"^\s*(\d+(?:\.\d*)?|\.\d+)\s*%\s*$")

__all__ = ["Budget", "BudgetError", "ENV", "memory_limit", "parse_size", "physical_memory", "human"]


def physical_memory() -> int:
    """The machine's physical memory in bytes (FALLBACK_MEMORY when unknown)."""
    try:
        pages, size = os.sysconf("SC_PHYS_PAGES"), os.sysconf("SC_PAGE_SIZE")
        if pages > 0 and size > 0:
            return int(pages) * int(size)
    except (ValueError, OSError, AttributeError):
        pass
    return FALLBACK_MEMORY


def parse_size(text: str, what: str = ENV) -> int:
    """'8G' -> 8 GiB, '512M', '1.5T', '1000000', '2GiB', '25%' (of the physical memory) -> bytes;
    ValueError naming `what` for anything else (zero included: a budget of nothing loads nothing)."""
    raw = str(text)
    m = _PERCENT.match(raw)
    if m:
        value = float(m.group(1)) / 100.0 * physical_memory()
    else:
        m = _SIZE.match(raw)
        if m is None:
            raise ValueError(f"{what}={raw!r}: not a size (expected bytes, or a number with K, M, G or T, "
                             f"e.g. 8G, or a percentage of the physical memory, e.g. 25%)")
        value = float(m.group(1)) * _UNITS[m.group(2).upper()]
    if not value >= 1:
        raise ValueError(f"{what}={raw!r}: the memory budget must be at least 1 byte")
    return int(value)


def memory_limit() -> int:
    """The budget in bytes: $CLRENDER_MAX_MEMORY, else DEFAULT_FRACTION of the physical memory."""
    text = os.environ.get(ENV, "").strip()
    if text:
        return parse_size(text)
    return int(physical_memory() * DEFAULT_FRACTION)


def human(n: float) -> str:
    """12884901888 -> '12 GiB', 1536 -> '1.5 KiB'."""
    n = float(n)
    for unit in ("bytes", "KiB", "MiB", "GiB", "TiB", "PiB"):
        if abs(n) < 1024 or unit == "PiB":
            return f"{int(n)} bytes" if unit == "bytes" else f"{n:.3g} {unit}"
        n /= 1024.0
    return f"{n:.3g} EiB"


class Budget:
    """Bytes one load may hold. Thread-safe: images decode on a thread pool."""

    def __init__(self, limit: Optional[int] = None):
        self.limit = memory_limit() if limit is None else int(limit)
        self.used = 0
        self._lock = threading.Lock()

    def _refuse(self, where, what: str, nbytes: int, held: int) -> BudgetError:
        size = f"{human(nbytes)} ({nbytes:,} bytes)"
        if held:
            return BudgetError(f"{where}: {what} would take {size}, which with the {human(held)} this load already "
                               f"holds is over the memory budget of {human(self.limit)} ({ENV})")
        return BudgetError(f"{where}: {what} would take {size}, over the memory budget of {human(self.limit)} "
                           f"({ENV})")

    def check(self, nbytes, where, what: str) -> None:
        """BudgetError when `nbytes` alone would not fit the budget (nothing is charged)."""
        nbytes = int(nbytes)
        if nbytes > self.limit:
            raise self._refuse(where, what, nbytes, 0)

    def charge(self, nbytes, where, what: str, peak=None) -> int:
        """Reserve `nbytes` for the rest of the load, after checking that `peak` (default `nbytes`:
        what the allocation needs while it is made, e.g. a decoder's own buffer) fits beside what
        the load holds. BudgetError naming `where` and `what` when it does not. Returns nbytes."""
        nbytes = int(nbytes)
        need = max(nbytes, int(peak)) if peak is not None else nbytes
        with self._lock:
            if need > self.limit:
                raise self._refuse(where, what, need, 0)
            if self.used + need > self.limit:
                raise self._refuse(where, what, need, self.used)
            self.used += nbytes
        return nbytes

    def release(self, nbytes) -> None:
        """Give back bytes charged for something the load has dropped."""
        with self._lock:
            self.used = max(0, self.used - int(nbytes))
