"""The per-chunk bounding-box cull (kernels/chunk_cull.cl, clrender/passes/chunk_cull.py).

The boxes and each view's verdicts are checked against a NumPy reference (float64 corners of
the boxes against the clip planes setup.cl rejects on); setup with the cull must give the same
prims, in the same order, and the same per-triangle statuses as without; shadow maps and the
G-buffer must be bit-identical with RenderConfig.chunk_cull on and off.
"""
from __future__ import annotations

import numpy as np
import pytest

import clrender
from clrender import Camera, Scene
from clrender.passes import Resources
from clrender.passes.chunk_cull import CHUNK, chunk_bounds, n_chunks
from clrender.passes.setup import SetupPass

GUARD_PIXELS = 262144.0
TOLERANCE = 1e-5           # chunk_cull.cl CULL_TOLERANCE
CULLED_NEAR, OFFSCREEN, STRADDLES = 2, 5, 7
CUBE = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], np.float32)
CUBE_FACES = np.concatenate([[[q[0], q[1], q[2]], [q[0], q[2], q[3]]] for q in
                             ([0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4], [1, 5, 7, 3])])


def assert_no_device_diagnostics(capfd):
    """Oclgrind prints each finding to stderr (`Kernel:` lines); any such text fails (as in
    tests/test_oclgrind_tier.py)."""
    err = capfd.readouterr().err
    flagged = [line for line in err.splitlines()
               if "Kernel:" in line or "oclgrind" in line.lower() or "error" in line.lower()]
    assert not flagged, "the OpenCL implementation reported problems:\n" + err[:4000]


def cl_device(info):
    from clrender.device.core import Device
    return Device.get(info.id)


# ---- NumPy reference ------------------------------------------------------------------------

def reference_bounds(positions, triangles):
    """(C, 2, 3) float32 lo/hi per chunk; ±inf for a chunk with a non-finite vertex."""
    out = []
    for c in range(n_chunks(len(triangles))):
        v = positions[triangles[c * CHUNK:(c + 1) * CHUNK].reshape(-1)]
        if not np.isfinite(v).all():
            out.append([[-np.inf] * 3, [np.inf] * 3])
        else:
            out.append([v.min(0), v.max(0)])
    return np.asarray(out, np.float32).reshape(-1, 2, 3)


