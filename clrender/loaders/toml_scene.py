"""TOML scene files (format: docs/scene-format.md): the scene assembled from the checked tables
(clrender.loaders.toml_tables) and the mesh files, which load through the `load_mesh` function the
caller passes (clrender.loaders.load: `load_scene`, in the same load context).

Order: every table is checked first (a typo fails before any mesh file is read), then each
[[mesh]] loads, gets its materials' overrides and its transform, and the parts are concatenated
into one Scene (one object per [[mesh]] entry); then camera (`Scene.cameras`: [camera] as "camera", else
the mesh files' cameras as "<mesh name>/<camera name>"), ambient, environment, [render],
lights (the mesh files', [[light]], [lights] random), sun and keyframes.
"""
from __future__ import annotations

import fnmatch
import tomllib
import warnings
from dataclasses import replace
from pathlib import Path
from typing import Callable, Optional

import numpy as np

from clrender.scene import keyframes
from clrender.abi import structs
from clrender.scene.camera import Camera
from clrender.scene.model import Material, Scene, SceneError, SceneObject
from clrender.loaders import budget, confine
from clrender.loaders.common import (
    charge_scene_arrays, concat_vertex_attributes, fail, parse_nested, shift_textures, transform_normals,
    transform_points, transform_tangents)
from clrender.loaders.toml_tables import (
    MESH_KEYS, TOP_LEVEL, _camera, _environment, _lights, _material_overrides, _material_values, _mesh_transform,
    _number, _random_lights, _render, _sun, _table, _unknown)
from clrender.scene.lights import (
    AUTO_RADIUS_KEY, DIRECTIONAL_KEY, auto_radius, refresh_auto_radii, scene_diagonal, sun_from_directional,
    transform_lights, warn_directional)


def _transform_scene(scene: Scene, matrix: np.ndarray) -> Scene:
    """Move a loaded mesh file's scene (geometry, camera, lights) by `matrix`; ValueError if degenerate."""
    if np.array_equal(matrix, np.eye(4)):
        return scene
    transform_lights(scene, matrix)
    scene.positions = transform_points(matrix, scene.positions).astype(np.float32)
    scene.normals = transform_normals(matrix, scene.normals).astype(np.float32)
    scene.tangents = transform_tangents(matrix, scene.tangents)
    if np.linalg.det(matrix[:3, :3]) < 0:
        scene.triangles = np.ascontiguousarray(scene.triangles[:, [0, 2, 1]])
    if scene.camera is not None:
        scene.camera = _moved_camera(scene.camera, matrix)
    scene.cameras = [(name, _moved_camera(c, matrix)) for name, c in scene.cameras]
    return scene


def _moved_camera(c: Camera, matrix: np.ndarray) -> Camera:
    eye, target = transform_points(matrix, [c.eye, c.target])
    up = matrix[:3, :3] @ np.asarray(c.up)
    scale = abs(np.linalg.det(matrix[:3, :3])) ** (1.0 / 3.0)
    if c.is_orthographic:
        return Camera.orthographic(eye, target, up, c.xmag * scale, c.ymag * scale, c.near * scale, c.far * scale)
    return Camera.look_at(eye, target, up, c.fov_y_deg, c.near * scale, c.far * scale)


