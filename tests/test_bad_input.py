"""Bad and extreme input: each case is a one-line error naming the problem (SceneError naming the
file for file input) or a documented safe result checked against an independent expectation
(files, materials and option names: test_bad_input_files.py).

Covered elsewhere (not repeated here):
  NaN/Inf/1e31 vertices ..... test_geometry_validity.py (SceneError naming the accessor / vertex); the
                              kernels' own guard: test_raster.py::test_non_finite_vertices
  1e7 coordinates ........... test_raster.py::test_large_coordinates_within_guard_band / _guard_band
  empty scene ............... test_raster.py::test_empty_scene (all background, +inf depth)
  near-plane crossing ....... test_raster.py::test_near_plane_clipping, test_near_clipped_grid
  zero lights ............... test_lighting.py::test_no_lights_is_ambient_times_albedo
  missing texture / MTL ..... test_loaders_mesh.py::test_obj_missing_texture_and_mtl,
                              test_loaders_gltf.py::test_gltf_texture_sharing...
  malformed glTF / TOML ..... test_loaders_gltf.py::test_bad_gltf_*, test_loaders_toml.py::test_toml_errors
                              (incl. unknown keys)
  OBJ/PLY/glTF bad indices .. test_loaders_mesh.py::test_obj_index_out_of_range,
                              test_loaders_gltf.py::test_bad_gltf_index_out_of_range
  bad option values ......... test_lighting.py::test_unknown_options_are_rejected, test_cli.py
"""
from __future__ import annotations

import gc

import numpy as np
import pytest

import clrender
from clrender import Camera, Scene, SceneError
from clrender.render import memory
from clrender.abi import structs
from helpers import SHADING_TOL
from reference import shading as ref_shading
from reference.raster import pixel_exact_camera, rasterize, screen_to_world, triangles_scene

DEPTH_RTOL = 1e-6
STATS = ("invalid", "culled_near", "degenerate", "culled_backface", "triangles_in")


def assert_matches_reference(frame, scene, camera, width, height, stats=STATS):
    """triangle_id exact, depth within DEPTH_RTOL, the given stats equal, against tests/reference/raster.py."""
    ids, depth, ref_stats = rasterize(scene, camera, width, height)
    diff = np.argwhere(frame.triangle_id != ids)
    assert not len(diff), (f"triangle_id differs on {len(diff)} pixels, e.g. (row, col) {diff[0].tolist()}: "
                           f"{frame.triangle_id[tuple(diff[0])]} vs reference {ids[tuple(diff[0])]}")
    fg = ids >= 0
    assert np.all(np.isposinf(frame.depth[~fg]))
    np.testing.assert_allclose(frame.depth[fg], depth[fg], rtol=DEPTH_RTOL, atol=0)
    for key in stats:
        assert frame.stats[key] == ref_stats[key], (key, frame.stats[key], ref_stats[key])
    return ids, ref_stats


def ndc_tri(points, depth):
    return [(x * depth, y * depth, -depth) for x, y in points]


# ------------------------------------------------------------------------------------------------
# Geometry
# ------------------------------------------------------------------------------------------------
def test_degenerate_and_zero_area_triangles(make_renderer):
    """Repeated vertices, collinear vertices, a point, and a triangle whose snapped area is 0:
    dropped and counted as `degenerate`; the good triangles around them render exactly."""
    size = 32
    cam = pixel_exact_camera()
    good = ndc_tri([(-0.9, -0.9), (0.9, -0.9), (0.0, 0.9)], 2.0)
    p = (0.1, 0.2, -1.0)
    tris = [good,
            [p, p, (0.5, 0.5, -1.0)],                                   # repeated vertex
            [(-0.5, -0.5, -1.0), (0.0, 0.0, -1.0), (0.5, 0.5, -1.0)],   # collinear
            [p, p, p],                                                  # a point
            [(0.0, 0.0, -1.0), (1e-5, 0.0, -1.0), (0.0, 1e-5, -1.0)],   # snaps to zero area
            ndc_tri([(-0.2, -0.2), (0.2, -0.2), (0.0, 0.2)], 1.5)]      # a good one in front
    scene = triangles_scene(tris)
    frame = make_renderer(size, size).render(scene, camera=cam)
    ids, stats = assert_matches_reference(frame, scene, cam, size, size)
    assert stats["degenerate"] == 4 and frame.stats["degenerate"] == 4
    assert set(np.unique(frame.triangle_id).tolist()) == {-1, 0, 5}
    assert np.isfinite(frame.color).all() and np.isfinite(frame.normal).all()


