"""Scene loaders: `load_scene(path)` dispatches on the file suffix.

.gltf / .glb (glTF 2.0), .obj (+ .mtl), .ply, .stl (all through trimesh) and .toml (a scene file
that places several of those, with a camera, render settings and lights). Every loader returns one
world-space `clrender.scene.Scene` and reports bad input as `clrender.scene.SceneError`.
"""
from __future__ import annotations

from pathlib import Path

from ..scene import Scene, SceneError

SUFFIXES = (".toml", ".gltf", ".glb", ".obj", ".ply", ".stl")

__all__ = ["load_scene", "SUFFIXES"]


def load_scene(path) -> Scene:
    """Load a scene file into a Scene (world space, triangles in load order)."""
    try:
        path = Path(path)
    except TypeError:
        raise SceneError(f"{path!r}: not a file path") from None
    suffix = path.suffix.lower()
    if suffix not in SUFFIXES:
        raise SceneError(f"{path}: unsupported scene file type {suffix or '(no suffix)'!r} "
                         f"(supported: {', '.join(SUFFIXES)})")
    if not path.exists():
        raise SceneError(f"{path}: file not found")
    if not path.is_file():
        raise SceneError(f"{path}: not a file")
    if suffix == ".toml":
        from .toml_scene import load_toml
        return load_toml(path)
    if suffix in (".gltf", ".glb"):
        from .gltf import load_gltf
        return load_gltf(path)
    from . import mesh
    return {".obj": mesh.load_obj, ".ply": mesh.load_ply, ".stl": mesh.load_stl}[suffix](path)
