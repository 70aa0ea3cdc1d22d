"""The OpenCL rasterizer against the NumPy reference (tests/reference/raster.py).

docs/raster_contract.md fixes every arithmetic step, so `triangle_id` must equal the reference
bit for bit on every pixel. Depth is compared with rtol 1e-6 (a few float32 ulp) on pixels
whose ids agree: the contract's depth is exact too, but Frame.depth is decoded from the
G-buffer's depth/far and multiplied back by far, which costs up to ~2 ulp.

Stats: `invalid` and `culled_near` count input triangles and are always compared.
`degenerate` and `culled_backface` are compared only on scenes where every triangle is
on screen and unclipped (one prim per triangle), because the contract does not say how a
triangle whose pieces fail for different reasons is counted.
"""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from clrender import Camera, Scene
from helpers import reach_the_raster_guard
from reference.raster import (ReferenceScopeError, coverage_count, near_floor_grid, pixel_exact_camera,
                              rasterize, screen_to_world, tessellated_grid, triangles_scene)

DEPTH_RTOL = 1e-6
SIZES = [(64, 48), (97, 61), (128, 128)]


@pytest.fixture(scope="module", autouse=True)
def raster_guard():
    """This module feeds the raster NaN, infinite and huge vertices on purpose (helpers.reach_the_raster_guard)."""
    with pytest.MonkeyPatch.context() as mp:
        reach_the_raster_guard(mp)
        yield


# --------------------------------------------------------------------------------------
# Helpers
# --------------------------------------------------------------------------------------
def render(make_renderer, scene, camera, width, height, **opts):
    frame = make_renderer(width, height, **opts).render(scene, camera=camera)
    ids, depth = frame.triangle_id, frame.depth
    assert ids.shape == (height, width) and ids.dtype == np.int32
    assert depth.shape == (height, width) and depth.dtype == np.float32
    return frame


def assert_frame_matches(frame, ref, stats_keys=("invalid", "culled_near", "triangles_in")):
    ref_ids, ref_depth, ref_stats = ref
    ids, depth = frame.triangle_id, frame.depth
    diff = np.argwhere(ids != ref_ids)
    if len(diff):
        lines = [f"  (row {r}, col {c}): gpu id {ids[r, c]} depth {depth[r, c]!r}, "
                 f"reference id {ref_ids[r, c]} depth {ref_depth[r, c]!r}" for r, c in diff[:8]]
        pytest.fail(f"triangle_id differs on {len(diff)} of {ids.size} pixels:\n" + "\n".join(lines))
    fg = ref_ids >= 0
    assert np.all(np.isposinf(depth[~fg])), "background depth must be +inf"
    if fg.any():
        np.testing.assert_allclose(depth[fg], ref_depth[fg], rtol=DEPTH_RTOL, atol=0,
                                   err_msg="depth differs from the reference")
    for key in stats_keys:
        assert key in frame.stats, f"frame.stats lacks {key!r}: {sorted(frame.stats)}"
        assert frame.stats[key] == ref_stats[key], \
            f"stats[{key!r}] = {frame.stats[key]}, reference {ref_stats[key]} (all: {frame.stats})"


def check(make_renderer, scene, camera, width, height, stats_keys=("invalid", "culled_near", "triangles_in"),
          **opts):
    ref = rasterize(scene, camera, width, height)
    frame = render(make_renderer, scene, camera, width, height, **opts)
    assert_frame_matches(frame, ref, stats_keys)
    return frame, ref


ALL_STATS = ("invalid", "culled_near", "degenerate", "culled_backface", "triangles_in")


def ndc_tri(points, depth):
    """View-space = world-space vertices (pixel_exact_camera) at depth for NDC xy points."""
    return [(x * depth, y * depth, -depth) for x, y in points]


# --------------------------------------------------------------------------------------
# Random triangle soups
# --------------------------------------------------------------------------------------
def _orthonormal_frame(camera: Camera):
    right, up, back = camera.basis()
    return right, up, -back