def test_only_degenerate_triangles_render_background(make_renderer):
    tris = np.zeros((50, 3, 3), np.float32)
    tris[:, :, 2] = -2.0
    tris[:, 1, 0] = np.linspace(0.0, 1.0, 50)             # two equal vertices, or all three
    frame = make_renderer(16, 16).render(triangles_scene(tris), camera=pixel_exact_camera())
    assert np.all(frame.triangle_id == -1) and np.all(np.isposinf(frame.depth))
    assert frame.stats["degenerate"] == 50 and np.all(frame.color == 0)


def test_index_out_of_range_is_an_error(device):
    v = np.array([[0, 0, -1], [1, 0, -1], [0, 1, -1]], np.float32)
    for faces, word in (([[0, 1, 3]], "[0, 1, 3]"), ([[0, -1, 2]], "[0, -1, 2]")):
        with pytest.raises(SceneError, match="out of range") as info:
            Scene.from_arrays(v, faces)
        assert word in str(info.value)
    with pytest.raises(SceneError, match="out of range"):
        Scene(v, v, np.zeros((3, 2)), [[0, 1, 5]], [0])
    # Arrays replaced after construction are validated before they reach the device.
    r = clrender.Renderer(16, 16, device=device.id)
    scene = Scene.from_arrays(v, [[0, 1, 2]])
    cam = pixel_exact_camera()
    assert (r.render(scene, cam).triangle_id == 0).any()
    scene.triangles = np.array([[0, 1, 7]], np.int32)
    with pytest.raises(SceneError, match="out of range"):
        r.render(scene, cam)
    scene.triangles = np.array([0, 1, 2, 0, 2, 1], np.int32)      # flat: would be read as 6 triangles
    with pytest.raises(SceneError, match=r"triangles must have shape \(N, 3\)"):
        r.render(scene, cam)
    scene.triangles = np.array([[0, 1, 2]], np.int32)
    scene.triangle_material = np.array([3], np.int32)
    with pytest.raises(SceneError, match="material"):
        r.render(scene, cam)


def test_triangles_behind_the_camera_and_across_the_near_plane(make_renderer):
    """Entirely behind the eye (both windings, large and small), between the eye and the near
    plane, and crossing the near plane: culled and counted `culled_near`, or clipped; exact ids."""
    size = 48
    cam = pixel_exact_camera(near=0.5, far=50.0)
    tris = [ndc_tri([(-0.5, -0.5), (0.5, -0.5), (0.0, 0.5)], -2.0),          # behind: w = -2
            ndc_tri([(-0.5, -0.5), (0.0, 0.5), (0.5, -0.5)], -2.0),          # behind, other winding
            [(-100.0, -100.0, 5.0), (100.0, -100.0, 5.0), (0.0, 100.0, 5.0)],  # huge, behind
            ndc_tri([(-0.5, -0.5), (0.5, -0.5), (0.0, 0.5)], 0.25),          # before the near plane
            [(-1.0, -1.0, 1.0), (1.0, -1.0, 1.0), (0.0, 0.5, -4.0)],         # crosses the near plane
            ndc_tri([(-0.9, 0.2), (-0.2, 0.2), (-0.5, 0.9)], 3.0)]
    scene = triangles_scene(tris)
    frame = make_renderer(size, size).render(scene, camera=cam)
    ids, stats = assert_matches_reference(frame, scene, cam, size, size)
    assert stats["culled_near"] == 4
    assert set(np.unique(frame.triangle_id).tolist()) == {-1, 4, 5}


