"""Small-frame tier that also runs under the Oclgrind simulator (`pytest -m oclgrind --device oclgrind`).

Every kernel of the pipeline runs here on tiny frames: setup (with near clipping), binning,
fine raster (with an alpha-masked, textured material) and the G-buffer resolve. Results are
checked against the NumPy reference, and any error the OpenCL implementation prints (Oclgrind
reports invalid memory accesses on stderr) fails the test.
"""
import numpy as np
import pytest

import clrender
import clrender.gbuffer
from clrender import Camera, Material, Scene, Texture
from reference.raster import rasterize

pytestmark = pytest.mark.oclgrind


def assert_no_device_diagnostics(capfd):
    """Oclgrind prints each finding to stderr with a `Kernel:` line; any such text fails."""
    err = capfd.readouterr().err
    flagged = [line for line in err.splitlines()
               if "Kernel:" in line or "oclgrind" in line.lower() or "error" in line.lower()]
    assert not flagged, "the OpenCL implementation reported problems:\n" + err[:4000]


def soup(seed=5, n=40):
    rng = np.random.default_rng(seed)
    centers = rng.uniform([-1.5, -1.0, -6.0], [1.5, 1.0, -0.05], (n, 1, 3))
    verts = (centers + rng.normal(scale=0.5, size=(n, 3, 3))).reshape(-1, 3).astype(np.float32)
    # Two in front of the camera reaching behind it: visible, so clipped (not trivially rejected).
    crossing = np.array([[-0.3, -0.2, -1.0], [0.3, -0.2, -1.0], [0.0, 0.3, 0.5],
                         [-0.2, 0.2, -2.0], [0.0, -0.4, 0.4], [0.4, 0.1, -1.5]], np.float32)
    verts = np.concatenate([verts, crossing])
    return Scene.from_arrays(verts, np.arange(len(verts)).reshape(-1, 3))


def masked_quad_scene():
    """A textured MASK quad (left half of the texture transparent) over an opaque floor."""
    rgba = np.zeros((8, 8, 4), np.uint8)
    rgba[..., 0] = 200
    rgba[:, 4:, 3] = 255
    quad = np.array([[-1, -1, -3], [1, -1, -3], [1, 1, -3], [-1, 1, -3]], np.float32)
    floor = np.array([[-3, -3, -5], [3, -3, -5], [3, 3, -5], [-3, 3, -5]], np.float32)
    uvs = np.array([[0, 1], [1, 1], [1, 0], [0, 0]] * 2, np.float32)
    positions = np.concatenate([quad, floor])
    tris = np.array([[0, 1, 2], [0, 2, 3], [4, 5, 6], [4, 6, 7]], np.int32)
    return Scene(positions, np.tile([[0, 0, 1]], (8, 1)), uvs, tris, np.array([0, 0, 1, 1], np.int32),
                 materials=[Material("leaf", base_color_texture=0, alpha_mode="MASK", alpha_cutoff=0.5),
                            Material("floor", base_color=(0.2, 0.4, 0.6, 1.0))],
                 textures=[Texture("mask", rgba)])


def test_soup_with_near_clipping_matches_reference(device, capfd):
    scene = soup()
    cam = Camera.look_at((0, 0, 0), (0, 0, -1), near=0.1, far=50)
    frame = clrender.Renderer(24, 16, device=device.id, tile_size=8).render(scene, cam)
    ids, depth, _ = rasterize(scene, cam, 24, 16)
    np.testing.assert_array_equal(frame.triangle_id, ids)
    assert frame.stats["clipped"] > 0, "the soup must exercise near clipping"
    assert (ids >= 0).sum() > 100
    assert_no_device_diagnostics(capfd)


def test_alpha_mask_and_resolve(device, capfd):
    scene = masked_quad_scene()
    cam = Camera.look_at((0, 0, 0), (0, 0, -1), fov_y_deg=60, near=0.1, far=50)
    frame = clrender.Renderer(16, 16, device=device.id, tile_size=8).render(scene, cam)
    ids = frame.triangle_id
    # The quad covers the middle; its left (transparent) half shows the floor (ids 2, 3).
    row = ids[8]
    assert set(row[5:7]) <= {2, 3}, row
    assert set(row[9:11]) <= {0, 1}, row
    quad = np.isin(ids, (0, 1))
    np.testing.assert_allclose(frame.albedo[quad], np.broadcast_to(clrender.gbuffer.srgb_to_linear_lut()[200] * np.array([1, 0, 0]), frame.albedo[quad].shape), atol=0.01)
    np.testing.assert_allclose(frame.albedo[np.isin(ids, (2, 3))][0], (0.2, 0.4, 0.6), atol=0.01)
    np.testing.assert_allclose(frame.normal[quad], np.broadcast_to((0, 0, 1), frame.normal[quad].shape), atol=1e-3)
    assert_no_device_diagnostics(capfd)