def perspective_soup(rng, n, width, height, single_fraction):
    """Overlapping triangles of all sizes, some crossing the near plane, some off screen,
    behind the camera or past the far plane, some degenerate, some exact duplicates, a few
    with NaN/Inf vertices."""
    fov = rng.uniform(55.0, 100.0)
    near = rng.uniform(0.2, 1.0)
    far = rng.uniform(20.0, 200.0)
    eye = rng.uniform(-4, 4, 3) + np.array([0.0, 0.0, 9.0])
    target = rng.uniform(-2, 2, 3)
    cam = Camera.look_at(eye, target, (0.0, 1.0, 0.0), fov, near=near, far=far)
    right, up, fwd = _orthonormal_frame(cam)
    kinds = rng.choice(["scene", "near", "offscreen", "far", "degenerate", "duplicate", "bad"], n,
                       p=[0.55, 0.15, 0.08, 0.06, 0.06, 0.06, 0.04])
    tris = np.zeros((n, 3, 3))
    for i, kind in enumerate(kinds):
        if kind == "duplicate" and i > 0:
            tris[i] = tris[rng.integers(i)]
            if rng.integers(2):
                tris[i] = tris[i][[0, 2, 1]]
            continue
        if kind == "near":
            center = eye + fwd * near * rng.uniform(0.3, 3.0) + right * rng.uniform(-2, 2) + up * rng.uniform(-2, 2)
            scale = near * rng.uniform(0.3, 3.0)
        elif kind == "offscreen":
            if rng.integers(2):
                center = eye - fwd * rng.uniform(1, 10) + right * rng.uniform(-3, 3)     # behind
            else:
                d = rng.uniform(2, 10)
                center = eye + fwd * d + right * d * rng.choice([-1, 1]) * rng.uniform(3, 6)
            scale = rng.uniform(0.1, 2.0)
        elif kind == "far":
            d = far * rng.uniform(0.8, 1.3)
            center = eye + fwd * d + (right * rng.uniform(-0.5, 0.5) + up * rng.uniform(-0.5, 0.5)) * d
            scale = d * rng.uniform(0.05, 0.3)
        else:
            center = rng.uniform(-8, 8, 3)
            scale = float(np.exp(rng.uniform(np.log(0.03), np.log(3.0))))
        tris[i] = center + rng.normal(size=(3, 3)) * scale
        if kind == "degenerate":
            if rng.integers(2):
                tris[i, 2] = tris[i, rng.integers(2)]                                   # repeated vertex
            else:
                tris[i, 2] = tris[i, 0] + rng.uniform(-1, 2) * (tris[i, 1] - tris[i, 0])  # collinear
        elif kind == "bad":
            tris[i, rng.integers(3), rng.integers(3)] = rng.choice([np.nan, np.inf, -np.inf])
    single = rng.random(n) < single_fraction
    return triangles_scene(tris, single_sided=single), cam


def quantized_soup(rng, n, width, height, single_fraction):
    """Axis-aligned camera, vertices on a 1/16 grid at depths 1, 2, 4: many vertices snap to
    the same points, edges pass exactly through pixel centers, coplanar overlaps tie in depth."""
    cam = pixel_exact_camera(near=0.5, far=50.0)
    aspect = width / height
    tris = np.zeros((n, 3, 3))
    for i in range(n):
        if i > 0 and rng.random() < 0.1:
            tris[i] = tris[rng.integers(i)]
            continue
        if rng.random() < 0.8:
            d = np.full(3, rng.choice([1.0, 2.0, 4.0]))
        else:
            d = rng.choice([1.0, 2.0, 4.0], 3)
        center = rng.integers(-20, 21, 2) / 16.0
        span = rng.integers(1, 12) / 16.0
        xy = center + rng.integers(-4, 5, (3, 2)) / 4.0 * span
        xy[:, 0] *= aspect
        tris[i, :, 0] = xy[:, 0] * d
        tris[i, :, 1] = xy[:, 1] * d
        tris[i, :, 2] = -d
    single = rng.random(n) < single_fraction
    return triangles_scene(tris, single_sided=single), cam


@st.composite
def soups(draw):
    size = draw(st.sampled_from(SIZES))
    n = draw(st.integers(1, 200))
    seed = draw(st.integers(0, 2**32 - 1))
    mode = draw(st.sampled_from(["perspective", "quantized"]))
    single_fraction = draw(st.sampled_from([0.0, 0.3, 1.0]))
    return size, n, seed, mode, single_fraction


def make_soup(size, n, seed, mode, single_fraction):
    rng = np.random.default_rng(seed)
    build = perspective_soup if mode == "perspective" else quantized_soup
    scene, cam = build(rng, n, size[0], size[1], single_fraction)
    return scene, cam


