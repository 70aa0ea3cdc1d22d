"""One subject (the Oclgrind tier: every kernel on tiny frames; .ci/run runs it by its marker) in one file: 621 lines.

Small-frame tier that also runs under the Oclgrind simulator (`pytest -m oclgrind --device oclgrind`).

Every kernel of the pipeline runs here on tiny frames: setup (with near clipping), binning,
fine raster (with an alpha-masked, textured material) and the G-buffer resolve, lighting, SSAO,
shadows, and transparency (fragment count/fill/next layer, the A-buffer's sort (both paths) and
resolve with a grown buffer, depth peeling, the capped fill, screen door, the refraction
composite). Results are checked against the NumPy references, and any error the OpenCL
implementation prints (Oclgrind reports invalid memory accesses on stderr) fails the test.
"""
import numpy as np
import pytest

import clrender
import clrender.abi.gbuffer
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


def test_orthographic_camera_kernels(device, capfd):
    """An orthographic camera (docs/raster_contract.md §11): the ORTHO variants of setup (near
    clipping), raster, G-buffer, light culling, SSAO and shading, with a shadowed sun, on one
    tiny frame; triangle ids against the reference's orthographic path."""
    scene = soup()
    scene.add_point_light((0.3, 0.2, -2.0), (2.0, 1.5, 1.0), 2.5)
    scene.set_sun((0.3, -0.2, -1.0), (1.0, 1.0, 1.0), shadow_map_size=16)
    cam = Camera.orthographic((0, 0, 0), (0, 0, -1), xmag=1.5, ymag=1.0, near=0.1, far=50)
    frame = clrender.Renderer(19, 13, device=device.id, tile_size=8, light_tile_size=8, sun_cascades=1,
                              ssao=True).render(scene, cam)
    ids, _, _ = rasterize(scene, cam, 19, 13)
    np.testing.assert_array_equal(frame.triangle_id, ids)
    assert frame.stats["clipped"] > 0 and (ids >= 0).mean() > 0.5
    assert np.isfinite(frame.color).all() and frame.color.max() > 0.1 and frame.ao.min() >= 0.0
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
    np.testing.assert_allclose(frame.albedo[quad], np.broadcast_to(clrender.abi.gbuffer.srgb_to_linear_lut()[200] * np.array([1, 0, 0]), frame.albedo[quad].shape), atol=0.01)
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


def test_light_accumulation_kernels(device, capfd):
    """light_culling="quads" (light_view_bounds, light_quad_rects, light_quads_count/fill) and "stencil"
    (stencil_words_needed, light_stencil, shade.cl with STENCIL) on a 19x13 frame with 8-pixel tiles:
    40 lights, some reaching the whole view, so the quad lists outgrow their 16 entries per tile and
    the tile lists their first stencil word (both grown and redone), one holding the eye, one beside
    it across the near plane; both equal tiled culling, stencil's evaluated pairs are the useful ones."""
    rng = np.random.default_rng(11)
    scene = masked_quad_scene()
    for k in range(40):
        pos = rng.uniform((-2.5, -2.0, -5.5), (2.5, 2.0, -1.0))
        if k % 4 == 3:
            scene.add_spot_light(pos, rng.normal(size=3) + (0, 0, -2), (1.0, 0.8, 0.6), float(rng.uniform(2, 6)),
                                 10.0, 40.0)
        else:
            scene.add_point_light(pos, (0.6, 0.7, 0.8), float(rng.uniform(1.0, 6.0)))
    scene.add_point_light((0.0, 0.0, 0.0), (0.3, 0.3, 0.3), 2.5)          # holds the eye
    scene.add_point_light((0.8, 0.0, -0.05), (0.3, 0.3, 0.3), 0.6)        # across the near plane, beside
    cam = Camera.look_at((0, 0, 0), (0, 0, -1), fov_y_deg=60, near=0.1, far=50)
    opts = dict(device=device.id, tile_size=8, light_tile_size=8)
    tiled = clrender.Renderer(19, 13, **opts).render(scene, cam)
    assert tiled.stats["lights_per_tile_max"] > 32
    for mode in ("quads", "stencil"):
        got = clrender.Renderer(19, 13, light_culling=mode, **opts).render(scene, cam)
        assert got.stats["retries"] >= 1, mode
        np.testing.assert_allclose(got.color, tiled.color, rtol=0, atol=1e-5 * tiled.color.max())
        assert got.stats["light_pairs_useful"] == tiled.stats["light_pairs_useful"] > 0
        assert f"light_{mode}_ms" in got.stats
    assert got.stats["light_pairs_evaluated"] == got.stats["light_pairs_useful"] < tiled.stats["light_pairs_evaluated"]
    assert_no_device_diagnostics(capfd)

