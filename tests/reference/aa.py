"""Ground truth for the anti-aliasing filters (tests/test_aa.py), in NumPy.

* `aa_scene()`: hard-edged, flat-coloured opaque shapes (thin bars at several angles, a rotated
  square, a folded "roof" whose two faces meet with a continuous depth but a 60° normal change,
  a back wall that leaves part of the frame empty) lit by ambient light only (ambient 1, no
  lights): every pixel's colour is its albedo, the background is black. Shapes are given in
  normalized screen coordinates, so the scene looks the same at any resolution of the same
  aspect ratio (`aa_camera`).
* `truth(frame_hr, s)`: the box average of a frame rendered at s·W × s·H (with tonemap="clamp" the
  tone-mapped value is the HDR colour clamped to [0, 1], so averaging `color` is averaging the
  linear display values). `edge_pixels` are the pixels whose s×s block is not uniform.
* `edge_mask`: the filter's edge test, written independently (float64, from the Frame's decoded
  depth, normal and triangle_id AOVs), and `threshold_margin`, how far the frame's neighbour
  pairs lie from the thresholds (the comparison with the kernel is exact only when no pair sits
  on a threshold).
"""
from __future__ import annotations

import numpy as np

from clrender import Camera, Material, Scene
from clrender.abi.gbuffer import srgb_to_linear_lut

FAR = 50.0


def aa_camera() -> Camera:
    return Camera.look_at((0.0, 0.0, 0.0), (0.0, 0.0, -1.0), (0.0, 1.0, 0.0), 90.0, near=0.1, far=FAR)


def _world(u, v, depth, aspect):
    """Normalized screen (u right, v down, both in [0, 1]) at view depth -> world point (aa_camera)."""
    return np.array([(2.0 * u - 1.0) * aspect * depth, (1.0 - 2.0 * v) * depth, -depth], np.float64)


def _polygon(points_uv, depth, aspect):
    """A convex screen-space polygon at constant depth, as a triangle fan (n-2, 3, 3)."""
    p = [_world(u, v, depth, aspect) for u, v in points_uv]
    return np.array([[p[0], p[i], p[i + 1]] for i in range(1, len(p) - 1)])


def _bar(center, length, width, angle_deg, aspect):
    """Corners (u, v) of a rectangle centred at `center` (u, v), length/width in units of the
    image height, rotated by angle (degrees, counter-clockwise on screen)."""
    a = np.radians(angle_deg)
    d = np.array([np.cos(a), -np.sin(a)])          # along the bar (v points down)
    n = np.array([np.sin(a), np.cos(a)])
    c = np.array([center[0] * aspect, center[1]])  # isotropic units: x scaled by the aspect
    pts = [c + sl * length / 2 * d + sw * width / 2 * n for sl, sw in ((-1, -1), (1, -1), (1, 1), (-1, 1))]
    return [(x / aspect, y) for x, y in pts]


