"""TOML scene files: several meshes with transforms, a camera, render settings and lights.

```toml
ambient = 0.05                # optional, top level (before any table): Scene.ambient, default 0.03

[[mesh]]                      # any number, concatenated in file order
path = "demo.gltf"            # relative to this file: .gltf .glb .obj .ply .stl
name = "demo"                 # optional, prefixes the mesh names (default: the file name)
transform = { translate = [0, 0, 0], rotate_deg = [0, 30, 0], scale = 1.0 }   # optional
opacity = 0.5                 # optional, in [0, 1]: multiplies the opacity of every material of this mesh
refraction = 0.05             # optional, >= 0: sets the refraction strength of every material of this mesh
extras = { class = "chair" }  # optional table: the entry's object's extras (Scene.objects, Frame.object_id)

[[material]]                  # any number: override materials of the mesh files by name
name = "*curtain*"            # required: a material name as loaded (exact, or an fnmatch glob)
opacity = 0.6                 # optional, in [0, 1]: sets the material's opacity
refraction = 0.02             # optional, >= 0: sets its refraction strength
alpha_mode = "BLEND"          # optional: "OPAQUE" | "MASK" | "BLEND"
alpha_cutoff = 0.5            # optional, in [0, 1]: the MASK threshold

[camera]                      # optional; default: the first mesh file's camera, else none
eye = [0, 2, 8]
target = [0, 0, 0]
up = [0, 1, 0]                # optional, default [0, 1, 0]
fov_y_deg = 50                # optional, default 60
near = 0.1                    # optional, default 0.1
far = 100                     # optional, default 100
projection = "perspective"    # optional: "perspective" (default) or "orthographic", which takes
# xmag = 4, ymag = 3          #   instead of fov_y_deg the view box's half-width and half-height
                              #   (world units; the image aspect decides the width: ymag·W/H, as glTF
                              #   viewers do) and allows near = 0

[[camera.keys]]               # optional, instead of eye/target: keyframes (any number >= 1)
time = 0.0                    # seconds, strictly increasing from key to key
eye = [0, 2, 8]
target = [0, 0, 0]
fov_y_deg = 50                # optional, perspective only; default: [camera]'s fov_y_deg

[camera.orbit]                # optional, instead of eye/target and keys: eye circling center about +Y
center = [0, 1, 0]
radius = 8.0                  # > 0
height = 3.0                  # optional, default 0: the eye's y relative to center
period = 10.0                 # > 0: seconds per revolution
start_deg = 0.0               # optional, default 0: the angle at t = 0 (0: eye on center's +Z side)

[render]                      # -> Scene.settings["render"]
width = 960
height = 540
supersample = 2               # any RenderConfig option (README: options), e.g. bloom = true, edge_aa = true;
                              # the command line's flags override them

[[light]]                     # any number -> Scene.lights, in file order
type = "point"                # point | spot | directional
position = [0, 3, 2]          # point, spot: required
color = [1.0, 0.6, 0.3]       # optional, default [1, 1, 1]
intensity = 10.0              # optional, default 1; multiplies color
radius = 6.0                  # point, spot: optional (`range` is a synonym; at most one of the two)

[[light]]
type = "spot"
position = [0, 6, 3]
direction = [0, -1, -0.5]     # spot, directional: required (need not be unit length)
inner_cone_deg = 15           # spot: optional, default 0
outer_cone_deg = 25           # spot: optional, default 45; 0 <= inner <= outer < 90
shadow = true                 # spot: optional, default false: a shadow map over the cone
shadow_map_size = 1024        # spot: optional, default 1024 (texels per side, 16..8192)
keys = [{ time = 0, position = [0, 6, 3] }, { time = 2, position = [2, 6, 3], intensity = 8 }]
                              # point, spot: optional keyframes of position, color, intensity (each
                              #   optional; default the table's); `position` may then be left out
                              #   of the table when every key gives it. Also as [[light.keys]] tables

[sun]                         # optional: the directional light (Scene.sun), lights every pixel
direction = [-0.4, -1, -0.3]  # required: the way the light travels
color = [1.0, 0.95, 0.9]      # optional, default [1, 1, 1]
intensity = 3.0               # optional, default 1; multiplies color
shadow = true                 # optional, default true: cascaded shadow maps
shadow_map_size = 2048        # optional, default 2048 per cascade

[lights]                      # optional
random = { count = 64, seed = 7, radius = [0.5, 1.5], intensity = 1.0 }

[environment]                 # optional: an HDR environment lighting the scene (Scene.environment)
source = "studio.exr"         # required: an .exr/.hdr/.pic file relative to this file, or "studio"
intensity = 1.0               # optional, >= 0, default 1: scales its radiance
rotation = 0.0                # optional, degrees, default 0: turns it about +Y
background = true             # optional, default true: pixels that hit no surface show it
```

Environment (clrender/scene/environment.py: formats, the direction convention, the studio numbers): with
an `[environment]` table the scene is lit by the image (`Scene.set_environment`) and the constant
`ambient` term is not added. Without one a TOML scene has no environment, whatever its mesh files
are (a glTF file loaded alone gets the studio environment when it has no lights: `load_scene`).

Lights: `Scene.lights` holds, in this order, the lights of the mesh files (glTF
KHR_lights_punctual, moved by the mesh's transform), then the `[[light]]` tables in file order,
then `[lights] random` (`Scene.add_random_lights(count, seed, radius, intensity)`, called once all
meshes are loaded so the lights fill the whole scene's bounds; `count` is required, `seed`
defaults to 0, `radius` (a number or [min, max]) to [0.5, 2.0], `intensity` to 1). A point or spot
light without `radius`/`range` gets the infinite-range radius sqrt(256 * max(color * intensity))
clamped to [1e-3, 4 x scene diagonal] (`clrender.scene.lights`); radii and cone angles are not
changed by mesh transforms. `type = "directional"` (direction, color, intensity) goes to
`Scene.settings["directional_lights"]` as {direction (unit), color x intensity} with a warning;
without a `[sun]` table the first directional light (mesh files' first) becomes the sun.
`Scene.settings["lights"]` keeps the validated `[[light]]` tables as written.

Animation (clrender/scene/keyframes.py): camera keys, an orbit or light keys put a
`keyframes.KeyframeAnimation` on `Scene.animation`; `scene.pose(t, dt)` then sets the camera and
the keyed lights at time t and returns the camera at t - dt (as for glTF animations), and the
loaded scene is posed at t = 0. Keys interpolate linearly (eye, target, fov_y_deg; light position
and color x intensity), clamped to the first / last key outside their times; one key is a fixed
camera or light. The orbit's eye is center + (radius sin a, height, radius cos a), a = start_deg +
360° t / period, looking at center (up, near, far, fov_y_deg and projection from [camera]).
`Scene.animation.duration`: the last key time of all tracks, one period for an orbit. A light
without radius/range whose color is keyed gets the automatic radius of its color at each time.

Transparency (docs/transparency.md): a material is transparent when its `alpha_mode` is "BLEND";
its alpha is base_color.a x opacity x texture.a, and an opacity below 1 makes an "OPAQUE" material
"BLEND" (a "MASK" material with opacity < 1 is an error: set its `alpha_mode` to "BLEND" with a
`[[material]]` override). Material names are the mesh files' own (glTF `name`, MTL `newmtl`),
not prefixed by the mesh's `name`; patterns match case-sensitively (fnmatch), and every pattern
must match at least one loaded material. Each material's final values are: the `[[material]]`
keys of the tables matching it (in file order, a later table's key winning), else the loaded
values; then `opacity` times the mesh's `opacity`, and the mesh's `refraction` where no table
sets `refraction`. `refraction` only matters for BLEND materials rendered with
`RenderConfig(refraction=True)` (`clrender render --refraction`).

`ambient` lives at the top level (it is a Scene property, not a render setting); TOML puts keys
written after a table header into that table, so write it before the first `[...]` line.

Transform: world = T · R · S · local, with R = Rz · Ry · Rx (rotate about X first, then Y, then Z;
angles in degrees) and `scale` a number or three numbers. Unknown tables or keys, and wrong types,
are a SceneError naming the file and the key.
"""
from __future__ import annotations