@settings(max_examples=25, derandomize=True, deadline=None, print_blob=True,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
@given(params=soups())
def test_random_soup_matches_reference(make_renderer, params):
    size, n, seed, mode, single_fraction = params
    scene, cam = make_soup(*params)
    check(make_renderer, scene, cam, *size)


def test_soup_generators_stay_in_reference_scope():
    """The generators never need guard-band clipping (the reference would refuse)."""
    for seed in range(40):
        for mode in ("perspective", "quantized"):
            size = SIZES[seed % 3]
            scene, cam = make_soup(size, 200, seed, mode, 0.3)
            rasterize(scene, cam, *size)


# --------------------------------------------------------------------------------------
# Watertightness
# --------------------------------------------------------------------------------------
@pytest.mark.parametrize("seed", [0, 1])
def test_tessellated_square_pixel_centers(make_renderer, seed):
    size = 64
    rng = np.random.default_rng(seed)
    cols = np.unique(np.concatenate([[4, 59], rng.choice(np.arange(5, 59), 12, replace=False)]))
    rows = np.unique(np.concatenate([[3, 60], rng.choice(np.arange(4, 60), 12, replace=False)]))
    tris = tessellated_grid(cols + 0.5, rows + 0.5, rng)
    scene = triangles_scene(screen_to_world(tris[..., 0], tris[..., 1], size, 2.0))
    cam = pixel_exact_camera()
    frame, _ = check(make_renderer, scene, cam, size, size, stats_keys=ALL_STATS)
    inside = np.zeros((size, size), bool)
    inside[rows[0]:rows[-1], cols[0]:cols[-1]] = True
    assert np.all(frame.triangle_id[inside] >= 0), "crack inside the tessellated square"
    assert np.all(frame.triangle_id[~inside] == -1)
    # Each pixel of the square is covered by exactly one triangle (the reference counts all
    # fragments, not only the winners), so the GPU's id is the only candidate there.
    assert np.array_equal(coverage_count(scene, cam, size, size), inside.astype(np.int32))


def test_large_prims_watertight_and_exact(make_renderer):
    """Prims hundreds of pixels wide: raster.cl's large-prim path picks per edge and run 32-bit
    lanes, exact doubles (CPUs) or 64-bit lanes; every choice must give the reference's exact
    coverage (no crack, no double cover between neighbours) and ids, with a second layer
    behind so depth decides visibility."""
    size = 1024
    rng = np.random.default_rng(4)
    cols = np.unique(np.concatenate([[7, 1013], rng.choice(np.arange(8, 1013), 5, replace=False)]))
    rows = np.unique(np.concatenate([[5, 1017], rng.choice(np.arange(6, 1017), 5, replace=False)]))
    front = tessellated_grid(cols + 0.5, rows + 0.5, rng)
    back = np.array([[(0.2, 0.3), (1023.7, 10.1), (500.5, 1023.9)]], np.float32)
    scene = triangles_scene(np.concatenate([screen_to_world(front[..., 0], front[..., 1], size, 2.0),
                                            screen_to_world(back[..., 0], back[..., 1], size, 3.0)]))
    cam = pixel_exact_camera()
    frame, (ref_ids, _, _) = check(make_renderer, scene, cam, size, size, stats_keys=ALL_STATS)
    inside = np.zeros((size, size), bool)
    inside[rows[0]:rows[-1], cols[0]:cols[-1]] = True
    assert np.all((frame.triangle_id >= 0) & (frame.triangle_id < len(front)) == inside), "crack or leak"
    assert np.any(frame.triangle_id == len(front)), "the back triangle shows outside the square"


def test_tessellated_square_perspective(make_renderer):
    W, H = 97, 61
    cam = Camera.look_at((0.3, 0.8, 2.2), (0.0, 0.0, 0.0), (0, 1, 0), 60.0, near=0.1, far=50.0)
    rng = np.random.default_rng(11)
    u = np.sort(np.concatenate([[-1.0, 1.0], rng.uniform(-1, 1, 20)]))
    v = np.sort(np.concatenate([[-1.0, 1.0], rng.uniform(-1, 1, 16)]))
    uv = tessellated_grid(u, v, rng)
    p0, a, b = np.array([0.1, -0.2, 0.0]), np.array([1.0, 0.1, 0.3]), np.array([-0.2, 0.6, 0.7])
    scene = triangles_scene(p0 + uv[..., :1] * a + uv[..., 1:] * b)
    count = coverage_count(scene, cam, W, H)
    assert count.max() == 1
    frame, _ = check(make_renderer, scene, cam, W, H, stats_keys=ALL_STATS)
    assert np.array_equal(frame.triangle_id >= 0, count == 1)


# --------------------------------------------------------------------------------------
# Near plane, facing
# --------------------------------------------------------------------------------------
def test_near_plane_clipping(make_renderer):
    size = 64
    cam = pixel_exact_camera(near=2.0, far=1000.0)
    tris = [
        [(0.0, -1.0, 10.0), (-40.0, -1.0, -200.0), (40.0, -1.0, -200.0)],   # floor: quad after clipping
        [(-3.0, -2.0, 1.0), (-3.0, 3.0, -30.0), (-3.0, -2.0, -30.0)],       # left wall, one vertex behind
        [(2.5, 2.0, 3.0), (2.5, -2.0, 3.0), (2.5, 0.0, -25.0)],             # right wall, two behind
        [(-1.0, -1.0, -1.0), (1.0, -1.0, -1.5), (0.0, 1.0, -1.9)],          # between the eye and the near plane: culled
        [(-1.0, 1.0, -2.0), (1.0, 1.0, -2.0), (0.0, 1.5, -2.0)],            # exactly on the near plane
    ]
    scene = triangles_scene(tris, single_sided=[False, True, False, False, False])
    frame, ref = check(make_renderer, scene, cam, size, size)
    assert ref[2]["culled_near"] == 1 and frame.stats["culled_near"] == 1
    assert {0, 2}.issubset(set(np.unique(frame.triangle_id).tolist()))
    # The near plane cuts the floor between rows 47 and 48.
    assert np.any(frame.triangle_id[47] == 0) and not np.any(frame.triangle_id[48:] == 0)


@pytest.mark.parametrize("seed", [0, 1])
def test_near_clipped_grid(make_renderer, seed):
    """A tessellated floor whose shared edges cross the near plane (clipped from the inside
    endpoint by both neighbours): exact ids, and no pixel twice covered in the reference."""
    scene, cam, W, H = near_floor_grid(seed)
    assert coverage_count(scene, cam, W, H).max() == 1
    frame, ref = check(make_renderer, scene, cam, W, H)
    assert ref[2]["culled_near"] > 0 and (frame.triangle_id >= 0).sum() > 1000


@pytest.mark.parametrize("size", [(64, 48), (97, 61)])
def test_backface_culling(make_renderer, size):
    W, H = size
    cam = Camera.look_at((0, 0, 0), (0, 0, -1), (0, 1, 0), 90.0, near=0.1, far=100.0)
    ccw = [(-0.9, 0.1), (-0.1, 0.1), (-0.5, 0.9)]                  # counter-clockwise in NDC
    tris, single = [], []
    for k, (dx, dy) in enumerate([(0.0, 0.0), (1.0, 0.0), (0.0, -1.0), (1.0, -1.0)]):
        pts = [(x + dx, y + dy) for x, y in ccw]
        if k % 2:
            pts = [pts[0], pts[2], pts[1]]                         # clockwise: back-facing
        tris.append(ndc_tri(pts, 2.0 + k))
        single.append(k < 2)                                       # 0: front single, 1: back single
    scene = triangles_scene(tris, single_sided=single)
    frame, ref = check(make_renderer, scene, cam, W, H, stats_keys=ALL_STATS)
    assert ref[2]["culled_backface"] == 1
    assert set(np.unique(frame.triangle_id).tolist()) == {-1, 0, 2, 3}


def test_visibility_ties_go_to_lower_id(make_renderer):
    """Exact depth ties (coplanar overlaps at w = 1 in a 16×16 frame, so every depth is
    exactly 1.0) must resolve to the lower triangle id on every device and tile size."""
    size = 16
    cam = pixel_exact_camera()
    a = ndc_tri([(-0.8, -0.8), (0.6, -0.8), (-0.1, 0.7)], 1.0)
    b = ndc_tri([(-0.6, -0.6), (0.8, -0.6), (0.1, 0.8)], 1.0)
    for tris in ([a, b], [b, a], [b, a, b, a, b]):
        for tile in (8, 16):
            check(make_renderer, triangles_scene(tris), cam, size, size, stats_keys=ALL_STATS, tile_size=tile)


# --------------------------------------------------------------------------------------
# Dense scenes: every tile holds thousands of triangles
# --------------------------------------------------------------------------------------
def dense_scene(n=20000, size=64, seed=5):
    rng = np.random.default_rng(seed)
    n_hot = n // 4                                   # a quarter piled into one 8×8 tile
    centers = np.concatenate([rng.uniform(0, size, (n - n_hot, 2)), rng.uniform(8, 16, (n_hot, 2))])
    extent = np.exp(rng.uniform(np.log(0.5), np.log(12.0), n))[:, None, None]
    xy = centers[:, None, :] + rng.uniform(-1, 1, (n, 3, 2)) * extent
    depth = rng.uniform(1.0, 30.0, (n, 1)) * rng.uniform(0.8, 1.25, (n, 3))
    depth[rng.random(n) < 0.2] = 1.0                 # a coplanar layer: exact ties
    world = screen_to_world(xy[..., 0], xy[..., 1], size, 1.0).astype(np.float64)
    world *= depth[..., None]
    return triangles_scene(world, single_sided=rng.random(n) < 0.3), pixel_exact_camera(near=0.5, far=40.0)


@pytest.mark.parametrize("tile_size", [8, 16, 32])
def test_dense_scene_matches_reference(make_renderer, tile_size):
    size = 64
    scene, cam = dense_scene(size=size)
    frame, ref = check(make_renderer, scene, cam, size, size, stats_keys=ALL_STATS, tile_size=tile_size)
    assert frame.stats["triangles_in"] == 20000
    assert np.all(frame.triangle_id >= 0), "a pixel lost all its fragments"


# --------------------------------------------------------------------------------------
# Bad inputs
# --------------------------------------------------------------------------------------
def test_non_finite_vertices(make_renderer):
    W, H = 64, 48
    cam = pixel_exact_camera()
    rng = np.random.default_rng(3)
    tris = rng.uniform(-1, 1, (60, 3, 3)) + np.array([0.0, 0.0, -3.0])
    for i, bad in zip(range(0, 60, 4), [np.nan, np.inf, -np.inf] * 5):
        tris[i, i % 3, (i // 3) % 3] = bad
    tris[1] = np.nan                                 # every coordinate NaN
    scene = triangles_scene(tris)
    frame, ref = check(make_renderer, scene, cam, W, H, stats_keys=ALL_STATS)
    assert frame.stats["invalid"] == 16
    all_bad = triangles_scene(np.full((5, 3, 3), np.nan))
    frame, _ = check(make_renderer, all_bad, cam, W, H, stats_keys=ALL_STATS)
    assert np.all(frame.triangle_id == -1) and frame.stats["invalid"] == 5


def test_empty_scene(make_renderer):
    W, H = 97, 61
    cam = pixel_exact_camera()
    for scene in (Scene.from_arrays(np.zeros((0, 3), np.float32), np.zeros((0, 3), np.int64)),
                  Scene.from_arrays(np.ones((4, 3), np.float32), np.zeros((0, 3), np.int64))):
        frame = render(make_renderer, scene, cam, W, H)
        assert np.all(frame.triangle_id == -1)
        assert np.all(np.isposinf(frame.depth))
        assert frame.stats["triangles_in"] == 0


def test_large_coordinates_within_guard_band(make_renderer):
    """Coordinates of 1e7 that still project near the screen: exact comparison. Also a camera
    1e7 away from the origin (catastrophic cancellation in M·p, but fully specified)."""
    W, H = 64, 48
    cam = Camera.look_at((0, 0, 0), (0, 0, -1), (0, 1, 0), 60.0, near=1.0, far=1e8)
    tris = [[(-1e7, -1e7, -1e7), (1e7, -1e7, -1.2e7), (0.0, 1e7, -2e7)],
            [(-3e6, -1e6, -5e6), (4e6, 2e6, -5e6), (0.0, 3e6, -9e6)]]
    check(make_renderer, triangles_scene(tris), cam, W, H, stats_keys=ALL_STATS)

    eye = np.array([1e7, -3e6, 2e7])
    cam = Camera.look_at(eye, eye + np.array([0.0, 0.0, -1.0]), (0, 1, 0), 70.0, near=0.5, far=500.0)
    rng = np.random.default_rng(9)
    local = rng.uniform(-20, 20, (150, 3, 3)) + np.array([0.0, 0.0, -40.0])
    check(make_renderer, triangles_scene(eye + local), cam, W, H)


def test_large_coordinates_guard_band(make_renderer):
    """A floor with 1e7 coordinates under a camera 1 unit above it: its snapped vertices
    would be far outside any fixed-point range, so the kernel must guard-band clip. Checked
    against the analytic floor (the reference does not model the guard band)."""
    W, H = 64, 48
    cam = Camera.look_at((0, 0, 0), (0, 0, -1), (0, 1, 0), 90.0, near=0.1, far=1e8)
    floor = [(-1e7, -1.0, 1e7), (1e7, -1.0, 1e7), (0.0, -1.0, -1e7)]
    scene = triangles_scene([floor])
    with pytest.raises(ReferenceScopeError):
        rasterize(scene, cam, W, H)
    frame = render(make_renderer, scene, cam, W, H)
    ids = frame.triangle_id
    assert np.all(ids[: H // 2] == -1), "nothing above the horizon"
    assert np.all(ids[H // 2:] == 0), "the floor covers every pixel below the horizon"
    ny = 1.0 - (np.arange(H // 2, H) + 0.5) / H * 2
    expected = np.broadcast_to((-1.0 / ny)[:, None], (H - H // 2, W))        # t = 1 (fov 90)
    np.testing.assert_allclose(frame.depth[H // 2:], expected, rtol=0.05)

    # Entirely off screen at 1e7 pixels to the right: clipped away without a crash.
    off = [(1e7, -1.0, -1.0), (1e7 + 1.0, -1.0, -1.0), (1e7, 1.0, -1.0)]
    frame = render(make_renderer, triangles_scene([off]), cam, W, H)
    assert np.all(frame.triangle_id == -1)


def test_extreme_coordinates_do_not_crash(make_renderer):
    """Finite float32 coordinates near the float32 limit (clip coordinates may overflow):
    the contract does not define the image, only that rendering completes with valid ids."""
    W, H = 64, 48
    cam = pixel_exact_camera(near=0.1, far=100.0)
    big = 3e38
    tris = [[(-big, -1.0, -2.0), (big, -1.0, -2.0), (0.0, big, -2.0)],
            [(-0.5, -0.5, -2.0), (0.5, -0.5, -2.0), (0.0, 0.5, -2.0)],
            [(0.0, 0.0, -big), (1.0, 0.0, -big), (0.0, 1.0, big)]]
    frame = render(make_renderer, triangles_scene(tris), cam, W, H)
    assert set(np.unique(frame.triangle_id).tolist()) <= {-1, 0, 1, 2}
    assert frame.stats["triangles_in"] == 3


# --------------------------------------------------------------------------------------
# Determinism
# --------------------------------------------------------------------------------------
def test_determinism(make_renderer, device):
    import clrender
    W, H = 97, 61
    scene, cam = make_soup((W, H), 200, 1234, "perspective", 0.3)
    dense, dcam = dense_scene(n=6000, size=64)
    for sc, c, (w, h) in ((scene, cam, (W, H)), (dense, dcam, (64, 64))):
        r = make_renderer(w, h)
        f1 = r.render(sc, camera=c)
        f2 = r.render(sc, camera=c)
        f3 = clrender.Renderer(width=w, height=h, device=device.id).render(sc, camera=c)
        for f in (f2, f3):
            assert np.array_equal(f.triangle_id, f1.triangle_id)
            assert np.array_equal(f.depth.view(np.uint32), f1.depth.view(np.uint32))


def opaque_copy(scene):
    """The scene with MASK/BLEND materials made opaque: the reference does not model alpha."""
    import dataclasses
    from clrender import Scene as _Scene
    mats = [dataclasses.replace(m, alpha_mode="OPAQUE") for m in scene.materials]
    return _Scene(scene.positions, scene.normals, scene.uvs, scene.triangles, scene.triangle_material,
                  materials=mats, textures=scene.textures, mesh_names=scene.mesh_names,
                  triangle_mesh=scene.triangle_mesh, triangle_face=scene.triangle_face, camera=scene.camera)


@pytest.mark.parametrize("size", [(160, 90), (317, 203)])
def test_bundled_demo_scene_matches_reference(make_renderer, size):
    """The bundled demo (glTF + OBJ via TOML: textures, single-sided torus, node transforms)."""
    from pathlib import Path
    import clrender
    scene = opaque_copy(clrender.load_scene(Path(__file__).resolve().parents[1] / "scenes" / "demo.toml"))
    assert any(not m.double_sided for m in scene.materials), "the demo must exercise back-face culling"
    frame, _ = check(make_renderer, scene, scene.camera, *size, stats_keys=("invalid", "triangles_in"))
    assert frame.stats["culled_backface"] > 0
    assert (frame.triangle_id >= 0).mean() > 0.3