def test_lighting_kernels(device, capfd):
    """Culling, shading (tiled and brute force), tone mapping and particles on a tiny frame."""
    scene = masked_quad_scene()
    scene.add_point_light((0.5, 0.2, -2.0), (2.0, 1.5, 1.0), 2.5)
    scene.add_spot_light((-1.0, 1.0, -1.0), (0.3, -0.3, -1.0), (3.0, 3.0, 3.0), 6.0, 10.0, 30.0)
    scene.add_light_particles(20, seed=2, radius=(0.5, 1.5), bounds=((-2, -2, -5), (2, 2, -2)))
    cam = Camera.look_at((0, 0, 0), (0, 0, -1), fov_y_deg=60, near=0.1, far=50)
    tiled = clrender.Renderer(16, 16, device=device.id, tile_size=8, light_tile_size=8).render(scene, cam, time=0.5)
    brute = clrender.Renderer(16, 16, device=device.id, tile_size=8, light_tile_size=8,
                              light_culling="brute_force", tonemap="aces").render(scene, cam, time=0.5)
    assert tiled.stats["lights"] == 22 and tiled.light_count.max() > 0
    np.testing.assert_allclose(tiled.color, brute.color, rtol=0, atol=1e-5 * brute.color.max())
    assert tiled.color.max() > 0.1 and not np.array_equal(tiled.image, brute.image)
    assert_no_device_diagnostics(capfd)


def test_ssao_kernels(device, capfd):
    """SSAO and its depth-aware blur on a tiny corner (floor, two walls, a box); image sides that
    are not multiples of the work-group exercise the partial groups and runs."""
    from reference.ao import bilateral_blur
    from test_ssao import FLOOR, box, flat_scene
    scene = flat_scene([FLOOR, box((-6, 0, -6.5), (6, 4, -6)), box((-6.5, 0, -6.5), (-6, 4, 6)),
                        box((-4.5, 0, -5), (-3, 1.5, -3.5))], lights=True)
    cam = Camera.look_at((-1.0, 3.0, 0.0), (-5.0, 0.5, -5.0), fov_y_deg=60, near=0.1, far=50)
    raw = clrender.Renderer(21, 13, device=device.id, ssao=True, ssao_blur=False).render(scene, cam)
    blurred = clrender.Renderer(21, 13, device=device.id, ssao=True).render(scene, cam)
    fg = raw.triangle_id >= 0
    assert fg.all() and raw.ao.min() < 0.8 and raw.ao.max() == 1.0
    np.testing.assert_allclose(blurred.ao, bilateral_blur(raw.ao, raw.linear_depth), rtol=0, atol=2e-6)
    assert {"ssao_ms", "ssao_blur_ms"} <= set(blurred.stats)
    assert_no_device_diagnostics(capfd)


@pytest.mark.parametrize("filt", ["hard", "pcf3x3", "poisson"])
def test_shadow_kernels(device, capfd, filt):
    """Shadow maps on a tiny frame: a perspective spot map and 2 orthographic sun cascades
    through setup/binning/raster (ORTHO and not, an alpha-masked caster, atlas offsets), and
    shade.cl's lookups with every filter; odd sizes exercise partial runs and groups."""
    scene = masked_quad_scene()
    scene.add_spot_light((0.3, 0.2, -1.0), (0.0, 0.0, -1.0), (3.0, 3.0, 3.0), 8.0, 20.0, 40.0, shadow=True,
                         shadow_map_size=24)
    scene.add_point_light((0.5, 0.2, -2.0), (2.0, 1.5, 1.0), 2.5)
    scene.set_sun((0.3, -0.2, -1.0), (1.0, 1.0, 1.0), shadow_map_size=16)
    cam = Camera.look_at((0, 0, 0), (0, 0, -1), fov_y_deg=60, near=0.1, far=50)
    frame = clrender.Renderer(19, 13, device=device.id, tile_size=8, light_tile_size=8, sun_cascades=2,
                              shadow_filter=filt).render(scene, cam)
    assert frame.shadow.shape == (13, 19, 2) and frame.stats["shadow_maps"] == 3
    assert frame.shadow.min() >= 0.0 and frame.shadow.max() <= 1.0
    assert (frame.shadow < 1.0).any(), "the masked quad shadows the floor"
    assert_no_device_diagnostics(capfd)