def aa_scene(aspect: float = 4.0 / 3.0) -> Scene:
    """The anti-aliasing test scene (see the module docstring), for an image of this aspect."""
    mats = {name: Material(name, (*rgb, 1.0), specular_intensity=0.0) for name, rgb in (
        ("wall", (0.25, 0.35, 0.6)), ("square", (0.9, 0.15, 0.1)), ("yellow", (0.95, 0.85, 0.2)),
        ("green", (0.1, 0.8, 0.3)), ("white", (0.9, 0.9, 0.9)), ("cyan", (0.1, 0.7, 0.8)),
        ("magenta", (0.8, 0.1, 0.7)))}
    h = 1.0 / 48.0                                    # one pixel of a 48-row image, in v units
    parts = [
        (_polygon([(0.0, 0.0), (0.82, 0.0), (0.82, 1.0), (0.0, 1.0)], 20.0, aspect), "wall"),
        (_polygon(_bar((0.34, 0.5), 22 * h, 22 * h, 23.0, aspect), 10.0, aspect), "square"),
        (_polygon(_bar((0.5, 0.2), 0.9, 1.6 * h, 7.0, aspect), 6.0, aspect), "yellow"),
        (_polygon(_bar((0.62, 0.55), 0.8, 2.5 * h, 80.0, aspect), 6.0, aspect), "green"),
        (_polygon(_bar((0.45, 0.78), 0.7, 3.0 * h, 35.0, aspect), 5.0, aspect), "white"),
    ]
    # The roof: two faces folded ±30° about a ridge at depth 8 (continuous depth, normals 60°
    # apart), symmetric about the direction to the eye, its ridge leaning 15° from the vertical on
    # screen; a valley (outer sides nearer the eye), placed in the empty right part.
    half_w, half_l, t = 1.2, 3.0, np.tan(np.radians(30.0))
    c = _world(0.91, 0.6, 8.0, aspect)
    fwd = -c / np.linalg.norm(c)
    a0 = np.array([np.sin(np.radians(15.0)), np.cos(np.radians(15.0)), 0.0])
    along = a0 - a0.dot(fwd) * fwd
    along /= np.linalg.norm(along)
    across = np.cross(along, fwd)
    r0, r1 = c - half_l * along, c + half_l * along
    side = lambda r, s: r + s * half_w * across + half_w * t * fwd
    left = np.array([[r0, r1, side(r1, -1)], [r0, side(r1, -1), side(r0, -1)]])
    right = np.array([[r0, side(r0, 1), side(r1, 1)], [r0, side(r1, 1), r1]])
    parts += [(left, "cyan"), (right, "magenta")]
    names = list(mats)
    pos, nrm, mat = [], [], []
    for tris, name in parts:
        fn = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
        fn /= np.linalg.norm(fn, axis=-1, keepdims=True)
        fn *= np.sign(fn[:, 2:3])                      # facing the camera (+z)
        pos.append(tris)
        nrm.append(np.repeat(fn[:, None, :], 3, axis=1))
        mat.append(np.full(len(tris), names.index(name), np.int32))
    pos, nrm = np.concatenate(pos), np.concatenate(nrm)
    t_count = len(pos)
    scene = Scene(pos.reshape(-1, 3).astype(np.float32), nrm.reshape(-1, 3).astype(np.float32),
                  np.zeros((3 * t_count, 2), np.float32), np.arange(3 * t_count, dtype=np.int32).reshape(-1, 3),
                  np.concatenate(mat), [mats[n] for n in names])
    scene.ambient = 1.0
    return scene


# -- truth and error ------------------------------------------------------------------------------

def blocks(a: np.ndarray, s: int) -> np.ndarray:
    """(s·H, s·W, ...) -> (H, W, s·s, ...): each output pixel's s×s block of samples."""
    hh, ww = a.shape[0] // s, a.shape[1] // s
    b = a.reshape(hh, s, ww, s, *a.shape[2:]).swapaxes(1, 2)
    return b.reshape(hh, ww, s * s, *a.shape[2:])


def truth(color_hr: np.ndarray, s: int) -> np.ndarray:
    """Box average of the clamped linear colour of an s-times larger frame: (H, W, 3) float64."""
    return blocks(np.clip(color_hr.astype(np.float64), 0.0, 1.0), s).mean(axis=2)


def edge_pixels(color_hr: np.ndarray, s: int, margin: int = 0) -> np.ndarray:
    """(H, W) bool: pixels whose s×s block of the high-resolution frame is not one colour; with
    `margin`, the block widened by that many samples on every side (so an outline lying exactly
    on a pixel border counts for the pixels on both sides)."""
    hi, lo = color_hr, color_hr
    for dy in range(-margin, margin + 1):
        for dx in range(-margin, margin + 1):
            shifted = _shifted(color_hr, dy, dx)
            hi, lo = np.maximum(hi, shifted), np.minimum(lo, shifted)
    return (blocks(hi, s).max(axis=2) != blocks(lo, s).min(axis=2)).any(axis=-1)