def reference_verdicts(bounds, m, width, height, near, ortho):
    """Each chunk's verdict: its 8 corners in float64 against setup.cl's reject planes, each
    with the kernel's margin (CULL_TOLERANCE × the sum of the terms' magnitudes)."""
    m = np.asarray(m, np.float64).reshape(4, 4)
    gx, gy = np.float32(GUARD_PIXELS * 2) / np.float32(width), np.float32(GUARD_PIXELS * 2) / np.float32(height)
    depth = m[2] if ortho else m[3]
    planes = [(depth - [0, 0, 0, near], np.abs(depth) + [0, 0, 0, abs(near)])]
    for g in (1.0, None):
        for row, gg in ((0, gx), (1, gy)):
            k = 1.0 if g else float(gg)
            for sign in (-1.0, 1.0):
                planes.append((k * m[3] + sign * m[row], k * np.abs(m[3]) + np.abs(m[row])))
    out = []
    for lo, hi in bounds.astype(np.float64):
        if not np.isfinite(lo).all():
            out.append(0)
            continue
        corners = np.array([[x, y, z, 1.0] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
        mag = np.concatenate([np.maximum(np.abs(lo), np.abs(hi)), [1.0]])

        def outside(a, s):
            return (corners @ a).max() < -TOLERANCE * (s @ mag)
        a0, s0 = planes[0]
        if outside(a0, s0):
            out.append(CULLED_NEAR)
        elif any(outside(a, s) for a, s in planes[1:]):
            out.append(OFFSCREEN if outside(-a0, s0) else STRADDLES)
        else:
            out.append(0)
    return np.array(out)


# ---- scenes and views -----------------------------------------------------------------------

def cluster_scene(centers, sizes=None, last=None, seed=0):
    """One chunk per center: CHUNK triangles of small random boxes around it (the last chunk
    `last` triangles when given: a partial chunk)."""
    rng = np.random.default_rng(seed)
    verts, faces, base = [], [], 0
    for k, c in enumerate(centers):
        r = 0.5 if sizes is None else sizes[k]
        tris = CHUNK if (last is None or k < len(centers) - 1) else last
        boxes = -(-tris // 12)
        for _ in range(boxes):
            s = rng.uniform(0.05, 0.3, 3).astype(np.float32) * r
            p = np.asarray(c, np.float32) + rng.uniform(-r, r, 3).astype(np.float32)
            verts.append(CUBE * s + p)
            faces.append(CUBE_FACES + base)
            base += 8
        faces[-1] = faces[-1][: tris - 12 * (boxes - 1)]
    return np.concatenate(verts).astype(np.float32), np.concatenate(faces).astype(np.int32)


def ortho_matrix(direction, center, extent, depth0):
    """A sun-cascade style matrix (clrender/passes/shadow_views.py): clip.w = 1, clip.z = linear depth."""
    from clrender.passes.shadow_views import _basis
    s, u, f = _basis(direction)
    m = np.zeros((4, 4))
    m[0, :3], m[0, 3] = s * 2 / extent, -(s @ center) * 2 / extent
    m[1, :3], m[1, 3] = u * 2 / extent, -(u @ center) * 2 / extent
    m[2, :3], m[2, 3] = f, -(f @ center) + depth0
    m[3, 3] = 1.0
    return m.astype(np.float32)


def run_setup(device, positions, triangles, matrix, width, height, near, ortho, chunk_cull, select="all"):
    """SetupPass alone on uploaded arrays: (prims, prim total, statuses, chunk verdicts or None)."""
    import pyopencl.array as cla
    from clrender.abi import structs
    q = device.queue
    n = len(triangles)
    mats = np.zeros(1, structs.material_dtype)
    mats["flags"] = 1                      # double-sided: back faces are prims too
    res = Resources(buffers=dict(positions=cla.to_device(q, positions.reshape(-1)),
                                 triangles=cla.to_device(q, triangles.reshape(-1)),
                                 tri_material=cla.to_device(q, np.zeros(n, np.int32)),
                                 materials=cla.to_device(q, mats),
                                 view_proj=cla.to_device(q, np.asarray(matrix, np.float32).reshape(-1))),
                    values=dict(n_tris=n, near=near, width=width, height=height))
    from dataclasses import replace
    config = replace(clrender.RenderConfig(), chunk_cull=chunk_cull)
    setup = SetupPass(device, config, ortho=ortho, select=select)
    setup.allocate(width, height)
    setup.prepare_scene(res)
    setup.publish(res)
    setup.run(res)
    total = int(setup.prim_total.get(queue=q)[0])
    assert total <= setup.capacity
    prims = setup.prims.get(queue=q)[:total]
    status = setup.status.get(queue=q)[:n]
    verdict = setup.cull.chunk_status.get(queue=q)[: n_chunks(n)] if setup.cull else None
    return prims, status, verdict, setup


# ---- tests ----------------------------------------------------------------------------------

@pytest.mark.oclgrind
def test_chunk_bounds_match_numpy(device, capfd):
    dev = cl_device(device)
    rng = np.random.default_rng(3)
    n = 5 * CHUNK + 37                                      # a partial last chunk
    positions = rng.normal(0, 10, (900, 3)).astype(np.float32)
    triangles = rng.integers(0, len(positions), (n, 3)).astype(np.int32)
    positions[17] = (np.nan, 0, 0)                          # every chunk using vertex 17: never culled
    positions[18] = (0, np.inf, 0)
    import pyopencl.array as cla
    pos_buf, tri_buf = cla.to_device(dev.queue, positions.reshape(-1)), cla.to_device(dev.queue, triangles.reshape(-1))
    got = chunk_bounds(dev, pos_buf, tri_buf, n).get(queue=dev.queue).reshape(-1, 8)
    ref = reference_bounds(positions, triangles)
    assert got.shape[0] == n_chunks(n) == 6
    np.testing.assert_array_equal(got[:, 0:3], ref[:, 0])
    np.testing.assert_array_equal(got[:, 4:7], ref[:, 1])
    # kept: the same buffers give the same boxes without a launch; new buffers recompute
    assert chunk_bounds(dev, pos_buf, tri_buf, n) is chunk_bounds(dev, pos_buf, tri_buf, n)
    finite = positions.copy()
    finite[17:19] = 1.0
    pos2 = cla.to_device(dev.queue, finite.reshape(-1))
    got2 = chunk_bounds(dev, pos2, tri_buf, n).get(queue=dev.queue).reshape(-1, 8)
    np.testing.assert_array_equal(got2[:, 0:3], reference_bounds(finite, triangles)[:, 0])
    assert np.isfinite(got2).all()
    assert_no_device_diagnostics(capfd)


def _named_views():
    """Perspective views with a chunk behind the camera, one straddling the near plane beside
    the view, one off-screen in front, visible ones, and the partial last chunk visible."""
    cam = Camera.look_at((0.0, 0.0, 0.0), (0.0, 0.0, -1.0), fov_y_deg=60, near=0.5, far=100)
    centers = [(0, 0, 6),            # behind the camera: culled_near
               (8, 0, -0.5),         # beside the eye, crossing the near plane (depth 0 to 1.1): straddles
               (30, 0, -10),         # in front, right of the view: offscreen
               (0, 0, -10), (2, 1, -20),   # visible
               (-1, 0, -8)]          # partial last chunk, visible
    return cam, centers


@pytest.mark.oclgrind
def test_verdicts_of_named_chunks(device, capfd):
    dev = cl_device(device)
    cam, centers = _named_views()
    positions, triangles = cluster_scene(centers, last=100)
    w, h = 64, 48
    m = cam.raster_matrix(w, h)
    prims, status, verdict, _ = run_setup(dev, positions, triangles, m, w, h, cam.near, False, True)
    assert list(verdict) == [CULLED_NEAR, STRADDLES, OFFSCREEN, 0, 0, 0]
    ref = reference_verdicts(reference_bounds(positions, triangles), m, w, h, cam.near, False)
    assert list(ref) == list(verdict)
    # setup's own statuses of those triangles: the verdict, or per triangle where it straddles
    assert (status[:CHUNK] == CULLED_NEAR).all() and (status[2 * CHUNK:3 * CHUNK] == OFFSCREEN).all()
    assert set(status[CHUNK:2 * CHUNK]) <= {CULLED_NEAR, OFFSCREEN} and len(set(status[CHUNK:2 * CHUNK])) == 2
    prims0, status0, _, _ = run_setup(dev, positions, triangles, m, w, h, cam.near, False, False)
    np.testing.assert_array_equal(status, status0)
    assert prims.tobytes() == prims0.tobytes() and len(prims) > 0
    assert prims["tri"].min() >= 3 * CHUNK
    assert_no_device_diagnostics(capfd)


def _random_views(rng, bounds_lo, bounds_hi, count):
    views = []
    for k in range(count):
        eye = rng.uniform(bounds_lo, bounds_hi, 3)
        target = eye + rng.normal(0, 1, 3)
        if k % 3 == 2:                                  # orthographic, sun-cascade style
            extent = float(rng.uniform(5, 40))
            views.append((ortho_matrix(target - eye, eye, extent, 30.0), 0.05, True))
        else:
            cam = Camera.look_at(tuple(eye), tuple(target), fov_y_deg=float(rng.uniform(20, 90)),
                                 near=float(rng.uniform(0.01, 2.0)), far=200)
            views.append((cam.raster_matrix(96, 64), cam.near, False))
    return views


def test_random_views_match_reference_and_setup(device):
    """Random perspective and orthographic views over a scene of scattered clusters: verdicts
    equal the NumPy reference; prims (bytes, order) and statuses equal setup without the cull."""
    dev = cl_device(device)
    rng = np.random.default_rng(7)
    centers = rng.uniform(-20, 20, (40, 3))
    sizes = rng.uniform(0.3, 4.0, 40)
    positions, triangles = cluster_scene(centers, sizes, last=200, seed=1)
    ref_bounds = reference_bounds(positions, triangles)
    culled = 0
    kinds = set()
    for m, near, ortho in _random_views(rng, -15, 15, 9):
        prims, status, verdict, _ = run_setup(dev, positions, triangles, m, 96, 64, near, ortho, True)
        ref = reference_verdicts(ref_bounds, m, 96, 64, near, ortho)
        np.testing.assert_array_equal(verdict, ref)
        prims0, status0, _, _ = run_setup(dev, positions, triangles, m, 96, 64, near, ortho, False)
        np.testing.assert_array_equal(status, status0)
        assert prims.tobytes() == prims0.tobytes()
        culled += int((verdict != 0).sum())
        kinds |= set(verdict.tolist())
    assert culled > 40 and {0, CULLED_NEAR, OFFSCREEN} <= kinds        # the test exercised the cull


def test_transparent_select_statuses(device):
    """select="opaque": a culled chunk's BLEND triangles are STATUS_TRANSPARENT, as setup says."""
    dev = cl_device(device)
    cam, centers = _named_views()
    positions, triangles = cluster_scene(centers, last=100)
    scene = Scene.from_arrays(positions, triangles)
    glass = clrender.Material(base_color=(1, 1, 1, 0.5), alpha_mode="BLEND")
    scene.materials.append(glass)
    scene.triangle_material[::3] = len(scene.materials) - 1
    from clrender.render import scene_upload as scene_gpu
    from dataclasses import replace
    res = scene_gpu.upload(scene, dev)
    w, h = 64, 48
    out = {}
    for cc in (False, True):
        import pyopencl.array as cla
        r = Resources(buffers={**res.buffers, "view_proj": cla.to_device(dev.queue, cam.raster_matrix(w, h)
                                                                        .astype(np.float32).reshape(-1))},
                      values={**res.values, "near": cam.near, "width": w, "height": h})
        setup = SetupPass(dev, replace(clrender.RenderConfig(), chunk_cull=cc), select="opaque")
        setup.allocate(w, h)
        setup.prepare_scene(r)
        setup.run(r)
        out[cc] = (setup.status.get(queue=dev.queue)[: len(triangles)],
                   setup.prims.get(queue=dev.queue)[: int(setup.prim_total.get(queue=dev.queue)[0])].tobytes(),
                   setup.triangle_stats())
    np.testing.assert_array_equal(out[True][0], out[False][0])
    assert out[True][1] == out[False][1]
    assert (out[True][0] == 6).sum() > 0 and out[True][2]["culled_chunks"] == 3
    assert {k: v for k, v in out[True][2].items() if k != "culled_chunks"} == \
        {k: v for k, v in out[False][2].items() if k != "culled_chunks"}


def field_scene(n=24, spots=4, seed=0, spot_size=128, sun_size=256):
    """A floor and n×n small boxes (about 11 boxes per chunk, a row of them), shadowed spots and sun."""
    rng = np.random.default_rng(seed)
    verts = [np.array([[-30, 0, -30], [30, 0, -30], [30, 0, 30], [-30, 0, 30]], np.float32)]
    faces, base = [np.array([[0, 2, 1], [0, 3, 2]])], 4
    for i in range(n):
        for j in range(n):
            s = rng.uniform(0.3, 0.9, 3).astype(np.float32)
            verts.append(CUBE * s + np.array([i * 1.5 - n * 0.75, 0, j * 1.5 - n * 0.75], np.float32))
            faces.append(CUBE_FACES + base)
            base += 8
    scene = Scene.from_arrays(np.concatenate(verts), np.concatenate(faces))
    for _ in range(spots):
        a = rng.uniform(-15, 15, 2)
        scene.add_spot_light((a[0], 5.0, a[1]), (0.2, -1.0, 0.1), (20, 20, 20), 12.0, 25.0, 35.0,
                             shadow=True, shadow_map_size=spot_size)
    scene.set_sun((0.4, -1.0, 0.3), (3, 3, 3), shadow=True, shadow_map_size=sun_size)
    return scene


def maps_and_gbuffer(renderer, scene, camera):
    frame = renderer.render(scene, camera)
    shadow = renderer.pipeline.shadow
    lay = shadow.layout
    atlas = shadow.atlas.get()[: lay.atlas_width * lay.atlas_height].reshape(lay.atlas_height, lay.atlas_width)
    maps = [atlas[v.y0:v.y0 + v.size, v.x0:v.x0 + v.size].copy() for v in lay.views]
    return maps, np.array(frame.gbuffer), frame.stats


def _compare_on_off(make_renderer, scene, camera, w, h):
    on = maps_and_gbuffer(make_renderer(w, h, chunk_cull=True, shadow_map_reuse=False), scene, camera)
    off = maps_and_gbuffer(make_renderer(w, h, chunk_cull=False, shadow_map_reuse=False), scene, camera)
    assert len(on[0]) == len(off[0]) > 1
    for a, b in zip(on[0], off[0]):
        assert np.array_equal(a, b) and np.isfinite(a).any()
    assert np.array_equal(on[1], off[1])
    same = ("triangles_in", "invalid", "culled_near", "degenerate", "culled_backface", "culled_offscreen",
            "transparent", "clipped", "prims", "chunks")
    assert {k: on[2][k] for k in same} == {k: off[2][k] for k in same}
    assert off[2]["culled_chunks"] == 0
    return on, off


def test_maps_and_gbuffer_bit_identical_procedural(make_renderer):
    scene = field_scene()
    camera = Camera.look_at((-5.0, 3.0, -4.0), (10.0, 0.0, 8.0), fov_y_deg=60, near=0.1, far=80)
    on, _ = _compare_on_off(make_renderer, scene, camera, 160, 120)
    assert n_chunks(scene.triangle_count) > 20 and on[2]["culled_chunks"] > 5


def test_moved_geometry_recomputes_the_boxes(make_renderer):
    """An animation frame replaces the positions buffer: the boxes follow (stale ones would cull
    chunks that moved into view and break the bit-identity)."""
    scene = field_scene(n=16, spots=2)
    camera = Camera.look_at((0.0, 2.0, 0.0), (6.0, 0.5, 1.0), fov_y_deg=60, near=0.1, far=60)
    first, _ = _compare_on_off(make_renderer, scene, camera, 120, 90)
    move = np.eye(4)
    move[:3, 3] = (-9.0, 0.0, 3.0)
    scene.set_transform(0, move)
    second, _ = _compare_on_off(make_renderer, scene, camera, 120, 90)
    assert second[2]["culled_chunks"] != first[2]["culled_chunks"]


@pytest.mark.oclgrind
def test_small_frame_bit_identical(make_renderer, capfd):
    """The Oclgrind tier: a few chunks, a tiny frame and small maps."""
    scene = field_scene(n=8, spots=1, spot_size=32, sun_size=32)
    camera = Camera.look_at((0.0, 1.5, 0.0), (5.0, 0.5, 0.5), fov_y_deg=60, near=0.1, far=40)   # rows behind: culled
    with_cull, _ = _compare_on_off(make_renderer, scene, camera, 24, 16)
    assert with_cull[2]["chunks"] == n_chunks(scene.triangle_count) > 4
    assert with_cull[2]["culled_chunks"] > 0
    assert_no_device_diagnostics(capfd)


def test_sponza_bit_identical(make_renderer):
    from bench.common import SPONZA, SPONZA_CAMERA
    if not SPONZA.is_file():
        pytest.skip(f"Sponza is not in the shared scenes ({SPONZA}): the procedural scene above stands in")
    import argparse
    from bench.shadows import add_lights
    scene = clrender.load_scene(SPONZA)
    add_lights(scene, argparse.Namespace(sun_size=256, spot_size=128, spots=4, lights=0, intensity=0.1))
    on, _ = _compare_on_off(make_renderer, scene, Camera.look_at(**SPONZA_CAMERA), 160, 90)
    assert on[2]["culled_chunks"] > 0