import warnings

import fnmatch
import math
import tomllib
from dataclasses import replace
from pathlib import Path
from typing import Optional

import numpy as np

from clrender.scene import keyframes
from clrender.abi import structs
from clrender.scene.camera import Camera
from clrender.scene.model import ALPHA_MODES, Material, Scene, SceneError, SceneObject, Sun
from clrender.loaders import budget, confine
from clrender.loaders.common import (
    charge_scene_arrays, concat_vertex_attributes, fail, shift_textures, transform_normals, transform_points,
    transform_tangents, parse_nested)
from clrender.scene.lights import (
    AUTO_RADIUS_KEY, DIRECTIONAL_KEY, auto_radius, refresh_auto_radii, scene_diagonal, sun_from_directional,
    transform_lights, warn_directional)

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
        c = scene.camera
        eye, target = transform_points(matrix, [c.eye, c.target])
        up = matrix[:3, :3] @ np.asarray(c.up)
        scale = abs(np.linalg.det(matrix[:3, :3])) ** (1.0 / 3.0)
        if c.is_orthographic:
            scene.camera = Camera.orthographic(eye, target, up, c.xmag * scale, c.ymag * scale, c.near * scale,
                                               c.far * scale)
        else:
            scene.camera = Camera.look_at(eye, target, up, c.fov_y_deg, c.near * scale, c.far * scale)
    return scene


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
    import dataclasses

    from clrender.render.renderer import RenderConfig
    data = _table(path, "[render]", data)
    options = {f.name for f in dataclasses.fields(RenderConfig)}
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
        return load_environment(source, intensity, rotation, background)
    except SceneError as exc:
        raise fail(path, f"[environment]: {exc}") from None


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


def load_toml(path) -> Scene:
    from clrender.loaders import load_scene

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
            sub = load_scene(file, default_environment=False)
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
