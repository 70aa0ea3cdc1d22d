"""Independent NumPy (float64) reference of the deferred shading model and the tone mapping.

The model (the report's Blinn-Phong with a finite light radius), for a foreground pixel with
G-buffer normal N, albedo, specular intensity s, specular power p and view depth z:

    P = eye + z·(F + x_ndc·tan(fov/2)·aspect·R + y_ndc·tan(fov/2)·U)       (R, U, -F) = camera.basis()
    x_ndc = (px + 0.5)/W·2 - 1,  y_ndc = 1 - (py + 0.5)/H·2,  V = normalize(eye - P)
    orthographic camera: P = eye + x_ndc·ymag·aspect·R + y_ndc·ymag·U + z·F,  V = -F
    per light: Lv = position - P, d = |Lv|, L = Lv/d
        A = (1 - (d/r)²)³ if d < r else 0
        S = 1 (point) | t², t = clamp((dot(-L, dir) - cos_outer) / max(cos_inner - cos_outer, 1e-4), 0, 1) (spot)
        NdotL = max(N·L, 0); H = normalize(L + V); spec = s·max(N·H, 0)^p where N·L > 0, else 0
        diffuse += A·S·color·NdotL; specular += A·S·color·spec
    color = albedo·(ambient + diffuse) + specular;  background (triangle_id < 0): 0

Tone mapping of `Frame.image`: c = color·exposure; Reinhard c/(1+c) or ACES fitted (Narkowicz
2015) clamp(c(2.51c+0.03)/(c(2.43c+0.59)+0.14), 0, 1) per channel; then sRGB-encoded to uint8.

The reference reads the *decoded* G-buffer (the Frame's normal/albedo/... fields), so the only
differences from the kernels are float32 vs float64 arithmetic.

Public API::

    world_positions(depth, camera) -> (H, W, 3) float64 (inf on background)
    view_vectors(points, camera) -> (..., 3) unit vectors towards the viewer
    shade(normal, albedo, specular_intensity, specular_power, depth, triangle_id, camera, lights, ambient,
          details=False) -> (H, W, 3) float64 [, details dict]
    shade_frame(frame, camera, lights, ambient, details=False)
    light_reach_mask(points, lights, margin) -> (n_lights, ...) bool: lights certainly reaching each point
    tile_light_truth(frame, camera, lights, tile, margin) -> (tiles_y, tiles_x) int
    tonemap_curve(color, operator, exposure) -> float64 in [0, 1];  tonemap(...) -> uint8 sRGB
"""
from __future__ import annotations

import numpy as np

from clrender.abi import structs
from clrender.abi.gbuffer import linear_to_srgb8

TONEMAPS = ("reinhard", "aces")


def _camera_frame(camera):
    right, up, back = (np.asarray(v, np.float64) for v in camera.basis())
    return np.asarray(camera.eye, np.float64), right, up, -back


def is_ortho(camera) -> bool:
    return getattr(camera, "projection", "perspective") == "orthographic"


def _eye_plane(camera, width: int, height: int) -> np.ndarray:
    """(H, W, 3) orthographic: x_ndc·ymag·aspect·R + y_ndc·ymag·U at the pixel centres."""
    _, right, up, _ = _camera_frame(camera)
    t = float(camera.ymag)
    aspect = width / height
    x_ndc = (np.arange(width) + 0.5) / width * 2.0 - 1.0
    y_ndc = 1.0 - (np.arange(height) + 0.5) / height * 2.0
    return (x_ndc * t * aspect)[None, :, None] * right[None, None, :] + (y_ndc * t)[:, None, None] * up[None, None, :]


def pixel_directions(camera, width: int, height: int) -> np.ndarray:
    """(H, W, 3) un-normalized directions whose forward component is 1: P = origin + z·dir
    (pixel_origins). Orthographic: the forward axis at every pixel."""
    _, right, up, forward = _camera_frame(camera)
    if is_ortho(camera):
        return np.broadcast_to(forward, (height, width, 3)).copy()
    if getattr(camera, "intrinsics", None) is not None:     # a pinhole K: OpenCV's x/z, y/z of the centres
        fx, fy, cx, cy = np.multiply(camera.intrinsics, (width, height, width, height))
        xs = (np.arange(width) + 0.5 - cx) / fx
        ys = (np.arange(height) + 0.5 - cy) / fy         # OpenCV y points down
        return forward + xs[None, :, None] * right - ys[:, None, None] * up
    t = np.tan(np.radians(camera.fov_y_deg) / 2.0)
    aspect = width / height
    x_ndc = (np.arange(width) + 0.5) / width * 2.0 - 1.0
    y_ndc = 1.0 - (np.arange(height) + 0.5) / height * 2.0
    return (forward[None, None, :]
            + (x_ndc * t * aspect)[None, :, None] * right[None, None, :]
            + (y_ndc * t)[:, None, None] * up[None, None, :])


