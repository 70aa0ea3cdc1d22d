"""`load_scene(path)`: the dispatch on the file suffix to each format's loader (clrender.loaders' docstring),
inside one load context (confinement, budget, the files read).
"""
from __future__ import annotations

import functools
import os
from pathlib import Path

from clrender.scene.model import Scene, SceneError

SUFFIXES = (".toml", ".gltf", ".glb", ".obj", ".ply", ".stl")

__all__ = ["load_scene", "SUFFIXES"]


def load_scene(path, default_environment: bool = True, allow=None, variant=None) -> Scene:
    """Load a scene file into a Scene (world space, triangles in load order).

    A glTF file (.gltf/.glb) that lights nothing itself (no KHR_lights_punctual light instanced in
    its scene: no point or spot light, no sun, no directional light) would render with the constant
    ambient term alone, nearly black: it gets the neutral studio environment instead
    (`scene.set_environment("studio")`, clrender.scene.environment) and
    `scene.settings["default_environment"] = True`, so the CLI can say so. A glTF that defines
    lights keeps exactly its lights. `default_environment=False` turns this off (the TOML loader's
    mesh files: a TOML scene has the [environment] table). OBJ/PLY/STL and TOML files get no default
    environment (`scene.environment` is None unless a TOML [environment] table sets one).

    `allow`: folders outside the scene file's own folder that the files it references may lie in
    (clrender.loaders.context; by default a scene reads only its own folder and data URIs).

    `variant`: the glTF material variant (KHR_materials_variants) to load with, as
    `scene.set_variant(variant)` after loading: an unknown name is a one-line SceneError listing
    the file's variants (`scene.variants`); None: the default materials."""
    scene = _load_confined(path, default_environment, allow)
    if variant is not None:
        scene.set_variant(variant)
    return scene


def _load_confined(path, default_environment: bool, allow) -> Scene:
    from clrender.loaders.context import loading
    if isinstance(allow, (str, os.PathLike)):      # one folder, not its characters
        allow = [allow]
    with loading(allow) as ctx:
        if ctx.scene_dir is not None:               # a TOML scene's mesh file: the TOML's folder stays
            return _load(path, default_environment)
        try:
            ctx.scene_dir = Path(path).parent.resolve()
        except (TypeError, OSError, RuntimeError, ValueError):
            return _load(path, default_environment)   # not a usable path: _load says so
        try:
            return _load(path, default_environment)
        finally:
            ctx.scene_dir = None


def _load(path, default_environment: bool) -> Scene:
    """`_dispatch`, recording the files read (`Scene.source_files`) and turning any unexpected
    failure (a library's AttributeError, MemoryError, RecursionError, PIL's DecompressionBombError)
    into one SceneError line naming the file; a KeyboardInterrupt stays one."""
    from clrender.loaders import context
    from clrender.interrupt import import_deferring_interrupts
    if isinstance(path, (str, os.PathLike)):
        context.record(path)
        if Path(path).suffix.lower() in (".obj", ".ply", ".stl"):      # glTF loads without trimesh
            # trimesh's import catches BaseException around its optional imports: a Ctrl-C there
            # would be swallowed and the job run to the end (issue 34, problem 7)
            import_deferring_interrupts("trimesh")
    try:
        scene = _dispatch(path, default_environment)
    except SceneError:
        raise
    except Exception as exc:
        raise SceneError(f"{path}: {_unexpected(exc)}") from exc
    scene.source_files = tuple(context.current().files)
    return scene


def _unexpected(exc: BaseException) -> str:
    """One capped line for an error a loader did not anticipate (never a file's content at length)."""
    if isinstance(exc, MemoryError):
        return "out of memory while loading (a count or size in the file is too large for this machine)"
    if isinstance(exc, RecursionError):
        return "structure nested too deeply to load"
    if isinstance(exc, OSError) and exc.strerror:
        return f"cannot read {exc.filename or 'the file'}: {exc.strerror}"
    first = next((ln.strip() for ln in str(exc).splitlines() if ln.strip()), "")
    if len(first) > 160:
        first = first[:157] + "..."
    name = type(exc).__name__
    if type(exc).__name__ == "DecompressionBombError":
        return f"an image is too large to decode ({first})"
    return f"cannot load ({name}: {first})" if first else f"cannot load ({name})"


def _dispatch(path, default_environment: bool) -> Scene:
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
    if suffix == ".toml":        # its mesh files load through load_scene, in this load's context
        from clrender.loaders.toml_scene import load_toml
        return load_toml(path, functools.partial(load_scene, default_environment=False))
    if suffix in (".gltf", ".glb"):
        from clrender.loaders.gltf.assemble import load_gltf
        scene = load_gltf(path)
        if default_environment and not _has_lights(scene):
            scene.set_environment("studio")
            scene.settings["default_environment"] = True
        return scene
    from clrender.loaders import mesh
    return {".obj": mesh.load_obj, ".ply": mesh.load_ply, ".stl": mesh.load_stl}[suffix](path)


def _has_lights(scene: Scene) -> bool:
    """Whether a loaded scene lights itself: punctual lights, a sun or directional lights."""
    from clrender.scene.lights import DIRECTIONAL_KEY
    settings = scene.settings if isinstance(scene.settings, dict) else {}
    return len(scene.lights) > 0 or scene.sun is not None or bool(settings.get(DIRECTIONAL_KEY))
