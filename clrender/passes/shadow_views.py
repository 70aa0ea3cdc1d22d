"""Shadow-map views on the host: a spot light's perspective view over its cone, the sun's
orthographic cascades fitted to the camera frustum, and the shelf packing of all maps into
one atlas. Pure NumPy (float64, cast to float32 once); kernels/structs.h `ShadowView` is the
record the shading kernel reads, and the same matrix drives setup.cl for the map itself.

Matrix convention (both kinds): for a world point p, ndc = (r0·p, r1·p) / (r3·p) and the
linear depth is r2·p. Perspective (spot): r3·p = r2·p = view depth along the spot axis.
Orthographic (sun): r3 = (0, 0, 0, 1) and r2·p = distance along the sun direction from a
plane in front of the scene's bounds (setup.cl / raster.cl ORTHO).
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from clrender.abi import structs

SPOT_BORDER_TEXELS = 4        # the cone fits inside size - 2·border texels: room for PCF taps
SPOT_NEAR_FRACTION = 1e-3     # near plane at this fraction of the light's radius
# Sun cascades are placed so that a small camera move gives the same matrix (and the kept map is
# reused, ShadowPass): the side is rounded up to a ladder of CASCADE_STEPS_PER_OCTAVE steps per
# doubling and the centre snapped to 1/CASCADE_GRID of the side, the side grown to cover the
# slice from any snapped centre: texels about 19 % wider on average (8/7 and half a ladder step).
CASCADE_STEPS_PER_OCTAVE = 8
CASCADE_GRID = 8


@dataclass(frozen=True)
class MapView:
    """One shadow map to render: its matrix, clip range and atlas square."""
    matrix: np.ndarray        # (4, 4) float32, the convention above
    near: float
    far: float
    size: int
    ortho: bool
    texel: float              # world size of a texel per unit depth (perspective) or absolute (ortho)
    split: float = np.inf     # sun cascade: camera view depth where the next cascade takes over
    x0: int = 0
    y0: int = 0


@dataclass(frozen=True)
class ShadowLayout:
    """Every shadow map of a frame: sun cascades first, then shadowed spots in light order."""
    views: tuple              # MapView, placed in the atlas
    sun_views: int            # leading cascades of the sun (0: no shadowed sun)
    spot_views: int
    atlas_width: int
    atlas_height: int

    @property
    def planes(self) -> int:
        """Frame.shadow planes: one for a shadowed sun, one per shadowed spot."""
        return int(self.sun_views > 0) + self.spot_views

    def records(self) -> np.ndarray:
        out = np.zeros(max(len(self.views), 1), structs.shadow_view_dtype)
        for i, v in enumerate(self.views):
            out[i] = (v.matrix.reshape(-1), v.x0, v.y0, v.size, int(v.ortho), v.texel, v.far,
                      v.split if np.isfinite(v.split) else np.finfo(np.float32).max, 0.0)
        return out


EMPTY = ShadowLayout((), 0, 0, 0, 0)


def _basis(forward) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(side, up, forward) orthonormal, up chosen from the world axis least aligned with forward."""
    f = np.asarray(forward, np.float64)
    f = f / np.linalg.norm(f)
    helper = np.eye(3)[int(np.argmin(np.abs(f)))]
    s = np.cross(f, helper)
    s /= np.linalg.norm(s)
    return s, np.cross(s, f), f


def spot_view(light, size: int) -> MapView:
    """Perspective view from a spot light's position down its axis, covering its outer cone."""
    pos = np.asarray(light["position"], np.float64)
    s, u, f = _basis(light["direction"])
    cos_o = float(np.clip(light["cos_outer"], 1e-6, 1.0))
    tan_half = np.sqrt(max(1.0 - cos_o * cos_o, 0.0)) / cos_o * size / (size - 2 * SPOT_BORDER_TEXELS)
    tan_half = max(tan_half, 1e-4)
    radius = float(light["radius"])
    m = np.zeros((4, 4))
    m[0, :3], m[1, :3] = s / tan_half, u / tan_half
    m[2, :3] = m[3, :3] = f
    m[:, 3] = -m[:, :3] @ pos
    return MapView(m.astype(np.float32), near=radius * SPOT_NEAR_FRACTION, far=radius, size=int(size),
                   ortho=False, texel=2.0 * tan_half / size)


def _box_corners(lo, hi) -> np.ndarray:
    return np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])], np.float64)


def cascade_splits(near: float, far: float, count: int, lam: float) -> np.ndarray:
    """The practical split scheme (Zhang et al.): lam·logarithmic + (1 - lam)·uniform; count + 1 values."""
    i = np.arange(count + 1) / count
    return lam * near * (far / near) ** i + (1.0 - lam) * (near + (far - near) * i)


def _ladder_up(x: float) -> float:
    """The smallest 2^(k / CASCADE_STEPS_PER_OCTAVE) >= x (k an integer)."""
    k = np.ceil(np.log2(x) * CASCADE_STEPS_PER_OCTAVE)
    while 2.0 ** ((k - 1) / CASCADE_STEPS_PER_OCTAVE) >= x:      # log2 rounding: the rung below may fit
        k -= 1
    while 2.0 ** (k / CASCADE_STEPS_PER_OCTAVE) < x:
        k += 1
    return float(2.0 ** (k / CASCADE_STEPS_PER_OCTAVE))


