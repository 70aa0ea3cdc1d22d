"""AOV previews and output files: how a rendered `Frame` and its AOVs land on disk.

`preview(name, data, background)` turns one AOV array into a viewable uint8 image (depth as
gray, normals as RGB, triangle ids as stable hash colors, velocity as a color wheel, ...);
`write_outputs(frame, image, aovs, bit_depth=8, exr=False)` writes the image (8- or 16-bit) plus,
per AOV, <stem>.<aov>.npy (exact) and <stem>.<aov>.png (preview), and with `exr` one multi-layer
<stem>.exr holding the colour and every requested float AOV. `write_video(path, frames, fps)`
assembles frames into .mp4 (H.264) or .gif.

The pieces live beside this module: atomic writes (atomic.py), EXR (exr.py), previews and
contact sheets (previews.py), video (video.py); their names stay importable from here. Which AOVs
exist, their previews and EXR channels: the AOV table, clrender/abi/aovs.py.

Every file is written through `atomic_write`: to a temporary name in the destination folder,
renamed into place (os.replace) only once complete, and removed on failure, so a killed or
failed job never leaves a truncated file under a final name.

Libraries (optional extra `clrender[outputs]`):
- EXR: the maintained `OpenEXR` binding (Academy Software Foundation, PyPI `OpenEXR` >= 3.2).
  It installs from PyPI as a self-contained manylinux/macOS/Windows wheel (~2 MB, NumPy only),
  writes any number of named float32 channels, so one file holds every AOV as a layer
  (color.R/G/B, depth.Z, normal.X/Y/Z, velocity.X/Y, ao, ...), and reads them back bit-exact.
  imageio's EXR support goes through FreeImage, whose shared library imageio downloads at run
  time (not from PyPI; nothing here may reach the network), and writes one RGB(A) layer per file.
- Video: imageio-ffmpeg (a pip wheel bundling an ffmpeg with libx264) for .mp4; Pillow through
  imageio for .gif.
- 16-bit PNG: Pillow cannot write 16-bit RGB, so `_write_png16` encodes it with zlib (PNG is
  simple: one IHDR, zlib-deflated filter-0 rows, IEND).
NumPy only at import; imageio, OpenEXR and imageio-ffmpeg are imported when something is written.
"""
from __future__ import annotations

import os  # noqa: F401  (tests patch aov_io.os.replace: the one os module every writer renames with)
import struct
import zlib
from pathlib import Path
from typing import Sequence

import numpy as np

from clrender.abi.aovs import INT_AOVS  # noqa: F401  (the AOV table's; callers import it from here)
# The writers this module assembles, re-exported: callers and tests import them from here
from clrender.outputs.atomic import (  # noqa: F401
    PNG_COMPRESS_LEVEL, STALE_TEMP_S, OutputError, _SCANNED, _imwrite, _save_npy, atomic_write, remove_stale_temps,
    temp_prefix)
from clrender.outputs.exr import (  # noqa: F401
    EXR_CHANNELS, EXR_MISSING, _EXR_STATE, exr_available, exr_channels, exr_layers, read_exr, write_exr)
from clrender.outputs.previews import LABEL_HEIGHT, contact_sheet, preview  # noqa: F401
from clrender.outputs.video import (  # noqa: F401
    FFMPEG_MISSING, VIDEO_SUFFIXES, check_video_path, ffmpeg_available, write_video)

BIT_DEPTHS = (8, 16)


# -- the display image: 8 and 16 bits ---------------------------------------------------------
def tonemap(color: np.ndarray, operator: str = "reinhard", exposure: float = 1.0) -> np.ndarray:
    """kernels/tonemap.cl's `tonemap(c · exposure)` in float32: linear HDR -> linear [0, 1]."""
    c = np.maximum(np.asarray(color, np.float32) * np.float32(exposure), np.float32(0.0))
    if operator == "reinhard":
        return c / (np.float32(1.0) + c)
    if operator == "aces":
        num = c * (np.float32(2.51) * c + np.float32(0.03))
        den = c * (np.float32(2.43) * c + np.float32(0.59)) + np.float32(0.14)
        return np.clip(num / den, 0.0, 1.0).astype(np.float32)
    if operator == "clamp":
        return np.clip(c, 0.0, 1.0).astype(np.float32)
    raise ValueError(f"unknown tone-mapping operator {operator!r}")


def display_linear(frame) -> np.ndarray:
    """(H, W, 3) float32 in [0, 1]: the tone-mapped linear colour `frame.image` was sRGB-encoded
    from. With LDR post effects it is the device's final LDR planes (`frame.ldr`); otherwise
    tonemap.cl's operator applied here to `frame.color` (the HDR colour after bloom, motion blur
    and the supersample resolve, which is exactly what the tone-mapping kernel read)."""
    ldr = getattr(frame, "ldr", None)
    if ldr is not None:
        return np.clip(np.asarray(ldr, np.float32), 0.0, 1.0)
    return tonemap(frame.color, getattr(frame, "tonemap", "reinhard"), getattr(frame, "exposure", 1.0))