def test_ssao_kernels(device, capfd):
    """SSAO and its depth-aware blur on a tiny corner (floor, two walls, a box); image sides that
    are not multiples of the work-group exercise the partial groups and runs."""
    from reference.ao import bilateral_blur
    from test_ssao import FLOOR, box, flat_scene
    scene = flat_scene([FLOOR, box((-6, 0, -6.5), (6, 4, -6)), box((-6.5, 0, -6.5), (-6, 4, 6)),
                        box((-4.5, 0, -5), (-3, 1.5, -3.5))], lights=True)
    cam = Camera.look_at((-1.0, 3.0, 0.0), (-5.0, 0.5, -5.0), fov_y_deg=60, near=0.1, far=50)
    raw_renderer = clrender.Renderer(21, 13, device=device.id, ssao=True, ssao_blur=False)
    raw = raw_renderer.render(scene, cam)
    blurred = clrender.Renderer(21, 13, device=device.id, ssao=True).render(scene, cam)
    fg = raw.triangle_id >= 0
    assert fg.all() and raw.ao.min() < 0.8 and raw.ao.max() == 1.0
    np.testing.assert_allclose(blurred.ao, bilateral_blur(raw.ao, raw.linear_depth), rtol=0, atol=2e-6)
    assert {"ssao_ms", "ssao_blur_ms"} <= set(blurred.stats)
    # an off-centre pinhole (Camera.from_opencv): SSAO's and the light culling's shifted frustum
    K, R, t = cam.to_opencv(21, 13)
    K[0, 2] += 6.0
    K[1, 2] -= 3.0
    shifted = raw_renderer.render(scene, Camera.from_opencv(K, R, t, 21, 13, near=0.1, far=50))  # same programs
    assert (shifted.triangle_id >= 0).all() and shifted.ao.min() < 0.8 and np.isfinite(shifted.position).all()
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


# -- transparency (docs/transparency.md): every new kernel on tiny frames --------------------------

TW, TH = 24, 16
T_CAM = Camera.look_at((0, 0, 0), (0, 0, -1), fov_y_deg=90.0, near=0.1, far=50)


def pixel_rect(x0, x1, y0, y1, depth):
    """Two camera-facing triangles covering pixels [x0, x1) × [y0, y1) of a TW×TH T_CAM image."""
    tx, ty = TW / TH, 1.0

    def at(px, py):
        return ((px / TW * 2 - 1) * tx * depth, (1 - py / TH * 2) * ty * depth, -depth)
    a, b, c, d = at(x0, y1), at(x1, y1), at(x1, y0), at(x0, y0)
    return np.array([[a, b, c], [a, c, d]], np.float64)


FRONT = (2, 10, 2, 10)        # one glass layer near the camera
STACK = (13, 21, 5, 13)       # 20 layers: lists longer than the 16-entry private sort


def transparent_stack_scene():
    """A far wall, two full-frame glass layers, a front glass and a stack of 20 thin layers (ids in a
    random depth order; depths 12 % apart, so the shadow map's biases, a few of its texels, cannot
    bridge them); a shadowed spot at the eye (every layer behind another lies in its shadow; its
    40-degree cone reaches the middle of the frame, both the front glass and the stack) and two
    point lights.
    384·2 + 64 + 64·20 fragments: more than a fresh A-buffer holds (2 per pixel)."""
    from transparency_cases import build_scene, point_lights
    rng = np.random.default_rng(3)
    glass = lambda name, rgb, a: Material(name, (*rgb, 1.0), opacity=a, specular_intensity=0.4, specular_power=12.0)
    parts = [(pixel_rect(0, TW, 0, TH, 44.0), None, Material("wall", (0.7, 0.7, 0.7, 1.0), specular_intensity=0.2)),
             (pixel_rect(0, TW, 0, TH, 30.0), None, glass("haze", (0.4, 0.6, 0.9), 0.3)),
             (pixel_rect(0, TW, 0, TH, 36.0), None, glass("mist", (0.9, 0.6, 0.4), 0.25)),
             (pixel_rect(*FRONT, 2.0), None, glass("front", (0.9, 0.9, 0.2), 0.5))]
    films = [glass(f"film{k}", rng.uniform(0.2, 1.0, 3), float(rng.uniform(0.05, 0.12))) for k in range(4)]
    for k, d in enumerate(3.0 * 1.12 ** rng.permutation(20)):
        parts.append((pixel_rect(*STACK, d), None, films[k % 4]))
    scene = build_scene(parts, ambient=0.1,
                        lights=point_lights([((-1.0, 0.5, -2.5), (1.0, 0.8, 0.6), 40.0),
                                             ((1.5, -0.5, -10.0), (0.5, 0.7, 1.0), 30.0)]))
    # 64 texels over the ±40° cone: one is 2.6 % of a layer's depth and 1/5 of a pixel, so the biases
    # (<= ~2.3 texels) stay below the 12 % gaps and the PCF blur inside the left-out edge pixels; at 128
    # the map's raster was most of these tests' time under Oclgrind.
    scene.add_spot_light((0.0, 0.0, 0.0), (0.0, 0.0, -1.0), (12.0, 12.0, 12.0), 100.0, 30.0, 40.0, shadow=True,
                         shadow_map_size=64)
    return scene


