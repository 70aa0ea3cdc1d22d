"""Tests of the pure-NumPy reference rasterizer alone (no OpenCL needed).

The reference (tests/reference/raster.py) implements docs/raster_contract.md; these tests pin
the properties the contract promises on scenes whose answer is known independently.
"""
from __future__ import annotations

import numpy as np
import pytest

from clrender import Camera, Material, Scene
from reference.raster import (ReferenceScopeError, clip_near, coverage_count, near_floor_grid,
                              pixel_exact_camera, rasterize, screen_to_world, setup, tessellated_grid,
                              triangles_scene)


def screen_tris(tris_xy, size, depth=1.0):
    """(T, 3, 2) screen positions (pixels, centers at k + 0.5) -> (T, 3, 3) world vertices."""
    t = np.asarray(tris_xy, np.float64)
    return screen_to_world(t[..., 0], t[..., 1], size, depth)


# --------------------------------------------------------------------------------------
# Top-left rule on a 2×2-pixel square
# --------------------------------------------------------------------------------------
# Square with corners on the pixel centers of (col, row) (1, 1), (3, 1), (3, 3), (1, 3) of an
# 8×8 image. Its boundary passes through 9 pixel centers (cols 1..3 × rows 1..3). The top edge
# (row 1) and the left edge (col 1) are top-left edges and own their centers; the right edge
# (col 3) and the bottom edge (row 3) are not. So exactly rows 1-2 × cols 1-2 are covered:
# (col, row) = (1, 1), (2, 1), (1, 2), (2, 2). The inner diagonal gives each of its centers
# to exactly one of the two triangles.
SQUARE_EXPECTED = {(1, 1), (2, 1), (1, 2), (2, 2)}   # (col, row)


@pytest.mark.parametrize("diagonal", ["main", "anti"])
@pytest.mark.parametrize("winding", ["ccw", "cw", "mixed"])
def test_two_by_two_square_top_left(diagonal, winding):
    size = 8
    a, b, c, d = (1.5, 1.5), (3.5, 1.5), (3.5, 3.5), (1.5, 3.5)    # TL, TR, BR, BL on screen
    tris = [(a, b, c), (a, c, d)] if diagonal == "main" else [(a, b, d), (b, c, d)]
    if winding in ("cw", "mixed"):
        tris[0] = (tris[0][0], tris[0][2], tris[0][1])
    if winding == "cw":
        tris[1] = (tris[1][0], tris[1][2], tris[1][1])
    scene = triangles_scene(screen_tris(tris, size))
    cam = pixel_exact_camera()

    prims, stats = setup(scene, cam, size, size)
    assert stats["prims"] == 2
    # The vertices snap exactly onto pixel centers: 256 * k + 128.
    assert set(prims.X.ravel().tolist()) == {384, 896} and set(prims.Y.ravel().tolist()) == {384, 896}

    count = coverage_count(scene, cam, size, size)
    expected = np.zeros((size, size), np.int32)
    for col, row in SQUARE_EXPECTED:
        expected[row, col] = 1
    assert np.array_equal(count, expected), f"coverage:\n{count}"

    ids, depth, _ = rasterize(scene, cam, size, size)
    assert {(int(c), int(r)) for r, c in zip(*np.nonzero(ids >= 0))} == SQUARE_EXPECTED
    assert np.all(depth[ids >= 0] == np.float32(1.0))
    assert np.all(np.isinf(depth[ids < 0]))


def test_single_triangle_top_left_edges():
    """Right triangle with a top and a left edge through pixel centers: those are included,
    the hypotenuse's centers are excluded."""
    size = 8
    # Screen TL (1.5,1.5), TR (5.5,1.5), BL (1.5,5.5); hypotenuse x + y = 7 passes through
    # the centers (col, row) with col + row = 6.
    scene = triangles_scene(screen_tris([[(1.5, 1.5), (5.5, 1.5), (1.5, 5.5)]], size))
    count = coverage_count(scene, pixel_exact_camera(), size, size)
    rows, cols = np.mgrid[0:size, 0:size]
    expected = (cols >= 1) & (rows >= 1) & (cols + rows < 6)
    assert np.array_equal(count.astype(bool), expected), f"coverage:\n{count}"


