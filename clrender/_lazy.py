"""Lazy public names for clrender's subpackages: `from clrender.device import Device` imports
clrender/device/core.py only when the name is first used, so importing a package (or one of its
light modules) never pulls in pyopencl, trimesh or dask by itself."""
from __future__ import annotations

import importlib
import importlib.util


def exports(package: str, table: dict[str, tuple[str, ...]], fallback: str | None = None):
    """(__all__, __getattr__, __dir__) for `package` from {submodule: public names}. `fallback`:
    the submodule that answers any other name (a package that replaced a module of the same name
    keeps that module's attributes reachable)."""
    where = {name: module for module, names in table.items() for name in names}

    def __getattr__(name: str):
        module = where.get(name)
        if module is not None:
            return getattr(importlib.import_module(f"{package}.{module}"), name)
        if not name.startswith("__") and importlib.util.find_spec(f"{package}.{name}") is not None:
            return importlib.import_module(f"{package}.{name}")
        if fallback is not None and not name.startswith("__"):
            target = importlib.import_module(f"{package}.{fallback}")
            if hasattr(target, name):
                return getattr(target, name)
        raise AttributeError(f"module {package!r} has no attribute {name!r}")

    def __dir__():
        return sorted(set(where) | set(table))

    return sorted(where), __getattr__, __dir__