def transparency_expected(frame, scene, layers=None, shadows=True):
    """(reference blend, comparable pixels): the spot's visibility of fragments by ray casting, of the
    opaque wall from the frame's own shadow AOV; pixels next to a layer's edge (shadow-map texels and
    PCF blur the shadow there) are left out."""
    from reference import shading as ref_shading
    from reference import transparency as ref
    from reference.shadow_rays import occluded
    spot = int(np.flatnonzero(scene.lights["type"] == clrender.abi.structs.LIGHT_SPOT)[0])

    def light_visibility(points, i):
        if i != spot:
            return np.ones(len(points))
        v = scene.lights["position"][i].astype(np.float64) - points
        dist = np.linalg.norm(v, axis=1)
        dirs = v / dist[:, None]
        return (~occluded(scene, points + 1e-3 * dirs, dirs, dist - 2e-3)).astype(np.float64)

    others = np.delete(scene.lights, spot)
    sh = lambda ls: ref_shading.shade_frame(frame, T_CAM, ls, scene.ambient)
    vis = frame.shadow[..., 0].astype(np.float64)[..., None]
    opaque = sh(others) + vis * (sh(scene.lights[spot:spot + 1]) - sh(scene.lights[:0]))
    exp = ref.blend(scene, T_CAM, TW, TH, opaque, layers=layers, light_visibility=light_visibility if shadows else None)
    edge = np.zeros((TH, TW), bool)
    for x0, x1, y0, y1 in (FRONT, STACK):
        edge[max(y0 - 1, 0):y1 + 1, max(x0 - 1, 0):x1 + 1] = True
        edge[y0 + 1:y1 - 1, x0 + 1:x1 - 1] = False
    return exp, ~edge & ~exp.ambiguous


def assert_transparency_matches(frame, exp, ok, what):
    np.testing.assert_array_equal(frame.fragment_count, exp.fragment_count, err_msg=what)
    np.testing.assert_array_equal(frame.triangle_id, exp.fragments.opaque_id, err_msg=what)
    assert ok.sum() > 200
    np.testing.assert_allclose(frame.transmittance[ok], exp.transmittance[ok], rtol=0, atol=1e-5, err_msg=what)
    peak = float(exp.color.max())
    np.testing.assert_allclose(frame.color[ok], exp.color[ok], rtol=0, atol=1e-4 * peak, err_msg=what)


def test_abuffer_kernels(device, capfd):
    """Fragment count, fill, sort (insertion and, beyond 16, heap), forward shading with the tile light
    lists and a spot's shadow map, composite; a fresh renderer's A-buffer overflows and grows (retry)."""
    scene = transparent_stack_scene()
    frame = clrender.Renderer(TW, TH, device=device.id, tile_size=8, light_tile_size=8).render(scene, T_CAM)
    exp, ok = transparency_expected(frame, scene)
    assert exp.fragment_count.max() == 22 and exp.fragment_count.sum() > 2 * TW * TH
    assert frame.stats["retries"] >= 1, "the A-buffer must have grown"
    assert frame.shadow.shape == (TH, TW, 1) and frame.shadow[6, 6, 0] < 0.05, "the layers shadow the wall"
    assert_transparency_matches(frame, exp, ok, "A-buffer")
    blend = np.array([m.alpha_mode == "BLEND" for m in scene.materials])
    front = exp.fragment_count > 0                       # the nearest-fragment rule of the ids
    assert blend[frame.material_id[front]].all() and not blend[frame.material_id[~front & (frame.material_id >= 0)]].any()
    unshadowed, _ = transparency_expected(frame, scene, shadows=False)
    assert np.abs(unshadowed.color - exp.color)[ok].max() > 0.05 * exp.color.max(), \
        "the spot's shadows must matter in the comparison"
    assert_no_device_diagnostics(capfd)


def test_depth_peeling_and_cap_kernels(device, capfd):
    """Depth peeling (fragment_next_layer, peel_shade, composite) with 3 layers, and the A-buffer's
    capped fill (max_fragments_per_pixel keeps the 4 nearest, counting the rest as dropped)."""
    scene = transparent_stack_scene()
    peeled = clrender.Renderer(TW, TH, device=device.id, tile_size=8, light_tile_size=8,
                               transparency="depth_peeling", peel_layers=3).render(scene, T_CAM)
    exp, ok = transparency_expected(peeled, scene, layers=3)
    assert_transparency_matches(peeled, exp, ok, "3 peels")
    capped = clrender.Renderer(TW, TH, device=device.id, tile_size=8, light_tile_size=8,
                               max_fragments_per_pixel=4).render(scene, T_CAM)
    exp4, ok4 = transparency_expected(capped, scene, layers=4)
    assert_transparency_matches(capped, exp4, ok4, "max_fragments_per_pixel=4")
    assert capped.stats["fragments_dropped"] == int(np.maximum(exp4.fragment_count - 4, 0).sum())
    assert_no_device_diagnostics(capfd)