# --------------------------------------------------------------------------------------
# Watertightness
# --------------------------------------------------------------------------------------
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_tessellated_square_exactly_once(seed):
    """A grid on pixel centers, random diagonals and windings: every pixel whose center is in
    [x0, x1) × [y0, y1) is hit exactly once, every other pixel never."""
    size = 64
    rng = np.random.default_rng(seed)
    cols = np.unique(np.concatenate([[4, 59], rng.choice(np.arange(5, 59), 9, replace=False)]))
    rows = np.unique(np.concatenate([[3, 60], rng.choice(np.arange(4, 60), 11, replace=False)]))
    tris = tessellated_grid(cols + 0.5, rows + 0.5, rng)
    depth_plane = 2.0
    scene = triangles_scene(screen_tris(tris, size, depth=depth_plane))
    cam = pixel_exact_camera()

    count = coverage_count(scene, cam, size, size)
    expected = np.zeros((size, size), np.int32)
    expected[rows[0]:rows[-1], cols[0]:cols[-1]] = 1
    bad = np.argwhere(count != expected)
    assert len(bad) == 0, f"{len(bad)} pixels wrong, e.g. (row, col) {bad[:5].tolist()} count {count[tuple(bad[0])]}"

    ids, depth, stats = rasterize(scene, cam, size, size)
    assert stats["prims"] == len(tris) and stats["degenerate"] == 0
    assert np.array_equal(ids >= 0, expected.astype(bool))
    assert np.all(depth[ids >= 0] == np.float32(depth_plane))     # exact: w is a power of 2


def pixel_rays(camera: Camera, width: int, height: int):
    """(origin (3,), directions (H, W, 3)) float64 world rays through the pixel centers."""
    right, up, back = camera.basis()
    t = 1.0 / np.tan(np.radians(camera.fov_y_deg) / 2.0)
    aspect = width / height
    nx = (np.arange(width) + 0.5) / width * 2.0 - 1.0
    ny = 1.0 - (np.arange(height) + 0.5) / height * 2.0
    NX, NY = np.meshgrid(nx, ny)
    dirs = (NX * aspect / t)[..., None] * right + (NY / t)[..., None] * up - back
    return np.asarray(camera.eye, np.float64), dirs


def ray_plane(origin, dirs, p0, a, b):
    """Solve origin + s*dir = p0 + u*a + v*b per pixel -> (s, u, v) arrays (H, W)."""
    H, W = dirs.shape[:2]
    A = np.empty((H, W, 3, 3))
    A[..., 0] = dirs
    A[..., 1] = -np.asarray(a, float)
    A[..., 2] = -np.asarray(b, float)
    rhs = np.broadcast_to(np.asarray(p0, float) - origin, (H, W, 3))
    sol = np.linalg.solve(A, rhs[..., None])[..., 0]
    return sol[..., 0], sol[..., 1], sol[..., 2]


def test_tessellated_square_perspective_watertight():
    """A randomly subdivided square on a tilted plane under perspective (vertices nowhere
    near pixel centers): no pixel is hit twice and no pixel inside the square is missed."""
    W, H = 97, 61
    cam = Camera.look_at((0.3, 0.8, 2.2), (0.0, 0.0, 0.0), (0, 1, 0), 60.0, near=0.1, far=50.0)
    rng = np.random.default_rng(7)
    u = np.sort(np.concatenate([[-1.0, 1.0], rng.uniform(-1, 1, 14)]))
    v = np.sort(np.concatenate([[-1.0, 1.0], rng.uniform(-1, 1, 10)]))
    uv_tris = tessellated_grid(u, v, rng)
    p0 = np.array([0.1, -0.2, 0.0])
    a = np.array([1.0, 0.1, 0.3])
    b = np.array([-0.2, 0.6, 0.7])
    world = p0 + uv_tris[..., :1] * a + uv_tris[..., 1:] * b
    scene = triangles_scene(world)

    count = coverage_count(scene, cam, W, H)
    assert count.max() == 1, f"double hits at {np.argwhere(count > 1)[:5].tolist()}"
    origin, dirs = pixel_rays(cam, W, H)
    s, pu, pv = ray_plane(origin, dirs, p0, a, b)
    m = np.maximum(np.abs(pu), np.abs(pv))
    inside = (s > 0) & (m < 0.97)
    outside = (s <= 0) | (m > 1.03)
    assert inside.sum() > 500
    assert np.all(count[inside] == 1), f"cracks at {np.argwhere(inside & (count != 1))[:5].tolist()}"
    assert np.all(count[outside] == 0)


