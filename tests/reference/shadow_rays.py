"""Ray-cast shadow truth for the shadow-map tests: is the segment from a G-buffer point to the
light blocked? World positions are rebuilt from Frame.depth and the camera's pixel rays (as
shade.cl does, in float64; parallel rays from the eye plane for an orthographic camera); rays go through trimesh (Embree when `embreex` is installed, else a
brute-force NumPy Möller-Trumbore for small scenes). Nothing here comes from clrender's maps.
"""
from __future__ import annotations

import numpy as np


def world_positions(frame, camera) -> np.ndarray:
    """(H, W, 3) float64 world positions of the G-buffer's pixels (NaN on background)."""
    h, w = frame.depth.shape
    ortho = getattr(camera, "projection", "perspective") == "orthographic"
    tan_y = float(camera.ymag) if ortho else np.tan(np.radians(camera.fov_y_deg) / 2)   # ortho: half-height
    tan_x = tan_y * w / h
    right, up, back = camera.basis()
    xs = (np.arange(w) + 0.5) * (2.0 / w) - 1.0
    ys = 1.0 - (np.arange(h) + 0.5) * (2.0 / h)
    depth = np.where(np.isfinite(frame.depth), frame.depth, np.nan).astype(np.float64)
    if getattr(camera, "intrinsics", None) is not None:     # a pinhole K: OpenCV's x/z, y/z of the centres
        fx, fy, cx, cy = np.multiply(camera.intrinsics, (w, h, w, h))
        xs, ys = (np.arange(w) + 0.5 - cx) / fx, (np.arange(h) + 0.5 - cy) / fy
        rays = -back + xs[None, :, None] * right - ys[:, None, None] * up
        return np.asarray(camera.eye) + depth[..., None] * rays
    if ortho:       # parallel rays from the eye plane
        origins = np.asarray(camera.eye) + xs[None, :, None] * right * tan_x + ys[:, None, None] * up * tan_y
        return origins - depth[..., None] * back
    rays = -back + xs[None, :, None] * right * tan_x + ys[:, None, None] * up * tan_y
    return np.asarray(camera.eye) + depth[..., None] * rays


def face_normals(scene) -> np.ndarray:
    p = scene.positions.astype(np.float64)
    t = scene.triangles
    n = np.cross(p[t[:, 1]] - p[t[:, 0]], p[t[:, 2]] - p[t[:, 0]])
    return n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-30)


def _numpy_any_hit(verts, faces, origins, dirs, max_t) -> np.ndarray:
    """Möller-Trumbore, every ray against every triangle (small scenes only)."""
    v0, v1, v2 = verts[faces[:, 0]], verts[faces[:, 1]], verts[faces[:, 2]]
    e1, e2 = v1 - v0, v2 - v0
    hit = np.zeros(len(origins), bool)
    for s in range(0, len(origins), 256):
        o, d = origins[s:s + 256, None], dirs[s:s + 256, None]
        pv = np.cross(d, e2)
        det = (e1 * pv).sum(-1)
        ok = np.abs(det) > 1e-12
        inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
        tv = o - v0
        u = (tv * pv).sum(-1) * inv
        qv = np.cross(tv, e1)
        v = (d * qv).sum(-1) * inv
        t = (e2 * qv).sum(-1) * inv
        good = ok & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 0) & (t < max_t[s:s + 256, None])
        hit[s:s + 256] = good.any(1)
    return hit


def occluded(scene, origins, dirs, max_t) -> np.ndarray:
    """True where the ray origin + t·dir (unit dir) hits scene geometry at 0 < t < max_t."""
    verts = scene.positions.astype(np.float64)
    faces = scene.triangles
    try:
        from trimesh.ray.ray_pyembree import RayMeshIntersector
        import trimesh
    except ImportError:
        RayMeshIntersector = None
    if RayMeshIntersector is None or len(origins) == 0:
        return _numpy_any_hit(verts, faces, origins, dirs, max_t)
    mesh = trimesh.Trimesh(verts, faces, process=False)
    loc, ray_idx, _ = RayMeshIntersector(mesh).intersects_location(origins, dirs, multiple_hits=False)
    hit = np.zeros(len(origins), bool)
    if len(ray_idx):
        t = ((loc - origins[ray_idx]) * dirs[ray_idx]).sum(1)
        hit[ray_idx[t < max_t[ray_idx]]] = True
    return hit


def has_embree() -> bool:
    try:
        from trimesh.ray import ray_pyembree  # noqa: F401
        import embreex  # noqa: F401
        return True
    except ImportError:
        return False


def visibility(scene, frame, camera, light_pos=None, sun_dir=None, pixels=None, eps=1e-3):
    """(visible bool[n], mask of the pixels tested (flat indices)). Rays start `eps` (scene
    units × diagonal) off the surface towards the light (and a tenth of that along the geometric
    normal facing the light)."""
    P = world_positions(frame, camera).reshape(-1, 3)
    tri = frame.triangle_id.reshape(-1)
    idx = np.flatnonzero(tri >= 0) if pixels is None else np.asarray(pixels)
    p = P[idx]
    if sun_dir is not None:
        L = -np.asarray(sun_dir, np.float64) / np.linalg.norm(sun_dir)
        dirs = np.broadcast_to(L, p.shape).copy()
        dist = np.full(len(p), np.inf)
    else:
        v = np.asarray(light_pos, np.float64) - p
        dist = np.linalg.norm(v, axis=1)
        dirs = v / dist[:, None]
    lo, hi = scene.bounds().astype(np.float64)
    off = eps * float(np.linalg.norm(hi - lo))
    n = face_normals(scene)[tri[idx]]
    n *= np.sign((n * dirs).sum(1, keepdims=True) + 1e-30)
    origins = p + n * (0.1 * off) + dirs * off      # mostly along the ray: a normal step can cross thin parts
    return ~occluded(scene, origins, dirs, dist - 2 * off), idx


def near_edge(vis_image: np.ndarray, valid: np.ndarray, radius: int) -> np.ndarray:
    """Pixels within `radius` (Chebyshev) of a pixel whose reference visibility differs."""
    from scipy.ndimage import maximum_filter, minimum_filter
    v = np.where(valid, vis_image.astype(np.float32), np.nan)
    hi = maximum_filter(np.nan_to_num(v, nan=0.0), size=2 * radius + 1)
    lo = minimum_filter(np.nan_to_num(v, nan=1.0), size=2 * radius + 1)
    return hi != lo
