"""Pinhole camera: right-handed, looking down -Z in view space, OpenGL-style clip space.

Clip-space w equals the positive view-space depth, which is what the rasterizer
interpolates (as 1/w) and what the G-buffer stores (divided by `far`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


def _vec3(value, name: str) -> tuple[float, float, float]:
    arr = np.asarray(value, dtype=np.float64).reshape(-1)
    if arr.shape != (3,) or not np.all(np.isfinite(arr)):
        raise ValueError(f"camera {name} must be 3 finite numbers, got {value!r}")
    return (float(arr[0]), float(arr[1]), float(arr[2]))


@dataclass(frozen=True)
class Camera:
    eye: tuple[float, float, float]
    target: tuple[float, float, float]
    up: tuple[float, float, float] = (0.0, 1.0, 0.0)
    fov_y_deg: float = 60.0
    near: float = 0.1
    far: float = 100.0

    def __post_init__(self):
        object.__setattr__(self, "eye", _vec3(self.eye, "eye"))
        object.__setattr__(self, "target", _vec3(self.target, "target"))
        object.__setattr__(self, "up", _vec3(self.up, "up"))
        if not 0.0 < self.fov_y_deg < 180.0:
            raise ValueError(f"camera fov_y_deg must be in (0, 180), got {self.fov_y_deg}")
        if not (0.0 < self.near < self.far and np.isfinite(self.far)):
            raise ValueError(f"camera needs 0 < near < far < inf, got near={self.near} far={self.far}")
        forward = np.subtract(self.target, self.eye)
        if np.linalg.norm(forward) == 0.0:
            raise ValueError("camera eye and target coincide")
        if np.linalg.norm(np.cross(forward, self.up)) < 1e-12 * np.linalg.norm(forward):
            raise ValueError("camera up vector is parallel to the view direction")

    @classmethod
    def look_at(cls, eye, target, up=(0.0, 1.0, 0.0), fov_y_deg=60.0, near=0.1, far=100.0) -> "Camera":
        return cls(eye, target, up, float(fov_y_deg), float(near), float(far))

    def view_matrix(self) -> np.ndarray:
        """World -> view (float64, 4x4)."""
        eye = np.array(self.eye)
        f = np.array(self.target) - eye
        f /= np.linalg.norm(f)
        s = np.cross(f, self.up)
        s /= np.linalg.norm(s)
        u = np.cross(s, f)
        m = np.eye(4)
        m[0, :3], m[1, :3], m[2, :3] = s, u, -f
        m[:3, 3] = -m[:3, :3] @ eye
        return m

    def projection_matrix(self, aspect: float) -> np.ndarray:
        """View -> clip, OpenGL convention (w_clip = -z_view)."""
        t = 1.0 / np.tan(np.radians(self.fov_y_deg) / 2.0)
        n, f = self.near, self.far
        m = np.zeros((4, 4))
        m[0, 0] = t / aspect
        m[1, 1] = t
        m[2, 2] = (f + n) / (n - f)
        m[2, 3] = 2.0 * f * n / (n - f)
        m[3, 2] = -1.0
        return m

    def view_projection(self, width: int, height: int) -> np.ndarray:
        return self.projection_matrix(width / height) @ self.view_matrix()

    def basis(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(right, up, back) unit vectors in world space: the rows of the view rotation."""
        v = self.view_matrix()
        return v[0, :3].copy(), v[1, :3].copy(), v[2, :3].copy()