def test_screen_door_kernels(device, capfd):
    """BLEND triangles through the opaque setup and raster with the 4x4 dither threshold."""
    from transparency_cases import build_scene
    scene = build_scene([(pixel_rect(0, TW, 0, TH, 12.0), None, Material("wall", (0.7, 0.7, 0.7, 1.0))),
                         (pixel_rect(4, 20, 4, 12, 4.0), None, Material("glass", (0.9, 0.2, 0.2, 1.0), opacity=0.5))])
    scene.add_spot_light((0.5, 0.5, 0.0), (0.0, 0.0, -1.0), (5.0, 5.0, 5.0), 30.0, 50.0, 65.0, shadow=True,
                         shadow_map_size=32)
    frame = clrender.Renderer(TW, TH, device=device.id, tile_size=8, light_tile_size=8,
                              transparency="screen_door").render(scene, T_CAM)
    ids = frame.triangle_id
    kept = np.isin(ids, (2, 3))
    assert kept[4:12, 4:20].mean() == 0.5 and not kept[:4].any() and not kept[12:].any()
    blocks = kept[4:12, 4:20].reshape(2, 4, 4, 4).sum(axis=(1, 3))
    assert (blocks == 8).all(), blocks
    assert (ids >= 0).all()
    assert np.all(frame.fragment_count == 0) and np.all(frame.transmittance == 1.0)
    assert frame.color[kept].max() > 0 and np.isfinite(frame.color).all()
    assert_no_device_diagnostics(capfd)


