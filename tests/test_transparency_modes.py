"""Transparency modes and limits against the reference (docs/transparency.md): order independence
(shuffled transparent triangles: bit-identical), depth peeling (== A-buffer bit for bit with enough
layers, == the reference truncated to N layers with fewer), max_fragments_per_pixel, overflow
(200 fragments per pixel; > 1M fragments; retries), opaque scenes unchanged by the transparency
mode, the Khronos AlphaBlendModeTest scene, bad input.
"""
from __future__ import annotations

import os

import numpy as np
import pytest

import clrender
from clrender import Material, Scene
from clrender.scene.model import SceneError
from reference import shading as ref_shading
from reference import transparency as ref
from reference.raster import coverage_count
from transparency_cases import (CAMERA, COLOR_TOL, PX_CAM, TRANSMITTANCE_TOL, H, W, assert_matches_reference,
                                build_scene, expected, point_lights, quad, random_soup, screen_quad,
                                shuffled_transparent, wall)

KHRONOS = os.path.join(os.path.dirname(__file__), "..", "..", "shared", "scenes", "khronos-AlphaBlendModeTest",
                       "AlphaBlendModeTest.gltf")


_FRAMES = {}


def render(make_renderer, device, key, scene, width=W, height=H, camera=CAMERA, **opts):
    full = (device.id, key, width, height, repr(sorted(opts.items())))
    if full not in _FRAMES:
        _FRAMES[full] = make_renderer(width, height, **opts).render(scene, camera)
    return _FRAMES[full]


SEEDS = (3, 11, 2024)


@pytest.mark.parametrize("seed", SEEDS)
def test_abuffer_is_not_black(make_renderer, device, seed):
    """Whatever the reference says: where transparent layers are, the frame shows them."""
    scene = random_soup(seed, n_transparent=8)
    frame = render(make_renderer, device, ("soup", seed), scene)
    exp, ok = expected(frame, scene)
    layered = exp.fragment_count > 0
    assert layered.mean() > 0.1, "the soup must cover a good part of the frame"
    assert np.all(frame.fragment_count[layered] > 0), "fragment_count must be non-zero where layers are"
    assert np.all(frame.transmittance[layered] < 1.0), "layers with alpha >= 0.05 must absorb"
    assert frame.color[layered].max() > 0.05
    # the layers change the colour: compared with the opaque colour alone
    opaque = ref_shading.shade_frame(frame, CAMERA, scene.lights, scene.ambient)
    change = np.abs(frame.color.astype(np.float64) - opaque).max(-1)
    expect_change = np.abs(exp.color - opaque).max(-1)
    visible = layered & (expect_change > 0.02 * exp.color.max())
    assert visible.sum() > 50
    assert np.all(change[visible] > 0.5 * expect_change[visible]), "transparent layers missing from the colour"
    # the image is the tone-mapped blend
    diff = np.abs(frame.image.astype(int) - ref_shading.tonemap(frame.color, "reinhard").astype(int))
    assert diff.max() <= 1 and frame.image[layered].max() > 20


@pytest.mark.parametrize("seed", SEEDS)
def test_order_independence(make_renderer, device, seed):
    scene = random_soup(seed, n_transparent=10)
    base = render(make_renderer, device, ("soup10", seed), scene)
    assert base.fragment_count.max() >= 2
    for k in range(2):
        shuffled, perm = shuffled_transparent(scene, seed + 100 * k)
        assert not np.array_equal(perm, np.arange(len(perm)))
        got = make_renderer(W, H).render(shuffled, CAMERA)
        np.testing.assert_array_equal(got.color, base.color, err_msg="shuffling transparent triangles changed color")
        np.testing.assert_array_equal(got.transmittance, base.transmittance)
        np.testing.assert_array_equal(got.fragment_count, base.fragment_count)
        np.testing.assert_array_equal(got.gbuffer, base.gbuffer)


