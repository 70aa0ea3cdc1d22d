"""The `clrender` command: a thin layer over the API (one module per command family).

`clrender.cli` was a module before the package: `clrender.cli.main` and `run` stay."""
from clrender._lazy import exports

__all__, __getattr__, __dir__ = exports(__name__, {
    "app": ("main", "run",),
}, fallback="app")
