"""The memory budget of one load: every count read from a file is turned into bytes and checked
here BEFORE the array it implies is made.

A file is small, the arrays its counts imply need not be: a 1 KB glTF whose accessor has no
bufferView (the spec fills it with zeros) and a count of 402,653,184 asks for gigabytes, a TOML
`[lights] random` count of 3·10^8 for 60 GB. Each such request is checked against

* the budget: `CLRENDER_MAX_MEMORY` (bytes, or a number with K, M, G or T: binary multiples,
  "8G", "512M", "1.5T"; or a percentage of the machine's physical memory, "25%"), else half of
  the machine's physical memory;
* the running total of the load (`Budget.used`): what the load already holds (accessor data,
  decoded images, the scene's arrays) plus the request.

Over it: one `BudgetError` (a SceneError) naming the file, the field and the bytes, e.g.
`a.gltf: accessors[0].count (402653184 x VEC3 of FLOAT) would take 14.4 GiB, over the memory
budget of 11.5 GiB (CLRENDER_MAX_MEMORY)`. The estimates are of what the loader really makes of
a count (an accessor's data and the float64 copy the loader works in; an image's decoded RGBA and
Pillow's own buffer), not only the raw bytes, so a request that passes fits in memory.

`current()` is the active load's Budget (clrender.loaders.context; made on first use and shared by
a TOML scene's mesh files and the image-decoding threads). Outside a load, each call gets a fresh
budget: single requests are still checked.
"""
from __future__ import annotations

import threading

from clrender.budget import (  # noqa: F401  (re-exported: the budget's arithmetic lives below the layers)
    DEFAULT_FRACTION, ENV, FALLBACK_MEMORY, Budget, BudgetError, human, memory_limit, parse_size, physical_memory)

__all__ = ["Budget", "BudgetError", "ENV", "current", "memory_limit", "parse_size", "physical_memory", "human"]


def current() -> Budget:
    """The active load's Budget, made on first use (a fresh one outside a load)."""
    from clrender.loaders.context import current as current_context
    ctx = current_context()
    budget = ctx.budget
    if budget is None:
        with _MAKE_LOCK:
            budget = ctx.budget
            if budget is None:
                budget = ctx.budget = Budget()
    return budget


_MAKE_LOCK = threading.Lock()