def test_empty_meshes_in_a_scene_file(tmp_path, make_renderer):
    """A TOML scene combining an empty OBJ (and an OBJ with vertices but no faces) with a triangle:
    the empty meshes add no triangles, the triangle keeps id 0 and renders."""
    (tmp_path / "empty.obj").write_text("# no geometry\n")
    (tmp_path / "points.obj").write_text("v 0 0 0\nv 1 0 0\n")
    (tmp_path / "tri.obj").write_text("v -2 -2 -3\nv 2 -2 -3\nv 0 2 -3\nf 1 2 3\n")
    (tmp_path / "s.toml").write_text('[[mesh]]\npath = "empty.obj"\n[[mesh]]\npath = "points.obj"\n'
                                     '[[mesh]]\npath = "tri.obj"\n')
    scene = clrender.load_scene(tmp_path / "s.toml")
    assert scene.triangle_count == 1
    cam = pixel_exact_camera()
    frame = make_renderer(32, 32).render(scene, camera=cam)
    assert_matches_reference(frame, scene, cam, 32, 32)
    assert (frame.triangle_id == 0).sum() > 150
    assert scene.triangle_source(0)[0].startswith("tri")


@pytest.mark.parametrize("culling", ["tiled", "brute_force"])
def test_no_triangles_with_lights_is_black(make_renderer, culling):
    scene = Scene.from_arrays(np.zeros((0, 3), np.float32), np.zeros((0, 3), np.int64))
    scene.add_point_light((0, 0, -2), (5, 5, 5), 3.0)
    scene.add_random_lights(100, seed=1)
    frame = make_renderer(40, 24, light_culling=culling).render(scene, camera=pixel_exact_camera())
    assert np.all(frame.triangle_id == -1) and np.all(frame.color == 0) and np.all(frame.image == 0)
    assert frame.stats["triangles_in"] == 0 and frame.stats["lights"] == 101


# ------------------------------------------------------------------------------------------------
# Resolutions
# ------------------------------------------------------------------------------------------------
def small_scene(seed=0, n=40, aspect=1.0):
    """Random triangles in front of a 90° camera looking down -z (image aspect `aspect`), some
    crossing the frame edges, lit."""
    rng = np.random.default_rng(seed)
    centers = rng.uniform(-1.1, 1.1, (n, 1, 2))
    xy = (centers + rng.uniform(-0.4, 0.4, (n, 3, 2))) * (aspect, 1.0)
    depth = rng.uniform(1.5, 6.0, (n, 1, 1))
    tris = np.concatenate([xy * depth, -depth * np.ones((n, 3, 1))], axis=-1)
    scene = triangles_scene(tris)
    scene.add_point_light((0.2, 0.3, -1.0), (2.0, 1.8, 1.5), 6.0)
    scene.add_spot_light((-0.5, 0.5, 0.0), (0.1, -0.1, -1.0), (1.5, 1.5, 2.0), 8.0, 10, 30)
    return scene


@pytest.mark.parametrize("size", [(1, 1), (1001, 17), (17, 203), (2, 3)], ids=lambda s: f"{s[0]}x{s[1]}")
def test_odd_resolutions_match_reference(make_renderer, size):
    w, h = size
    scene = small_scene(aspect=w / h)
    cam = Camera.look_at((0, 0, 0), (0, 0, -1), (0, 1, 0), 90.0, near=0.1, far=100.0)
    for tile in (8, 32):
        frame = make_renderer(w, h, tile_size=tile, light_tile_size=tile).render(scene, camera=cam)
        assert frame.image.shape == (h, w, 3) and frame.color.shape == (h, w, 3)
        assert_matches_reference(frame, scene, cam, w, h, stats=("invalid", "culled_near", "triangles_in"))
        expect = ref_shading.shade_frame(frame, cam, scene.lights, scene.ambient)
        np.testing.assert_allclose(frame.color, expect, rtol=0, atol=SHADING_TOL * max(float(expect.max()), 1e-3))
    if w * h > 100:
        assert (frame.triangle_id >= 0).mean() > 0.3


