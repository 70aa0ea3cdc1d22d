"""TOML scene files, the tables: each table of the file checked and turned into values (a Camera,
lights, an Environment, material overrides...), before any mesh file is read. The format:
docs/scene-format.md; the assembly of the scene from these values: clrender.loaders.toml_scene.
Every unknown table or key, and every wrong type, is a SceneError naming the file and the key.
"""
from __future__ import annotations

import math

import numpy as np

from clrender.scene import keyframes
from clrender.abi import structs
from clrender.scene.camera import Camera
from clrender.scene.model import ALPHA_MODES, SceneError, Sun
from clrender.loaders import budget, confine
from clrender.loaders.common import fail

TOP_LEVEL = {"mesh", "material", "camera", "render", "light", "lights", "ambient", "sun", "environment"}
ENVIRONMENT_KEYS = {"source", "intensity", "rotation", "background"}
SUN_KEYS = {"direction", "color", "intensity", "shadow", "shadow_map_size"}
MESH_KEYS = {"path", "name", "transform", "opacity", "refraction", "extras"}
MATERIAL_KEYS = {"name", "opacity", "refraction", "alpha_mode", "alpha_cutoff"}
TRANSFORM_KEYS = {"translate", "rotate_deg", "scale"}
CAMERA_KEYS = {"eye", "target", "up", "fov_y_deg", "near", "far", "projection", "xmag", "ymag", "keys", "orbit"}
# [render]: the image size, a background colour, and any RenderConfig option (validated by it)
RENDER_KEYS = {"width", "height", "background"}
LIGHT_KEYS = {"type", "name", "position", "direction", "color", "intensity", "radius", "range",
              "inner_cone_deg", "outer_cone_deg", "shadow", "shadow_map_size", "keys"}
LIGHT_TYPES = ("directional", "point", "spot")
# keys each light type accepts (the union is LIGHT_KEYS)
LIGHT_TYPE_KEYS = {
    "point": {"type", "name", "position", "color", "intensity", "radius", "range", "keys"},
    "spot": {"type", "name", "position", "direction", "color", "intensity", "radius", "range",
             "inner_cone_deg", "outer_cone_deg", "shadow", "shadow_map_size", "keys"},
    "directional": {"type", "name", "direction", "color", "intensity"},
}
LIGHT_REQUIRED = {"point": ("position",), "spot": ("position", "direction"), "directional": ("direction",)}
LIGHTS_KEYS = {"random"}
RANDOM_KEYS = {"count", "seed", "radius", "intensity"}


def _unknown(path, table: str, data: dict, allowed: set) -> None:
    extra = sorted(set(data) - allowed)
    if extra:
        hint = ""
        if extra[0] == "ambient":
            hint = "; ambient is a top-level key: write it before the first [table] line"
        raise fail(path, f"unknown key {extra[0]!r} in {table} (allowed: {', '.join(sorted(allowed))}){hint}")


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


def _camera(path, data):
    """[camera] -> a Camera, or with keys / orbit a keyframes.CameraKeys / Orbit."""
    data = _table(path, "[camera]", data)
    _unknown(path, "[camera]", data, CAMERA_KEYS)
    moving = "keys" in data or "orbit" in data
    for key in () if moving else ("eye", "target"):
        if key not in data:
            raise fail(path, f"[camera] needs {key!r} (or camera.keys / camera.orbit)")
    kw = {"up": _vector(path, "camera.up", data.get("up", [0, 1, 0]))}
    projection = data.get("projection", "perspective")
    if projection not in ("perspective", "orthographic"):
        raise fail(path, f"camera.projection must be \"perspective\" or \"orthographic\", got {projection!r}")
    ortho = projection == "orthographic"
    for key in ("fov_y_deg",) if ortho else ("xmag", "ymag"):
        if key in data:
            raise fail(path, f"[camera]: {key} applies to "
                             f"{'perspective' if ortho else 'orthographic'} cameras, not {projection!r} ones")
    for key in ("xmag", "ymag") if ortho else ():
        if key not in data:
            raise fail(path, f"[camera] with projection = \"orthographic\" needs {key!r} (half-"
                             f"{'width' if key == 'xmag' else 'height'} of the view box, world units)")
        kw[key] = _number(path, f"camera.{key}", data[key], positive=True)
    for key, default in ((() if ortho else (("fov_y_deg", 60.0),)) + (("near", 0.1), ("far", 100.0))):
        kw[key] = _number(path, f"camera.{key}", data.get(key, default), positive=not (ortho and key == "near"))

    def make(where, eye, target, fov_y_deg=None):
        if fov_y_deg is not None and ortho:
            raise fail(path, f"{where}: fov_y_deg applies to perspective cameras, not orthographic ones")
        try:
            if ortho:
                return Camera.orthographic(eye=eye, target=target, **kw)
            return Camera.look_at(eye=eye, target=target, **{**kw, **({} if fov_y_deg is None else
                                                                     {"fov_y_deg": fov_y_deg})})
        except ValueError as exc:
            raise fail(path, f"{where}: {exc}") from None

    if moving:
        return keyframes.camera_motion(path, data, make)
    return make("[camera]", _vector(path, "camera.eye", data["eye"]), _vector(path, "camera.target", data["target"]))


