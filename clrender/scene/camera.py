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

Intrinsic (pinhole K, `Camera.from_opencv`): a perspective camera whose `intrinsics` hold K
normalized by the image size, (fx/W, fy/H, cx/W, cy/H), so fx != fy and a principal point
anywhere (an asymmetric frustum) are honoured, and rendering at another size scales K with it.
Pixel convention (the raster contract's): pixel (i, j) covers [i, i+1) x [j, j+1) and its centre
is (i + 0.5, j + 0.5); a world point X lands at (u, v) = K(RX + t) / z in those coordinates,
as COLMAP and nerfstudio count (OpenCV's calibration puts centres on integers: add 0.5 to its
cx, cy). Every pass reads the frustum through `half_extents` and `principal_offset`: the ray
through NDC (x, y) is F + (x - ox)·R·tan_x + (y - oy)·U·tan_y (kernels/lighting.h).

`Frame.depth` is the z-depth along the optical axis (OpenCV depth maps store it), not the
distance to the eye; `Frame.linear_depth` is that depth / far.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Optional

import numpy as np


def _vec3(value, name: str) -> tuple[float, float, float]:
    arr = np.asarray(value, dtype=np.float64).reshape(-1)
    if arr.shape != (3,) or not np.all(np.isfinite(arr)):
        raise ValueError(f"camera {name} must be 3 finite numbers, got {value!r}")
    return (float(arr[0]), float(arr[1]), float(arr[2]))


PROJECTIONS = ("perspective", "orthographic")


def _matrix(value, shape, name: str) -> np.ndarray:
    try:
        m = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be numbers of shape {shape}, got {value!r}") from None
    if m.shape != shape:
        m = m.reshape(-1) if m.size == int(np.prod(shape)) and len(shape) == 1 else m
    if m.shape != shape:
        raise ValueError(f"{name} must have shape {shape}, got {m.shape}")
    if not np.isfinite(m).all():
        raise ValueError(f"{name} has a NaN or infinite value: {m.tolist()}")
    return m


def _image_size(width, height) -> tuple[int, int]:
    if not all(isinstance(v, (int, np.integer)) and not isinstance(v, bool) and v > 0 for v in (width, height)):
        raise ValueError(f"image size must be two positive integers, got width={width!r} height={height!r}")
    return int(width), int(height)


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
    intrinsics: Optional[tuple[float, float, float, float]] = None   # (fx/W, fy/H, cx/W, cy/H); see module doc

    def __post_init__(self):
        object.__setattr__(self, "eye", _vec3(self.eye, "eye"))
        object.__setattr__(self, "target", _vec3(self.target, "target"))
        object.__setattr__(self, "up", _vec3(self.up, "up"))
        if self.projection not in PROJECTIONS:
            raise ValueError(f"camera projection must be one of {PROJECTIONS}, got {self.projection!r}")
        if not (_is_real(self.fov_y_deg) and 0.0 < self.fov_y_deg < 180.0):
            raise ValueError(f"camera fov_y_deg must be in (0, 180), got {self.fov_y_deg}")
        if self.intrinsics is not None:
            if self.is_orthographic:
                raise ValueError("camera intrinsics (a pinhole K) apply to perspective cameras only")
            k = np.asarray(self.intrinsics, np.float64).reshape(-1)
            if k.shape != (4,) or not np.isfinite(k).all() or k[0] <= 0 or k[1] <= 0:
                raise ValueError(f"camera intrinsics must be 4 finite numbers (fx/W, fy/H, cx/W, cy/H) with "
                                 f"positive focal lengths, got {self.intrinsics!r}")
            object.__setattr__(self, "intrinsics", tuple(float(v) for v in k))
            # the vertical field of view K implies, for code that reads fov_y_deg
            object.__setattr__(self, "fov_y_deg", float(np.degrees(2.0 * np.arctan(0.5 / k[1]))))
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

    @classmethod
    def from_opencv(cls, K, R, t, width: int, height: int, near: float = 0.1, far: float = 100.0) -> "Camera":
        """The camera of OpenCV's pinhole model: K (3×3: fx, fy, cx, cy in pixels of a width × height
        image, no skew), R (3×3 rotation) and t (3,) map world points to camera coordinates
        (x right, y down, z forward): pixel = K(RX + t) / z, pixel centres at integer + 0.5 (module
        doc). ValueError for a singular or skewed K, non-positive focal lengths, an R that is not a
        rotation (within 1e-4), non-finite values or a bad image size."""
        width, height = _image_size(width, height)
        K = _matrix(K, (3, 3), "K")
        R = _matrix(R, (3, 3), "R")
        t = _matrix(t, (3,), "t")
        fx, fy, cx, cy = K[0, 0], K[1, 1], K[0, 2], K[1, 2]
        if not (fx > 0 and fy > 0):
            raise ValueError(f"K's focal lengths must be positive, got fx={fx:g} fy={fy:g}")
        if abs(K[0, 1]) > 1e-9 * fx or np.any(K[1:, 0] != 0) or K[2, 1] != 0 or K[2, 2] != 1:
            raise ValueError(f"K must be [[fx, 0, cx], [0, fy, cy], [0, 0, 1]] (no skew), got {K.tolist()}")
        if np.abs(R @ R.T - np.eye(3)).max() > 1e-4 or abs(np.linalg.det(R) - 1.0) > 1e-4:
            raise ValueError(f"R is not a rotation within 1e-4 (R·Rᵀ = I, det R = +1), got {R.tolist()}")
        eye = -R.T @ t
        return cls(tuple(eye), tuple(eye + R[2]), tuple(-R[1]), near=float(near), far=float(far),
                   intrinsics=(fx / width, fy / height, cx / width, cy / height))

    def to_opencv(self, width: int, height: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(K, R, t) of this perspective camera rendered at width × height (float64; the inverse of
        from_opencv, module doc for the pixel convention)."""
        if self.is_orthographic:
            raise ValueError("an orthographic camera has no pinhole K (to_opencv is for perspective cameras)")
        width, height = _image_size(width, height)
        tan_x, tan_y = self.half_extents(width / height)
        ox, oy = self.principal_offset()
        K = np.array([[width / (2 * tan_x), 0.0, (ox + 1.0) * width / 2],
                      [0.0, height / (2 * tan_y), (1.0 - oy) * height / 2],
                      [0.0, 0.0, 1.0]])
        v = self.view_matrix()
        R = np.stack([v[0, :3], -v[1, :3], -v[2, :3]])
        return K, R, -R @ np.asarray(self.eye)

    def principal_offset(self) -> tuple[float, float]:
        """(ox, oy): the principal point in NDC (x right, y up); (0, 0) for a centred frustum."""
        if self.intrinsics is None:
            return 0.0, 0.0
        return 2.0 * self.intrinsics[2] - 1.0, 1.0 - 2.0 * self.intrinsics[3]

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
        (tan(fov/2)·aspect, tan(fov/2)), in world units for an orthographic one (ymag·aspect, ymag).
        An intrinsic camera's come from K alone (W/(2fx), H/(2fy)), whatever the aspect."""
        if self.intrinsics is not None:
            return 0.5 / self.intrinsics[0], 0.5 / self.intrinsics[1]
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
        tan_x, tan_y = self.half_extents(aspect)
        ox, oy = self.principal_offset()
        m = np.zeros((4, 4))
        m[0, 0] = 1.0 / tan_x
        m[1, 1] = 1.0 / tan_y
        m[0, 2], m[1, 2] = -ox, -oy          # x_ndc = x/(-z)/tan_x + ox
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
    keep_fov = fov is None
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
    if ortho is None and keep_fov and cam.intrinsics is not None:     # a moved pinhole keeps its K
        return replace(cam, eye=tuple(eye), target=tuple(target), up=tuple(up), near=min(cam.near, far * 0.5),
                       far=far)
    if ortho is not None:
        xmag = cam.xmag * ortho / cam.ymag if cam.is_orthographic else ortho
        return Camera.orthographic(eye, target, tuple(up), xmag, ortho, near=min(cam.near, far * 0.5), far=far)
    return Camera.look_at(eye, target, tuple(up), fov, near=min(cam.near, far * 0.5), far=far)