def test_bad_image_sizes_are_errors(device):
    for w, h in ((0, 5), (5, -1), (16385, 4), (2.5, 3)):      # the message names the parameter
        with pytest.raises(ValueError, match=r"^(width|height) must be an integer in \[1, 16384\], got "):
            clrender.Renderer(w, h, device=device.id)


def test_memory_check_names_bytes_needed_and_available(device, monkeypatch):
    """Before building or allocating anything, a frame that cannot fit is a one-line error stating
    the bytes needed and available (global memory, then CL_DEVICE_MAX_MEM_ALLOC_SIZE)."""
    config = clrender.RenderConfig()
    need = memory.estimate(8192, 8192, config)
    assert need["total"] > 48 * 8192 * 8192 and need["largest_name"] == "gbuffer"
    monkeypatch.setattr(memory, "limits", lambda dev: (need["total"] - 1, 2**40))
    with pytest.raises(memory.DeviceMemoryError) as info:
        clrender.Renderer(8192, 8192, device=device.id)
    msg = str(info.value)
    assert "\n" not in msg and "8192x8192" in msg
    assert str(need["total"]) in msg and str(need["total"] - 1) in msg, msg
    monkeypatch.setattr(memory, "limits", lambda dev: (2**40, need["largest"] - 1))
    with pytest.raises(memory.DeviceMemoryError, match="MAX_MEM_ALLOC_SIZE") as info:
        clrender.Renderer(8192, 8192, device=device.id)
    assert str(need["largest"]) in str(info.value) and str(need["largest"] - 1) in str(info.value)
    # The scene's upload counts too: checked at render time, naming the triangle count.
    monkeypatch.setattr(memory, "limits", lambda dev: (memory.estimate(64, 64, config)["total"] + 10**6, 2**40))
    r = clrender.Renderer(64, 64, device=device.id)
    big = triangles_scene(np.tile(np.asarray(ndc_tri([(-0.5, -0.5), (0.5, -0.5), (0, 0.5)], 2.0)), (20000, 1, 1)))
    with pytest.raises(memory.DeviceMemoryError, match="20000 triangles"):
        r.render(big, pixel_exact_camera())
    monkeypatch.undo()
    # 16384² (the largest size accepted) on the real device: an error unless it really fits.
    real, max_alloc = memory.limits(clrender.device.core.Device.get(device.id).cl_device)
    big_need = memory.estimate(16384, 16384, config)
    if big_need["total"] > real or big_need["largest"] > max_alloc:
        with pytest.raises(memory.DeviceMemoryError, match="bytes"):
            clrender.Renderer(16384, 16384, device=device.id)


def _mem_available() -> int:
    with open("/proc/meminfo") as f:
        for line in f:
            if line.startswith("MemAvailable:"):
                return int(line.split()[1]) * 1024
    return 0


@pytest.fixture(scope="module")
def first_device(request):
    """The first selected device: the 8192² frame runs once per session (~6 GiB of host memory on PoCL)."""
    from conftest import _selected_devices
    info, why = _selected_devices(request.config)[0]
    if info is None:
        pytest.skip(why)
    return info