def test_refraction_kernels(device, capfd):
    """The composite's displaced lookup behind a tilted refracting glass (shadows on)."""
    from transparency_cases import build_scene
    light_m = Material("light", (0.9, 0.9, 0.9, 1.0), specular_intensity=0.0)
    dark_m = Material("dark", (0.05, 0.1, 0.3, 1.0), specular_intensity=0.0)
    parts = [(pixel_rect(x, x + 2, 0, TH, 12.0), None, light_m if (x // 2) % 2 else dark_m) for x in range(0, TW, 2)]
    t = np.radians(35.0)
    rot = np.array([[np.cos(t), 0, np.sin(t)], [0, 1, 0], [-np.sin(t), 0, np.cos(t)]])
    q = 2.0 * np.array([[[-1, -1, 0], [1, -1, 0], [1, 1, 0]], [[-1, -1, 0], [1, 1, 0], [-1, 1, 0]]], np.float64) @ rot.T
    glass = Material("glass", (0.3, 0.8, 0.4, 1.0), opacity=0.5, refraction=0.15)
    scene = build_scene(parts + [(q + (0.0, 0.0, -4.0), None, glass)], ambient=0.5)
    scene.add_spot_light((0.5, 0.5, 0.0), (0.0, 0.0, -1.0), (2.0, 2.0, 2.0), 30.0, 50.0, 65.0, shadow=True,
                         shadow_map_size=32)
    opts = dict(device=device.id, tile_size=8, light_tile_size=8)
    plain = clrender.Renderer(TW, TH, **opts).render(scene, T_CAM)
    bent = clrender.Renderer(TW, TH, refraction=True, **opts).render(scene, T_CAM)
    layered = plain.fragment_count > 0
    assert layered.sum() > 20
    np.testing.assert_array_equal(bent.fragment_count, plain.fragment_count)
    np.testing.assert_array_equal(bent.transmittance, plain.transmittance)
    np.testing.assert_array_equal(bent.color[~layered], plain.color[~layered])
    assert (np.abs(bent.color - plain.color).max(-1)[layered] > 1e-3).mean() > 0.3
    assert_no_device_diagnostics(capfd)


# --- hatching (tests/test_hatching.py) -----------------------------------------------------------

@pytest.mark.parametrize("scale", [1.0, 0.7])
def test_hatching_kernel(device, capfd, scale):
    """hatching.cl on a 24x16 frame (level 0, and the trilinear levels 0-1), against the NumPy
    formula on the tone-mapped Frame.color."""
    from clrender.abi.gbuffer import linear_to_srgb8
    from reference.shading import tonemap_curve
    from test_hatching import COLOURED_CAMERA, assert_matches_expected, coloured_scene, hatching_reference
    frame = clrender.Renderer(TW, TH, device=device.id, tile_size=8, light_tile_size=8, hatching=True,
                              hatching_scale=scale).render(coloured_scene(), COLOURED_CAMERA)
    ldr = tonemap_curve(frame.color, "reinhard")
    assert_matches_expected(frame.image, frame, ldr, scale, 0.3)    # paper, ink outlines, strokes
    expect = linear_to_srgb8(hatching_reference(ldr, scale, 0.3))
    assert np.abs(expect.astype(int) - linear_to_srgb8(ldr).astype(int)).mean() > 10
    assert "hatching_ms" in frame.stats
    assert_no_device_diagnostics(capfd)


# -- anti-aliasing (docs/post.md "Anti-aliasing"): edge_aa.cl and fxaa.cl on a tiny frame ----------------

def test_anti_aliasing_kernels(device, capfd):
    """tonemap_ldr -> edge_detect, edge_blur -> fxaa_luma, fxaa -> encode on tests/reference/aa.py's
    scene at an odd size (partial work-groups, clamped borders): the edge mask equals the NumPy test
    on the frame's own AOVs, only pixels at most 1 px from a marked one change, and the HDR colour
    is untouched."""
    from reference import aa
    w, h = 22, 15
    scene, cam = aa.aa_scene(w / h), aa.aa_camera()
    opts = dict(device=device.id, tile_size=8, light_tile_size=8, tonemap="clamp")
    plain = clrender.Renderer(w, h, **opts).render(scene, cam)
    frame = clrender.Renderer(w, h, edge_aa=True, color_aa="fxaa", **opts).render(scene, cam)
    rel_margin, angle_margin = aa.threshold_margin(frame.depth, frame.normal, frame.triangle_id)
    assert rel_margin > 0.1 and angle_margin > 5.0
    expect = aa.edge_mask(frame.depth, frame.normal, frame.triangle_id)
    np.testing.assert_array_equal(frame.edges, expect)
    assert 20 < expect.sum() < 0.7 * w * h
    changed = np.abs(frame.image.astype(int) - plain.image).max(-1) > 0
    assert changed.sum() > 10 and not (changed & ~aa.dilate(expect.astype(bool), 1)).any()
    np.testing.assert_array_equal(frame.color, plain.color)
    assert {"edge_aa_ms", "fxaa_ms", "encode_ms"} <= set(frame.stats)
    assert_no_device_diagnostics(capfd)


# -- bloom (docs/post.md, kernels/bloom.cl) ---------------------------------------------------------------

@pytest.mark.parametrize("size, radius", [((TW, TH), 16.0), ((21, 13), 5.0)])
def test_bloom_kernels(device, capfd, size, radius):
    """Threshold + 2x2 means (odd sizes clamp), the Gaussian rows/columns with the cascaded 2x
    upsampling, the compose: 3 levels at 24x16 (12x8, 6x4, 3x2), 2 at 21x13 (11x7, 6x4); against
    the NumPy pyramid of test_bloom on the same frame without bloom."""
    from test_bloom import assert_bloom_matches, spot_scene
    scene = spot_scene((0.5, 0.3, -4.0), (6.0, 5.0, 4.0), 2.5, extra=[((-4.5, -4.0, -4.6), (4.0, 2.0, 6.0), 1.5)])
    opts = dict(device=device.id, tile_size=8, light_tile_size=8)
    off = clrender.Renderer(*size, **opts).render(scene, T_CAM)
    on = clrender.Renderer(*size, bloom=True, bloom_threshold=0.5, bloom_strength=0.4, bloom_radius=radius,
                           **opts).render(scene, T_CAM)
    lit = off.color.max(-1) > 0.5
    assert 4 <= lit.sum() < lit.size // 2 and lit[-1].any(), "bright spots, one at the bottom edge"
    assert "bloom_ms" in on.stats
    assert_bloom_matches(on.color, off.color, 0.5, 0.4, radius)
    assert_no_device_diagnostics(capfd)


# -- motion blur (docs/post.md, kernels/motion_blur.cl) and object motion (Scene.set_transform) -----------

def test_motion_blur_kernels(device, capfd):
    """A camera pan plus a quad moved with set_transform (the G-buffer's prev_positions) at 40x20
    (two 32-pixel tiles along x, partial tiles and work-groups): mb_velocity, mb_neighbor_max and
    mb_gather against test_motion_blur's NumPy implementation on the same frame without blur."""
    from test_motion_blur import CAM, panned, reference_motion_blur, translation, wall_and_quad
    scene = wall_and_quad()
    scene.set_transform("quad", translation(-0.4), previous=translation(0.4))   # on screen: with the pan
    prev = panned(-1.5)
    opts = dict(device=device.id, tile_size=8, light_tile_size=8)
    off = clrender.Renderer(40, 20, **opts).render(scene, CAM, previous_camera=prev)
    on = clrender.Renderer(40, 20, motion_blur=True, shutter=1.0, motion_blur_samples=6,
                           **opts).render(scene, CAM, previous_camera=prev)
    quad = np.isin(off.triangle_id, (scene.triangle_count - 2, scene.triangle_count - 1))
    assert quad.sum() > 20 and np.abs(off.velocity[quad][:, 0]).min() > 8 > np.abs(off.velocity[~quad][:, 0]).max()
    np.testing.assert_array_equal(on.velocity, off.velocity)
    np.testing.assert_allclose(on.color, reference_motion_blur(off.color, off.velocity, off.linear_depth, 1.0, 6), rtol=1e-5, atol=1e-6)
    assert (np.abs(on.color - off.color).max(-1) > 1e-3).mean() > 0.5 and "motion_blur_ms" in on.stats
    assert_no_device_diagnostics(capfd)


# -- renderer variants (docs/variants.md): light pre-pass, multisampled colour, light-indexed -----------

def test_pipeline_variant_kernels(device, capfd):
    """The light pre-pass (thin G-buffer, light_buffer.cl in float and half with RGB and luminance
    specular, the raster again, material.cl; msaa=4: the raster at every sample, material_samples) and light-indexed
    (depth-only G-buffer, forward_shade.cl) on a tiny frame with a shadowed spot, a shadowed sun
    and a masked, textured quad, against the deferred frame: light-indexed bit-identical, the light
    pre-pass within 1e-5 of the peak (RGB), the others within their own bounds."""
    scene = masked_quad_scene()
    scene.add_spot_light((0.3, 0.2, -1.0), (0.0, 0.0, -1.0), (3.0, 1.0, 0.5), 8.0, 20.0, 40.0, shadow=True,
                         shadow_map_size=24)
    scene.add_point_light((0.5, 0.2, -2.0), (0.5, 1.5, 2.0), 2.5)
    scene.set_sun((0.3, -0.2, -1.0), (1.0, 1.0, 1.0), shadow_map_size=16)
    cam = Camera.look_at((0, 0, 0), (0, 0, -1), fov_y_deg=60, near=0.1, far=50)
    opts = dict(device=device.id, tile_size=8, light_tile_size=8, sun_cascades=1)
    deferred = clrender.Renderer(19, 13, **opts).render(scene, cam)
    indexed = clrender.Renderer(19, 13, pipeline="light_indexed", **opts).render(scene, cam)
    for name in ("color", "gbuffer", "shadow", "light_count"):
        np.testing.assert_array_equal(getattr(indexed, name), getattr(deferred, name), err_msg=name)
    peak = float(deferred.color.max())
    assert peak > 0.1
    for extra, rel in ((dict(), 1e-5), (dict(light_buffer_precision="float16"), 1e-3),
                       (dict(light_buffer_specular="luminance"), 0.3)):
        prepass = clrender.Renderer(19, 13, pipeline="light_prepass", **extra, **opts).render(scene, cam)
        np.testing.assert_array_equal(prepass.gbuffer, deferred.gbuffer)
        assert np.abs(prepass.color - deferred.color).max() <= rel * peak, extra
    msaa = clrender.Renderer(19, 13, pipeline="light_prepass", msaa=4, **opts).render(scene, cam)
    np.testing.assert_array_equal(msaa.gbuffer, deferred.gbuffer)
    changed = np.abs(msaa.color - deferred.color).max(-1) > 1e-5 * peak
    assert 0 < changed.mean() < 0.5, "only edge pixels change"
    assert_no_device_diagnostics(capfd)


def test_material_feature_kernels(device, capfd):
    """The glTF material paths of the resolve (material_eval.h) and the shading (emission,
    occlusion, unlit; gbuffer_decode.h) on a 12x12 frame: a quad with constant metallic-roughness,
    normal, occlusion and emissive textures read through a texture transform and TEXCOORD_1, with
    vertex colours, next to an unlit quad; deferred and light-indexed give the same bits, and the
    decoded G-buffer equals the documented mapping (docs/materials.md) of the constant texels."""
    from clrender.scene.model import UVTransform, metallic_roughness_to_blinn_phong

    def const(rgba, srgb):
        return Texture("c", np.broadcast_to(np.asarray(rgba, np.uint8), (2, 2, 4)).copy(), srgb=srgb)

    quads = np.array([[-1, -1, -3], [0, -1, -3], [0, 1, -3], [-1, 1, -3],
                      [0, -1, -3], [1, -1, -3], [1, 1, -3], [0, 1, -3]], np.float32)
    uvs = np.array([[0, 1], [1, 1], [1, 0], [0, 0]] * 2, np.float32)
    tris = np.array([[0, 1, 2], [0, 2, 3], [4, 5, 6], [4, 6, 7]], np.int32)
    shifted = UVTransform(texcoord=1, offset=(0.25, 0.5), rotation=0.3, scale=(2.0, 0.5))
    lit = Material("pbr", (0.9, 0.8, 0.7, 1.0), metallic=0.8, roughness=0.9, metallic_roughness_texture=0,
                   normal_texture=1, occlusion_texture=2, occlusion_strength=0.5, emissive=(0.2, 0.4, 0.6),
                   emissive_texture=3, emissive_strength=3.0, metallic_roughness_uv=shifted, normal_uv=shifted)
    unlit = Material("unlit", (0.3, 0.6, 0.9, 1.0), unlit=True)
    textures = [const((0, 128, 255, 255), False), const((128, 128, 255, 255), False),
                const((51, 0, 0, 255), False), const((255, 255, 255, 255), True)]
    scene = Scene(quads, np.tile([[0, 0, 1]], (8, 1)), uvs, tris, np.array([0, 0, 1, 1], np.int32),
                  materials=[lit, unlit], textures=textures, colors=np.tile([[1.0, 0.5, 1.0, 1.0]], (8, 1)),
                  extra_uvs=uvs[None] * 0.5)
    scene.add_point_light((0.0, 0.0, -1.0), (2.0, 2.0, 2.0), 5.0)
    cam = Camera.look_at((0, 0, 0), (0, 0, -1), fov_y_deg=60, near=0.1, far=50)
    # the documented Blinn-Phong mapping (the glTF BRDF's kernels: test_environment_and_gltf_brdf_kernels)
    opts = dict(device=device.id, tile_size=8, light_tile_size=8, shading="blinn_phong")
    deferred = clrender.Renderer(12, 12, **opts).render(scene, cam)
    indexed = clrender.Renderer(12, 12, pipeline="light_indexed", **opts).render(scene, cam)
    np.testing.assert_array_equal(deferred.gbuffer, indexed.gbuffer)
    np.testing.assert_array_equal(deferred.color, indexed.color)

    ids = deferred.triangle_id
    pbr, flat = np.isin(ids, (0, 1)), np.isin(ids, (2, 3))
    assert pbr.sum() > 12 and flat.sum() > 12
    m, r = 0.8 * 1.0, 0.9 * 128 / 255
    base = np.array([0.9, 0.4, 0.7])
    si, sp = metallic_roughness_to_blinn_phong(base, m, r)
    np.testing.assert_allclose(deferred.albedo[pbr], np.broadcast_to(base * (1 - m), (pbr.sum(), 3)), atol=4e-3)
    np.testing.assert_allclose(deferred.specular_intensity[pbr], si, atol=1 / 255)
    np.testing.assert_allclose(np.log2(deferred.specular_power[pbr]), np.log2(sp), atol=11 / 255)
    # texel 128 encodes 2·128/255 - 1 = 0.004 along T and B
    np.testing.assert_allclose(deferred.normal[pbr], np.broadcast_to((0, 0, 1), (pbr.sum(), 3)), atol=6e-3)
    np.testing.assert_allclose(deferred.occlusion[pbr], 1 + 0.5 * (51 / 255 - 1), atol=1 / 255)
    np.testing.assert_allclose(deferred.emissive[pbr], np.broadcast_to((0.2, 0.4, 0.6), (pbr.sum(), 3)), atol=4e-3)
    # unlit: base colour × vertex colour (1, 0.5, 1), no light
    np.testing.assert_allclose(deferred.color[flat], np.broadcast_to((0.3, 0.3, 0.9), (flat.sum(), 3)), atol=4e-3)
    assert (deferred.color[pbr] >= 3.0 * deferred.emissive[pbr] - 1e-5).all()

    # The same slots read through a white base colour texture's footprint (sample_slot_shared), the
    # occlusion and metallic-roughness images merged into one ORM texture by the upload: same planes.
    from dataclasses import replace
    scene.textures = textures + [const((255, 255, 255, 255), True)]
    scene.materials = [replace(lit, base_color_texture=4, metallic_roughness_uv=UVTransform(),
                               normal_uv=UVTransform()), unlit]
    from clrender.render.scene_upload import device_materials
    flags = device_materials(scene)[1]["flags"][0]
    assert flags & (15 << 5) == 15 << 5, "every slot must share the base colour's footprint"
    shared = clrender.Renderer(12, 12, **opts).render(scene, cam)
    np.testing.assert_array_equal(shared.gbuffer, deferred.gbuffer)
    assert_no_device_diagnostics(capfd)


# --- the glTF BRDF and image-based lighting (tests/test_brdf.py, tests/test_ibl_shading.py) -------

def _gltf_spheres_with_environment():
    """Two glTF spheres (a rough dielectric, a smooth metal), a transparent glTF sphere in front, a
    Blinn-Phong floor, a point light with KHR inverse-square falloff, and a small HDR environment."""
    from reference.geometry import uv_sphere
    parts = [uv_sphere(6, 12, radius=0.6, center=c) for c in ((-0.7, 0, -3), (0.7, 0, -3))]
    parts.append(uv_sphere(3, 6, radius=0.35, center=(0, -0.2, -1.8)))     # within the first lists' room
    floor = np.array([[-3, -0.7, -1], [3, -0.7, -1], [3, -0.7, -6], [-3, -0.7, -6]], np.float32)
    pos = np.concatenate([p for p, _, _ in parts] + [floor])
    nrm = np.concatenate([n for _, _, n in parts] + [np.tile([[0, 1, 0]], (4, 1))]).astype(np.float32)
    faces, mats, base = [], [], 0
    for k, (p, f, _) in enumerate(parts):
        faces.append(f + base)
        mats.append(np.full(len(f), k))
        base += len(p)
    faces.append(np.array([[0, 1, 2], [0, 2, 3]]) + base)
    mats.append(np.full(2, 3))
    scene = Scene(pos, nrm, np.zeros((len(pos), 2), np.float32), np.concatenate(faces),
                  np.concatenate(mats).astype(np.int32),
                  materials=[Material("rough", (0.8, 0.3, 0.2, 1), metallic=0.0, roughness=0.7),
                             Material("metal", (0.9, 0.7, 0.3, 1), metallic=1.0, roughness=0.2),
                             Material("glass", (0.6, 0.8, 1.0, 1), metallic=0.0, roughness=0.1, opacity=0.5),
                             Material("floor", (0.5, 0.5, 0.5, 1))])
    scene.add_point_light((0, 1.5, -1.5), (4, 4, 4), 6.0)
    scene.lights["falloff"][-1] = clrender.abi.structs.FALLOFF_INVERSE_SQUARE
    d = np.random.default_rng(4).uniform(0.2, 1.5, (8, 16, 3)).astype(np.float32)
    d[1, 5] = 30.0                                          # a small bright sun
    scene.set_environment(d, rotation_deg=40.0)
    return scene


@pytest.mark.parametrize("options", [dict(), dict(pipeline="light_prepass", msaa=2),
                                     dict(pipeline="light_indexed", transparency="depth_peeling", peel_layers=2)])
def test_environment_and_gltf_brdf_kernels(device, capfd, monkeypatch, options):
    """ibl.cl (mip chain, prefilter, SH, DFG), and the environment and the glTF BRDF in shade.cl,
    light_buffer.cl + material.cl, forward_shade.cl and the transparent fragments, on 24x16. The
    DFG table is 8x8 with 8x4 quadrature nodes here (64x64 with 64x16 takes minutes in Oclgrind;
    the same kernel either way: tests/test_ibl.py checks the full table), and the prefilter takes
    16-32 GGX samples per texel (a runtime count: the default 512-4096 took ~4 min of Oclgrind)."""
    import clrender.passes.ibl as ibl
    monkeypatch.setattr(ibl, "DFG_SIZE", 8)
    monkeypatch.setattr(ibl, "DFG_SAMPLES", (8, 4))
    monkeypatch.setattr(ibl, "PREFILTER_SAMPLES", (16, 16, 32, 32, 32))
    scene = _gltf_spheres_with_environment()
    cam = Camera.look_at((0, 0.3, 0.5), (0, 0, -3), near=0.1, far=20)
    frame = clrender.Renderer(24, 16, device=device.id, tile_size=8, light_tile_size=8, **options).render(scene, cam)
    fg = frame.triangle_id >= 0
    assert fg.any() and (~fg).any() and "ibl_ms" in frame.stats
    assert np.isfinite(frame.color).all() and (frame.color[fg] > 0).any(-1).all()   # lit, every surface pixel
    assert (frame.shading_model[fg] >= 0).all() and (frame.shading_model == 1).any()
    bg = ~fg & (frame.fragment_count == 0)
    assert bg.any() and (frame.color[bg] > 0).all()          # the environment behind
    assert_no_device_diagnostics(capfd)


@pytest.mark.filterwarnings("ignore:.*skin weights that do not sum to 1")
def test_skinned_and_morph_pose_kernels(device, capfd, tmp_path):
    """pose.cl (morph targets then 8 influences over two weight sets, a mirrored skin, tangents and
    the previous pose) on a generated rig, against the NumPy reference, then a 24x16 frame of it
    with the velocity of the two poses."""
    from test_skinning import rigged_file
    from reference.skinning_reference import GltfReference
    path, node = rigged_file(tmp_path, seed=31, influences=8, mirrored=True)
    scene, ref = clrender.load_scene(path), GltfReference(path)
    scene.set_environment(None)          # no default studio environment: its precompute is ibl.cl's test
    scene.add_point_light((0, 0, 3), (2, 2, 2), 10.0)
    scene.pose(0.7, dt=0.05)
    r = clrender.Renderer(24, 16, device=device.id, tile_size=8, light_tile_size=8)
    got = r.posed_vertices(scene)
    d = scene.deformation.deformers[0]
    sl = slice(d.first, d.first + d.count)
    for name, t in (("positions", 0.7), ("previous_positions", 0.65)):
        p = ref.pose(node, 0, t)[0]
        np.testing.assert_allclose(got[name][sl], p, atol=3e-5 * max(1.0, np.abs(p).max()))
    _, n, tg = ref.pose(node, 0, 0.7)
    np.testing.assert_allclose(got["normals"][sl], n, atol=3e-5)
    np.testing.assert_allclose(got["tangents"][sl], tg, atol=3e-5)
    lo, hi = got["positions"][sl].min(0), got["positions"][sl].max(0)
    c = (lo + hi) / 2
    cam = Camera.look_at(c + np.array([0.2, 0.3, 1.0]) * 1.1 * np.linalg.norm(hi - lo), c, near=0.1, far=100)
    frame = r.render(scene, cam)
    fg = frame.triangle_id >= 0
    assert fg.mean() > 0.05 and "pose_ms" not in frame.stats      # posed_vertices posed it: no second run
    assert np.isfinite(frame.velocity[fg]).all() and np.abs(frame.velocity[fg]).max() > 0.1
    assert_no_device_diagnostics(capfd)