# --------------------------------------------------------------------------------------
# Near-plane clipping
# --------------------------------------------------------------------------------------
@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_near_clipped_grid_watertight(seed):
    """Clipping a shared edge from its inside endpoint gives both triangles the same vertex:
    no pixel is hit twice and none inside the visible floor is missed."""
    scene, cam, W, H = near_floor_grid(seed)
    _, stats = setup(scene, cam, W, H)
    count = coverage_count(scene, cam, W, H)
    assert count.max() == 1, f"double hits at {np.argwhere(count > 1)[:5].tolist()}"
    origin, dirs = pixel_rays(cam, W, H)
    s, pu, pv = ray_plane(origin, dirs, (0.0, -1.0, 0.0), (1.0, 0.0, 0.0), (0.0, 0.0, 1.0))
    hit = origin + s[..., None] * dirs
    right, up, back = cam.basis()
    w = (hit - origin) @ -back                      # view depth of the floor point
    inside = (s > 0) & (np.abs(pu) < 11.9) & (pv > -29.9) & (pv < 3.9) & (w > cam.near * 1.01)
    assert inside.sum() > 1000
    assert np.all(count[inside] == 1), f"cracks at {np.argwhere(inside & (count != 1))[:5].tolist()}"
    assert stats["culled_near"] > 0
    # The near plane's cut is on screen: floor pixels nearer than `near` are empty.
    cut = (s > 0) & (np.abs(pu) < 11.9) & (w < cam.near * 0.99)
    assert cut.sum() > 100 and np.all(count[cut] == 0)


def test_clip_near_order_and_inside_endpoint():
    v = np.array([[0.0, 0.0, 0.0, 3.0], [1.0, 0.0, 0.0, -1.0], [0.0, 1.0, 0.0, 2.0]], np.float32)
    near = np.float32(1.0)
    d = v[:, 3] - near
    poly = clip_near(v, d)
    assert len(poly) == 4 and all(p.dtype == np.float32 for p in poly)
    t01 = d[0] / (d[0] - d[1])
    t21 = d[2] / (d[2] - d[1])
    expected = [v[0], v[0] + t01 * (v[1] - v[0]), v[2] + t21 * (v[1] - v[2]), v[2]]
    for got, want in zip(poly, expected):
        assert np.array_equal(got, want)
    # Two vertices outside: a triangle (inside vertex, then the two crossings).
    d2 = np.array([1.0, -1.0, -2.0], np.float32)
    assert len(clip_near(v, d2)) == 3


def floor_scene():
    # Floor y = -1: one vertex behind the camera, two far in front (a quad after clipping).
    return triangles_scene([[(0.0, -1.0, 10.0), (-40.0, -1.0, -200.0), (40.0, -1.0, -200.0)]])


def test_near_plane_clipping_matches_projection():
    size = 64
    near, far = 2.0, 1000.0
    cam = pixel_exact_camera(near=near, far=far)
    scene = floor_scene()
    ids, depth, stats = rasterize(scene, cam, size, size)
    assert stats["prims"] == 2 and stats["culled_near"] == 0 and stats["invalid"] == 0

    # Analytic: the ray through NDC (nx, ny) (t = 1, aspect = 1) hits y = -1 at view depth
    # w = -1/ny, at world (nx*w, -1, -w); covered when near <= w <= far and inside the triangle.
    n = (np.arange(size) + 0.5) / size * 2 - 1
    NX, NY = np.meshgrid(n, -n)
    with np.errstate(divide="ignore"):
        w = np.where(NY < 0, -1.0 / NY, np.inf)
    px, pz = NX * w, -w
    tri = np.array([(0.0, 10.0), (-40.0, -200.0), (40.0, -200.0)])
    dist = np.full(w.shape, np.inf)        # signed distance to the triangle's edges (inside > 0)
    for k in range(3):
        (x0, z0), (x1, z1) = tri[k], tri[(k + 1) % 3]
        ex, ez = x1 - x0, z1 - z0
        with np.errstate(invalid="ignore"):
            dk = (ex * (pz - z0) - ez * (px - x0)) / np.hypot(ex, ez)
        dist = np.minimum(dist, dk)        # the triangle is counter-clockwise in (x, z)
    footprint = 2.0 * w / size             # world size of one pixel at depth w
    finite = np.isfinite(w)
    covered = finite & (w >= near) & (w <= far) & (dist > 0)
    decisive = ~finite | ((np.abs(dist) > 0.25 * footprint) & (np.abs(w - near) > 0.01 * near))
    assert decisive.sum() > 0.9 * size * size
    assert np.array_equal((ids >= 0)[decisive], covered[decisive])
    # Snapping moves vertices by up to 1/512 pixel; on this grazing floor depth changes by
    # w² per unit of NDC y, so the analytic depth is only good to about w * 2/(256 * size).
    sel = covered & decisive
    np.testing.assert_array_less(np.abs(depth[sel] - w[sel]), w[sel] * (1e-5 + 2.0 * w[sel] / (256 * size)))
    # The near plane cuts the floor between rows 47 (w = 2.06) and 48 (w = 1.94).
    assert np.all(ids[47] == 0) and np.all(ids[48:] == -1) and np.all(ids[:32] == -1)