def test_8192_square_frame(first_device):
    """8192×8192 on the first selected device (PoCL: device memory is host memory) with a small
    scene: exact coverage of a screen-aligned rectangle, exact depth, and analytic shading at a
    few pixels."""
    size = 8192
    need = memory.estimate(size, size, clrender.RenderConfig())
    total, max_alloc = memory.limits(clrender.device.core.Device.get(first_device.id).cl_device)
    if need["total"] > total or need["largest"] > max_alloc:      # e.g. Oclgrind's 128 MiB
        with pytest.raises(memory.DeviceMemoryError, match="bytes"):
            clrender.Renderer(size, size, device=first_device.id)
        return
    need = need["total"]
    if _mem_available() < 2.2 * need:
        pytest.skip(f"8192x8192 needs ~{2.2 * need / 2**30:.1f} GiB of free host memory "
                    f"(device buffers + host copies); {_mem_available() / 2**30:.1f} GiB available")
    r = clrender.Renderer(size, size, device=first_device.id)
    x0, x1, y0, y1 = 1000, 7000, 2000, 5000        # pixel edges: no pixel center on the border
    corners = screen_to_world([x0, x1, x1, x0], [y0, y0, y1, y1], size, depth=2.0).astype(np.float64)
    far_tri = screen_to_world([7500, 8100, 7800], [100, 100, 600], size, depth=4.0).astype(np.float64)
    scene = triangles_scene([corners[[0, 1, 2]], corners[[0, 2, 3]], far_tri])
    light = scene.add_point_light((0.0, 0.0, -1.0), (2.0, 1.5, 1.0), 3.0)
    cam = pixel_exact_camera()
    frame = r.render(scene, camera=cam)
    stats = dict(frame.stats)
    ids = frame.triangle_id
    rect = np.zeros((size, size), bool)
    rect[y0:y1, x0:x1] = True
    assert np.array_equal((ids == 0) | (ids == 1), rect), "the rectangle must be covered exactly"
    assert (ids == 2).sum() > 1000 and np.all(ids[~rect] != 0) and np.all(ids[~rect] != 1)
    assert np.all(frame.depth[rect] == np.float32(2.0))
    assert np.all(ids[:, :x0] == -1) and np.all(np.isposinf(frame.depth[:, :x0]))
    # Analytic shading: point on the plane z = -2, normal +z (facing the eye), white, s = 0.04, p = 32.
    lt = scene.lights[light]
    for row, col in [(y0, x0), (4096, 4096), (y1 - 1, x1 - 1), (3000, 5000)]:
        P = screen_to_world(col + 0.5, row + 0.5, size, 2.0).astype(np.float64)
        a_s, L, _ = ref_shading.light_factor(P[None], lt)
        N = np.array([0.0, 0.0, 1.0])
        V = -P / np.linalg.norm(P)
        H = (L[0] + V) / np.linalg.norm(L[0] + V)
        spec = 0.04 * max(N @ H, 0.0) ** 32 if N @ L[0] > 0 else 0.0
        expect = scene.ambient + a_s[0] * lt["color"] * (max(N @ L[0], 0.0) + spec)
        np.testing.assert_allclose(frame.color[row, col], expect, rtol=2e-3, err_msg=f"pixel {(row, col)}")
    assert frame.image[4096, 4096].min() > frame.image[y0, x0].min()        # the light is in the middle
    assert stats["device_bytes"] >= 48 * size * size
    del frame, r, ids, rect
    gc.collect()


