"""Independent pure-NumPy reference of docs/raster_contract.md (coverage, depth, visibility).

Every float step is an IEEE float32 operation (numpy float32 arrays/scalars; numpy never
fuses a multiply and an add across two ufunc calls), evaluated in the order the contract
writes it. Fixed-point and edge-function arithmetic is int64.

Deliberately out of scope (``ReferenceScopeError`` is raised instead of guessing):
  * guard-band clipping (§2): every prim vertex must stay within 2^16 pixels of the image
    center (the contract's band is 2^21 pixels), so no guard-band clip can trigger;
  * alpha MASK materials (§7);
  * a finite vertex whose clip coordinates overflow float32 (the contract does not say).

Orthographic cameras (``camera.is_orthographic``, contract §11): the transform's z row is the
view depth and w = 1; the near test is z - near; vertex depths are interpolated linearly in
screen space (depth = Σ e_k·z_k / area) instead of perspective-correctly.

Public API::

    rasterize(scene, camera, width, height) -> (triangle_id, depth, stats)
    coverage_count(scene, camera, width, height) -> (H, W) int32 fragments per pixel
    setup(scene, camera, width, height) -> (Prims, stats)

``stats`` counts ``invalid``, ``culled_near`` (per input triangle), ``degenerate``,
``culled_backface`` (per prim: a near-clipped triangle yields up to two prims, each tested
on its own), ``prims`` (prims that survived setup) and ``triangles_in``.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Iterator

import numpy as np

F32 = np.float32
SUB = 256          # 24.8 fixed point
HALF = 128         # pixel center offset in fixed point
SCOPE_PIXELS = 2.0 ** 16   # see setup(): the reference's stand-in for the guard band
STAT_KEYS = ("invalid", "culled_near", "degenerate", "culled_backface", "prims", "triangles_in")


class ReferenceScopeError(AssertionError):
    """The input needs behaviour the reference deliberately does not model."""


@dataclass
class Prims:
    """Setup output, sorted by (triangle id, fan index). Orientation already normalised:
    every prim has area > 0 (front-facing prims had v1/v2 swapped)."""
    tri: np.ndarray        # (N,) int64 original triangle id
    X: np.ndarray          # (N, 3) int64 24.8 fixed point
    Y: np.ndarray          # (N, 3) int64
    w: np.ndarray          # (N, 3) float32 clip w (orthographic: clip z, the vertex view depths)
    area: np.ndarray       # (N,) int64, > 0
    backface: np.ndarray   # (N,) bool (kept back-facing prim of a double-sided material)
    ortho: bool = False    # orthographic camera: `w` holds depths interpolated linearly (§11)

    def __len__(self) -> int:
        return int(len(self.tri))


# --------------------------------------------------------------------------------------
# §1 transform
# --------------------------------------------------------------------------------------
def is_ortho(camera) -> bool:
    return getattr(camera, "projection", "perspective") == "orthographic"


def view_projection_f32(camera, width: int, height: int) -> np.ndarray:
    """M = P·V in float64 on the host, cast to float32. Orthographic (§11): P is glOrtho, so
    row w is (0, 0, 0, 1); row z is replaced by the view depth, minus V's third row."""
    M = np.array(camera.view_projection(width, height), dtype=np.float64)
    if is_ortho(camera):
        assert np.array_equal(M[3], [0.0, 0.0, 0.0, 1.0]), M[3]
        M[2] = -np.asarray(camera.view_matrix(), np.float64)[2]
    return M.astype(np.float32)


def transform(positions: np.ndarray, M: np.ndarray) -> np.ndarray:
    """clip[r] = ((M[r,0]*x + M[r,1]*y) + M[r,2]*z) + M[r,3], all float32. (V, 4)."""
    p = np.asarray(positions, dtype=np.float32).reshape(-1, 3)
    M = np.asarray(M, dtype=np.float32)
    x, y, z = p[:, 0], p[:, 1], p[:, 2]
    out = np.empty((len(p), 4), np.float32)
    with np.errstate(all="ignore"):           # non-finite inputs are dropped later
        for r in range(4):
            out[:, r] = ((M[r, 0] * x + M[r, 1] * y) + M[r, 2] * z) + M[r, 3]
    assert out.dtype == np.float32
    return out