def sun_views(sun, camera, aspect: float, bounds, cascades: int, lam: float) -> list[MapView]:
    """Orthographic cascades over the camera frustum's depth slices (the frustum clamped to the
    scene's bounds), each map square, its side on a ladder and its centre on a grid of 1/8 of
    the side (a multiple of the texel: it does not shimmer, and a camera moving less than the
    grid keeps the same map, which ShadowPass then reuses). An
    orthographic camera's view volume is a box: its slices are boxes too, split uniformly in
    depth (its pixels have the same world size at every depth, so the logarithmic share of
    the split scheme, there for perspective, would buy nothing)."""
    lo, hi = np.asarray(bounds, np.float64)
    size = sun.shadow_map_size
    s, u, f = _basis(sun.direction)
    corners = _box_corners(lo, hi)
    light = corners @ np.stack([s, u, f]).T                     # scene box in light space
    l_lo, l_hi = light.min(0), light.max(0)
    margin = 0.01 * max(float(np.linalg.norm(hi - lo)), 1e-3) + 1e-3
    z0 = l_lo[2] - 2 * margin                                    # depth origin in front of the scene
    right, up, back = camera.basis()
    eye, fwd = np.asarray(camera.eye, np.float64), -back
    ortho = camera.is_orthographic
    tan_x, tan_y = camera.half_extents(aspect)          # ortho: half-extents in world units
    ox, oy = camera.principal_offset()                  # an off-centre pinhole's frustum is asymmetric
    depths = (corners - eye) @ fwd
    near = max(camera.near, float(depths.min()))
    far = min(camera.far, float(depths.max()))
    far = max(far, near * 1.001 + 1e-6)
    splits = near + (far - near) * np.arange(cascades + 1) / cascades if ortho else \
        cascade_splits(near, far, cascades, lam)
    out = []
    for c in range(cascades):
        pts = np.array([eye + d * fwd + (sx * tan_x * right + sy * tan_y * up) if ortho else
                        eye + d * (fwd + (sx - ox) * tan_x * right + (sy - oy) * tan_y * up)
                        for d in (splits[c], splits[c + 1]) for sx in (-1, 1) for sy in (-1, 1)])
        lp = pts @ np.stack([s, u]).T
        a = np.maximum(lp.min(0), l_lo[:2])
        b = np.minimum(lp.max(0), l_hi[:2])
        b = np.maximum(a, b)                                     # slice outside the scene: a point
        needed = max(float((b - a).max()), margin) * (1.0 + 4.0 / size)     # + PCF border
        # |centre - midpoint| <= grid / 2 on each axis, so extent - grid >= needed covers the slice
        extent = _ladder_up(needed * CASCADE_GRID / (CASCADE_GRID - 1))
        grid = extent / CASCADE_GRID
        texel = extent / size
        center = np.round((a + b) / 2 / grid) * grid
        m = np.zeros((4, 4))
        m[0, :3], m[0, 3] = s * (2 / extent), -center[0] * (2 / extent)
        m[1, :3], m[1, 3] = u * (2 / extent), -center[1] * (2 / extent)
        m[2, :3], m[2, 3] = f, -z0
        m[3, 3] = 1.0
        out.append(MapView(m.astype(np.float32), near=margin, far=float(l_hi[2] - z0 + 2 * margin), size=size,
                           ortho=True, texel=texel, split=float(splits[c + 1]) if c + 1 < cascades else np.inf))
    return out


def pack(sizes, max_side: int) -> tuple[list[tuple[int, int]], int, int]:
    """Shelf packing of square maps (largest first, then index order: deterministic) into the
    narrowest power-of-two-wide atlas at most as tall as it is wide; (positions, width, height).
    Raises ValueError when the maps do not fit in max_side × max_side."""
    if not sizes:
        return [], 0, 0
    order = sorted(range(len(sizes)), key=lambda i: (-sizes[i], i))
    width = 1 << (int(max(sizes)) - 1).bit_length()
    while width <= max_side:
        pos, x, y, shelf = [None] * len(sizes), 0, 0, 0
        for i in order:
            s = sizes[i]
            if x + s > width:
                x, y, shelf = 0, y + shelf, 0
            shelf = max(shelf, s)
            pos[i] = (x, y)
            x += s
        height = y + shelf
        if height <= width:
            return pos, width, height
        width *= 2
    raise ValueError(f"{len(sizes)} shadow maps ({sum(s * s for s in sizes):,} texels, sizes {sorted(set(sizes))}) "
                     f"do not fit a {max_side}x{max_side} shadow atlas (RenderConfig shadow_atlas_max): "
                     f"lower shadow_map_size or the number of shadowed lights")


def layout(shadow_lights, sun, camera, aspect: float, bounds, config) -> ShadowLayout:
    """All views of a frame, placed in the atlas."""
    views = []
    if sun is not None and sun.shadow:
        views += sun_views(sun, camera, aspect, bounds, config.sun_cascades, config.sun_split_lambda)
    n_sun = len(views)
    views += [spot_view(rec, int(rec["shadow_size"])) for rec in shadow_lights]
    if not views:
        return EMPTY
    pos, w, h = pack([v.size for v in views], config.shadow_atlas_max)
    placed = tuple(replace(v, x0=x, y0=y) for v, (x, y) in zip(views, pos))
    return ShadowLayout(placed, n_sun, len(views) - n_sun, w, h)