# ------------------------------------------------------------------------------------------------
# Lights
# ------------------------------------------------------------------------------------------------
def test_100k_lights_equal_brute_force(make_renderer):
    """100 000 point lights over a small frame: tiled (32- and 8-pixel tiles) equals brute force
    within 1e-4 of the brightest value, and the lights visibly light the frame."""
    w, h = 64, 48
    rng = np.random.default_rng(5)
    n = 100_000
    scene = small_scene(seed=3, n=60)
    scene.lights = np.zeros(0, structs.light_dtype)
    lights = np.zeros(n, structs.light_dtype)
    lights["position"] = rng.uniform((-3, -3, -7), (3, 3, 0), (n, 3))
    lights["radius"] = rng.uniform(0.2, 1.2, n)
    lights["color"] = rng.uniform(0.002, 0.02, (n, 3))
    lights["type"] = structs.LIGHT_POINT
    lights["direction"] = (0, 0, -1)
    scene.lights = lights
    cam = Camera.look_at((0, 0, 0), (0, 0, -1), (0, 1, 0), 90.0, near=0.1, far=100.0)
    brute = make_renderer(w, h, light_culling="brute_force").render(scene, camera=cam)
    fg = brute.triangle_id >= 0
    assert fg.mean() > 0.3 and brute.stats["lights"] == n and np.all(brute.light_count == n)
    ambient = brute.albedo * np.float32(scene.ambient)
    assert (brute.color[fg] > 2 * ambient[fg]).all(-1).mean() > 0.75, "the lights must light the frame"
    peak = float(brute.color.max())
    for tile in (32, 8):
        tiled = make_renderer(w, h, light_tile_size=tile).render(scene, camera=cam)
        assert 0 < tiled.stats["lights_per_tile_max"] < n
        diff = np.abs(tiled.color.astype(np.float64) - brute.color).max()
        assert diff <= 1e-4 * peak, f"tile {tile}: max |tiled - brute| {diff:.3g} (peak {peak:.3g})"


def test_bad_lights_are_errors_at_add_time():
    scene = Scene.from_arrays([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]])
    for radius in (0.0, -1.0, np.nan, np.inf):
        with pytest.raises(SceneError, match="radius"):
            scene.add_point_light((0, 0, 1), (1, 1, 1), radius)
    for position in ((np.nan, 0, 0), (0, np.inf, 0)):
        with pytest.raises(SceneError, match="position"):
            scene.add_point_light(position, (1, 1, 1), 1.0)
    with pytest.raises(SceneError, match="color"):
        scene.add_point_light((0, 0, 1), (1, -1, 1), 1.0)
    with pytest.raises(SceneError, match="direction"):
        scene.add_spot_light((0, 0, 1), (0, 0, 0), (1, 1, 1), 2.0, 10, 20)
    with pytest.raises(SceneError, match="radius"):
        scene.add_random_lights(4, seed=0, radius=(0.0, 1.0))
    assert len(scene.lights) == 0


@pytest.mark.parametrize("field, value, word", [
    ("position", (np.nan, 0.0, -1.0), "position"), ("position", (0.0, np.inf, -1.0), "position"),
    ("radius", 0.0, "radius"), ("radius", -2.0, "radius"), ("radius", np.nan, "radius"),
    ("color", (1.0, np.nan, 1.0), "color"), ("color", (1.0, -1.0, 1.0), "color"),
    ("direction", (np.nan, 0.0, 0.0), "direction")])
def test_bad_light_arrays_are_errors_at_render(make_renderer, field, value, word):
    """Lights assigned as an array bypass add_*_light: they are checked before upload."""
    scene = small_scene()
    lights = scene.lights.copy()
    lights[1][field] = value
    scene.lights = lights
    with pytest.raises(SceneError, match=rf"light 1: {word}"):
        make_renderer(16, 16).render(scene, camera=pixel_exact_camera())
    scene.lights = lights[:1]                       # fixed: renders again
    assert np.isfinite(make_renderer(16, 16).render(scene, camera=pixel_exact_camera()).color).all()


