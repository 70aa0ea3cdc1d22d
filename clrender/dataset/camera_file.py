"""Camera files: the shots `clrender view`'s "save view" appends, and `clrender render --camera FILE`
and `clrender dataset --cameras FILE` render (docs/datasets.md, *Camera files*).

    {"width": 800, "height": 600, "cameras": [{"eye": [0, 4, 10], "target": [0, 1, 0], "fov_y_deg": 45}, ...]}

(TOML: `width`/`height`, then one `[[cameras]]` table each; JSON may also be a bare list.) An entry
is a look-at camera (eye, target, optional up, fov_y_deg or ortho, principal_point) or OpenCV's
pinhole model (K, R, t in pixels of the file's width × height, else of the render size), with
optional near/far (default: around the scene's bounds), time (seconds: the scene's pose) and name.

Exactness: `camera_entry` gives plain floats, which json and the TOML writer below print as repr()
(17 significant digits at most: float64 round-trips), so entry_camera(camera_entry(c, W, H),
bounds, W, H) == c bit for bit for a look-at camera and for an orthographic one with
xmag = ymag * W / H (the half-width the image gives it anyway).
"""
from __future__ import annotations

import json
import math
import tomllib
import unicodedata
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

import numpy as np

from clrender.scene.camera import Camera

DEFAULT_FOV_DEG = 50.0
DEFAULT_NEAR, DEFAULT_FAR = 0.1, 100.0     # when the eye is not finite (a bad K/R/t, refused by Camera)
CAMERA_KEYS = {"eye", "target", "up", "fov_y_deg", "ortho", "principal_point", "K", "R", "t", "near", "far",
               "time", "name"}
PINHOLE_KEYS = {"K", "R", "t"}
SUFFIXES = (".json", ".toml")


def bounding_sphere(bounds) -> tuple[np.ndarray, float]:
    lo, hi = np.asarray(bounds, np.float64)
    return (lo + hi) / 2, max(float(np.linalg.norm(hi - lo)) / 2, 1e-6)


def near_far(eye, centre, radius: float) -> tuple[float, float]:
    """Depth range holding the bounding sphere seen from `eye` (a margin each side)."""
    dist = float(np.linalg.norm(np.subtract(eye, centre)))
    far = (dist + radius) * 1.1
    return max(0.9 * (dist - radius), 1e-3 * far), far


# -- one entry ------------------------------------------------------------------------------------
def _is_real(v) -> bool:
    return isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, (bool, np.bool_))


def _finite(v) -> bool:
    return _is_real(v) and math.isfinite(v)


def _reals(v, n: int) -> bool:
    return isinstance(v, (list, tuple, np.ndarray)) and len(v) == n and all(_finite(x) for x in v)


# key -> (accepts, what it must be); K, R and t are Camera.from_opencv's to check (shape, NaN, rotation)
_VALUE_CHECKS = {
    "eye": (lambda v: _reals(v, 3), "3 finite numbers [x, y, z]"),
    "target": (lambda v: _reals(v, 3), "3 finite numbers [x, y, z]"),
    "up": (lambda v: _reals(v, 3), "3 finite numbers [x, y, z]"),
    "fov_y_deg": (lambda v: _finite(v) and 0.0 < v < 180.0, "degrees in (0, 180)"),
    "ortho": (lambda v: _finite(v) and v > 0.0, "a positive half-height in world units"),
    "principal_point": (lambda v: _reals(v, 2), "2 finite numbers [cx, cy] (pixels)"),
    "near": (_finite, "a finite number"),
    "far": (_finite, "a finite number"),
    "time": (_finite, "a finite number of seconds"),
    "name": (lambda v: isinstance(v, str) and v != "" and not any(unicodedata.category(c) in ("Cc", "Cs") for c in v),
             "a non-empty string without control characters"),
}