def test_near_plane_culled_and_single_prim():
    size = 32
    cam = pixel_exact_camera(near=1.0)
    behind = [(-1.0, -1.0, 0.5), (1.0, -1.0, 0.5), (0.0, 1.0, 2.0)]            # all w < near
    two_out = [(0.0, 0.0, -5.0), (-1.0, -1.0, -0.5), (1.0, -1.0, -0.5)]       # two vertices at w = 0.5
    ids, _, stats = rasterize(triangles_scene([behind]), cam, size, size)
    assert stats["culled_near"] == 1 and stats["prims"] == 0 and np.all(ids == -1)
    ids, _, stats = rasterize(triangles_scene([two_out]), cam, size, size)
    assert stats["culled_near"] == 0 and stats["prims"] == 1 and np.any(ids == 0)
    # Exactly on the near plane (d = 0) counts as inside: no clipping.
    on_plane = [(-0.5, -0.5, -1.0), (0.5, -0.5, -1.0), (0.0, 0.5, -1.0)]
    ids, _, stats = rasterize(triangles_scene([on_plane]), cam, size, size)
    assert stats["prims"] == 1 and np.any(ids == 0)


# --------------------------------------------------------------------------------------
# Facing, visibility, far plane, bad input
# --------------------------------------------------------------------------------------
NDC_CCW = [(-0.5, -0.5), (0.5, -0.5), (0.0, 0.5)]   # counter-clockwise in NDC: front-facing


def ndc_tri(points, depth):
    return [(x * depth, y * depth, -depth) for x, y in points]


def test_backface_culling_single_sided():
    size = 16
    cam = pixel_exact_camera()
    front = ndc_tri(NDC_CCW, 1.0)
    back = [front[0], front[2], front[1]]
    ids, _, stats = rasterize(triangles_scene([front], single_sided=[True]), cam, size, size)
    assert stats["culled_backface"] == 0 and (ids == 0).sum() > 10
    ids_b, _, stats = rasterize(triangles_scene([back], single_sided=[True]), cam, size, size)
    assert stats["culled_backface"] == 1 and stats["prims"] == 0 and np.all(ids_b == -1)
    # Double-sided: both windings render, on the very same pixels.
    ids_f2, _, st_f = rasterize(triangles_scene([front]), cam, size, size)
    ids_b2, _, st_b = rasterize(triangles_scene([back]), cam, size, size)
    assert st_f["culled_backface"] == st_b["culled_backface"] == 0
    assert np.array_equal(ids_f2, ids) and np.array_equal(ids_b2, ids)
    prims, _ = setup(triangles_scene([front, back]), cam, size, size)
    assert prims.backface.tolist() == [False, True] and (prims.area > 0).all()


def test_nearest_wins_regardless_of_order():
    # 16×16 keeps every fixed-point area below 2^24, so e_k, num and depth are exact.
    size = 16
    cam = pixel_exact_camera()
    far_tri = ndc_tri([(-0.8, -0.8), (0.6, -0.8), (-0.1, 0.7)], 4.0)
    near_tri = ndc_tri([(-0.6, -0.6), (0.8, -0.6), (0.1, 0.8)], 2.0)
    for order in ([far_tri, near_tri], [near_tri, far_tri]):
        scene = triangles_scene(order)
        ids, depth, _ = rasterize(scene, cam, size, size)
        near_id = order.index(near_tri)
        count = coverage_count(scene, cam, size, size)
        overlap = count == 2
        assert overlap.sum() > 20
        assert np.all(ids[overlap] == near_id)
        assert np.all(depth[overlap] == np.float32(2.0))
        assert np.all(depth[(ids == 1 - near_id)] == np.float32(4.0))


def test_equal_depth_goes_to_lower_id():
    # 16×16 keeps every fixed-point area below 2^24: depth is exactly 1.0, a true tie.
    size = 16
    cam = pixel_exact_camera()
    a = ndc_tri([(-0.8, -0.8), (0.6, -0.8), (-0.1, 0.7)], 1.0)
    b = ndc_tri([(-0.6, -0.6), (0.8, -0.6), (0.1, 0.8)], 1.0)
    for tris in ([a, b], [b, a], [a, b, a], [b, a, b, a]):
        scene = triangles_scene(tris)
        ids, depth, _ = rasterize(scene, cam, size, size)
        count = coverage_count(scene, cam, size, size)
        assert np.all(depth[ids >= 0] == np.float32(1.0))           # exact tie everywhere
        overlap_a_b = count >= 2
        assert overlap_a_b.sum() > 20
        # Every covered pixel belongs to the lowest id among the triangles covering it.
        for t in range(len(tris)):
            single = triangles_scene([tris[t]])
            cov_t = coverage_count(single, cam, size, size) > 0
            assert np.all(ids[cov_t] <= t)
            assert np.all(ids[cov_t & ~np.isin(ids, range(t))] == t)


