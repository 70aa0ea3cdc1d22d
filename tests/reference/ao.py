"""Independent NumPy references for screen-space ambient occlusion (kernels/ssao*.cl).

* `ray_traced_ao`: the truth SSAO approximates: from each point, rays over the hemisphere of
  its normal (cosine-weighted, fixed seed) against every triangle of the scene, hits within
  `radius` counted: ao = 1 - hits / rays. Möller–Trumbore in float64, no acceleration
  structure (test scenes have tens of triangles).
* `bilateral_blur`: the depth-aware separable blur of kernels/ssao_blur.cl, float64: along x,
  then along y, weights (R + 1 - |i|)·max(0, 1 - ((d_q - d_p)/(tol·d_p))²), background (d = inf)
  and off-image neighbours weigh 0, background pixels are 1.

Public API::

    cosine_directions(normals, n_rays, seed) -> (M, n_rays, 3) unit vectors around each normal
    ray_traced_ao(points, normals, vertices, faces, radius, n_rays=128, seed=0) -> (M,) float64
    bilateral_blur(ao, linear_depth, radius=4, tolerance=0.05) -> (H, W) float64
"""
from __future__ import annotations

import numpy as np


def _tangent_frames(normals: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors orthogonal to each normal and to each other."""
    helper = np.where(np.abs(normals[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    t = np.cross(normals, helper)
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    return t, np.cross(normals, t)


def cosine_directions(normals: np.ndarray, n_rays: int, seed: int) -> np.ndarray:
    """Cosine-weighted hemisphere directions (Malley's method), one fixed random set per point."""
    n = np.asarray(normals, np.float64)
    rng = np.random.default_rng(seed)
    u1, u2 = rng.random((2, len(n), n_rays))
    r, phi = np.sqrt(u1), 2.0 * np.pi * u2
    local = np.stack([r * np.cos(phi), r * np.sin(phi), np.sqrt(1.0 - u1)], -1)
    t, b = _tangent_frames(n)
    return local[..., :1] * t[:, None] + local[..., 1:2] * b[:, None] + local[..., 2:] * n[:, None]


def _any_hit(origins: np.ndarray, dirs: np.ndarray, tris: np.ndarray, t_max: float) -> np.ndarray:
    """(K,) bool: does ray k hit any triangle at a distance in (0, t_max]? (Möller–Trumbore)"""
    v0, e1, e2 = tris[:, 0], tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]
    hit = np.zeros(len(origins), bool)
    chunk = max(1, 4_000_000 // max(len(tris), 1))
    for s in range(0, len(origins), chunk):
        o, d = origins[s:s + chunk, None], dirs[s:s + chunk, None]
        p = np.cross(d, e2)
        det = np.einsum("kti,ti->kt", p, e1)
        with np.errstate(divide="ignore", invalid="ignore"):
            inv = 1.0 / det
            tv = o - v0
            u = np.einsum("kti,kti->kt", tv, p) * inv
            q = np.cross(tv, e1)
            v = np.einsum("kti,kti->kt", d, q) * inv
            t = np.einsum("ti,kti->kt", e2, q) * inv
            ok = (np.abs(det) > 1e-12) & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 0) & (t <= t_max)
        hit[s:s + chunk] = ok.any(1)
    return hit


def ray_traced_ao(points, normals, vertices, faces, radius: float, n_rays: int = 128, seed: int = 0,
                  offset: float = 0.01) -> np.ndarray:
    """Fraction of `n_rays` cosine-weighted rays from each point (moved `offset`·radius along its
    normal: G-buffer positions are off the surface by ~1e-5 of their depth) that travel `radius`
    without hitting a triangle."""
    p = np.asarray(points, np.float64)
    n = np.asarray(normals, np.float64)
    n = n / np.linalg.norm(n, axis=1, keepdims=True)
    dirs = cosine_directions(n, n_rays, seed).reshape(-1, 3)
    origins = np.repeat(p + offset * radius * n, n_rays, axis=0)
    tris = np.asarray(vertices, np.float64)[np.asarray(faces)]
    hits = _any_hit(origins, dirs, tris, radius).reshape(len(p), n_rays)
    return 1.0 - hits.mean(1)


def _blur_axis(ao: np.ndarray, depth: np.ndarray, radius: int, tolerance: float, axis: int) -> np.ndarray:
    h, w = ao.shape
    fg = np.isfinite(depth)
    sum_w = np.zeros((h, w))
    sum_wa = np.zeros((h, w))
    d_p = np.where(fg, depth, 1.0)
    for i in range(-radius, radius + 1):
        d_q = np.full((h, w), np.inf)
        a_q = np.ones((h, w))
        if axis == 1:
            lo, hi = max(0, -i), min(w, w - i)
            d_q[:, lo:hi], a_q[:, lo:hi] = depth[:, lo + i:hi + i], ao[:, lo + i:hi + i]
        else:
            lo, hi = max(0, -i), min(h, h - i)
            d_q[lo:hi], a_q[lo:hi] = depth[lo + i:hi + i], ao[lo + i:hi + i]
        with np.errstate(invalid="ignore"):
            rel = (d_q - d_p) / (tolerance * d_p)
            wgt = (radius + 1 - abs(i)) * np.maximum(1.0 - rel * rel, 0.0)
        wgt = np.where(fg & np.isfinite(d_q), wgt, 0.0)
        sum_w += wgt
        sum_wa += wgt * a_q
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(fg, sum_wa / sum_w, 1.0)


def bilateral_blur(ao, linear_depth, radius: int = 4, tolerance: float = 0.05) -> np.ndarray:
    """kernels/ssao_blur.cl in float64: rows first, then columns."""
    ao = np.asarray(ao, np.float64)
    depth = np.asarray(linear_depth, np.float64)
    return _blur_axis(_blur_axis(ao, depth, radius, tolerance, 1), depth, radius, tolerance, 0)