@pytest.mark.parametrize("seed", SEEDS)
def test_depth_peeling(make_renderer, device, seed):
    scene = random_soup(seed, n_transparent=10)
    abuf = render(make_renderer, device, ("soup10", seed), scene)
    n_max = int(abuf.fragment_count.max())
    assert n_max >= 3, "the soup needs pixels with several layers"
    full = render(make_renderer, device, ("soup10", seed), scene, transparency="depth_peeling", peel_layers=n_max)
    np.testing.assert_array_equal(full.color, abuf.color, err_msg=f"{n_max} peels must equal the A-buffer bit for bit")
    np.testing.assert_array_equal(full.transmittance, abuf.transmittance)
    np.testing.assert_array_equal(full.fragment_count, abuf.fragment_count)
    np.testing.assert_array_equal(full.gbuffer, abuf.gbuffer)
    more = render(make_renderer, device, ("soup10", seed), scene, transparency="depth_peeling", peel_layers=64)
    np.testing.assert_array_equal(more.color, abuf.color)
    for n in (1, 2):
        few = render(make_renderer, device, ("soup10", seed), scene, transparency="depth_peeling", peel_layers=n)
        exp, ok = expected(few, scene, layers=n)
        assert_matches_reference(few, scene, exp, ok, f"soup {seed}, {n} peels")
        assert (exp.fragment_count > n).sum() > 20
        deeper = exp.fragment_count > n
        assert np.abs(few.color - abuf.color)[deeper].max() > 1e-3 * abuf.color.max(), \
            f"{n} peels must differ from the full A-buffer where pixels have more layers"


@pytest.mark.parametrize("seed", SEEDS[:2])
def test_max_fragments_per_pixel(make_renderer, device, seed):
    scene = random_soup(seed, n_transparent=10)
    abuf = render(make_renderer, device, ("soup10", seed), scene)
    n_max = int(abuf.fragment_count.max())
    assert n_max >= 3
    for k in (1, n_max - 1):
        capped = render(make_renderer, device, ("soup10", seed), scene, max_fragments_per_pixel=k)
        exp, ok = expected(capped, scene, layers=k)
        assert_matches_reference(capped, scene, exp, ok, f"soup {seed}, max_fragments_per_pixel={k}")
        dropped = int(np.maximum(exp.fragment_count.astype(np.int64) - k, 0).sum())
        assert dropped > 0
        assert capped.stats.get("fragments_dropped") == dropped, (
            f"stats['fragments_dropped'] = {capped.stats.get('fragments_dropped')!r}, expected {dropped}")
    uncapped = render(make_renderer, device, ("soup10", seed), scene, max_fragments_per_pixel=64)
    np.testing.assert_array_equal(uncapped.color, abuf.color)
    assert uncapped.stats.get("fragments_dropped", 0) == 0 and abuf.stats.get("fragments_dropped", 0) == 0


# -- overflow: long lists and retries ---------------------------------------------------------------

def test_200_fragments_per_pixel(device):
    """200 stacked layers over a region (in random id order): the long-list sort stays exact."""
    size = 32
    rng = np.random.default_rng(7)
    depths = 2.0 + 0.03 * rng.permutation(200)                # distinct depths, ids in random depth order
    parts = [(screen_quad(0, size, 0, size, 12.0), None,
              Material("wall", (0.8, 0.8, 0.8, 1.0), specular_intensity=0.3, specular_power=8.0))]
    mats = [Material(f"film{k}", (*rng.uniform(0.1, 1.0, 3), float(rng.uniform(0.01, 0.03))), alpha_mode="BLEND",
                     specular_intensity=0.3, specular_power=12.0) for k in range(8)]
    for k, d in enumerate(depths):
        parts.append((screen_quad(6, 26, 4, 28, d), None, mats[k % len(mats)]))
    scene = build_scene(parts, lights=point_lights([((1.0, 0.5, -1.0), (2.0, 1.8, 1.5), 20.0)]))
    renderer = clrender.Renderer(size, size, device=device.id)
    frame = renderer.render(scene, PX_CAM)
    exp, ok = expected(frame, scene, camera=PX_CAM, width=size, height=size)
    assert exp.fragment_count.max() == 200 and (exp.fragment_count == 200).sum() == 20 * 24
    assert exp.transmittance.min() > 1e-3, "every layer must count (no early stop)"
    assert_matches_reference(frame, scene, exp, ok, "200 layers")
    assert frame.stats.get("retries", 0) >= 1, "a fresh renderer's A-buffer must grow (retry) for 96000 fragments"
    again = renderer.render(scene, PX_CAM)                    # the grown buffer: no retry, the same bits
    assert again.stats.get("retries", 0) == 0
    np.testing.assert_array_equal(again.color, frame.color)
    np.testing.assert_array_equal(again.transmittance, frame.transmittance)
    peeled = clrender.Renderer(size, size, device=device.id, transparency="depth_peeling",
                               peel_layers=3).render(scene, PX_CAM)
    exp3, ok3 = expected(peeled, scene, camera=PX_CAM, width=size, height=size, layers=3)
    assert_matches_reference(peeled, scene, exp3, ok3, "200 layers, 3 peels")


