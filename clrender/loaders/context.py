"""What one `load_scene` call may read and allocate, shared by every loader it reaches.

A context variable holds the active `LoadContext`: a TOML scene's meshes load inside their scene's
context (one budget, one image cache), and two threads loading at once each have their own.
Code that runs a loader's work on a pool thread copies the context (`contextvars.copy_context`).

* `allow`: folders outside a scene file's own folder that its references may still reach
  (`load_scene(..., allow=[...])`, `--allow-outside PATH`); see `clrender.loaders.confine`.
* `budget`: the bytes a load may allocate from counts it read in files (`clrender.loaders.budget`).
* `images`: decoded images by resolved file path, so a file named by several entries is decoded once.
* `scene_dir`: the folder of the outermost scene file being loaded (set by `load_scene`): files a TOML
  scene's mesh files reference may lie anywhere in it.
* `files`: the resolved path of every file the load read (the scene files, and each reference
  `clrender.loaders.confine` let through), in first-read order: `Scene.source_files`, which the CLI
  checks its outputs against so a render never overwrites one of its own inputs.
"""
from __future__ import annotations

import contextlib
import contextvars
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterator, Optional, Sequence

from clrender.budget import Budget


@dataclass
class LoadContext:
    allow: tuple[Path, ...] = ()
    budget: Optional[Budget] = None      # loading() makes it; clrender.loaders.budget.current()
    images: dict = field(default_factory=dict)
    scene_dir: Optional[Path] = None     # the resolved folder of the file load_scene was called with
    files: dict = field(default_factory=dict)    # resolved Path -> None (an ordered set), see `record`


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
        if outer.budget is None:        # made now, so the nested load charges the same one
            outer.budget = Budget()
        ctx = LoadContext(allow=outer.allow + extra, budget=outer.budget, images=outer.images,
                          scene_dir=outer.scene_dir, files=outer.files)
    else:
        # the budget now, not lazily: a bad CLRENDER_MAX_MEMORY is its own one-line ValueError,
        # before any file is read, rather than an error inside some loader
        ctx = LoadContext(allow=extra, budget=Budget())
    token = _CURRENT.set(ctx)
    try:
        yield ctx
    finally:
        _CURRENT.reset(token)


def record(path) -> None:
    """Note that the active load reads `path` (resolved: symlinks and `..` cannot hide an input)."""
    ctx = _CURRENT.get()
    if ctx is None:
        return
    try:
        path = Path(path)
        ctx.files.setdefault(path.resolve(), None)
        # and the name in its resolved folder: replacing a symlink the scene reads through breaks it too
        ctx.files.setdefault(path.parent.resolve() / path.name, None)
    except (OSError, RuntimeError, ValueError):      # unresolvable: the loader reports it
        pass