def _render(path, data) -> dict:
    from clrender.config import OPTION_NAMES, RenderConfig     # the option table (numpy only, no OpenCL)
    data = _table(path, "[render]", data)
    options = set(OPTION_NAMES)
    _unknown(path, "[render]", data, RENDER_KEYS | options)
    try:
        RenderConfig.from_options(**{k: v for k, v in data.items() if k in options})
    except ValueError as exc:
        raise fail(path, f"[render]: {exc}") from None
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
    return out


def _lights(path, data) -> list[dict]:
    """The [[light]] tables, validated, as written (numbers as floats)."""
    if not isinstance(data, list):
        raise fail(path, "light must be an array of tables ([[light]])")
    lights = []
    for k, light in enumerate(data):
        where = f"light[{k}]"
        light = _table(path, where, light)
        _unknown(path, where, light, LIGHT_KEYS)
        kind = light.get("type")
        if kind not in LIGHT_TYPES:
            raise fail(path, f"{where}.type must be one of {LIGHT_TYPES}, got {kind!r}")
        _unknown(path, f"{where} (type {kind!r})", light, LIGHT_TYPE_KEYS[kind])
        for key in LIGHT_REQUIRED[kind]:
            if key not in light and not (key == "position" and "keys" in light):
                raise fail(path, f"{where} (type {kind!r}) needs {key!r}")
        if "name" in light and not isinstance(light["name"], str):
            raise fail(path, f"{where}.name must be a string")
        out = dict(light)
        for key in ("position", "direction", "color"):
            if key in out:
                out[key] = _vector(path, f"{where}.{key}", out[key])
        for key in ("intensity", "radius", "range", "inner_cone_deg", "outer_cone_deg"):
            if key in out:
                out[key] = _number(path, f"{where}.{key}", out[key])
        _shadow_keys(path, where, out)
        if "keys" in out:    # without a table position, every key gives one
            out["keys"] = keyframes.light_keys(path, where, out["keys"], "position" in out)
        if "radius" in out and "range" in out:
            raise fail(path, f"{where}: give 'radius' or 'range' (a synonym), not both")
        for key in ("radius", "range"):
            if key in out and out[key] <= 0:
                raise fail(path, f"{where}.{key} must be > 0, got {out[key]!r}")
        if out.get("intensity", 1.0) < 0:
            raise fail(path, f"{where}.intensity must be >= 0, got {out['intensity']!r}")
        if any(c < 0 for c in out.get("color", ())):
            raise fail(path, f"{where}.color must be non-negative, got {out['color']!r}")
        if "direction" in out and not any(out["direction"]):
            raise fail(path, f"{where}.direction must not be the zero vector")
        if kind == "spot":
            inner, outer = out.get("inner_cone_deg", 0.0), out.get("outer_cone_deg", 45.0)
            if inner < 0:
                raise fail(path, f"{where}.inner_cone_deg must be >= 0, got {inner!r}")
            if inner > outer:
                raise fail(path, f"{where}.inner_cone_deg ({inner:g}) is larger than outer_cone_deg ({outer:g})")
            if outer >= 90:
                raise fail(path, f"{where}.outer_cone_deg must be < 90, got {outer!r}")
        lights.append(out)
    return lights


def _shadow_keys(path, where: str, table: dict) -> None:
    if "shadow" in table and not isinstance(table["shadow"], bool):
        raise fail(path, f"{where}.shadow must be true or false, got {table['shadow']!r}")
    size = table.get("shadow_map_size", 1024)
    if not (isinstance(size, int) and not isinstance(size, bool) and 16 <= size <= 8192):
        raise fail(path, f"{where}.shadow_map_size must be an integer in [16, 8192], got {size!r}")


def _sun(path, data) -> Sun:
    """[sun] -> Scene.sun."""
    data = _table(path, "[sun]", data)
    _unknown(path, "[sun]", data, SUN_KEYS)
    if "direction" not in data:
        raise fail(path, "[sun] needs 'direction'")
    direction = _vector(path, "sun.direction", data["direction"])
    color = np.asarray(_vector(path, "sun.color", data.get("color", [1.0, 1.0, 1.0])), np.float64)
    intensity = _number(path, "sun.intensity", data.get("intensity", 1.0))
    _shadow_keys(path, "sun", {"shadow_map_size": 2048, **data})
    try:
        return Sun(direction, color * intensity, data.get("shadow", True), data.get("shadow_map_size", 2048))
    except SceneError as exc:
        raise fail(path, f"[sun]: {exc}") from None