def linear(image: np.ndarray) -> np.ndarray:
    """8-bit sRGB image -> linear float64."""
    return srgb_to_linear_lut()[image].astype(np.float64)


def rmse(a: np.ndarray, b: np.ndarray, mask: np.ndarray) -> float:
    return float(np.sqrt(np.mean((np.asarray(a, np.float64)[mask] - np.asarray(b, np.float64)[mask]) ** 2)))


def dilate(mask: np.ndarray, r: int) -> np.ndarray:
    """Chebyshev dilation by r pixels (a (2r+1)² square)."""
    h, w = mask.shape
    p = np.pad(mask, r)
    out = np.zeros_like(mask)
    for dy in range(2 * r + 1):
        for dx in range(2 * r + 1):
            out |= p[dy:dy + h, dx:dx + w]
    return out


def box_blur3(img: np.ndarray) -> np.ndarray:
    """3×3 box blur of every pixel (edges clamped): what a filter that blurs everything does."""
    h, w = img.shape[:2]
    p = np.pad(img.astype(np.float64), ((1, 1), (1, 1), (0, 0)), mode="edge")
    return sum(p[dy:dy + h, dx:dx + w] for dy in range(3) for dx in range(3)) / 9.0


# -- the edge test ----------------------------------------------------------------------------------

NEIGHBOURS = ((0, -1), (0, 1), (-1, 0), (1, 0))      # (dy, dx): left, right, up, down


def _shifted(a, dy, dx):
    """a[y + dy, x + dx] with coordinates clamped at the borders."""
    h, w = a.shape[:2]
    ys = np.clip(np.arange(h) + dy, 0, h - 1)
    xs = np.clip(np.arange(w) + dx, 0, w - 1)
    return a[ys][:, xs]


def pair_measures(depth, normal, triangle_id):
    """Per neighbour direction: (relative depth jump, normal angle cosine, fg/bg change) arrays,
    float64, between each pixel and that neighbour (clamped at the borders)."""
    z = depth.astype(np.float64)
    n = normal.astype(np.float64)
    n = n / np.maximum(np.linalg.norm(n, axis=-1, keepdims=True), 1e-30)
    fg = triangle_id >= 0
    out = []
    for dy, dx in NEIGHBOURS:
        z1, n1, fg1 = _shifted(z, dy, dx), _shifted(n, dy, dx), _shifted(fg, dy, dx)
        both = fg & fg1
        with np.errstate(invalid="ignore", divide="ignore"):
            rel = np.where(both, np.abs(z1 - z) / np.minimum(z, z1), 0.0)
        cos = np.where(both, (n * n1).sum(-1), 1.0)
        out.append((rel, cos, fg != fg1))
    return out


def edge_mask(depth, normal, triangle_id, depth_threshold=0.05, normal_threshold_deg=30.0) -> np.ndarray:
    """(H, W) uint8: 1 where a 4-neighbour differs by a relative view-depth jump above
    depth_threshold, a normal angle above normal_threshold_deg, or foreground vs background."""
    cos_t = np.cos(np.radians(normal_threshold_deg))
    mark = np.zeros(depth.shape, bool)
    for rel, cos, change in pair_measures(depth, normal, triangle_id):
        mark |= (rel > depth_threshold) | (cos < cos_t) | change
    return mark.astype(np.uint8)


def threshold_margin(depth, normal, triangle_id, depth_threshold=0.05, normal_threshold_deg=30.0):
    """(smallest |relative jump / depth_threshold - 1|, smallest |angle - threshold| in degrees)
    over all foreground neighbour pairs: how far the frame is from an ambiguous decision."""
    rel_m, ang_m = np.inf, np.inf
    for rel, cos, _ in pair_measures(depth, normal, triangle_id):
        rel_m = min(rel_m, float(np.min(np.abs(rel / depth_threshold - 1.0))))
        ang = np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))
        ang_m = min(ang_m, float(np.min(np.abs(ang - normal_threshold_deg))))
    return rel_m, ang_m
