"""AOV previews and output files: how a rendered `Frame` and its AOVs land on disk.

`preview(name, data, background)` turns one AOV array into a viewable uint8 image (depth as
gray, normals as RGB, triangle ids as stable hash colors, velocity as a color wheel, ...);
`write_outputs(frame, image, aovs)` writes the image plus, per AOV, <stem>.<aov>.npy (exact),
<stem>.<aov>.png (preview) and <stem>.<aov>.exr (float AOVs, when `exr_available()`).
NumPy only at import; imageio is imported when something is written.
"""
from __future__ import annotations

import os
import tempfile
import warnings
from pathlib import Path
from typing import Sequence

import numpy as np

INT_AOVS = ("triangle_id", "fragment_count", "edges")     # integer AOVs: no .exr


# -- output files -----------------------------------------------------------------------------
_EXR_STATE: dict = {"available": None}


def exr_available() -> bool:
    """Whether imageio can write .exr with what is installed (probed once; never downloads)."""
    if _EXR_STATE["available"] is None:
        import imageio.v3 as iio
        saved = os.environ.get("IMAGEIO_NO_INTERNET")
        os.environ["IMAGEIO_NO_INTERNET"] = "1"
        try:
            with tempfile.TemporaryDirectory() as tmp, warnings.catch_warnings():
                warnings.simplefilter("ignore")      # imageio's deprecated legacy plugins load here
                iio.imwrite(os.path.join(tmp, "probe.exr"), np.zeros((2, 2, 3), np.float32), extension=".exr")
            _EXR_STATE["available"] = True
        except Exception:
            _EXR_STATE["available"] = False
        finally:
            if saved is None:
                os.environ.pop("IMAGEIO_NO_INTERNET", None)
            else:
                os.environ["IMAGEIO_NO_INTERNET"] = saved
    return _EXR_STATE["available"]


def aov_paths(image: Path, aovs: Sequence[str], exr: bool) -> list[Path]:
    """Every file `write_outputs` writes for `aovs` next to `image` (not `image` itself)."""
    stem = image.with_suffix("")
    paths = []
    for aov in aovs:
        paths += [Path(f"{stem}.{aov}.npy"), Path(f"{stem}.{aov}.png")]
        if exr and aov not in INT_AOVS:
            paths.append(Path(f"{stem}.{aov}.exr"))
    return paths


