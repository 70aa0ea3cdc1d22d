"""Cameras: right-handed, looking down -Z in view space, OpenGL-style clip space.

Perspective (pinhole, `Camera.look_at`): clip-space w equals the positive view-space depth,
which is what the rasterizer interpolates (as 1/w) and what the G-buffer stores (divided by
`far`).

Orthographic (`Camera.orthographic`, glTF's `orthographic` camera): a box view volume of
half-height `ymag` world units. As glTF viewers do, the image aspect decides the horizontal
extent: the half-width is `ymag · width / height`, whatever `xmag` says (`xmag` is kept, so
`xmag / ymag` still tells the aspect the author had in mind). The G-buffer stores the same
linear depth (view depth / far); the rasterizer runs its ORTHO variant (`raster_matrix`,
docs/raster_contract.md §11).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import numpy as np


def _vec3(value, name: str) -> tuple[float, float, float]:
    arr = np.asarray(value, dtype=np.float64).reshape(-1)
    if arr.shape != (3,) or not np.all(np.isfinite(arr)):
        raise ValueError(f"camera {name} must be 3 finite numbers, got {value!r}")
    return (float(arr[0]), float(arr[1]), float(arr[2]))


PROJECTIONS = ("perspective", "orthographic")


def _is_real(x) -> bool:
    return isinstance(x, (int, float, np.integer, np.floating)) and not isinstance(x, bool)


@dataclass(frozen=True)
class Camera:
    eye: tuple[float, float, float]
    target: tuple[float, float, float]
    up: tuple[float, float, float] = (0.0, 1.0, 0.0)
    fov_y_deg: float = 60.0            # perspective only
    near: float = 0.1
    far: float = 100.0
    projection: str = "perspective"    # or "orthographic"
    xmag: Optional[float] = None       # orthographic: half-width of the view volume (world units; see module doc)
    ymag: Optional[float] = None       # orthographic: half-height of the view volume (world units)

    def __post_init__(self):
        object.__setattr__(self, "eye", _vec3(self.eye, "eye"))
        object.__setattr__(self, "target", _vec3(self.target, "target"))
        object.__setattr__(self, "up", _vec3(self.up, "up"))
        if self.projection not in PROJECTIONS:
            raise ValueError(f"camera projection must be one of {PROJECTIONS}, got {self.projection!r}")
        if not (_is_real(self.fov_y_deg) and 0.0 < self.fov_y_deg < 180.0):
            raise ValueError(f"camera fov_y_deg must be in (0, 180), got {self.fov_y_deg}")
        if self.is_orthographic:
            for name in ("xmag", "ymag"):
                v = getattr(self, name)
                if not (_is_real(v) and np.isfinite(v) and v > 0):
                    raise ValueError(f"orthographic camera {name} must be a positive finite number (half-"
                                     f"{'width' if name == 'xmag' else 'height'} of the view volume, world units), "
                                     f"got {v!r}")
                object.__setattr__(self, name, float(v))
            # glTF allows znear = 0 for orthographic cameras: nothing divides by it.
            if not (_is_real(self.near) and _is_real(self.far) and 0.0 <= self.near < self.far
                    and np.isfinite(self.far)):
                raise ValueError(f"orthographic camera needs 0 <= near < far < inf, got near={self.near} "
                                 f"far={self.far}")
        else:
            if self.xmag is not None or self.ymag is not None:
                raise ValueError("camera xmag/ymag apply to orthographic cameras (projection='orthographic'); "
                                 "a perspective camera has fov_y_deg")
            if not (_is_real(self.near) and _is_real(self.far) and 0.0 < self.near < self.far
                    and np.isfinite(self.far)):
                raise ValueError(f"camera needs 0 < near < far < inf, got near={self.near} far={self.far}")
        forward = np.subtract(self.target, self.eye)
        if np.linalg.norm(forward) == 0.0:
            raise ValueError("camera eye and target coincide")
        if np.linalg.norm(np.cross(forward, self.up)) < 1e-12 * np.linalg.norm(forward):
            raise ValueError("camera up vector is parallel to the view direction")

    @classmethod
    def look_at(cls, eye, target, up=(0.0, 1.0, 0.0), fov_y_deg=60.0, near=0.1, far=100.0) -> "Camera":
        return cls(eye, target, up, float(fov_y_deg), float(near), float(far))

    @classmethod
    def orthographic(cls, eye, target, up=(0.0, 1.0, 0.0), xmag=1.0, ymag=1.0, near=0.1, far=100.0) -> "Camera":
        """An orthographic camera at `eye` looking at `target`: a view box of half-height `ymag`
        (world units) from depth `near` to `far`; the half-width is ymag·aspect of the image
        (glTF viewers' rule; `xmag` is kept but does not change the image)."""
        return cls(eye, target, up, near=near, far=far, projection="orthographic", xmag=xmag, ymag=ymag)

    @property
    def is_orthographic(self) -> bool:
        return self.projection == "orthographic"

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

    def half_extents(self, aspect: float) -> tuple[float, float]:
        """(x, y) half-extents of the image: per unit view depth for a perspective camera
        (tan(fov/2)·aspect, tan(fov/2)), in world units for an orthographic one (ymag·aspect, ymag)."""
        t = self.ymag if self.is_orthographic else float(np.tan(np.radians(self.fov_y_deg) / 2.0))
        return t * aspect, t

    def projection_matrix(self, aspect: float) -> np.ndarray:
        """View -> clip, OpenGL convention: perspective (w_clip = -z_view) or glOrtho (w_clip = 1)
        with right = ymag·aspect, top = ymag."""
        n, f = self.near, self.far
        if self.is_orthographic:
            m = np.eye(4)
            m[0, 0] = 1.0 / (self.ymag * aspect)
            m[1, 1] = 1.0 / self.ymag
            m[2, 2] = 2.0 / (n - f)
            m[2, 3] = (f + n) / (n - f)
            return m
        t = 1.0 / np.tan(np.radians(self.fov_y_deg) / 2.0)
        m = np.zeros((4, 4))
        m[0, 0] = t / aspect
        m[1, 1] = t
        m[2, 2] = (f + n) / (n - f)
        m[2, 3] = 2.0 * f * n / (n - f)
        m[3, 2] = -1.0
        return m

    def view_projection(self, width: int, height: int) -> np.ndarray:
        return self.projection_matrix(width / height) @ self.view_matrix()

    def raster_matrix(self, width: int, height: int) -> np.ndarray:
        """World -> the clip space setup.cl takes (float64, docs/raster_contract.md §1, §11): the
        view-projection of a perspective camera (w = view depth); for an orthographic one the
        view-projection's x, y and w (= 1) rows with z replaced by the view depth -z_view
        (setup.cl ORTHO: the near plane is z >= near, z interpolated linearly)."""
        m = self.view_projection(width, height)
        if self.is_orthographic:
            m[2] = -self.view_matrix()[2]
        return m

    def basis(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(right, up, back) unit vectors in world space: the rows of the view rotation."""
        v = self.view_matrix()
        return v[0, :3].copy(), v[1, :3].copy(), v[2, :3].copy()


def with_overrides(cam: Camera, bounds, eye=None, target=None, fov=None, ortho=None) -> Camera:
    """`cam` with a new eye, target, vertical fov (perspective) or half-height (orthographic), as
    the CLI's --camera-eye/--camera-target/--fov/--ortho give them; None keeps the camera's own.
    A moved camera's far plane grows to keep the scene (`bounds`: (lo, hi)) inside it. ValueError
    for contradictory or degenerate overrides."""
    if fov is not None and ortho is not None:
        raise ValueError("--fov (perspective) and --ortho (orthographic) exclude each other")
    if eye is None and target is None and fov is None and ortho is None:
        return cam
    eye = cam.eye if eye is None else eye
    target = cam.target if target is None else target
    if ortho is None and fov is None and cam.is_orthographic:
        ortho = cam.ymag                          # the scene's orthographic camera, moved
    fov = cam.fov_y_deg if fov is None else fov
    far = cam.far
    if eye is not cam.eye or target is not cam.target:
        lo, hi = np.asarray(bounds, np.float64)
        reach = float(np.linalg.norm(np.subtract((lo + hi) / 2, eye)) + np.linalg.norm(hi - lo) / 2)
        far = max(far, reach * 1.5)
    up = np.asarray(cam.up, np.float64)
    forward = np.subtract(target, eye)
    if np.linalg.norm(forward) == 0.0:
        raise ValueError(f"camera eye and target are the same point {tuple(eye)}")
    if np.linalg.norm(np.cross(forward, up)) < 1e-6 * np.linalg.norm(forward):
        up = np.array([0.0, 0.0, -1.0])          # looking straight up or down
    if ortho is not None:
        xmag = cam.xmag * ortho / cam.ymag if cam.is_orthographic else ortho
        return Camera.orthographic(eye, target, tuple(up), xmag, ortho, near=min(cam.near, far * 0.5), far=far)
    return Camera.look_at(eye, target, tuple(up), fov, near=min(cam.near, far * 0.5), far=far)
