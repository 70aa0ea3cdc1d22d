"""AOV previews: each AOV as a viewable uint8 picture, drawn as its row in the AOV table says
(clrender/abi/aovs.py `preview`: depth as grey, normals as RGB, ids as stable hash colours,
velocity as a colour wheel...), and contact sheets of labelled previews."""
from __future__ import annotations

from typing import Sequence

import numpy as np

from clrender.abi import aovs as aov_table
from clrender.abi.gbuffer import SPEC_POWER_LOG2_MAX, linear_to_srgb8


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


def _preview_position(p: np.ndarray, background: np.ndarray) -> np.ndarray:
    fg = ~background & np.isfinite(p).all(-1)
    if not fg.any():
        return np.zeros(p.shape, np.uint8)
    lo, hi = p[fg].min(0), p[fg].max(0)
    out = _u8((np.nan_to_num(p) - lo) / np.maximum(hi - lo, 1e-30))
    out[~fg] = 0
    return out


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


def _preview_normal(n: np.ndarray, background: np.ndarray) -> np.ndarray:
    out = _u8(n * 0.5 + 0.5)
    out[background] = 0
    return out


def _preview_log_power(power: np.ndarray) -> np.ndarray:
    return _u8(np.log2(np.maximum(power, 1.0)) / SPEC_POWER_LOG2_MAX)


# The AOV table's preview kinds (clrender.abi.aovs.PREVIEWS) -> (data, background) -> uint8 picture
DRAW = {
    "depth": _preview_depth,
    "normal": _preview_normal,
    "srgb": lambda data, bg: linear_to_srgb8(data),                  # linear [0, 1] colours (emissive before its strength)
    "unit": lambda data, bg: _u8(data),                    # [0, 1] as grey; white = unoccluded / clear / metal / rough
    "log_power": lambda data, bg: _preview_log_power(data),
    "ids": lambda data, bg: _preview_ids(data),
    "position": _preview_position,
    "shading_model": lambda data, bg:                      # black background, grey Blinn-Phong, white glTF BRDF
        np.array([0, 96, 255], np.uint8)[np.clip(data.astype(np.int64) + 1, 0, 2)][..., None].repeat(3, -1),
    "velocity": lambda data, bg: _preview_velocity(data),
    "hdr": lambda data, bg: linear_to_srgb8(data / (1.0 + np.maximum(data, 0.0))),    # linear HDR: Reinhard, as the image
    "heat": lambda data, bg: _preview_heat(data),
    "mask": lambda data, bg: np.where(data > 0, 255, 0).astype(np.uint8),  # the edge-AA mask: white on black
    "shadow": lambda data, bg:                             # (H, W, K): the darkest shadowed light, white = lit
        _u8(data.min(-1) if data.shape[-1] else np.ones(data.shape[:2], np.float32)),
    "picture": lambda data, bg: data,
}


def preview(name: str, data: np.ndarray, background: np.ndarray) -> np.ndarray:
    """A viewable uint8 image of AOV `name`, drawn as its row in the AOV table says."""
    row = aov_table.AOVS.get(name)
    if row is None:
        raise ValueError(f"no preview for AOV {name!r}")
    return DRAW[row.preview](data, background)


LABEL_HEIGHT = 14          # pixels of the name strip above each contact-sheet tile


def contact_sheet(tiles: Sequence[tuple], columns: int = 4) -> np.ndarray:
    """(rows·(H + LABEL_HEIGHT), columns·W, 3) uint8: (name, (H, W, 3) uint8 picture) tiles of one
    size, row by row, each under a dark strip with its name (Pillow's default font)."""
    from PIL import Image, ImageDraw

    if not tiles:
        raise ValueError("a contact sheet needs at least one picture")
    h, w = tiles[0][1].shape[:2]
    if any(t.shape[:2] != (h, w) for _, t in tiles):
        raise ValueError("contact sheet pictures must all have the same size")
    columns = max(1, min(int(columns), len(tiles)))
    rows = -(-len(tiles) // columns)
    sheet = Image.new("RGB", (columns * w, rows * (h + LABEL_HEIGHT)), (24, 24, 24))
    draw = ImageDraw.Draw(sheet)
    for k, (name, picture) in enumerate(tiles):
        x, y = (k % columns) * w, (k // columns) * (h + LABEL_HEIGHT)
        sheet.paste(Image.fromarray(np.ascontiguousarray(picture[..., :3], np.uint8)), (x, y + LABEL_HEIGHT))
        draw.text((x + 3, y + 1), str(name), fill=(235, 235, 235))
    return np.asarray(sheet)