def linear_to_srgb16(x: np.ndarray) -> np.ndarray:
    """Linear [0, 1] -> 16-bit sRGB codes (the exact curve, rounded; the 8-bit image rounds the same
    curve to 255 levels, so round(v16 / 257) is within one code of it)."""
    x = np.clip(np.nan_to_num(np.asarray(x, np.float64), nan=0.0), 0.0, 1.0)
    s = np.where(x <= 0.0031308, x * 12.92, 1.055 * x ** (1 / 2.4) - 0.055)
    return np.floor(s * 65535.0 + 0.5).astype(np.uint16)


def image16(frame) -> np.ndarray:
    """(H, W, 3) uint16 sRGB: the display image at 16 bits, from the float colour (not `frame.image`)."""
    return linear_to_srgb16(display_linear(frame))


def _write_png16(path, rgb16: np.ndarray) -> None:
    """A 16-bit RGB (or grey) PNG: IHDR, one zlib stream of filter-0 big-endian rows, IEND."""
    a = np.ascontiguousarray(rgb16, np.uint16)
    if a.ndim == 2:
        a = a[..., None]
    h, w, c = a.shape
    colour_type = {1: 0, 3: 2, 4: 6}[c]
    rows = np.zeros((h, 1 + w * c * 2), np.uint8)
    rows[:, 1:] = a.astype(">u2").reshape(h, w * c).view(np.uint8)

    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)

    data = (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 16, colour_type, 0, 0, 0))
            + chunk(b"IDAT", zlib.compress(rows.tobytes(), 6)) + chunk(b"IEND", b""))

    def write(tmp):
        with open(tmp, "wb") as f:
            f.write(data)
    atomic_write(path, write)


def write_image(frame, path, bit_depth: int = 8) -> Path:
    """Write the display image of `frame` to `path`: 8 bits (`frame.image`, any imageio format) or
    16 bits (PNG only; `image16(frame)`)."""
    path = Path(path)
    if bit_depth not in BIT_DEPTHS:
        raise ValueError(f"bit_depth must be 8 or 16, got {bit_depth!r}")
    if bit_depth == 16:
        if path.suffix.lower() != ".png":
            raise ValueError(f"{path}: 16-bit images are written as PNG only (got {path.suffix!r})")
        _write_png16(path, image16(frame))
    else:
        _imwrite(path, frame.image)
    return path


def exr_path(image) -> Path:
    return Path(image).with_suffix(".exr")


def sheet_path(image) -> Path:
    return Path(image).with_suffix(".sheet.png")


def aov_paths(image: Path, aovs: Sequence[str], exr: bool, sheet: bool = False) -> list[Path]:
    """Every file `write_outputs` writes for `aovs` next to `image` (not `image` itself)."""
    stem = Path(image).with_suffix("")
    paths = []
    for aov in aovs:
        paths += [Path(f"{stem}.{aov}.npy"), Path(f"{stem}.{aov}.png")]
    if exr:
        paths.append(exr_path(image))
    if sheet:
        paths.append(sheet_path(image))
    return paths


def write_outputs(frame, image: Path, aovs: Sequence[str], bit_depth: int = 8, exr: bool = False,
                  sheet: bool = False) -> None:
    """Write the display image of `frame` to `image` (creating its folder; `bit_depth` 8 or 16),
    then `write_aovs` beside it, with `exr` the multi-layer <stem>.exr (`write_exr`) and with
    `sheet` <stem>.sheet.png: the image and the previews of `aovs`, labelled (`contact_sheet`)."""
    image = Path(image)
    write_image(frame, image, bit_depth)
    write_aovs(frame, image, aovs)
    if exr:
        write_exr(exr_path(image), frame, aovs)
    if sheet:
        _imwrite(str(sheet_path(image)), frame.contact_sheet(["image", *aovs]))


def write_aovs(frame, image: Path, aovs: Sequence[str]) -> None:
    """Write each AOV of `frame` named in `aovs` next to `image`: <stem>.<aov>.npy (exact values)
    and <stem>.<aov>.png (`preview`)."""
    stem = Path(image).with_suffix("")
    background = frame.triangle_id < 0
    for aov in aovs:
        data = np.asarray(frame.aov(aov))
        _save_npy(f"{stem}.{aov}.npy", data)
        _imwrite(f"{stem}.{aov}.png", preview(aov, data, background))