def test_more_than_a_million_fragments(device):
    """256x256 with 20 full-screen layers (1,310,720 fragments): exact counts, colour analytic."""
    size, n = 256, 20
    rng = np.random.default_rng(11)
    depths = 2.0 + 0.25 * rng.permutation(n)
    amb = 0.25
    wall_m = Material("wall", (0.6, 0.7, 0.8, 1.0), specular_intensity=0.0)
    mats = [Material(f"layer{k}", (*rng.uniform(0.1, 1.0, 3), float(rng.uniform(0.1, 0.25))), alpha_mode="BLEND",
                     specular_intensity=0.0) for k in range(n)]
    big = lambda d: np.array([[[-2 * d, -2 * d, -d], [2 * d, -2 * d, -d], [2 * d, 2 * d, -d]],
                              [[-2 * d, -2 * d, -d], [2 * d, 2 * d, -d], [-2 * d, 2 * d, -d]]])
    parts = [(big(10.0), None, wall_m)] + [(big(d), None, mats[k]) for k, d in enumerate(depths)]
    scene = build_scene(parts, ambient=amb)
    frame = clrender.Renderer(size, size, device=device.id).render(scene, PX_CAM)
    assert (frame.fragment_count == n).all(), f"fragment_count: {np.unique(frame.fragment_count)} (expected all {n})"
    # analytic: layers front to back, ambient only
    acc, T = np.zeros(3), 1.0
    for k in np.argsort(depths):
        a = mats[k].base_color[3]
        acc += T * a * np.asarray(mats[k].base_color[:3]) * np.float32(amb)
        T *= 1 - a
    # the wall's colour comes from the G-buffer's (8-bit sRGB) albedo: ambient · decoded albedo
    assert np.all(frame.albedo == frame.albedo[0, 0])
    expect = acc + T * frame.albedo[0, 0].astype(np.float64) * np.float32(amb)
    assert T > 1e-3
    np.testing.assert_allclose(frame.color.reshape(-1, 3), np.broadcast_to(expect, (size * size, 3)),
                               rtol=0, atol=COLOR_TOL * expect.max())
    np.testing.assert_allclose(frame.transmittance, T, rtol=0, atol=TRANSMITTANCE_TOL)
    assert frame.stats.get("retries", 0) >= 1
    # and the reference on a subsample of pixels
    pixels = np.zeros((size, size), bool)
    pixels[::37, ::23] = True
    exp, ok = expected(frame, scene, camera=PX_CAM, width=size, height=size, pixels=pixels)
    assert (exp.fragment_count == n).all()
    err = np.abs(frame.color[pixels].astype(np.float64) - exp.color[pixels])
    assert err.max() <= COLOR_TOL * expect.max()


# -- opaque scenes are unchanged -------------------------------------------------------------------------

def test_opaque_scene_identical_in_every_mode(make_renderer, device):
    rng = np.random.default_rng(5)
    parts = [wall()]
    for k in range(6):
        m = Material(f"opaque{k}", (*rng.uniform(0.2, 1.0, 3), 1.0), specular_intensity=0.3, specular_power=16.0)
        v = rng.uniform((-3, -2, -9), (3, 2, -3), (2, 3, 3))
        parts.append((v, None, m))
    # MASK materials stay opaque too
    parts.append((quad(-1, 1, -1, 1, -4.0), None, Material("mask", (0.9, 0.9, 0.1, 1.0), alpha_mode="MASK")))
    scene = build_scene(parts, lights=point_lights([((0.0, 1.0, -2.0), (2.0, 2.0, 2.0), 9.0)]))
    frames = {mode: make_renderer(W, H, transparency=mode).render(scene, CAMERA)
              for mode in ("abuffer", "depth_peeling", "screen_door")}
    base = frames["abuffer"]
    assert (base.triangle_id >= 0).all() and base.color.max() > 0.1
    for mode, f in frames.items():
        np.testing.assert_array_equal(f.color, base.color, err_msg=mode)
        np.testing.assert_array_equal(f.gbuffer, base.gbuffer, err_msg=mode)
        np.testing.assert_array_equal(f.image, base.image, err_msg=mode)
        assert np.all(f.fragment_count == 0) and np.all(f.transmittance == 1.0), mode
        assert f.stats.get("transparent", 0) == 0
        launched = [k for k in f.stats if k.endswith("_ms") and k.split("_")[0] in ("fragments", "abuffer", "peel",
                                                                                    "composite")]
        assert not launched, f"{mode}: an opaque scene launched transparency kernels: {launched}"