# -- previews -------------------------------------------------------------------------------
def _u8(x: np.ndarray) -> np.ndarray:
    return np.floor(np.clip(np.nan_to_num(x, nan=0.0), 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8)


def _preview_depth(depth: np.ndarray, background: np.ndarray) -> np.ndarray:
    """Near white -> far dark gray, background black."""
    fg = ~background & np.isfinite(depth)
    out = np.zeros(depth.shape, np.float64)
    if fg.any():
        lo, hi = float(depth[fg].min()), float(depth[fg].max())
        t = (depth[fg] - lo) / (hi - lo) if hi > lo else np.zeros(int(fg.sum()))
        out[fg] = 1.0 - 0.85 * t
    return _u8(out)


def _hash_u32(x: np.ndarray) -> np.ndarray:
    """A fixed integer hash (lowbias32), so a triangle keeps its color across runs and scenes."""
    h = x.astype(np.uint32)
    with np.errstate(over="ignore"):
        h ^= h >> np.uint32(16)
        h *= np.uint32(0x7FEB352D)
        h ^= h >> np.uint32(15)
        h *= np.uint32(0x846CA68B)
        h ^= h >> np.uint32(16)
    return h


def _preview_ids(ids: np.ndarray) -> np.ndarray:
    h = _hash_u32(ids)
    rgb = np.stack([(h >> np.uint32(s)) & np.uint32(255) for s in (0, 8, 16)], -1)
    rgb = (48 + rgb * 207 // 255).astype(np.uint8)      # never black: black is the background
    rgb[ids < 0] = 0
    return rgb


def _preview_velocity(vel: np.ndarray) -> np.ndarray:
    """Color wheel: hue = direction, brightness = speed relative to the fastest pixel."""
    v = np.nan_to_num(vel.astype(np.float64), nan=0.0, posinf=0.0, neginf=0.0)
    mag = np.hypot(v[..., 0], v[..., 1])
    peak = float(mag.max()) if mag.size else 0.0
    value = mag / peak if peak > 0 else np.zeros_like(mag)
    hue = (np.arctan2(-v[..., 1], v[..., 0]) / (2 * np.pi)) % 1.0
    k = (np.array([5.0, 3.0, 1.0]) + hue[..., None] * 6.0) % 6.0
    rgb = value[..., None] * (1.0 - np.clip(np.minimum(k, 4.0 - k), 0.0, 1.0))
    return _u8(rgb)


def _preview_heat(counts: np.ndarray) -> np.ndarray:
    """Counts (lights per tile, fragments per pixel) as a black -> red -> yellow -> white heat map
    (scaled to the maximum; all black when every count is 0)."""
    t = np.clip(counts.astype(np.float64) / max(int(counts.max()), 1), 0.0, 1.0)[..., None]
    ramp = np.clip(np.concatenate([t * 3.0, t * 3.0 - 1.0, t * 3.0 - 2.0], -1), 0.0, 1.0)
    return _u8(ramp)


def preview(name: str, data: np.ndarray, background: np.ndarray) -> np.ndarray:
    """A viewable uint8 image of AOV `name`."""
    from .gbuffer import SPEC_POWER_LOG2_MAX, linear_to_srgb8

    if name in ("depth", "linear_depth"):
        return _preview_depth(data, background)
    if name == "normal":
        out = _u8(data * 0.5 + 0.5)
        out[background] = 0
        return out
    if name in ("albedo", "emissive"):     # linear [0, 1] colours (emissive before its strength)
        return linear_to_srgb8(data)
    if name in ("specular_intensity", "ao", "transmittance", "occlusion"):   # [0, 1] as grey; white = unoccluded / clear
        return _u8(data)
    if name == "specular_power":
        return _u8(np.log2(np.maximum(data, 1.0)) / SPEC_POWER_LOG2_MAX)
    if name == "triangle_id":
        return _preview_ids(data)
    if name == "velocity":
        return _preview_velocity(data)
    if name == "color":                    # linear HDR: Reinhard, as the default image
        return linear_to_srgb8(data / (1.0 + np.maximum(data, 0.0)))
    if name in ("light_count", "fragment_count"):
        return _preview_heat(data)
    if name == "edges":                    # the edge-AA mask: marked pixels white on black
        return np.where(data > 0, 255, 0).astype(np.uint8)
    if name == "shadow":                   # (H, W, K): the darkest shadowed light per pixel, white = lit
        return _u8(data.min(-1) if data.shape[-1] else np.ones(data.shape[:2], np.float32))
    raise ValueError(f"no preview for AOV {name!r}")


def write_outputs(frame, image: Path, aovs: Sequence[str]) -> None:
    """Write `frame.image` to `image` (creating its folder), then `write_aovs` beside it."""
    import imageio.v3 as iio

    image = Path(image)
    image.parent.mkdir(parents=True, exist_ok=True)
    iio.imwrite(image, frame.image)
    write_aovs(frame, image, aovs)


def write_aovs(frame, image: Path, aovs: Sequence[str]) -> None:
    """Write each AOV of `frame` named in `aovs` next to `image`: <stem>.<aov>.npy (exact values),
    <stem>.<aov>.png (`preview`) and, for float AOVs when `exr_available()`, <stem>.<aov>.exr."""
    import imageio.v3 as iio

    stem = Path(image).with_suffix("")
    background = frame.triangle_id < 0
    for aov in aovs:
        data = np.asarray(frame.aov(aov))
        np.save(f"{stem}.{aov}.npy", data)
        iio.imwrite(f"{stem}.{aov}.png", preview(aov, data, background))
        if aov not in INT_AOVS and exr_available() and not (data.ndim == 3 and data.shape[2] not in (1, 2, 3, 4)):
            arr = data.astype(np.float32)
            if arr.ndim == 3 and arr.shape[2] == 2:       # velocity: pad to RGB
                arr = np.concatenate([arr, np.zeros_like(arr[..., :1])], -1)
            iio.imwrite(f"{stem}.{aov}.exr", arr, extension=".exr")