def _environment(path, data):
    """[environment] -> an Environment (clrender.scene.environment), its file relative to the TOML file."""
    from clrender.scene.environment import STUDIO, load_environment
    data = _table(path, "[environment]", data)
    _unknown(path, "[environment]", data, ENVIRONMENT_KEYS)
    source = data.get("source")
    if not isinstance(source, str) or not source.strip():
        raise fail(path, f"[environment] needs 'source': a file path (.exr, .hdr, .pic) or \"studio\", "
                         f"got {source!r}")
    intensity = _number(path, "environment.intensity", data.get("intensity", 1.0))
    if intensity < 0:
        raise fail(path, f"environment.intensity must be >= 0, got {intensity!r}")
    rotation = _number(path, "environment.rotation", data.get("rotation", 0.0))
    background = data.get("background", True)
    if not isinstance(background, bool):
        raise fail(path, f"environment.background must be true or false, got {background!r}")
    if source.strip().lower() != STUDIO:
        source = confine.reference(path, source, "environment.source")
    try:
        return load_environment(source, intensity, rotation, background, budget.current())
    except SceneError as exc:
        raise fail(path, f"[environment]: {exc}") from None


RANDOM_LIGHT_BYTES = 2 * structs.light_dtype.itemsize + 7 * 8


def _random_lights(path, data) -> dict:
    """[lights] -> keyword arguments for Scene.add_random_lights (None when there is no `random`)."""
    data = _table(path, "[lights]", data)
    _unknown(path, "[lights]", data, LIGHTS_KEYS)
    if "random" not in data:
        raise fail(path, "[lights] is empty: expected random = { count = N, seed = S, radius = [min, max], "
                         "intensity = I }")
    where = "lights.random"
    rnd = _table(path, where, data["random"])
    _unknown(path, where, rnd, RANDOM_KEYS)
    if "count" not in rnd:
        raise fail(path, f"{where} needs 'count'")
    out = {}
    for key, default in (("count", None), ("seed", 0)):
        value = rnd.get(key, default)
        if isinstance(value, bool) or not isinstance(value, int) or value < 0:
            raise fail(path, f"{where}.{key} must be an integer >= 0, got {value!r}")
        out[key] = value
    # checked here, before any mesh file loads: each light is a light_dtype record plus the
    # generator's float64 draws and the concatenated copy (Scene.add_random_lights)
    budget.current().charge(out["count"] * RANDOM_LIGHT_BYTES, path, f"{where}.count ({out['count']} lights)")
    radius = rnd.get("radius", [0.5, 2.0])
    if isinstance(radius, list):
        radius = _vector(path, f"{where}.radius", radius, 2)
    else:
        radius = [_number(path, f"{where}.radius", radius)] * 2
    if not 0 < radius[0] <= radius[1]:
        raise fail(path, f"{where}.radius must satisfy 0 < min <= max, got {rnd['radius']!r}")
    out["radius"] = tuple(radius)
    out["intensity"] = _number(path, f"{where}.intensity", rnd.get("intensity", 1.0))
    if out["intensity"] < 0:
        raise fail(path, f"{where}.intensity must be >= 0, got {out['intensity']!r}")
    return out


def _in_range(path, key: str, value, lo: float, hi: float = math.inf) -> float:
    value = _number(path, key, value)
    if not lo <= value <= hi:
        raise fail(path, f"{key} must be in [{lo:g}, {hi:g}], got {value!r}" if hi < math.inf
                   else f"{key} must be >= {lo:g}, got {value!r}")
    return value


def _material_values(path, where: str, table: dict) -> dict:
    """The material keys of `table` (a [[mesh]] or [[material]] table), validated."""
    out = {}
    if "opacity" in table:
        out["opacity"] = _in_range(path, f"{where}.opacity", table["opacity"], 0.0, 1.0)
    if "refraction" in table:
        out["refraction"] = _in_range(path, f"{where}.refraction", table["refraction"], 0.0)
    if "alpha_mode" in table:
        mode = table["alpha_mode"]
        if mode not in ALPHA_MODES:
            raise fail(path, f"{where}.alpha_mode must be one of {', '.join(map(repr, ALPHA_MODES))}, got {mode!r}")
        out["alpha_mode"] = mode
    if "alpha_cutoff" in table:
        out["alpha_cutoff"] = _in_range(path, f"{where}.alpha_cutoff", table["alpha_cutoff"], 0.0, 1.0)
    return out


def _material_overrides(path, data) -> list[tuple[str, str, dict]]:
    """[[material]] -> (where, name pattern, values) per table, in file order."""
    if not isinstance(data, list):
        raise fail(path, "material must be an array of tables ([[material]])")
    out = []
    for k, table in enumerate(data):
        where = f"material[{k}]"
        table = _table(path, where, table)
        _unknown(path, where, table, MATERIAL_KEYS)
        name = table.get("name")
        if not isinstance(name, str) or not name:
            raise fail(path, f"{where} needs a 'name' string (a material name or a glob such as \"*glass*\")")
        where = f"{where} ({name!r})"
        values = _material_values(path, where, table)
        if not values:
            raise fail(path, f"{where} changes nothing: give at least one of "
                             f"{', '.join(sorted(MATERIAL_KEYS - {'name'}))}")
        out.append((where, name, values))
    return out
