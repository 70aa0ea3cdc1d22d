"""Screen-space ambient occlusion (kernels/ssao.cl, kernels/ssao_blur.cl) against truth clrender
did not compute.

* against ray-traced ambient occlusion (tests/reference/ao.py: cosine-weighted rays from the
  G-buffer's own positions and normals, same radius, fixed seed) on a room with a corner, boxes
  and a step: Pearson correlation >= 0.8, raw and blurred; a pixel deep in the corner is darker
  than one on the open floor;
* the blur equals a float64 NumPy bilateral filter, keeps a constant image, and does not carry
  occlusion across a depth discontinuity;
* a flat open floor is unoccluded; strength 0 gives exactly 1; renders are bit-identical;
* SSAO off launches no kernel and gives ao = 1; SSAO on changes color only through the
  ambient term: color_on - color_off = albedo·ambient·(ao - 1).
"""
import numpy as np
import pyopencl.array as cla
import pytest

import clrender
import clrender.device.core
from clrender import Camera, Material, Scene
from clrender.abi import gbuffer as layout
from clrender.passes import Resources, SsaoBlurPass
from reference.ao import bilateral_blur, ray_traced_ao
from reference.shading import world_positions

RADIUS = 1.0
AMBIENT = 0.2
MIN_CORRELATION = 0.8
RAYS = 128                 # reference rays per pixel: std of the truth <= 0.5/sqrt(128) = 0.044
W, H = 160, 120
CAMERA = Camera.look_at((3.5, 5.0, 6.0), (-1.5, 0.5, -2.5), fov_y_deg=55, near=0.1, far=50)