def _add_lights(path, scene: Scene, lights: list[dict]) -> None:
    """Append validated [[light]] tables to `scene` (point/spot -> Scene.lights, directional -> settings)."""
    diagonal = scene_diagonal(scene)
    auto = list(scene.settings.get(AUTO_RADIUS_KEY, []))
    directional = list(scene.settings.get(DIRECTIONAL_KEY, []))
    for k, light in enumerate(lights):
        kind = light["type"]
        color = np.asarray(light.get("color", [1.0, 1.0, 1.0]), np.float64) * light.get("intensity", 1.0)
        if kind == "directional":
            d = np.asarray(light["direction"], np.float64)
            directional.append({"direction": (d / np.linalg.norm(d)).tolist(), "color": color.tolist()})
            continue
        radius = light.get("radius", light.get("range"))
        position = light["position"] if "position" in light else light["keys"][0]["position"]
        if radius is None:
            radius = auto_radius(color, diagonal)
            auto.append(len(scene.lights))
        try:
            if kind == "point":
                scene.add_point_light(position, color, radius)
            else:
                scene.add_spot_light(position, light["direction"], color, radius,
                                     light.get("inner_cone_deg", 0.0), light.get("outer_cone_deg", 45.0),
                                     shadow=light.get("shadow", False),
                                     shadow_map_size=light.get("shadow_map_size", 1024))
        except SceneError as exc:
            raise fail(path, f"light[{k}]: {exc}") from None
    if auto:
        scene.settings[AUTO_RADIUS_KEY] = auto
    if directional:
        scene.settings[DIRECTIONAL_KEY] = directional


def _apply_materials(path, where: str, scene: Scene, mesh: dict, overrides: list, used: list[bool]) -> None:
    """Apply the [[material]] overrides and the [[mesh]] table's opacity/refraction (`mesh`) to the
    materials of one mesh file's scene; marks in `used` the overrides that matched."""
    materials = []
    for m in scene.materials:
        kw: dict = {}
        for i, (_, pattern, values) in enumerate(overrides):
            if fnmatch.fnmatchcase(m.name, pattern):
                used[i] = True
                kw.update(values)
        if "opacity" in mesh:
            kw["opacity"] = kw.get("opacity", m.opacity) * mesh["opacity"]
        if "refraction" in mesh and "refraction" not in kw:
            kw["refraction"] = mesh["refraction"]
        if kw:
            if kw.get("alpha_mode", m.alpha_mode) == "MASK" and kw.get("opacity", m.opacity) < 1.0:
                hint = ("a [[material]] table sets alpha_mode = \"MASK\"" if "alpha_mode" in kw else
                        f"make it BLEND with a [[material]] table (name = {m.name!r}, alpha_mode = \"BLEND\")")
                raise fail(path, f"{where}: material {m.name!r} is alpha_mode MASK and cannot have opacity "
                                 f"{kw.get('opacity', m.opacity):g} < 1; {hint}")
            try:
                m = replace(m, **kw)
            except SceneError as exc:
                raise fail(path, f"{where}: {exc}") from None
        materials.append(m)
    scene.materials = materials