def pixel_origins(camera, width: int, height: int) -> np.ndarray:
    """(H, W, 3) where each pixel's view ray has depth 0: the eye (perspective), the pixel's point
    of the eye plane (orthographic)."""
    eye = np.asarray(camera.eye, np.float64)
    if is_ortho(camera):
        return eye + _eye_plane(camera, width, height)
    return np.broadcast_to(eye, (height, width, 3)).copy()


def world_positions(depth: np.ndarray, camera) -> np.ndarray:
    """World position of every pixel from its view depth (float64; non-finite where depth is)."""
    depth = np.asarray(depth, np.float64)
    h, w = depth.shape
    with np.errstate(invalid="ignore"):
        return pixel_origins(camera, w, h) + depth[..., None] * pixel_directions(camera, w, h)


def view_vectors(points: np.ndarray, camera) -> np.ndarray:
    """Unit vectors from `points` (..., 3) towards the viewer: to the eye, or -F (orthographic)."""
    points = np.asarray(points, np.float64)
    if is_ortho(camera):
        _, _, _, forward = _camera_frame(camera)
        return np.broadcast_to(-forward, points.shape).copy()
    return _unit(np.asarray(camera.eye, np.float64) - points)


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _lights(lights) -> np.ndarray:
    return np.asarray(lights, structs.light_dtype).reshape(-1)


def light_factor(points: np.ndarray, light) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(A·S, L, d) of one light at `points` (..., 3), float64."""
    lv = np.asarray(light["position"], np.float64) - points
    d = np.linalg.norm(lv, axis=-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        L = lv / d[..., None]
    r = float(light["radius"])
    atten = np.where(d < r, np.clip(1.0 - (d / r) ** 2, 0.0, None) ** 3, 0.0)
    if int(light["type"]) == structs.LIGHT_SPOT:
        direction = np.asarray(light["direction"], np.float64)
        cos_outer, cos_inner = float(light["cos_outer"]), float(light["cos_inner"])
        t = np.clip(((-L) @ direction - cos_outer) / max(cos_inner - cos_outer, 1e-4), 0.0, 1.0)
        atten = atten * t * t
    return atten, L, d


def shade(normal, albedo, specular_intensity, specular_power, depth, triangle_id, camera, lights, ambient,
          details: bool = False):
    """Expected linear HDR color (H, W, 3) float64.

    With details=True also returns a dict: `positions` (H, W, 3), `diffuse`, `specular` (H, W, 3)
    light sums, and `min_abs_ndotl` (H, W): the smallest |N·L| over lights with A·S > 0 (inf where
    none) — the specular term is discontinuous at N·L = 0, so pixels where it is ~0 are ambiguous
    between float32 and float64."""
    triangle_id = np.asarray(triangle_id)
    h, w = triangle_id.shape
    fg = triangle_id >= 0
    lights = _lights(lights)
    P_all = world_positions(depth, camera)
    P = P_all[fg]
    N = np.asarray(normal, np.float64)[fg]
    alb = np.asarray(albedo, np.float64)[fg]
    s = np.asarray(specular_intensity, np.float64)[fg]
    p = np.asarray(specular_power, np.float64)[fg]
    V = view_vectors(P, camera)
    diffuse = np.zeros_like(P)
    specular = np.zeros_like(P)
    min_abs = np.full(len(P), np.inf)
    for light in lights:
        w_ls, L, _ = light_factor(P, light)
        on = w_ls > 0
        if not on.any():
            continue
        ndotl = (N * L).sum(-1)
        H = _unit(L + V)
        ndoth = np.maximum((N * H).sum(-1), 0.0)
        spec = np.where(ndotl > 0, s * ndoth ** p, 0.0)
        color = np.asarray(light["color"], np.float64)
        diffuse += (w_ls * np.maximum(ndotl, 0.0))[:, None] * color
        specular += (w_ls * spec)[:, None] * color
        min_abs = np.where(on, np.minimum(min_abs, np.abs(ndotl)), min_abs)
    out = np.zeros((h, w, 3))
    out[fg] = alb * (float(np.float32(ambient)) + diffuse) + specular
    if not details:
        return out
    full = lambda a, fill: _scatter(fg, a, fill)
    return out, {"positions": P_all, "diffuse": full(diffuse, 0.0), "specular": full(specular, 0.0),
                 "min_abs_ndotl": full(min_abs, np.inf)}


def _scatter(mask, values, fill):
    out = np.full(mask.shape + values.shape[1:], fill, np.float64)
    out[mask] = values
    return out


def shade_frame(frame, camera, lights, ambient, details: bool = False):
    """`shade` on the frame's decoded G-buffer fields."""
    return shade(frame.normal, frame.albedo, frame.specular_intensity, frame.specular_power, frame.depth,
                 frame.triangle_id, camera, lights, ambient, details=details)


