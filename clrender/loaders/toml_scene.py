"""TOML scene files: several meshes with transforms, a camera, render settings and lights.

```toml
[[mesh]]                      # any number, concatenated in file order
path = "demo.gltf"            # relative to this file: .gltf .glb .obj .ply .stl
name = "demo"                 # optional, prefixes the mesh names (default: the file name)
transform = { translate = [0, 0, 0], rotate_deg = [0, 30, 0], scale = 1.0 }   # optional

[camera]                      # optional; default: the first mesh file's camera, else none
eye = [0, 2, 8]
target = [0, 0, 0]
up = [0, 1, 0]                # optional, default [0, 1, 0]
fov_y_deg = 50                # optional, default 60
near = 0.1                    # optional, default 0.1
far = 100                     # optional, default 100

[render]                      # -> Scene.settings["render"]
width = 960
height = 540

[[light]]                     # -> Scene.settings["lights"], plain dicts (a later issue renders them)
type = "directional"          # directional | point | spot
direction = [-1, -2, -1]
color = [1, 1, 1]
intensity = 3.0
```

Transform: world = T · R · S · local, with R = Rz · Ry · Rx (rotate about X first, then Y, then Z;
angles in degrees) and `scale` a number or three numbers. Unknown tables or keys, and wrong types,
are a SceneError naming the file and the key.
"""
from __future__ import annotations

import math
import tomllib
from dataclasses import replace
from pathlib import Path

import numpy as np

from ..camera import Camera
from ..scene import Material, Scene, SceneError
from .common import fail, transform_normals, transform_points

TOP_LEVEL = {"mesh", "camera", "render", "light"}
MESH_KEYS = {"path", "name", "transform"}
TRANSFORM_KEYS = {"translate", "rotate_deg", "scale"}
CAMERA_KEYS = {"eye", "target", "up", "fov_y_deg", "near", "far"}
# render settings understood by the renderer; extend this set when a new setting is added
RENDER_KEYS = {"width", "height", "background", "exposure"}
LIGHT_KEYS = {"type", "name", "position", "direction", "color", "intensity", "range",
              "inner_cone_deg", "outer_cone_deg"}
LIGHT_TYPES = ("directional", "point", "spot")


def _unknown(path, table: str, data: dict, allowed: set) -> None:
    extra = sorted(set(data) - allowed)
    if extra:
        raise fail(path, f"unknown key {extra[0]!r} in {table} (allowed: {', '.join(sorted(allowed))})")


def _table(path, name: str, value) -> dict:
    if not isinstance(value, dict):
        raise fail(path, f"{name} must be a table")
    return value


def _number(path, key: str, value, positive=False) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise fail(path, f"{key} must be a finite number, got {value!r}")
    if positive and value <= 0:
        raise fail(path, f"{key} must be > 0, got {value!r}")
    return float(value)


def _vector(path, key: str, value, n: int = 3) -> list[float]:
    if not isinstance(value, list) or len(value) != n:
        raise fail(path, f"{key} must be an array of {n} numbers, got {value!r}")
    return [_number(path, key, v) for v in value]


def transform_matrix(translate=(0.0, 0.0, 0.0), rotate_deg=(0.0, 0.0, 0.0), scale=1.0) -> np.ndarray:
    """T · Rz · Ry · Rx · S (float64, 4x4)."""
    rx, ry, rz = np.radians(np.asarray(rotate_deg, np.float64))
    cx, sx, cy, sy, cz, sz = np.cos(rx), np.sin(rx), np.cos(ry), np.sin(ry), np.cos(rz), np.sin(rz)
    Rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    Ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    Rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    m = np.eye(4)
    m[:3, :3] = Rz @ Ry @ Rx @ np.diag(np.broadcast_to(np.asarray(scale, np.float64), (3,)))
    m[:3, 3] = translate
    return m


def _mesh_transform(path, k: int, data) -> np.ndarray:
    where = f"mesh[{k}].transform"
    data = _table(path, where, data)
    _unknown(path, where, data, TRANSFORM_KEYS)
    translate = _vector(path, f"{where}.translate", data.get("translate", [0, 0, 0]))
    rotate = _vector(path, f"{where}.rotate_deg", data.get("rotate_deg", [0, 0, 0]))
    scale = data.get("scale", 1.0)
    scale = _vector(path, f"{where}.scale", scale) if isinstance(scale, list) else _number(path, f"{where}.scale", scale)
    return transform_matrix(translate, rotate, scale)


def _transform_scene(scene: Scene, matrix: np.ndarray) -> Scene:
    if np.array_equal(matrix, np.eye(4)):
        return scene
    scene.positions = transform_points(matrix, scene.positions).astype(np.float32)
    scene.normals = transform_normals(matrix, scene.normals).astype(np.float32)
    if np.linalg.det(matrix[:3, :3]) < 0:
        scene.triangles = np.ascontiguousarray(scene.triangles[:, [0, 2, 1]])
    if scene.camera is not None:
        c = scene.camera
        eye, target = transform_points(matrix, [c.eye, c.target])
        up = matrix[:3, :3] @ np.asarray(c.up)
        scale = abs(np.linalg.det(matrix[:3, :3])) ** (1.0 / 3.0)
        scene.camera = Camera.look_at(eye, target, up, c.fov_y_deg, c.near * scale, c.far * scale)
    return scene