# --------------------------------------------------------------------------------------
# §2 near-plane clipping
# --------------------------------------------------------------------------------------
def clip_near(v: np.ndarray, d: np.ndarray) -> list[np.ndarray]:
    """Sutherland–Hodgman over v0→v1→v2→v0 against d >= 0.

    For each edge (a=v_i, b=v_i+1): emit v_i when inside; when the endpoints are on
    different sides, emit the intersection computed from the inside endpoint towards the
    outside one: t = d_in / (d_in - d_out), q = in + t * (out - in) (float32, per component).
    """
    inside = d >= F32(0)
    poly: list[np.ndarray] = []
    for i in range(3):
        j = (i + 1) % 3
        if inside[i]:
            poly.append(v[i])
        if inside[i] != inside[j]:
            a, b = (i, j) if inside[i] else (j, i)
            t = d[a] / (d[a] - d[b])
            q = v[a] + t * (v[b] - v[a])
            assert q.dtype == np.float32 and np.asarray(t).dtype == np.float32
            poly.append(q)
    return poly


# --------------------------------------------------------------------------------------
# Setup: §1–§4
# --------------------------------------------------------------------------------------
def setup(scene, camera, width: int, height: int) -> tuple[Prims, dict]:
    W, H = int(width), int(height)
    M = view_projection_f32(camera, W, H)
    ortho = is_ortho(camera)
    depth_row = 2 if ortho else 3                 # the clip component that is the view depth
    near = F32(camera.near)
    positions = np.asarray(scene.positions, np.float32)
    triangles = np.asarray(scene.triangles, np.int64).reshape(-1, 3)
    T = len(triangles)
    clip_all = transform(positions, M)
    finite_vertex = np.isfinite(positions).all(axis=1)

    double_sided = np.array([bool(m.double_sided) for m in scene.materials], bool)
    masked = np.array([m.alpha_mode == "MASK" for m in scene.materials], bool)
    tri_mat = np.asarray(scene.triangle_material, np.int64).reshape(-1)

    stats = dict.fromkeys(STAT_KEYS, 0)
    stats["triangles_in"] = T
    prim_tri: list[int] = []
    prim_v: list[np.ndarray] = []
    for i in range(T):
        idx = triangles[i]
        if not finite_vertex[idx].all():
            stats["invalid"] += 1
            continue
        v = clip_all[idx]                                   # (3, 4) float32
        if not np.isfinite(v).all():
            raise ReferenceScopeError(f"triangle {i}: finite vertices but non-finite clip coordinates")
        d = v[:, depth_row] - near                          # float32
        inside = d >= F32(0)
        if inside.all():
            pieces = [v]
        elif not inside.any():
            stats["culled_near"] += 1
            continue
        # §2 trivial reject: all three vertices outside one side of the viewport (x = ±w, y = ±w).
        x, y, w4 = v[:, 0], v[:, 1], v[:, 3]
        if any(bool((side < F32(0)).all()) for side in (w4 - x, w4 + x, w4 - y, w4 + y)):
            continue
        else:
            poly = clip_near(v, d)
            assert len(poly) in (3, 4)
            pieces = [np.stack([poly[0], poly[k], poly[k + 1]]) for k in range(1, len(poly) - 1)]
        if masked[tri_mat[i]]:
            raise ReferenceScopeError(f"triangle {i}: alpha MASK materials are out of the reference's scope")
        for p in pieces:
            prim_tri.append(i)
            prim_v.append(p)

    empty = Prims(np.zeros(0, np.int64), np.zeros((0, 3), np.int64), np.zeros((0, 3), np.int64),
                  np.zeros((0, 3), np.float32), np.zeros(0, np.int64), np.zeros(0, bool))
    if not prim_v:
        return empty, stats
    tri = np.asarray(prim_tri, np.int64)
    cv = np.stack(prim_v).astype(np.float32, copy=False)    # (N, 3, 4)
    w = cv[..., 3]
    vertex_depth = cv[..., depth_row]                       # = w in perspective

    # §3 snapping (float32, order as written), then round half to even.
    with np.errstate(all="ignore"):
        ndc_x = cv[..., 0] / w
        ndc_y = cv[..., 1] / w
    # Out of scope: guard-band clipping. Every prim vertex must lie within SCOPE_PIXELS of the
    # image center, far inside the contract's guard band (2^21 pixels) so it never triggers.
    with np.errstate(all="ignore"):
        off_x = np.abs(ndc_x.astype(np.float64)) * (W / 2)
        off_y = np.abs(ndc_y.astype(np.float64)) * (H / 2)
    ok = (w > 0) & (off_x <= SCOPE_PIXELS) & (off_y <= SCOPE_PIXELS)
    if not ok.all():
        bad = int(tri[np.argmax(~ok.all(axis=1))])
        raise ReferenceScopeError(f"triangle {bad}: a prim vertex lies more than {SCOPE_PIXELS:g} pixels from "
                                  f"the image center (or has w <= 0); the reference does not model guard-band clipping")
    sx = ((ndc_x + F32(1)) * F32(0.5)) * F32(W)
    sy = ((F32(1) - ndc_y) * F32(0.5)) * F32(H)
    X = np.rint(sx * F32(SUB)).astype(np.int64)
    Y = np.rint(sy * F32(SUB)).astype(np.int64)
    assert sx.dtype == np.float32 and sy.dtype == np.float32

    # §4 facing and orientation (int64; |X|,|Y| < 2^25 here so nothing overflows).
    area = (X[:, 1] - X[:, 0]) * (Y[:, 2] - Y[:, 0]) - (X[:, 2] - X[:, 0]) * (Y[:, 1] - Y[:, 0])
    degenerate = area == 0
    single = ~double_sided[tri_mat[tri]]
    culled_back = ~degenerate & single & (area > 0)
    stats["degenerate"] = int(degenerate.sum())
    stats["culled_backface"] = int(culled_back.sum())
    keep = ~degenerate & ~culled_back
    tri, X, Y, area = tri[keep], X[keep].copy(), Y[keep].copy(), area[keep]
    w = vertex_depth[keep].copy()
    front = area < 0
    for arr in (X, Y, w):
        arr[front, 1], arr[front, 2] = arr[front, 2].copy(), arr[front, 1].copy()
    area = np.where(front, -area, area)
    stats["prims"] = int(len(tri))
    prims = Prims(tri, X, Y, w, area, ~front, ortho)
    # Re-check orientation after the swap (area > 0 for every stored prim).
    chk = (X[:, 1] - X[:, 0]) * (Y[:, 2] - Y[:, 0]) - (X[:, 2] - X[:, 0]) * (Y[:, 1] - Y[:, 0])
    assert np.array_equal(chk, area) and (area > 0).all()
    return prims, stats