# ------------------------------------------------------------------------------------------------
# One tile holding every triangle
# ------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("tile", [8, 16, 32])
def test_every_triangle_in_every_tile(make_renderer, tile):
    """N frame-covering triangles stacked at distinct depths (shuffled): every tile lists all N
    (the per-tile list grows and the frame is re-rendered), and the nearest one wins exactly."""
    size, n = 24, 6000
    rng = np.random.default_rng(tile)
    depths = rng.permutation(np.linspace(1.0, 40.0, n))     # distinct; the nearest (1.0) is somewhere inside
    cover = screen_to_world([-30, 90, -30], [-30, -30, 90], size, 1.0).astype(np.float64)
    tris = cover[None] * depths[:, None, None]
    scene = triangles_scene(tris)
    cam = pixel_exact_camera(near=0.5, far=50.0)
    frame = make_renderer(size, size, tile_size=tile).render(scene, camera=cam)
    tiles = (-(-size // tile)) ** 2
    assert frame.stats["tile_entries"] == tiles * n
    assert frame.stats["retries"] >= 1, "the per-tile list must have grown"
    assert np.all(frame.triangle_id == int(np.argmin(depths)))
    assert np.all(frame.depth == np.float32(1.0))
    assert frame.stats["prims"] == n and frame.stats["triangles_in"] == n


def test_fragment_buffer_that_cannot_fit_is_refused(device, monkeypatch):
    """A-buffer growth past the device's memory: DeviceMemoryError stating bytes needed and available,
    raised before the larger buffer is allocated (the limits are lowered to make it happen)."""
    import clrender
    from clrender.render import memory
    n = 40                                          # 40 full-frame layers: 40 fragments per pixel
    quads = [np.array([[-9, -9, -2 - k], [9, -9, -2 - k], [9, 9, -2 - k], [-9, 9, -2 - k]], np.float32)
             for k in range(n)]
    scene = clrender.Scene.from_arrays(np.vstack(quads), np.vstack([4 * k + np.array([[0, 1, 2], [0, 2, 3]])
                                                                    for k in range(n)]),
                                       material=clrender.Material("glass", opacity=0.05))
    cam = clrender.Camera.look_at((0, 0, 0), (0, 0, -1), fov_y_deg=20, near=0.1, far=50)   # every layer covers the frame
    clrender.Renderer(32, 32, device=device.id, transparency="screen_door").render(scene, camera=cam)  # upload
    from clrender.device import limits as device_limits     # what the passes check a buffer's growth with
    real = device_limits.limits
    monkeypatch.setattr(device_limits, "limits", lambda dev: (256 * 1024, 128 * 1024))   # a 256 KiB device
    r = clrender.Renderer(32, 32, device=device.id)
    with pytest.raises(memory.DeviceMemoryError, match=r"A-buffer's fragment lists need \d+ bytes .* for 40960 "
                                                       r"entries but .* has 262144 bytes"):
        r.render(scene, camera=cam)
    monkeypatch.setattr(device_limits, "limits", real)
    frame = r.render(scene, camera=cam)             # with the real limits it renders, after growing
    assert (frame.fragment_count == n).all() and frame.stats["retries"] >= 1


def test_more_fragments_than_32_bit_offsets_is_refused(device, monkeypatch):
    """Past 2^31 - 1 fragments the A-buffer's 32-bit offsets would wrap: the host counts them exactly
    and refuses the frame (the limit is lowered here; reaching it takes about 20 GB of device memory)."""
    import clrender
    from clrender.passes import abuffer
    n = 40
    quads = [np.array([[-9, -9, -2 - k], [9, -9, -2 - k], [9, 9, -2 - k], [-9, 9, -2 - k]], np.float32)
             for k in range(n)]
    scene = clrender.Scene.from_arrays(np.vstack(quads), np.vstack([4 * k + np.array([[0, 1, 2], [0, 2, 3]])
                                                                    for k in range(n)]),
                                       material=clrender.Material("glass", opacity=0.05))
    cam = clrender.Camera.look_at((0, 0, 0), (0, 0, -1), fov_y_deg=20, near=0.1, far=50)
    monkeypatch.setattr(abuffer, "MAX_FRAGMENTS", 40959)
    with pytest.raises(memory.DeviceMemoryError, match=r"the frame has 40960 transparent fragments; the A-buffer "
                                                       r"holds at most 40959"):
        clrender.Renderer(32, 32, device=device.id).render(scene, camera=cam)
    monkeypatch.setattr(abuffer, "MAX_FRAGMENTS", 40960)
    frame = clrender.Renderer(32, 32, device=device.id).render(scene, camera=cam)
    assert frame.stats["fragments"] == 40960