def _concatenate(parts: list[tuple[str, Scene]], source: str, extras: Optional[list] = None) -> Scene:
    """The parts' scenes as one; each part (a [[mesh]] entry) is one object, with `extras[k]`."""
    positions, normals, uvs, triangles, tri_mat, tri_mesh, tri_face = [], [], [], [], [], [], []
    materials, textures, names = [], [], []
    objects, mesh_object = [], []                 # one object per [[mesh]] entry
    lights, auto, directional = [], [], []
    v_off = l_off = 0
    scenes = [s for _, s in parts]
    charge_scene_arrays(sum(len(s.positions) for s in scenes), sum(len(s.triangles) for s in scenes),
                        32 + 16 * any(s.colors is not None for s in scenes)
                        + 16 * any(s.tangents is not None for s in scenes)
                        + 8 * max((len(s.extra_uvs) for s in scenes if s.extra_uvs is not None), default=0), source)
    for label, s in parts:
        if s.deformation is not None or s.animation is not None:
            warnings.warn(f"{source}: mesh {label!r}: its animations, skins and morph targets are not carried into a "
                          f"TOML scene: drawn at its load pose (render the glTF file itself to animate it)",
                          stacklevel=4)
        auto.extend(int(i) + l_off for i in s.settings.get(AUTO_RADIUS_KEY, []))
        lights.append(s.lights)
        l_off += len(s.lights)
        directional.extend(s.settings.get(DIRECTIONAL_KEY, []))
        t_off, m_off, n_off = len(textures), len(materials), len(names)
        textures.extend(s.textures)
        materials.extend(shift_textures(m, t_off) for m in s.materials)
        names.extend(f"{label}:{n}" for n in s.mesh_names)
        mesh_object.extend([len(objects)] * len(s.mesh_names))
        objects.append(SceneObject(label, s.mesh_names[0] if len(s.mesh_names) == 1 else label, label,
                                   None if extras is None else extras[len(objects)]))
        positions.append(s.positions)
        normals.append(s.normals)
        uvs.append(s.uvs)
        triangles.append(s.triangles.astype(np.int64) + v_off)
        tri_mat.append(s.triangle_material + m_off)
        tri_mesh.append(s.triangle_mesh + n_off)
        tri_face.append(s.triangle_face)
        v_off += len(s.positions)
    if v_off > np.iinfo(np.int32).max:
        raise fail(source, f"too many vertices ({v_off}) for 32-bit indices")

    def cat(items, shape, dtype):
        return np.concatenate(items).astype(dtype) if items else np.zeros(shape, dtype)

    settings = {}
    if auto:
        settings[AUTO_RADIUS_KEY] = auto
    if directional:
        settings[DIRECTIONAL_KEY] = directional
    return Scene(cat(positions, (0, 3), np.float32), cat(normals, (0, 3), np.float32), cat(uvs, (0, 2), np.float32),
                 cat(triangles, (0, 3), np.int32), cat(tri_mat, (0,), np.int32),
                 materials=materials or [Material()],
                 textures=textures, mesh_names=names, objects=objects,
                 mesh_object=np.asarray(mesh_object, np.int32),
                 triangle_mesh=cat(tri_mesh, (0,), np.int32), triangle_face=cat(tri_face, (0,), np.int32),
                 source=source, settings=settings,
                 lights=np.concatenate(lights) if lights else np.zeros(0, structs.light_dtype),
                 **concat_vertex_attributes([s for _, s in parts]))


TOML_PARSE_FACTOR = 12