def check_entry(entry) -> None:
    """ValueError (one line, no file name) unless `entry` is a camera: known keys of the right types,
    eye/target or K/R/t, and no keys that exclude each other."""
    if not isinstance(entry, dict):
        raise ValueError(f"expected a table of keys, got {entry!r}")
    unknown = sorted(set(entry) - CAMERA_KEYS, key=str)
    if unknown:
        raise ValueError(f"unknown key {unknown[0]!r} (keys: {', '.join(sorted(CAMERA_KEYS))})")
    for key, value in entry.items():
        if key in _VALUE_CHECKS and not _VALUE_CHECKS[key][0](value):
            raise ValueError(f"{key} must be {_VALUE_CHECKS[key][1]}, got {value!r}")
    pinhole, look = PINHOLE_KEYS & set(entry), {"eye", "target"} & set(entry)
    if (pinhole and look) or not (pinhole == PINHOLE_KEYS or len(look) == 2):
        raise ValueError("give either eye and target (optionally up, fov_y_deg or ortho, principal_point) "
                         "or K, R and t")
    for key in ("up", "fov_y_deg", "ortho", "principal_point"):
        if pinhole and key in entry:
            raise ValueError(f"{key} goes with eye/target, not with K/R/t")
    if "ortho" in entry and "fov_y_deg" in entry:
        raise ValueError("ortho (orthographic) and fov_y_deg (perspective) exclude each other")
    if "ortho" in entry and "principal_point" in entry:
        raise ValueError("principal_point is for perspective cameras, not with ortho")


def entry_camera(entry: dict, bounds, width: int, height: int, fov_y_deg: float = DEFAULT_FOV_DEG,
                 kw: Optional[int] = None, kh: Optional[int] = None) -> Camera:
    """The Camera of one entry rendered at width × height: K and principal_point in pixels of
    kw × kh (default: the render size), pixel centres at integer + 0.5; "ortho" (half-height ymag)
    gives xmag = ymag * width / height; fov_y_deg when the entry has none; near/far when absent
    enclose the bounding sphere of `bounds` ((lo, hi)). ValueError (one line, no file name)."""
    check_entry(entry)
    kw, kh = (kw, kh) if kw else (width, height)
    centre, radius = bounding_sphere(bounds)
    pinhole = "K" in entry
    if pinhole:
        R, t = np.asarray(entry["R"], np.float64), np.asarray(entry["t"], np.float64)
        eye = -R.T @ t if R.shape == (3, 3) and t.shape == (3,) else np.zeros(3)
    else:
        eye = entry["eye"]
    near, far = near_far(eye, centre, radius) if np.all(np.isfinite(eye)) else (DEFAULT_NEAR, DEFAULT_FAR)
    near, far = float(entry.get("near", near)), float(entry.get("far", far))
    if pinhole:
        return Camera.from_opencv(entry["K"], entry["R"], entry["t"], kw, kh, near, far)
    up = entry.get("up", (0.0, 1.0, 0.0))
    if "ortho" in entry:
        ymag = float(entry["ortho"])
        return Camera.orthographic(eye, entry["target"], up, ymag * width / height, ymag, near, far)
    fov = float(entry.get("fov_y_deg", fov_y_deg))
    intrinsics = None
    if "principal_point" in entry:
        # square pixels of kw × kh: fx = fy = (kh / 2) / tan(fov / 2), normalized by the size (scene/camera.py)
        cx, cy = (float(v) for v in entry["principal_point"])
        fy = 0.5 / math.tan(math.radians(fov) / 2.0)
        intrinsics = (fy * kh / kw, fy, cx / kw, cy / kh)
    return Camera(eye, entry["target"], up, fov, near, far, intrinsics=intrinsics)


def camera_entry(camera: Camera, width: int, height: int, *, time: Optional[float] = None,
                 name: Optional[str] = None) -> dict:
    """The entry of `camera` seen at width × height, of plain Python floats and lists (json-able):
    eye, target, up, fov_y_deg or ortho (ymag), principal_point (pixels) for a camera with
    intrinsics, near, far, time and name when given. A pinhole K whose pixels are not square at
    width × height (fx != fy) cannot be a fov and a principal point: its entry is K, R, t."""
    if camera.intrinsics is not None:
        fx, fy, cx, cy = camera.intrinsics
        if abs(fx * width - fy * height) > 1e-9 * fy * height:
            K, R, t = camera.to_opencv(width, height)
            entry = {"K": K.tolist(), "R": R.tolist(), "t": t.tolist()}
        else:
            entry = {"eye": list(camera.eye), "target": list(camera.target), "up": list(camera.up),
                     "fov_y_deg": float(camera.fov_y_deg), "principal_point": [cx * width, cy * height]}
    else:
        entry = {"eye": list(camera.eye), "target": list(camera.target), "up": list(camera.up)}
        if camera.is_orthographic:
            entry["ortho"] = float(camera.ymag)
        else:
            entry["fov_y_deg"] = float(camera.fov_y_deg)
    entry.update(near=float(camera.near), far=float(camera.far))
    if time is not None:
        entry["time"] = float(time) if _is_real(time) else time
    if name is not None:
        entry["name"] = name
    check_entry(entry)             # a bad time or name
    return entry