# --------------------------------------------------------------------------------------
# §5–§6 coverage and depth of one prim
# --------------------------------------------------------------------------------------
def _is_top_left(dX: int, dY: int) -> bool:
    return (dY == 0 and dX > 0) or dY < 0


def prim_fragments(X, Y, w, area, width: int, height: int, far, sample=(0, 0),
                   ortho: bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(rows, cols, depth float32) of the fragments of one prim, far-discarded; `sample` (dx, dy)
    moves the sample point from the pixel centre 256*p+128 to 256*p+128+d (contract §10).
    ortho: `w` are the vertex depths, interpolated linearly (contract §11)."""
    X = [int(v) for v in X]
    Y = [int(v) for v in Y]
    sx, sy = HALF + int(sample[0]), HALF + int(sample[1])
    # Pixels whose sample 256*p+s lies in [min, max], clamped to the image.
    x_lo = max(0, -((sx - min(X)) // SUB))
    x_hi = min(width - 1, (max(X) - sx) // SUB)
    y_lo = max(0, -((sy - min(Y)) // SUB))
    y_hi = min(height - 1, (max(Y) - sy) // SUB)
    none = (np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0, np.float32))
    if x_lo > x_hi or y_lo > y_hi:
        return none
    PX = (SUB * np.arange(x_lo, x_hi + 1, dtype=np.int64) + sx)[None, :]
    PY = (SUB * np.arange(y_lo, y_hi + 1, dtype=np.int64) + sy)[:, None]
    E = []
    covered = np.ones((len(PY), PX.shape[1]), bool)
    for k in range(3):
        k1 = (k + 1) % 3
        dX, dY = X[k1] - X[k], Y[k1] - Y[k]
        Ek = dX * (PY - Y[k]) - dY * (PX - X[k])           # int64 (H', W')
        E.append(Ek)
        covered &= (Ek > 0) | ((Ek == 0) & _is_top_left(dX, dY))
    rows, cols = np.nonzero(covered)
    if len(rows) == 0:
        return none
    # Vertex weights: e_k = edge function of the edge opposite vertex k.
    e0 = E[1][rows, cols].astype(np.float32)
    e1 = E[2][rows, cols].astype(np.float32)
    e2 = E[0][rows, cols].astype(np.float32)
    w = np.asarray(w, np.float32)
    area_f = np.asarray([area], np.int64).astype(np.float32)[0]
    if ortho:
        num = (e0 * w[0] + e1 * w[1]) + e2 * w[2]
        depth = num / area_f
    else:
        iw = F32(1.0) / w
        num = (e0 * iw[0] + e1 * iw[1]) + e2 * iw[2]
        depth = area_f / num
    assert depth.dtype == np.float32
    keep = ~(depth > F32(far))
    return rows[keep] + y_lo, cols[keep] + x_lo, depth[keep]


def iter_fragments(prims: Prims, width: int, height: int, far,
                   sample=(0, 0)) -> Iterator[tuple[int, int, np.ndarray, np.ndarray, np.ndarray]]:
    """(triangle id, prim index, rows, cols, depth) for every prim in setup order."""
    for n in range(len(prims)):
        rows, cols, depth = prim_fragments(prims.X[n], prims.Y[n], prims.w[n], prims.area[n], width, height, far,
                                           sample, prims.ortho)
        if len(rows):
            yield int(prims.tri[n]), n, rows, cols, depth


# --------------------------------------------------------------------------------------
# Public entry points
# --------------------------------------------------------------------------------------
def rasterize(scene, camera, width: int, height: int, sample=(0, 0)) -> tuple[np.ndarray, np.ndarray, dict]:
    """(triangle_id int32 (H, W) with -1 background, depth float32 (H, W) with +inf, stats);
    `sample` (dx, dy) in 1/256 pixel: coverage and depth at that sub-sample (contract §10)."""
    W, H = int(width), int(height)
    prims, stats = setup(scene, camera, W, H)
    ids = np.full((H, W), -1, np.int32)
    depth = np.full((H, W), np.inf, np.float32)
    # Prims come in ascending (triangle id, prim index) order, so a strict "<" keeps the
    # lower id (then the lower prim index) on equal depth.
    for tri, _, rows, cols, dep in iter_fragments(prims, W, H, F32(camera.far), sample):
        win = dep < depth[rows, cols]
        depth[rows[win], cols[win]] = dep[win]
        ids[rows[win], cols[win]] = tri
    return ids, depth, stats


def coverage_count(scene, camera, width: int, height: int) -> np.ndarray:
    """(H, W) int32: number of fragments (all prims, after culling and far discard) per pixel."""
    W, H = int(width), int(height)
    prims, _ = setup(scene, camera, W, H)
    count = np.zeros((H, W), np.int32)
    for _, _, rows, cols, _ in iter_fragments(prims, W, H, F32(camera.far)):
        count[rows, cols] += 1
    return count


# --------------------------------------------------------------------------------------
# Scene builders shared by the raster tests (pure NumPy; not part of the contract)
# --------------------------------------------------------------------------------------
def pixel_exact_camera(near: float = 0.1, far: float = 100.0):
    """Camera at the origin looking down -Z, fov 90°. For a SQUARE image M is exactly
    diag(1, 1, ·, ·) with w = -z, so a view point (x, y, -d) lands at NDC (x/d, y/d) exactly."""
    from clrender import Camera
    return Camera.look_at((0.0, 0.0, 0.0), (0.0, 0.0, -1.0), (0.0, 1.0, 0.0), 90.0, near=near, far=far)


def screen_to_world(sx, sy, size: int, depth: float = 1.0) -> np.ndarray:
    """World point that pixel_exact_camera projects to screen position (sx, sy) (pixels, row 0
    at the top, pixel centers at k + 0.5) of a size×size image. Exact for dyadic inputs."""
    sx = np.asarray(sx, np.float64)
    sy = np.asarray(sy, np.float64)
    x = (sx / size * 2.0 - 1.0) * depth
    y = (1.0 - sy / size * 2.0) * depth
    z = np.full(np.broadcast(x, y).shape, -depth)
    return np.stack(np.broadcast_arrays(x, y, z), axis=-1).astype(np.float32)


def triangles_scene(tri_vertices, single_sided=None):
    """A Scene with one material per sidedness from (T, 3, 3) world vertices.
    single_sided: (T,) bool (default all double-sided). Triangle ids follow the input order."""
    from clrender import Material, Scene
    from clrender.scene.geometry import vertex_normals
    v = np.asarray(tri_vertices, np.float32).reshape(-1, 3, 3)
    T = len(v)
    positions = v.reshape(-1, 3)
    faces = np.arange(3 * T, dtype=np.int32).reshape(-1, 3)
    ss = np.zeros(T, bool) if single_sided is None else np.asarray(single_sided, bool).reshape(T)
    materials = [Material(name="double", double_sided=True), Material(name="single", double_sided=False)]
    with np.errstate(all="ignore"):
        normals = vertex_normals(positions, faces)
    return Scene(positions, normals, np.zeros((3 * T, 2), np.float32), faces, ss.astype(np.int32), materials)


def tessellated_grid(xs, ys, rng, random_winding: bool = True) -> np.ndarray:
    """(2*(nx-1)*(ny-1), 3, 2) screen-space triangles of the grid xs × ys, each cell split
    along a random diagonal, each triangle with a random winding."""
    tris = []
    for j in range(len(ys) - 1):
        for i in range(len(xs) - 1):
            a, b = (xs[i], ys[j]), (xs[i + 1], ys[j])
            c, d = (xs[i + 1], ys[j + 1]), (xs[i], ys[j + 1])
            pair = [(a, b, c), (a, c, d)] if rng.integers(2) else [(a, b, d), (b, c, d)]
            for t in pair:
                if random_winding and rng.integers(2):
                    t = (t[0], t[2], t[1])
                tris.append(t)
    return np.asarray(tris, np.float64)


def near_floor_grid(seed):
    """A randomly subdivided floor (y = -1) reaching behind the camera: dozens of shared edges
    cross the near plane, each clipped by the two triangles that share it in opposite
    directions. Returns (scene, camera, width, height)."""
    rng = np.random.default_rng(seed)
    xs = np.sort(np.concatenate([[-12.0, 12.0], rng.uniform(-12, 12, 10)]))
    zs = np.sort(np.concatenate([[-30.0, 4.0], rng.uniform(-30, 4, 10), rng.uniform(-1.5, 0.5, 4)]))
    grid = tessellated_grid(xs, zs, rng)
    world = np.stack([grid[..., 0], np.full(grid.shape[:2], -1.0), grid[..., 1]], axis=-1)
    from clrender import Camera
    cam = Camera.look_at((0.2, 0.0, 0.0), (0.0, -0.25, -1.0), (0, 1, 0), 75.0, near=1.5, far=100.0)
    return triangles_scene(world), cam, 97, 61
