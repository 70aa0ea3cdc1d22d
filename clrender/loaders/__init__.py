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


def load_scene(path, default_environment: bool = True, allow=None) -> Scene:
    """Load a scene file into a Scene (world space, triangles in load order).

    A glTF file (.gltf/.glb) that lights nothing itself (no KHR_lights_punctual light instanced in
    its scene: no point or spot light, no sun, no directional light) would render with the constant
    ambient term alone, nearly black: it gets the neutral studio environment instead
    (`scene.set_environment("studio")`, clrender.environment) and
    `scene.settings["default_environment"] = True`, so the CLI can say so. A glTF that defines
    lights keeps exactly its lights. `default_environment=False` turns this off (the TOML loader's
    mesh files: a TOML scene has the [environment] table). OBJ/PLY/STL and TOML files get no default
    environment (`scene.environment` is None unless a TOML [environment] table sets one).

    `allow`: folders outside the scene file's own folder that the files it references may lie in
    (clrender.loaders.context; by default a scene reads only its own folder and data URIs)."""
    from .context import loading
    with loading(allow):
        return _load(path, default_environment)


def _load(path, default_environment: bool) -> Scene:
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
        scene = load_gltf(path)
        if default_environment and not _has_lights(scene):
            scene.set_environment("studio")
            scene.settings["default_environment"] = True
        return scene
    from . import mesh
    return {".obj": mesh.load_obj, ".ply": mesh.load_ply, ".stl": mesh.load_stl}[suffix](path)


def _has_lights(scene: Scene) -> bool:
    """Whether a loaded scene lights itself: punctual lights, a sun or directional lights."""
    from .lights import DIRECTIONAL_KEY
    settings = scene.settings if isinstance(scene.settings, dict) else {}
    return len(scene.lights) > 0 or scene.sun is not None or bool(settings.get(DIRECTIONAL_KEY))