def _camera(path, data) -> Camera:
    data = _table(path, "[camera]", data)
    _unknown(path, "[camera]", data, CAMERA_KEYS)
    for key in ("eye", "target"):
        if key not in data:
            raise fail(path, f"[camera] needs {key!r}")
    kw = {"eye": _vector(path, "camera.eye", data["eye"]), "target": _vector(path, "camera.target", data["target"]),
          "up": _vector(path, "camera.up", data.get("up", [0, 1, 0]))}
    for key, default in (("fov_y_deg", 60.0), ("near", 0.1), ("far", 100.0)):
        kw[key] = _number(path, f"camera.{key}", data.get(key, default), positive=True)
    try:
        return Camera.look_at(**kw)
    except ValueError as exc:
        raise fail(path, f"[camera]: {exc}") from None


def _render(path, data) -> dict:
    data = _table(path, "[render]", data)
    _unknown(path, "[render]", data, RENDER_KEYS)
    out = dict(data)
    for key in ("width", "height"):
        if key in out:
            value = out[key]
            if isinstance(value, bool) or not isinstance(value, int) or value <= 0:
                raise fail(path, f"render.{key} must be a positive integer, got {value!r}")
    if "background" in out:
        value = out["background"]
        if not isinstance(value, list) or len(value) not in (3, 4):
            raise fail(path, f"render.background must be 3 or 4 numbers, got {value!r}")
        out["background"] = [_number(path, "render.background", v) for v in value]
    if "exposure" in out:
        out["exposure"] = _number(path, "render.exposure", out["exposure"])
    return out


def _lights(path, data) -> list[dict]:
    if not isinstance(data, list):
        raise fail(path, "light must be an array of tables ([[light]])")
    lights = []
    for k, light in enumerate(data):
        where = f"light[{k}]"
        light = _table(path, where, light)
        _unknown(path, where, light, LIGHT_KEYS)
        if light.get("type") not in LIGHT_TYPES:
            raise fail(path, f"{where}.type must be one of {LIGHT_TYPES}, got {light.get('type')!r}")
        out = dict(light)
        for key in ("position", "direction", "color"):
            if key in out:
                out[key] = _vector(path, f"{where}.{key}", out[key])
        for key in ("intensity", "range", "inner_cone_deg", "outer_cone_deg"):
            if key in out:
                out[key] = _number(path, f"{where}.{key}", out[key])
        lights.append(out)
    return lights


def _concatenate(parts: list[tuple[str, Scene]], source: str) -> Scene:
    positions, normals, uvs, triangles, tri_mat, tri_mesh, tri_face = [], [], [], [], [], [], []
    materials, textures, names = [], [], []
    v_off = 0
    for label, s in parts:
        t_off, m_off, n_off = len(textures), len(materials), len(names)
        textures.extend(s.textures)
        materials.extend(replace(m, base_color_texture=m.base_color_texture + t_off)
                         if m.base_color_texture >= 0 else m for m in s.materials)
        names.extend(f"{label}:{n}" for n in s.mesh_names)
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

    return Scene(cat(positions, (0, 3), np.float32), cat(normals, (0, 3), np.float32), cat(uvs, (0, 2), np.float32),
                 cat(triangles, (0, 3), np.int32), cat(tri_mat, (0,), np.int32),
                 materials=materials or [Material()],
                 textures=textures, mesh_names=names,
                 triangle_mesh=cat(tri_mesh, (0,), np.int32), triangle_face=cat(tri_face, (0,), np.int32),
                 source=source)


def load_toml(path) -> Scene:
    from . import load_scene

    path = Path(path)
    try:
        data = tomllib.loads(path.read_bytes().decode("utf-8"))
    except UnicodeDecodeError as exc:
        raise fail(path, f"not UTF-8 text ({exc.reason} at byte {exc.start})") from None
    except tomllib.TOMLDecodeError as exc:
        raise fail(path, f"TOML syntax error: {exc}") from None
    except OSError as exc:
        raise fail(path, f"cannot read file ({exc.strerror or exc})") from None
    _unknown(path, "the top level", data, TOP_LEVEL)

    meshes = data.get("mesh", [])
    if not isinstance(meshes, list):
        raise fail(path, "mesh must be an array of tables ([[mesh]])")
    parts: list[tuple[str, Scene]] = []
    for k, entry in enumerate(meshes):
        where = f"mesh[{k}]"
        entry = _table(path, where, entry)
        _unknown(path, where, entry, MESH_KEYS)
        rel = entry.get("path")
        if not isinstance(rel, str) or not rel:
            raise fail(path, f"{where} needs a 'path' string")
        file = (path.parent / rel)
        if file.suffix.lower() == ".toml":
            raise fail(path, f"{where}.path {rel!r}: a TOML scene cannot include another TOML scene")
        if not file.is_file():
            raise fail(path, f"{where}.path: mesh file not found: {file}")
        matrix = _mesh_transform(path, k, entry["transform"]) if "transform" in entry else np.eye(4)
        label = entry.get("name", Path(rel).name)
        if not isinstance(label, str):
            raise fail(path, f"{where}.name must be a string")
        try:
            sub = load_scene(file)
        except SceneError as exc:
            raise SceneError(f"{path}: {where}: {exc}") from None
        parts.append((label, _transform_scene(sub, matrix)))

    scene = _concatenate(parts, str(path))
    if "camera" in data:
        scene.camera = _camera(path, data["camera"])
    else:
        scene.camera = next((s.camera for _, s in parts if s.camera is not None), None)
    settings = {}
    if "render" in data:
        settings["render"] = _render(path, data["render"])
    if "light" in data:
        settings["lights"] = _lights(path, data["light"])
    scene.settings = settings
    return scene
