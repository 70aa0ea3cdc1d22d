"""Geometry checks and helpers of the scene model: vertex coordinates in range (`check_positions`,
the one rule every loader, Scene construction, upload and set_transform apply), affine transforms,
area-weighted vertex normals.
"""
from __future__ import annotations

import numpy as np

from clrender.errors import SceneError

# Vertex coordinates beyond this are refused: float32 ends at 3.4e38, so a coordinate of 1e30 has
# only 8 orders of magnitude left before the camera's matrices (a far plane of 1e5, a pixel scale
# of 1e3) overflow it to inf; no scene spans 1e30 units, and such values come from garbage bytes.
MAX_COORDINATE = 1e30
_CHECK_ROWS = 1 << 20               # vertices checked per step: a bounded temporary for huge meshes


def bad_vertex(positions) -> int:
    """The first row of (V, 3) `positions` with a coordinate that is NaN, infinite or beyond
    ±MAX_COORDINATE; -1 when there is none."""
    p = np.asarray(positions).reshape(-1, 3)
    if not p.size or (-MAX_COORDINATE <= p.min() and p.max() <= MAX_COORDINATE):   # min/max carry NaN
        return -1                   # the usual case: two reductions, no temporary array
    for start in range(0, len(p), _CHECK_ROWS):
        with np.errstate(invalid="ignore"):
            ok = (np.abs(p[start:start + _CHECK_ROWS]) <= MAX_COORDINATE).all(axis=1)   # NaN compares False
        if not ok.all():
            return start + int(np.argmin(ok))
    return -1


def coordinates_text(row) -> str:
    """A vertex for a message: (x, y, z), float32's 7 significant digits each."""
    return "(" + ", ".join(f"{float(v):.7g}" for v in np.asarray(row).reshape(-1)) + ")"


BAD_COORDINATES = f"vertex coordinates must be finite and within ±1e{round(np.log10(MAX_COORDINATE))}"


def check_positions(positions, where: str, what: str = "positions") -> None:
    """SceneError `<where>: <what>[i] is (x, y, z): vertex coordinates must be finite and within
    ±1e+30` for the first bad vertex (bad_vertex), else nothing."""
    i = bad_vertex(positions)
    if i >= 0:
        row = np.asarray(positions).reshape(-1, 3)[i]
        raise SceneError(f"{where}: {what}[{i}] is {coordinates_text(row)}: {BAD_COORDINATES}")


def affine_matrix(matrix, what: str) -> np.ndarray:
    """A finite 4×4 affine transform (last row 0, 0, 0, 1) with an invertible 3×3 part, as float64."""
    try:
        a = np.asarray(matrix, dtype=np.float64)
    except (TypeError, ValueError):
        raise SceneError(f"set_transform: {what} must be a 4x4 numeric matrix, got {matrix!r}") from None
    if a.shape != (4, 4) or not np.isfinite(a).all():
        raise SceneError(f"set_transform: {what} must be a finite 4x4 matrix, got shape {a.shape}")
    if not np.array_equal(a[3], (0.0, 0.0, 0.0, 1.0)):
        raise SceneError(f"set_transform: {what} must be affine (last row 0, 0, 0, 1), got {a[3].tolist()}")
    det = np.linalg.det(a[:3, :3])
    if not abs(det) > 1e-12 * max(np.abs(a[:3, :3]).max(), 1e-300) ** 3:
        raise SceneError(f"set_transform: {what}'s 3x3 part is singular (determinant {det:g})")
    return a


def vertex_normals(positions: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """Area-weighted vertex normals; vertices touching no valid face get (0, 0, 1)."""
    positions = np.asarray(positions, np.float64)
    normals = np.zeros_like(positions)
    if len(triangles):
        tri = np.asarray(triangles, np.int64)
        p0, p1, p2 = positions[tri[:, 0]], positions[tri[:, 1]], positions[tri[:, 2]]
        fn = np.cross(p1 - p0, p2 - p0)
        fn[~np.isfinite(fn).all(1)] = 0.0
        for k in range(3):
            np.add.at(normals, tri[:, k], fn)
    length = np.linalg.norm(normals, axis=1, keepdims=True)
    ok = length[:, 0] > 0
    normals[ok] /= length[ok]
    normals[~ok] = (0.0, 0.0, 1.0)
    return normals.astype(np.float32)