# -- files ----------------------------------------------------------------------------------------
@dataclass(frozen=True)
class CameraFile:
    """A camera file: its entries (dicts of CAMERA_KEYS, each checked) and the image size its K
    and principal points are given for."""
    path: str
    entries: tuple
    width: Optional[int] = None
    height: Optional[int] = None


def _parse(path: Path, text: str):
    toml = path.suffix.lower() == ".toml"
    try:
        return tomllib.loads(text) if toml else json.loads(text)
    except (ValueError, tomllib.TOMLDecodeError) as exc:
        raise ValueError(f"{path}: not valid {'TOML' if toml else 'JSON'} ({str(exc).splitlines()[0]})") from None
    except RecursionError:      # the parsers recurse per level of nesting
        raise ValueError(f"{path}: nested too deeply to be a camera file") from None


def _camera_file(path: Path, data) -> CameraFile:
    if isinstance(data, list):
        data = {"cameras": data}
    entries = data.get("cameras") if isinstance(data, dict) else None
    if not isinstance(entries, list) or not entries:
        raise ValueError(f"{path}: expected a non-empty list \"cameras\" of camera tables")
    size = [data.get("width"), data.get("height")]
    if size != [None, None] and not all(isinstance(v, int) and not isinstance(v, bool) and v > 0 for v in size):
        raise ValueError(f"{path}: width and height must both be positive integers, got {size}")
    for i, e in enumerate(entries):
        try:
            check_entry(e)
        except ValueError as exc:
            raise ValueError(f"{path}: camera {i}: {exc}") from None
    return CameraFile(str(path), tuple(entries), size[0], size[1])