# -- the Khronos AlphaBlendModeTest scene -------------------------------------------------------------------

def test_khronos_alpha_blend_mode(make_renderer, device):
    if not os.path.exists(KHRONOS):
        pytest.skip(f"Khronos AlphaBlendModeTest not found at {os.path.normpath(KHRONOS)} (../shared/scenes)")
    scene = clrender.load_scene(KHRONOS)
    cam = scene.default_camera()
    w, h = 96, 64
    frame = make_renderer(w, h).render(scene, cam)
    blend_tri = ref.blend_mask(scene)
    mask_tri = np.array([scene.materials[m].alpha_mode == "MASK" for m in scene.triangle_material])
    assert blend_tri.sum() > 0 and mask_tri.sum() > 0
    assert frame.stats.get("transparent") == int(blend_tri.sum())
    # BLEND triangles are not in the G-buffer
    assert not np.isin(frame.triangle_id, np.flatnonzero(blend_tri)).any()
    # their coverage (reference raster on the BLEND triangles alone, plain double-sided materials)
    sub = np.flatnonzero(blend_tri)
    plain = [Material(f"p{k}", double_sided=m.double_sided) for k, m in enumerate(scene.materials)]
    covered = coverage_count(Scene(scene.positions, scene.normals, scene.uvs, scene.triangles[sub],
                                   scene.triangle_material[sub], plain), cam, w, h)
    assert (covered > 0).sum() > 50
    fc = frame.fragment_count
    assert np.all(fc <= covered), "fragments only where BLEND triangles cover"
    assert (fc[covered > 0] >= 1).mean() > 0.9, "the BLEND quads lie in front of the bed: fragments there"
    with_frag = fc > 0
    assert np.all(frame.transmittance[~with_frag] == 1.0)
    assert np.all(frame.transmittance <= 1.0) and np.all(frame.transmittance >= 0.0)
    assert (frame.transmittance[with_frag] < 1.0).mean() > 0.5, "BLEND quads absorb where their texture has alpha"
    # MASK quads are opaque: their ids show where alpha >= cutoff, and they make no fragments
    for m in np.unique(scene.triangle_material[mask_tri]):
        ids = np.flatnonzero(scene.triangle_material == m)
        shown = np.isin(frame.triangle_id, ids)
        assert shown.sum() > 10, f"MASK material {scene.materials[m].name} never shows"
        assert np.all(fc[shown & (covered == 0)] == 0)
    assert np.isfinite(frame.color).all() and frame.color.max() > 0


# -- bad input ---------------------------------------------------------------------------------------------

@pytest.mark.parametrize("value", [float("nan"), -0.1, 1.5, float("inf")])
def test_bad_opacity_is_a_scene_error(value):
    with pytest.raises(SceneError, match="frosted"):
        Material("frosted", (1, 1, 1, 1), opacity=value)


def test_mask_with_opacity_is_a_scene_error():
    with pytest.raises(SceneError, match="leaf"):
        Material("leaf", (1, 1, 1, 1), alpha_mode="MASK", opacity=0.5)


@pytest.mark.parametrize("value", [float("nan"), -0.5])
def test_bad_refraction_is_a_scene_error(value):
    with pytest.raises(SceneError, match="prism"):
        Material("prism", (1, 1, 1, 1), opacity=0.5, refraction=value)


@pytest.mark.parametrize("option,value", [("transparency", "weighted_oit"), ("peel_layers", 0), ("peel_layers", 65),
                                          ("peel_layers", 2.0), ("max_fragments_per_pixel", -1),
                                          ("refraction", 1)])
def test_bad_transparency_options(option, value):
    from clrender.render.renderer import RenderConfig
    with pytest.raises(ValueError, match=option):
        RenderConfig.from_options(**{option: value})
