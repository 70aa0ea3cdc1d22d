"""Keyframe animation of TOML scenes: camera keys, a camera orbit, light keys.

`clrender.loaders.toml_tables` parses (format: docs/scene-format.md)::

    [camera]                       # up, near, far, projection, fov_y_deg, xmag, ymag as usual
    [[camera.keys]]                # any number >= 1, strictly increasing times
    time = 0.0                     # seconds
    eye = [0, 4, 10]
    target = [0, 1, 0]
    fov_y_deg = 50                 # optional (perspective only); default: [camera]'s

    [camera.orbit]                 # instead of keys
    center = [0, 1, 0]
    radius = 8.0                   # > 0
    height = 3.0                   # optional, default 0: eye y relative to center
    period = 10.0                  # > 0: seconds per revolution
    start_deg = 0.0                # optional: the angle at t = 0

    [[light]]                      # a point or spot light
    keys = [{ time = 0, position = [0, 2, 0] }, { time = 4, position = [2, 2, 0], intensity = 5 }]

and puts a `KeyframeAnimation` on `Scene.animation`, so that `scene.pose(t, dt)` works as for glTF
animations (clrender.scene.animation): it sets `scene.camera` to the camera at t, replaces
`scene.lights` by a copy with the keyed lights moved, and returns the camera at t - dt (None when
dt is None). Posing is absolute. Keys interpolate linearly (eye, target, fov_y_deg; light position
and radiance color x intensity); times before the first key clamp to the first, after the last to
the last; one key holds still. The orbit eye is center + (radius sin a, height, radius cos a) with
a = start_deg + 360 t / period (counter-clockwise seen from +Y; a = 0 puts the eye on +Z), looking
at the center. `duration`: the last key time over all tracks, one period for an orbit.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Optional, Union

import numpy as np

from clrender.errors import SceneError

CAMERA_KEY_KEYS = {"time", "eye", "target", "fov_y_deg"}
ORBIT_KEYS = {"center", "radius", "height", "period", "start_deg"}
LIGHT_KEY_KEYS = {"time", "position", "color", "intensity"}


# -- parsing helpers ---------------------------------------------------------------------------------------
def fail(path, message: str) -> SceneError:
    return SceneError(f"{path}: {message}")


def _number(path, key: str, value, positive: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise fail(path, f"{key} must be a finite number, got {value!r}")
    if positive and value <= 0:
        raise fail(path, f"{key} must be > 0, got {value!r}")
    return float(value)


def _vector(path, key: str, value) -> tuple:
    if not isinstance(value, list) or len(value) != 3:
        raise fail(path, f"{key} must be an array of 3 numbers, got {value!r}")
    return tuple(_number(path, key, v) for v in value)


def _check_table(path, where: str, value, allowed: set) -> dict:
    if not isinstance(value, dict):
        raise fail(path, f"{where} must be a table")
    extra = sorted(set(value) - allowed)
    if extra:
        raise fail(path, f"unknown key {extra[0]!r} in {where} (allowed: {', '.join(sorted(allowed))})")
    return value


def _keys(path, where: str, value, allowed: set, required: tuple) -> list[dict]:
    """An array of key tables: known keys, required ones present, finite strictly increasing times."""
    if not isinstance(value, list) or not value:
        raise fail(path, f"{where} must be a non-empty array of tables, got {value!r}")
    keys = []
    for k, key in enumerate(value):
        name = f"{where}[{k}]"
        key = _check_table(path, name, key, allowed)
        for r in ("time",) + required:
            if r not in key:
                raise fail(path, f"{name} needs {r!r}")
        key = dict(key, time=_number(path, f"{name}.time", key["time"]))
        if keys and key["time"] <= keys[-1]["time"]:
            raise fail(path, f"{where}: times must be strictly increasing, but {name}.time = {key['time']:g} "
                             f"follows {keys[-1]['time']:g}")
        keys.append(key)
    return keys


def _lerp(times: np.ndarray, values: np.ndarray, t: float) -> np.ndarray:
    """Linear interpolation of values (K, C) at t, clamped outside [times[0], times[-1]]."""
    last = len(times) - 1
    if t <= times[0] or last == 0:
        return values[0]
    if t >= times[last]:
        return values[last]
    k = int(np.searchsorted(times, t, side="right")) - 1
    u = (t - times[k]) / (times[k + 1] - times[k])
    return (1.0 - u) * values[k] + u * values[k + 1]


# -- tracks ------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class CameraKey:
    time: float
    eye: tuple
    target: tuple
    fov_y_deg: float              # perspective; ignored (the base's) for orthographic cameras


@dataclass(frozen=True)
class CameraKeys:
    """Keyed camera: `base` gives up, near, far and the projection; keys the rest."""
    keys: tuple
    base: object                  # clrender.Camera

    @property
    def duration(self) -> float:
        return self.keys[-1].time

    def camera_at(self, t: float):
        times = np.array([k.time for k in self.keys])
        v = _lerp(times, np.array([k.eye + k.target + (k.fov_y_deg,) for k in self.keys]), t)
        fov = {} if self.base.is_orthographic else {"fov_y_deg": float(v[6])}
        return replace(self.base, eye=tuple(v[:3]), target=tuple(v[3:6]), **fov)


@dataclass(frozen=True)
class Orbit:
    center: tuple
    radius: float
    height: float
    period: float
    start_deg: float
    base: object                  # clrender.Camera: up, near, far, fov / projection

    @property
    def duration(self) -> float:
        return self.period

    def eye_at(self, t: float) -> tuple:
        a = math.radians(self.start_deg) + 2.0 * math.pi * (t / self.period)
        cx, cy, cz = self.center
        return (cx + self.radius * math.sin(a), cy + self.height, cz + self.radius * math.cos(a))

    def camera_at(self, t: float):
        return replace(self.base, eye=self.eye_at(t), target=self.center)


@dataclass(frozen=True)
class LightKey:
    time: float
    position: tuple
    color: tuple                  # radiance: color x intensity


@dataclass(frozen=True)
class LightTrack:
    index: int                    # in scene.lights
    keys: tuple
    auto_radius_diagonal: Optional[float] = None   # set: the radius follows the colour (scene.lights)

    @property
    def duration(self) -> float:
        return self.keys[-1].time

    def at(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """(position, color) at time t."""
        times = np.array([k.time for k in self.keys])
        v = _lerp(times, np.array([k.position + k.color for k in self.keys]), t)
        return v[:3], v[3:]


class KeyframeAnimation:
    """Camera (keys or orbit) and light tracks of a TOML scene; `base`: an animation posed first
    (a glTF one), whose camera the camera track overrides."""

    def __init__(self, camera: Union[CameraKeys, Orbit, None], lights=(), source: str = "<TOML>", base=None):
        self.camera, self.lights, self.source, self.base = camera, tuple(lights), source, base

    @property
    def duration(self) -> float:
        ends = [track.duration for track in ((self.camera,) if self.camera else ()) + self.lights]
        if self.base is not None:
            ends.append(self.base.duration)
        return max(ends, default=0.0)

    def _camera_at(self, t: float):
        try:
            return self.camera.camera_at(t)
        except ValueError as exc:
            raise SceneError(f"{self.source}: [camera] at t={t:g}: {exc}") from None

    def pose(self, scene, t: float, dt: Optional[float] = None):
        """Pose `scene` at time t (module docstring); returns the camera at t - dt (None when dt is None)."""
        t = float(t)
        if not np.isfinite(t) or (dt is not None and not np.isfinite(float(dt))):
            raise SceneError(f"{self.source}: animation time must be finite, got t={t!r} dt={dt!r}")
        if self.base is not None:
            previous = self.base.pose(scene, t, dt)
        else:
            previous = None if dt is None else scene.camera
        if self.camera is not None:
            scene.camera = self._camera_at(t)
            previous = None if dt is None else self._camera_at(t - float(dt))
        if self.lights:
            from clrender.scene.lights import auto_radius
            arr = scene.lights.copy()
            for track in self.lights:
                position, color = track.at(t)
                arr["position"][track.index] = position
                arr["color"][track.index] = color
                if track.auto_radius_diagonal is not None:
                    arr["radius"][track.index] = auto_radius(color, track.auto_radius_diagonal)
            scene.lights = arr
        return previous


# -- TOML ----------------------------------------------------------------------------------------------------
def camera_motion(path, data: dict, make_camera) -> Union[CameraKeys, Orbit]:
    """[camera] with `keys` or `orbit` -> the track. make_camera(where, eye, target, fov_y_deg=None)
    builds a Camera from the rest of [camera] (SceneError naming `where` when invalid)."""
    if "keys" in data and "orbit" in data:
        raise fail(path, "[camera]: give camera.keys or camera.orbit, not both")
    kind = "keys" if "keys" in data else "orbit"
    for key in ("eye", "target"):
        if key in data:
            raise fail(path, f"[camera]: {key} comes from camera.{kind}; remove it from [camera]")
    if kind == "orbit":
        where = "camera.orbit"
        o = _check_table(path, f"[{where}]", data["orbit"], ORBIT_KEYS)
        for key in ("center", "radius", "period"):
            if key not in o:
                raise fail(path, f"[{where}] needs {key!r}")
        center = _vector(path, f"{where}.center", o["center"])
        radius = _number(path, f"{where}.radius", o["radius"], positive=True)
        period = _number(path, f"{where}.period", o["period"], positive=True)
        height = _number(path, f"{where}.height", o.get("height", 0.0))
        start = _number(path, f"{where}.start_deg", o.get("start_deg", 0.0))
        orbit = Orbit(center, radius, height, period, start, None)
        return replace(orbit, base=make_camera(f"[{where}]", orbit.eye_at(0.0), center))
    keys = _keys(path, "camera.keys", data["keys"], CAMERA_KEY_KEYS, ("eye", "target"))
    out = []
    base = None
    for k, key in enumerate(keys):
        name = f"camera.keys[{k}]"
        eye, target = _vector(path, f"{name}.eye", key["eye"]), _vector(path, f"{name}.target", key["target"])
        fov = _number(path, f"{name}.fov_y_deg", key["fov_y_deg"]) if "fov_y_deg" in key else None
        cam = make_camera(name, eye, target, fov)       # validates the key's camera
        base = base or cam
        out.append(CameraKey(key["time"], eye, target, cam.fov_y_deg))
    return CameraKeys(tuple(out), base)


def light_keys(path, where: str, value, has_position: bool) -> list[dict]:
    """A [[light]] table's `keys`, validated (numbers as floats)."""
    keys = _keys(path, f"{where}.keys", value, LIGHT_KEY_KEYS, () if has_position else ("position",))
    out = []
    for k, key in enumerate(keys):
        name = f"{where}.keys[{k}]"
        key = dict(key)
        for v in ("position", "color"):
            if v in key:
                key[v] = list(_vector(path, f"{name}.{v}", key[v]))
        if "intensity" in key:
            key["intensity"] = _number(path, f"{name}.intensity", key["intensity"])
        if key.get("intensity", 1.0) < 0 or any(c < 0 for c in key.get("color", ())):
            raise fail(path, f"{name}: color and intensity must be non-negative")
        out.append(key)
    return out


def light_tracks(tables: list[dict], first: int, auto: set, diagonal: float) -> list[LightTrack]:
    """Tracks of the validated [[light]] tables (added to scene.lights from index `first`, the
    directional ones skipped); a key's missing position, color or intensity is the table's."""
    tracks, index = [], first
    for light in tables:
        if light["type"] == "directional":
            continue
        if "keys" in light:
            keys = []
            for key in light["keys"]:
                color = np.asarray(key.get("color", light.get("color", [1.0, 1.0, 1.0])), np.float64)
                radiance = color * key.get("intensity", light.get("intensity", 1.0))
                keys.append(LightKey(key["time"], tuple(key.get("position", light.get("position"))),
                                     tuple(float(c) for c in radiance)))
            tracks.append(LightTrack(index, tuple(keys), diagonal if index in auto else None))
        index += 1
    return tracks