def read_camera_file(path) -> CameraFile:
    """A .json or .toml camera file (module doc), every entry checked (check_entry). ValueError
    naming the file (and the camera, counted from 0)."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise ValueError(f"{path}: cannot read it ({exc.strerror or exc})") from None
    except UnicodeDecodeError:
        raise ValueError(f"{path}: not UTF-8 text") from None
    return _camera_file(path, _parse(path, text))


def file_camera(cf: CameraFile, i: int, bounds, width: int, height: int,
                fov_y_deg: float = DEFAULT_FOV_DEG) -> Camera:
    """Camera i of the file (entry_camera with the file's size for K and principal points);
    ValueError naming the file and the camera."""
    try:
        return entry_camera(cf.entries[i], bounds, width, height, fov_y_deg, cf.width, cf.height)
    except (ValueError, TypeError) as exc:
        raise ValueError(f"{cf.path}: camera {i}: {str(exc).splitlines()[0]}") from None


def file_cameras(cf: CameraFile, bounds, width: int, height: int, fov_y_deg: float = DEFAULT_FOV_DEG) -> list[Camera]:
    """Every camera of the file (file_camera), near/far where absent around `bounds`."""
    return [file_camera(cf, i, bounds, width, height, fov_y_deg) for i in range(len(cf.entries))]


# -- writing --------------------------------------------------------------------------------------
def _plain(value):
    """Numbers, strings and (nested) sequences as the JSON/TOML writers take them."""
    if isinstance(value, (str, bool)):
        return value
    if isinstance(value, (int, np.integer)):
        return int(value)
    if _is_real(value):
        return float(value)
    return [_plain(v) for v in value]


_TOML_ESCAPES = {'"': '\\"', "\\": "\\\\"}


def _toml_value(value) -> str:
    if isinstance(value, str):       # a basic string: escape quotes, backslashes and control characters
        return '"' + "".join(_TOML_ESCAPES.get(c, c) if c.isprintable() else f"\\U{ord(c):08X}" for c in value) + '"'
    if isinstance(value, list):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    return repr(value)               # int, or float: repr round-trips (finite: check_entry)


def _toml_table(entry: dict) -> str:
    return "[[cameras]]\n" + "".join(f"{k} = {_toml_value(v)}\n" for k, v in entry.items())


def _toml_document(width: int, height: int, entries) -> str:
    return f"width = {width}\nheight = {height}\n" + "".join("\n" + _toml_table(e) for e in entries)


def _json_document(data: dict) -> str:
    """One line per top-level value and per camera."""
    lines = [f" {json.dumps(k)}: {json.dumps(v, ensure_ascii=False)}," for k, v in data.items() if k != "cameras"]
    cameras = ",\n".join(f"  {json.dumps(e, ensure_ascii=False)}" for e in data["cameras"])
    return "{\n" + "\n".join(lines) + f'\n "cameras": [\n{cameras}\n ]\n}}\n'


def _appended_text(path: Path, text: str, entry: dict, width: int, height: int) -> str:
    """The file's new text with `entry` appended (an existing TOML keeps its text and comments: the
    table goes at the end)."""
    if path.suffix.lower() == ".json":
        data = json.loads(text)
        data["cameras"].append(entry)
        return _json_document(data)
    new = text + ("\n" if text and not text.endswith("\n") else "") + "\n" + _toml_table(entry)
    try:
        if len(tomllib.loads(new)["cameras"]) == len(tomllib.loads(text)["cameras"]) + 1:
            return new
    except (tomllib.TOMLDecodeError, KeyError, TypeError):
        pass
    data = tomllib.loads(text)       # cameras as an inline array: written again as tables
    if set(data) - {"width", "height", "cameras"}:
        raise ValueError(f"{path}: cannot append a [[cameras]] table to it (its cameras are not [[cameras]] "
                         f"tables and it has other keys)")
    return _toml_document(width, height, [*data["cameras"], entry])


def append_camera(path, entry: dict, width: int, height: int) -> int:
    """Append `entry` to the .json or .toml camera file `path`, creating it ({"width", "height",
    "cameras"}) if absent; returns the number of cameras now in it. An existing file must be a
    readable camera file for the same width × height. Written atomically (a temporary file in the
    same folder, renamed over it): on any error `path` is unchanged. ValueError naming the file."""
    from clrender.outputs.atomic import atomic_write
    path = Path(path)
    if path.suffix.lower() not in SUFFIXES:
        raise ValueError(f"{path}: a camera file is .json or .toml")
    if not all(isinstance(v, (int, np.integer)) and not isinstance(v, bool) and v > 0 for v in (width, height)):
        raise ValueError(f"{path}: width and height must be positive integers, got {width!r} x {height!r}")
    width, height = int(width), int(height)
    try:
        check_entry(entry)
        entry_camera(entry, ((-1.0,) * 3, (1.0,) * 3), width, height)    # a camera it can make
    except (ValueError, TypeError) as exc:
        raise ValueError(f"{path}: the new camera: {str(exc).splitlines()[0]}") from None
    entry = {k: _plain(v) for k, v in entry.items()}
    if path.exists():
        cf = read_camera_file(path)
        if (cf.width, cf.height) != (width, height):
            have = "no width and height" if cf.width is None else f"cameras for {cf.width}x{cf.height}"
            raise ValueError(f"{path}: it has {have}, not {width}x{height}: save into another file")
        text = _appended_text(path, path.read_text(encoding="utf-8"), entry, width, height)
    elif path.suffix.lower() == ".json":
        text = _json_document({"width": width, "height": height, "cameras": [entry]})
    else:
        text = _toml_document(width, height, [entry])
    written = _camera_file(path, _parse(path, text))          # what a reader will see
    if written.entries[-1] != entry:
        raise ValueError(f"{path}: the camera would not read back as written ({entry!r})")
    try:
        atomic_write(path, lambda tmp: Path(tmp).write_text(text, encoding="utf-8"))
    except OSError as exc:
        raise ValueError(f"{path}: cannot write it ({exc.strerror or exc})") from None
    return len(written.entries)