def load_toml(path, load_mesh: Callable[[Path], Scene]) -> Scene:
    """The Scene of TOML file `path`; `load_mesh(file)` loads each [[mesh]] file (a Scene)."""
    path = Path(path)
    try:
        # the text, and the tables tomllib makes of it (about ten times the text)
        budget.current().charge(path.stat().st_size * TOML_PARSE_FACTOR, path, "the file itself (parsed)")
        data = parse_nested(path, tomllib.loads, path.read_bytes().decode("utf-8"), "the TOML")
    except UnicodeDecodeError as exc:
        raise fail(path, f"not UTF-8 text ({exc.reason} at byte {exc.start})") from None
    except tomllib.TOMLDecodeError as exc:
        raise fail(path, f"TOML syntax error: {exc}") from None
    except OSError as exc:
        raise fail(path, f"cannot read file ({exc.strerror or exc})") from None
    _unknown(path, "the top level", data, TOP_LEVEL)

    # validate the other tables first: a typo fails before any mesh file is read
    ambient = None
    if "ambient" in data:
        ambient = _number(path, "ambient", data["ambient"])
        if ambient < 0:
            raise fail(path, f"ambient must be >= 0, got {ambient!r}")
    render = _render(path, data["render"]) if "render" in data else None
    tables = _lights(path, data["light"]) if "light" in data else None
    random = _random_lights(path, data["lights"]) if "lights" in data else None
    camera = _camera(path, data["camera"]) if "camera" in data else None
    sun = _sun(path, data["sun"]) if "sun" in data else None
    environment = _environment(path, data["environment"]) if "environment" in data else None
    overrides = _material_overrides(path, data["material"]) if "material" in data else []
    used = [False] * len(overrides)

    meshes = data.get("mesh", [])
    if not isinstance(meshes, list):
        raise fail(path, "mesh must be an array of tables ([[mesh]])")
    parts: list[tuple[str, Scene]] = []
    part_extras: list = []
    for k, entry in enumerate(meshes):
        where = f"mesh[{k}]"
        entry = _table(path, where, entry)
        _unknown(path, where, entry, MESH_KEYS)
        rel = entry.get("path")
        if not isinstance(rel, str) or not rel:
            raise fail(path, f"{where} needs a 'path' string")
        file = confine.reference(path, rel, f"{where}.path")
        if file.suffix.lower() == ".toml":
            raise fail(path, f"{where}.path {rel!r}: a TOML scene cannot include another TOML scene")
        if not file.is_file():
            raise fail(path, f"{where}.path: mesh file not found: {file}")
        matrix = _mesh_transform(path, k, entry["transform"]) if "transform" in entry else np.eye(4)
        label = entry.get("name", Path(rel).name)
        if not isinstance(label, str):
            raise fail(path, f"{where}.name must be a string")
        if "extras" in entry and not isinstance(entry["extras"], dict):
            raise fail(path, f"{where}.extras must be a table, got {entry['extras']!r}")
        part_extras.append(entry.get("extras"))
        mesh_values = _material_values(path, where, entry)
        try:
            sub = load_mesh(file)
        except SceneError as exc:
            raise SceneError(f"{path}: {where}: {exc}") from None
        _apply_materials(path, f"{where} ({rel})", sub, mesh_values, overrides, used)
        try:
            parts.append((label, _transform_scene(sub, matrix)))
        except ValueError as exc:
            raise fail(path, f"{where}.transform: {exc}") from None

    for (where, pattern, _), hit in zip(overrides, used):
        if not hit:
            loaded = sorted({m.name for _, sub in parts for m in sub.materials})
            shown = ", ".join(map(repr, loaded[:12])) + (f", ... ({len(loaded)} in all)" if len(loaded) > 12 else "")
            raise fail(path, f"{where}: name {pattern!r} matches no material of the mesh files "
                             f"(loaded: {shown or 'none'})")
    scene = _concatenate(parts, str(path), part_extras)
    camera_track = None if camera is None or isinstance(camera, Camera) else camera
    if camera_track is not None:
        camera = camera_track.base       # a valid camera; posed at t = 0 below
    scene.camera = camera if camera is not None else next((s.camera for _, s in parts if s.camera is not None), None)
    # [camera] (before any keyframes pose it), else the mesh files' cameras: scene.camera is the first
    scene.cameras = [("camera", camera)] if camera is not None else [
        (f"{label}/{name}", c) for label, s in parts for name, c in s.cameras]
    if ambient is not None:
        scene.ambient = ambient
    scene.environment = environment
    if render is not None:
        scene.settings["render"] = render
    first_light = len(scene.lights)
    if tables is not None:
        scene.settings["lights"] = tables
        _add_lights(path, scene, tables)
    if random is not None:
        try:
            scene.add_random_lights(random["count"], random["seed"], random["radius"], random["intensity"])
        except SceneError as exc:
            raise fail(path, f"lights.random: {exc}") from None
    refresh_auto_radii(scene)
    if sun is not None:
        scene.sun = sun
    else:
        sun_from_directional(scene)
    # the mesh files' directional lights and the [[light]] tables' (merged into settings)
    warn_directional(path, len(scene.settings.get(DIRECTIONAL_KEY, ())), sun_given=sun is not None, stacklevel=4)
    light_tracks = keyframes.light_tracks(tables or [], first_light, set(scene.settings.get(AUTO_RADIUS_KEY, [])),
                                          scene_diagonal(scene))
    if camera_track is not None or light_tracks:      # keyframes: posed at t = 0 once loaded
        scene.animation = keyframes.KeyframeAnimation(camera_track, light_tracks, str(path), base=scene.animation)
        scene.pose(0.0)
    return scene