def light_reach_mask(points: np.ndarray, lights, margin: float = 1e-3) -> np.ndarray:
    """(n_lights, ...) bool: the light certainly has A·S > 0 at the point — d < r·(1 - margin) and, for a
    spot, dot(-L, dir) > cos_outer + margin (so float32 rounding cannot flip the answer)."""
    lights = _lights(lights)
    points = np.asarray(points, np.float64)
    out = np.zeros((len(lights),) + points.shape[:-1], bool)
    if len(lights) == 0:
        return out
    finite = np.isfinite(points).all(-1)
    pts = np.where(finite[..., None], points, 0.0)
    pos = lights["position"].astype(np.float64)
    radius = lights["radius"].astype(np.float64)
    chunk = max(1, 2_000_000 // max(pts[..., 0].size, 1))
    flat = pts.reshape(-1, 3)
    for start in range(0, len(lights), chunk):
        sl = slice(start, start + chunk)
        lv = pos[sl, None, :] - flat[None]                      # (c, n, 3)
        d = np.linalg.norm(lv, axis=-1)
        hit = d < radius[sl, None] * (1.0 - margin)
        spot = lights["type"][sl] == structs.LIGHT_SPOT
        if spot.any():
            with np.errstate(invalid="ignore", divide="ignore"):
                cos_a = -(lv * lights["direction"][sl, None, :].astype(np.float64)).sum(-1) / d
            cone = cos_a > lights["cos_outer"][sl, None].astype(np.float64) + margin
            hit &= np.where(spot[:, None], cone, True)
        out[sl] = hit.reshape((-1,) + points.shape[:-1]) & finite
    return out


def tile_light_truth(frame, camera, lights, tile: int, margin: float = 1e-3) -> np.ndarray:
    """(tiles_y, tiles_x): how many lights certainly light (A·S > 0) at least one foreground pixel
    of each tile. A conservative culler must assign at least this many lights to the tile."""
    h, w = frame.triangle_id.shape
    ty, tx = -(-h // tile), -(-w // tile)
    P = world_positions(frame.depth, camera)
    P[frame.triangle_id < 0] = np.nan
    reach = light_reach_mask(P, lights, margin)                 # (n, H, W)
    padded = np.zeros((len(reach), ty * tile, tx * tile), bool)
    padded[:, :h, :w] = reach
    per_tile = padded.reshape(len(reach), ty, tile, tx, tile).any(axis=(2, 4))
    return per_tile.sum(0).astype(np.int64)


def tonemap_curve(color: np.ndarray, operator: str, exposure: float = 1.0) -> np.ndarray:
    c = np.asarray(color, np.float64) * float(exposure)
    if operator == "reinhard":
        return c / (1.0 + c)
    if operator == "aces":
        return np.clip((c * (2.51 * c + 0.03)) / (c * (2.43 * c + 0.59) + 0.14), 0.0, 1.0)
    raise ValueError(f"unknown tone map {operator!r}; known: {TONEMAPS}")


def tonemap(color: np.ndarray, operator: str, exposure: float = 1.0) -> np.ndarray:
    """Expected `Frame.image` (uint8 sRGB) for a linear HDR color."""
    return linear_to_srgb8(tonemap_curve(color, operator, exposure))
