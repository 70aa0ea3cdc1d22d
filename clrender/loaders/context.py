"""What one `load_scene` call may read and allocate, shared by every loader it reaches.

A context variable holds the active `LoadContext`: a TOML scene's meshes load inside their scene's
context (one budget, one image cache), and two threads loading at once each have their own.
Code that runs a loader's work on a pool thread copies the context (`contextvars.copy_context`).

* `allow`: folders outside a scene file's own folder that its references may still reach
  (`load_scene(..., allow=[...])`, `--allow-outside PATH`); see `clrender.loaders.confine`.
* `budget`: the bytes a load may allocate from counts it read in files (`clrender.loaders.budget`).
* `images`: decoded images by resolved file path, so a file named by several entries is decoded once.
"""
from __future__ import annotations

import contextlib
import contextvars
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterator, Optional, Sequence


@dataclass
class LoadContext:
    allow: tuple[Path, ...] = ()
    budget: Optional[object] = None      # clrender.loaders.budget.Budget, made lazily
    images: dict = field(default_factory=dict)


_CURRENT: contextvars.ContextVar[Optional[LoadContext]] = contextvars.ContextVar("clrender_load_context",
                                                                                  default=None)


def current() -> LoadContext:
    """The active load's context, or a fresh default one outside any `loading()` block."""
    ctx = _CURRENT.get()
    return ctx if ctx is not None else LoadContext()


@contextlib.contextmanager
def loading(allow: Optional[Sequence] = None) -> Iterator[LoadContext]:
    """Enter a load: the outermost call makes the context, nested calls (a TOML scene's meshes)
    share it, adding their own `allow` folders if they pass any."""
    outer = _CURRENT.get()
    extra = tuple(Path(p).resolve() for p in (allow or ()))
    if outer is not None:
        if not extra:
            yield outer
            return
        ctx = LoadContext(allow=outer.allow + extra, budget=outer.budget, images=outer.images)
    else:
        ctx = LoadContext(allow=extra)
    token = _CURRENT.set(ctx)
    try:
        yield ctx
    finally:
        _CURRENT.reset(token)