def test_far_plane_discard_is_per_pixel():
    size = 32
    cam = pixel_exact_camera(near=0.5, far=10.0)
    beyond = ndc_tri(NDC_CCW, 12.0)
    ids, _, stats = rasterize(triangles_scene([beyond]), cam, size, size)
    assert np.all(ids == -1) and stats["prims"] == 1       # set up, then discarded per pixel
    # A tilted floor crossing the far plane: covered rows are exactly those with depth <= far.
    floor = [(-50.0, -1.0, -1.0), (50.0, -1.0, -1.0), (0.0, -1.0, -40.0)]
    ids, depth, _ = rasterize(triangles_scene([floor]), cam, size, size)
    assert np.any(ids == 0) and np.all(depth[ids == 0] <= np.float32(10.0))
    ny = 1.0 - (np.arange(size) + 0.5) / size * 2
    rows_far = np.nonzero((ny < 0) & (-1.0 / np.where(ny < 0, ny, -1) > 10.5))[0]
    assert len(rows_far) and np.all(ids[rows_far] == -1)


def test_non_finite_vertices_dropped_and_counted(monkeypatch):
    from helpers import reach_the_raster_guard
    reach_the_raster_guard(monkeypatch)        # Scenes refuse such vertices; the reference still drops them
    size = 32
    cam = pixel_exact_camera()
    good0 = ndc_tri([(-0.9, -0.9), (0.0, -0.9), (-0.45, 0.0)], 2.0)
    nan_tri = ndc_tri(NDC_CCW, 1.0)
    nan_tri[1] = (np.nan, 0.0, -1.0)
    inf_tri = ndc_tri(NDC_CCW, 1.0)
    inf_tri[2] = (0.0, np.inf, -1.0)
    ninf_tri = ndc_tri(NDC_CCW, 1.0)
    ninf_tri[0] = (0.0, 0.0, -np.inf)
    good4 = ndc_tri([(0.1, 0.1), (0.9, 0.1), (0.5, 0.9)], 2.0)
    scene = triangles_scene([good0, nan_tri, inf_tri, ninf_tri, good4])
    ids, depth, stats = rasterize(scene, cam, size, size)
    assert stats["invalid"] == 3 and stats["prims"] == 2 and stats["triangles_in"] == 5
    assert set(np.unique(ids).tolist()) == {-1, 0, 4}
    assert np.all(np.isfinite(depth[ids >= 0]))


def test_empty_scene():
    scene = Scene.from_arrays(np.zeros((0, 3), np.float32), np.zeros((0, 3), np.int64))
    ids, depth, stats = rasterize(scene, pixel_exact_camera(), 16, 12)
    assert ids.shape == (12, 16) and ids.dtype == np.int32 and np.all(ids == -1)
    assert depth.dtype == np.float32 and np.all(np.isinf(depth))
    assert stats["triangles_in"] == 0 and stats["prims"] == 0


def test_out_of_scope_inputs_are_refused():
    cam = pixel_exact_camera(near=0.1)
    huge = [(-1e7, -1.0, -1.0), (1e7, -1.0, -1.0), (0.0, 1e7, -1.0)]   # needs guard-band clipping
    with pytest.raises(ReferenceScopeError):
        rasterize(triangles_scene([huge]), cam, 32, 32)
    masked = Scene.from_arrays(ndc_tri(NDC_CCW, 1.0), [[0, 1, 2]],
                               material=Material(alpha_mode="MASK"))
    with pytest.raises(ReferenceScopeError):
        rasterize(masked, cam, 32, 32)


def test_pixels_outside_the_image_never_written():
    """A triangle much larger than the screen covers every pixel exactly once."""
    size, cam = 24, pixel_exact_camera()
    big = ndc_tri([(-30.0, -30.0), (30.0, -30.0), (0.0, 30.0)], 3.0)
    count = coverage_count(triangles_scene([big]), cam, size, size + 5)
    assert count.shape == (size + 5, size) and np.all(count == 1)