def box(lo, hi):
    """12 outward (counter-clockwise) triangles of an axis-aligned box."""
    corners = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], np.float64)
    verts = np.asarray(lo) + corners * (np.asarray(hi) - np.asarray(lo))
    faces = [[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
             [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]]
    return verts[np.array(faces)]


def flat_scene(triangles, lights=False) -> Scene:
    """Unshared vertices, so every G-buffer normal is its face's normal (no smoothing at edges)."""
    tris = np.concatenate(triangles).astype(np.float32)
    scene = Scene.from_arrays(tris.reshape(-1, 3), np.arange(3 * len(tris)).reshape(-1, 3),
                              material=Material("clay", (0.8, 0.7, 0.6, 1.0), specular_intensity=0.2,
                                                specular_power=16.0))
    scene.ambient = AMBIENT
    if lights:
        scene.add_point_light((0.0, 3.0, 0.0), (2.0, 1.8, 1.5), 8.0)
        scene.add_point_light((-4.0, 1.5, -4.0), (0.5, 0.8, 1.2), 4.0)
    return scene


FLOOR = np.array([[[-6, 0, -6], [6, 0, 6], [6, 0, -6]], [[-6, 0, -6], [-6, 0, 6], [6, 0, 6]]], np.float64)


def room(lights=False) -> Scene:
    """A floor, two walls meeting in a corner at (-6, *, -6), two boxes, a low step, a small cube."""
    return flat_scene([FLOOR, box((-6, 0, -6.5), (6, 4, -6)), box((-6.5, 0, -6.5), (-6, 4, 6)),
                       box((-1.5, 0, -2), (0, 1, -0.5)), box((1, 0, -4), (2.5, 2.5, -2.5)),
                       box((-5, 0, -3), (-2.5, 0.4, 1)), box((0.8, 0, 0.5), (1.3, 0.5, 1.0))], lights)


def pixel_of(point, camera=CAMERA, width=W, height=H):
    clip = camera.view_projection(width, height) @ np.append(point, 1.0)
    x, y = clip[:2] / clip[3]
    return int((1 - y) * 0.5 * height), int((x + 1) * 0.5 * width)


_TRUTH = {}


def truth(frame, scene, stride=2):
    """Ray-traced AO at every `stride`-th foreground pixel (cached: the raster is bit-exact on
    every device, so the G-buffer positions and normals are the same)."""
    key = frame.depth.tobytes()
    if key not in _TRUTH:
        sel = np.zeros(frame.depth.shape, bool)
        sel[::stride, ::stride] = True
        sel &= frame.triangle_id >= 0
        points = world_positions(frame.depth, CAMERA)[sel]
        _TRUTH[key] = sel, ray_traced_ao(points, frame.normal[sel], scene.positions, scene.triangles, RADIUS,
                                         RAYS, seed=7)
    return _TRUTH[key]


@pytest.mark.parametrize("blur", [False, True], ids=["raw", "blurred"])
def test_ssao_correlates_with_ray_traced_ao(make_renderer, blur):
    scene = room()
    frame = make_renderer(W, H, ssao=True, ssao_radius=RADIUS, ssao_blur=blur).render(scene, CAMERA)
    sel, expect = truth(frame, scene)
    got = frame.ao[sel]
    assert got.dtype == np.float32 and got.min() >= 0.0 and got.max() <= 1.0
    corr = np.corrcoef(got, expect)[0, 1]
    assert corr >= MIN_CORRELATION, f"Pearson correlation with ray-traced AO {corr:.3f} < {MIN_CORRELATION}"
    # Monotone: deep in the corner (floor meets both walls) is darker than the open floor.
    corner, open_floor = pixel_of((-5.85, 0.0, -5.85)), pixel_of((3.5, 0.0, 0.0))
    assert frame.triangle_id[corner] >= 0 and frame.triangle_id[open_floor] >= 0
    assert frame.ao[corner] < frame.ao[open_floor] - 0.2, (frame.ao[corner], frame.ao[open_floor])
    assert frame.ao[open_floor] > 0.99


def test_flat_open_floor_is_unoccluded(make_renderer):
    """Nothing but a floor: every sample lies in the tangent plane, below the elevation bias."""
    frame = make_renderer(W, H, ssao=True, ssao_radius=RADIUS, ssao_blur=False).render(flat_scene([FLOOR]), CAMERA)
    floor = frame.triangle_id >= 0
    assert floor.mean() > 0.5
    assert frame.ao[floor].min() >= 1.0 - 1e-6, frame.ao[floor].min()
    assert np.all(frame.ao[~floor] == 1.0)


def test_strength_zero_is_exactly_one_and_leaves_color_unchanged(make_renderer):
    scene = room(lights=True)
    frame = make_renderer(W, H, ssao=True, ssao_strength=0.0).render(scene, CAMERA)
    off = make_renderer(W, H).render(scene, CAMERA)
    assert np.all(frame.ao == 1.0)
    np.testing.assert_array_equal(frame.color, off.color)


def test_ssao_off_launches_nothing_and_ao_is_one(make_renderer):
    frame = make_renderer(W, H).render(room(lights=True), CAMERA)
    assert frame.ao.shape == (H, W) and frame.ao.dtype == np.float32
    assert np.all(frame.ao == 1.0)
    assert not any(k.startswith("ssao") for k in frame.stats), frame.stats
    np.testing.assert_array_equal(frame.aov("ao"), frame.ao)


def test_ssao_changes_color_only_through_the_ambient_term(make_renderer):
    scene = room(lights=True)
    on = make_renderer(W, H, ssao=True).render(scene, CAMERA)
    off = make_renderer(W, H).render(scene, CAMERA)
    assert {"ssao_ms", "ssao_blur_ms"} <= set(on.stats)
    fg = on.triangle_id >= 0
    assert (on.ao[fg] < 0.8).mean() > 0.01, "the scene must have occluded pixels"
    expect = on.albedo * AMBIENT * (on.ao[..., None] - 1.0)
    # float32 rounding of albedo·(ambient·ao + diffuse) + specular vs the same without ao
    tol = 4e-7 * np.abs(off.color).max() + 1e-7
    np.testing.assert_allclose(on.color - off.color, expect, rtol=0, atol=tol)
    assert np.abs(on.color - off.color).max() > 0.01


def test_renders_are_bit_identical(device):
    scene = room(lights=True)
    frames = [clrender.Renderer(W, H, device=device.id, ssao=True).render(scene, CAMERA) for _ in range(2)]
    np.testing.assert_array_equal(frames[0].ao, frames[1].ao)
    np.testing.assert_array_equal(frames[0].color, frames[1].color)


def test_pixels_per_work_item_do_not_change_bits(device, monkeypatch):
    """The GPU path (a pixel per work-item) and the CPU paths (8 or 16 per work-item) compute the
    same bits, at sizes that leave partial runs and work-groups."""
    scene = room(lights=True)
    frames = {}
    for vec in ("1", "8", "16"):
        monkeypatch.setenv("CLRENDER_VEC", vec)
        frames[vec] = clrender.Renderer(61, 37, device=device.id, ssao=True).render(scene, CAMERA)
    assert frames["1"].ao.min() < 0.8
    for vec in ("8", "16"):
        np.testing.assert_array_equal(frames[vec].ao, frames["1"].ao)


def test_blur_matches_numpy_bilateral_reference(make_renderer):
    scene = room()
    raw = make_renderer(W, H, ssao=True, ssao_blur=False).render(scene, CAMERA)
    blurred = make_renderer(W, H, ssao=True, ssao_blur=True).render(scene, CAMERA)
    np.testing.assert_array_equal(raw.depth, blurred.depth)
    expect = bilateral_blur(raw.ao, raw.linear_depth)
    np.testing.assert_allclose(blurred.ao, expect, rtol=0, atol=2e-6)   # float32 sums of 9 terms, twice
    assert np.abs(blurred.ao - raw.ao).max() > 0.05                   # it does blur


# -- the blur stage alone, on synthetic G-buffers ----------------------------------------------

def run_blur(device, ao, linear_depth):
    """kernels/ssao_blur.cl on `ao` with a G-buffer whose depth plane is `linear_depth`."""
    h, w = ao.shape
    dev = clrender.device.core.Device.get(device.id)
    planes = np.zeros((len(layout.PLANES), h, w), np.uint32)
    planes[layout.FIELDS["linear_depth"].plane] = np.asarray(linear_depth, np.float32).view(np.uint32)
    blur = SsaoBlurPass(dev, clrender.RenderConfig(ssao=True))
    blur.allocate(w, h)
    res = Resources(buffers={"gbuffer": cla.to_device(dev.queue, planes.reshape(-1)),
                             "ao_raw": cla.to_device(dev.queue, np.asarray(ao, np.float32).reshape(-1))},
                    values={"width": w, "height": h})
    blur.run(res)
    return blur.ao.get(queue=dev.queue).reshape(h, w)


def test_blur_keeps_a_constant_image(device):
    rng = np.random.default_rng(3)
    depth = rng.uniform(0.2, 0.21, (37, 53)).astype(np.float32)       # one surface, slightly rough
    out = run_blur(device, np.full(depth.shape, 0.37, np.float32), depth)
    np.testing.assert_allclose(out, 0.37, rtol=0, atol=1e-6)


def test_blur_does_not_bleed_across_a_depth_discontinuity(device):
    h, w = 24, 40
    depth = np.full((h, w), 0.1, np.float32)
    depth[:, 20:] = 0.3                                               # a step of 3x in depth
    depth[:4] = np.inf                                                # and a background strip
    ao = np.where(np.arange(w) < 20, 0.25, 1.0).astype(np.float32) * np.ones((h, 1), np.float32)
    out = run_blur(device, ao, depth)
    np.testing.assert_allclose(out[4:, :20], 0.25, rtol=0, atol=1e-6)
    np.testing.assert_allclose(out[4:, 20:], 1.0, rtol=0, atol=1e-6)
    assert np.all(out[:4] == 1.0)
    # Random occlusion over random depth steps: the NumPy bilateral filter, same weights.
    rng = np.random.default_rng(11)
    depth = np.repeat(rng.choice([0.1, 0.104, 0.2, np.inf], (h, 5)), 8, axis=1).astype(np.float32)
    ao = rng.random((h, w)).astype(np.float32)
    np.testing.assert_allclose(run_blur(device, ao, depth), bilateral_blur(ao, depth), rtol=0, atol=2e-6)


@pytest.mark.parametrize("vec", ["1", "4", "8", "16"])
def test_blur_weights_match_reference_at_every_pixel_width(device, monkeypatch, vec):
    """The tent-times-depth weights at each pixels-per-work-item build (CPUs use 8 or 16, GPUs 1):
    Intel's CPU runtime 2021.2 once folded abs(i) of the tap loop to 0 in the VEC 1 build only,
    a box filter instead of the tent (the SSAO differences between widths on that runtime)."""
    monkeypatch.setenv("CLRENDER_VEC", vec)
    rng = np.random.default_rng(17)
    h, w = 19, 45                                    # partial runs and work-groups at every width
    depth = (0.2 + 0.01 * rng.random((h, w))).astype(np.float32)      # one surface: every tap weighs
    depth[:, 30:] += np.float32(0.006)               # a step within the depth tolerance: partial weights
    depth[:2] = np.inf
    depth[rng.random((h, w)) < 0.1] = np.inf         # background amid a row: diverging work-items
    ao = rng.random((h, w)).astype(np.float32)
    np.testing.assert_allclose(run_blur(device, ao, depth), bilateral_blur(ao, depth), rtol=0, atol=2e-6)


def test_options_are_validated():
    for bad in (dict(ssao="yes"), dict(ssao_blur=1), dict(ssao_radius=0.0), dict(ssao_radius=float("nan")),
                dict(ssao_radius="1"), dict(ssao_strength=-0.5), dict(ssao_strength=float("inf"))):
        with pytest.raises(ValueError, match=next(iter(bad))):
            clrender.RenderConfig(**bad)
    assert clrender.RenderConfig().ssao is False


def test_ao_preview_and_portability_check():
    from clrender.outputs import aov_io
    from clrender.tools import check
    ao = np.array([[0.0, 0.5, 1.0]], np.float32)
    assert aov_io.preview("ao", ao, np.zeros(ao.shape, bool)).tolist() == [[0, 128, 255]]   # grey, white = open
    assert "ao" in clrender.Frame.AOV_NAMES and "ao" in check.AOVS and check.TOLERANCES["ao"][0] == "abs"
