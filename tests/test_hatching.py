"""Hatching (report IV.3, Praun et al. 2001): the tonal art maps' nesting and tones
(clrender/tam.py), and kernels/hatching.cl through the Renderer against an independent NumPy
version of its per-pixel formula (docs/post.md's LDR chain)."""
from __future__ import annotations

import math

import numpy as np
import pytest

from clrender import Camera, Material, Scene, tam
from clrender.gbuffer import linear_to_srgb8
from clrender.passes.hatching import mip_levels
from reference.shading import tonemap_curve

LUMA = np.array([0.2126, 0.7152, 0.0722])          # linear Rec. 709 / sRGB luminance


# --- the tonal art map ---------------------------------------------------------------------------

def test_tam_shapes_and_range():
    maps = tam.tonal_art_map()
    assert len(maps) == tam.TONES == 7
    for tone in maps:
        assert len(tone) == tam.LEVELS
        for level, m in enumerate(tone):
            n = tam.SIZE >> level
            assert m.shape == (n, n) and m.dtype == np.float32
            assert 0.0 <= m.min() and m.max() <= 1.0
    flat = tam.device_layout()
    assert flat.size == tam.TONES * tam.LEVEL_TEXELS and flat.nbytes == tam.DEVICE_BYTES
    # the device layout: tone-major, levels from level 0 at the documented offsets
    for t in (0, 3, 6):
        for level in (0, 1, 5, tam.LEVELS - 1):
            n = tam.SIZE >> level
            start = t * tam.LEVEL_TEXELS + tam.level_offset(level)
            np.testing.assert_array_equal(flat[start:start + n * n].reshape(n, n), maps[t][level])


def test_tam_nesting_at_every_level():
    """Every inked texel of tone t is inked in tone t + 1, at every mip level; stronger, the
    coverage never decreases texel by texel (what makes the blended ink monotone)."""
    maps = tam.tonal_art_map()
    for t in range(tam.TONES - 1):
        for level in range(tam.LEVELS):
            lighter, darker = maps[t][level], maps[t + 1][level]
            assert not np.any((lighter > 0) & (darker == 0)), (t, level)
            assert np.all(darker >= lighter), (t, level)
            if level < 4:                       # the new strokes really add ink at this level
                assert np.count_nonzero(darker > lighter) > 0.05 * darker.size, (t, level)


def test_tam_coverage_strictly_increases_with_tone():
    maps = tam.tonal_art_map()
    for level in range(tam.LEVELS):
        means = np.array([maps[t][level].mean(dtype=np.float64) for t in range(tam.TONES)])
        assert means[0] == 0.0, "tone 0 is blank paper"
        assert np.all(np.diff(means) > 0.1), (level, means)
        assert means[-1] > 0.9, means
    # coverage tracks the tone targets (mean of level 0 within one stroke's worth of ink)
    level0 = np.array([maps[t][0].mean(dtype=np.float64) for t in range(tam.TONES)])
    np.testing.assert_allclose(level0, tam.TARGETS, atol=0.01)


def test_tam_mips_are_box_filtered():
    maps = tam.tonal_art_map()
    for t in (1, 4, 6):
        for level in range(1, tam.LEVELS):
            fine = maps[t][level - 1].astype(np.float64)
            n = fine.shape[0] // 2
            np.testing.assert_allclose(maps[t][level], fine.reshape(n, 2, n, 2).mean(axis=(1, 3)), rtol=0, atol=1e-6)


def test_tam_is_tileable_and_stroked():
    """Strokes wrap around the tile edges: across the seam neighbouring texels agree as well as
    inside; and the map is strokes (mostly blank or inked texels), not a flat grey."""
    m = tam.tonal_art_map()[2][0].astype(np.float64)
    inside = np.abs(np.diff(m, axis=1)).mean()
    seam = np.abs(m[:, 0] - m[:, -1]).mean()
    assert seam < 1.5 * inside, (seam, inside)
    inside_v = np.abs(np.diff(m, axis=0)).mean()
    assert np.abs(m[0] - m[-1]).mean() < 1.5 * inside_v
    assert ((m < 0.05) | (m > 0.6)).mean() > 0.7         # anti-aliased edges are the rest


def test_tam_is_deterministic():
    first = tam.device_layout().copy()
    tam.tonal_art_map.cache_clear()
    tam.device_layout.cache_clear()
    np.testing.assert_array_equal(tam.device_layout(), first)


def test_mip_level_choice():
    assert mip_levels(1.0) == (0, 1.0, 1, 0.5, 0.0)
    assert mip_levels(3.0)[::2] == (0, 1, 0.0)                 # magnified: level 0 only
    assert mip_levels(0.5) == (1, 1.0, 2, 0.5, 0.0)
    level0, k0, level1, k1, frac = mip_levels(0.7)
    assert (level0, level1) == (0, 1) and frac == pytest.approx(math.log2(1 / 0.7))
    assert k0 == pytest.approx(1 / 0.7) and k1 == pytest.approx(1 / 1.4)
    assert mip_levels(1e-4)[0] == tam.LEVELS - 1 and mip_levels(1e-4)[4] == 0.0


# --- the per-pixel formula, independently in NumPy ---------------------------------------------

def hatching_reference(ldr: np.ndarray, scale: float, saturation: float) -> np.ndarray:
    """(H, W, 3) hatched linear colour for tone-mapped linear `ldr` (H, W, 3), float64.

    Y = clamp(luma(c), 0, 1), tone = 6(1 - Y) blended between its two nearest tones' maps, each
    sampled bilinearly (wrapped) at ((x + ½)/s, (y + ½)/s) level-0 texels on mip level
    log2(1/s) (trilinear, clamped to [0, last level]); out = (1 + sat·(c - 1))·(1 - ink)."""
    maps = tam.tonal_art_map()
    h, w = ldr.shape[:2]
    luma = np.clip(ldr.astype(np.float64) @ LUMA, 0.0, 1.0)
    tone = (1.0 - luma) * 6.0
    t = np.minimum(np.floor(tone), 5).astype(int)
    f = tone - t
    lam = min(max(-math.log2(scale), 0.0), tam.LEVELS - 1)
    levels = [(int(lam), 1.0 - (lam - int(lam)))]
    if lam > int(lam):
        levels.append((int(lam) + 1, lam - int(lam)))

    def sample(tones: np.ndarray) -> np.ndarray:
        ink = np.zeros((h, w))
        for level, weight in levels:
            stack = np.stack([maps[k][level] for k in range(tam.TONES)]).astype(np.float64)
            n = stack.shape[1]
            u = (np.arange(w) + 0.5) / (scale * 2**level) - 0.5
            v = (np.arange(h) + 0.5) / (scale * 2**level) - 0.5
            iu, iv = np.floor(u).astype(int), np.floor(v).astype(int)
            wu, wv = (u - iu)[None, :], (v - iv)[:, None]
            cols0, cols1 = iu % n, (iu + 1) % n
            rows0, rows1 = (iv % n)[:, None], ((iv + 1) % n)[:, None]
            top = stack[tones, rows0, cols0] * (1 - wu) + stack[tones, rows0, cols1] * wu
            bottom = stack[tones, rows1, cols0] * (1 - wu) + stack[tones, rows1, cols1] * wu
            ink += weight * (top * (1 - wv) + bottom * wv)
        return ink

    ink = sample(t) * (1 - f) + sample(t + 1) * f
    return (1.0 + saturation * (ldr - 1.0)) * (1.0 - ink)[..., None]


def coloured_scene() -> Scene:
    from test_supersample import hard_edged_scene
    return hard_edged_scene()


COLOURED_CAMERA = Camera.look_at((0, 0, 0), (0, 0, -1), fov_y_deg=70.0, near=0.1, far=50.0)


@pytest.mark.parametrize("scale,saturation", [(1.0, 0.3), (0.7, 0.0), (2.5, 1.0), (0.25, 0.3), (1e-3, 0.5)])
def test_matches_numpy_formula(make_renderer, scale, saturation):
    """Frame.image equals the NumPy formula applied to the tone-mapped Frame.color, within one
    8-bit code; scales cover level 0, trilinear levels 0-1, magnification, level 2 and the 1×1 level."""
    w, h = 71, 43                                    # not a multiple of VEC: the tail path too
    frame = make_renderer(w, h, hatching=True, hatching_scale=scale, hatching_saturation=saturation).render(
        coloured_scene(), COLOURED_CAMERA)
    ldr = tonemap_curve(frame.color, "reinhard")
    expect = linear_to_srgb8(hatching_reference(ldr, scale, saturation))
    diff = np.abs(frame.image.astype(int) - expect.astype(int))
    assert diff.max() <= 1, (diff.max(), np.argwhere(diff > 1)[:5])
    plain = linear_to_srgb8(ldr)
    assert np.abs(expect.astype(int) - plain.astype(int)).mean() > 10, "hatching changes the image"
    assert "hatching_ms" in frame.stats and "encode_ms" in frame.stats


# --- a luminance ramp through the renderer ------------------------------------------------------

RW, RH, PATCHES = 160, 40, 8
RAMP_CAMERA = Camera.look_at((0, 0, 0), (0, 0, -1), fov_y_deg=90.0, near=0.1, far=50.0)


def patch_scene(albedos) -> Scene:
    """len(albedos) camera-facing grey quads side by side filling the RW×RH RAMP_CAMERA image,
    lit only by a uniform ambient term of 1 (colour = albedo)."""
    depth, n = 5.0, len(albedos)

    def at(px, py):
        return ((px / RW * 2 - 1) * RW / RH * depth, (1 - py / RH * 2) * depth, -depth)
    verts, faces = [], []
    for i in range(n):
        x0, x1 = i * RW / n, (i + 1) * RW / n
        verts += [at(x0, RH), at(x1, RH), at(x1, 0), at(x0, 0)]
        faces += [[4 * i, 4 * i + 1, 4 * i + 2], [4 * i, 4 * i + 2, 4 * i + 3]]
    scene = Scene.from_arrays(np.array(verts, np.float32), np.array(faces))
    scene.materials = [Material(f"grey{i}", (a, a, a, 1.0), specular_intensity=0.0) for i, a in enumerate(albedos)]
    scene.triangle_material = np.repeat(np.arange(n, dtype=np.int32), 2)
    scene.ambient = 1.0
    return scene


def patch_means(image: np.ndarray, n: int) -> np.ndarray:
    """Mean of each patch's interior (2 pixels in from its edges), per channel averaged."""
    wide = RW // n
    return np.array([image[2:-2, i * wide + 2:(i + 1) * wide - 2].astype(np.float64).mean() for i in range(n)])


def test_luminance_ramp_darkens_monotonically(make_renderer):
    albedos = np.linspace(0.0, 1.0, PATCHES)
    scene = patch_scene(albedos)
    plain = make_renderer(RW, RH, tonemap="clamp").render(scene, RAMP_CAMERA)
    hatched = make_renderer(RW, RH, tonemap="clamp", hatching=True).render(scene, RAMP_CAMERA)
    assert (plain.triangle_id >= 0).all()
    np.testing.assert_allclose(patch_means(plain.color[..., 0], PATCHES), albedos, atol=0.01)
    means = patch_means(hatched.image, PATCHES)
    assert np.all(np.diff(means) > 3), means           # darker as the luminance decreases
    # white paper where the input is white, nearly (not exactly) black where it is black
    assert means[-1] >= 254 and 0 < means[0] < 60, means
    # neither the input nor black: strokes on paper, their mean near the input's for mid tones
    plain_means = patch_means(plain.image, PATCHES)
    for i in range(1, PATCHES - 1):
        patch = hatched.image[2:-2, i * (RW // PATCHES) + 2:(i + 1) * (RW // PATCHES) - 2].astype(np.float64)
        assert patch.std() > 25 and patch.max() > 150, (i, patch.std(), patch.max())
        assert abs(means[i] - plain_means[i]) > 2, (means, plain_means)
    # in linear light the ink coverage reproduces the tone (saturation 0: paper·(1 - ink))
    ink_only = make_renderer(RW, RH, tonemap="clamp", hatching=True, hatching_saturation=0.0).render(
        scene, RAMP_CAMERA)
    linear = patch_means(hatching_reference(plain.color.astype(np.float64), 1.0, 0.0)[..., 0], PATCHES)
    assert np.all(np.diff(linear) > 0.05)
    np.testing.assert_allclose(linear[1:-1], albedos[1:-1], atol=0.08)
    assert np.all(np.diff(patch_means(ink_only.image, PATCHES)) > 3)


def test_desaturates_partly(make_renderer):
    """A saturated red patch keeps `hatching_saturation` of its chroma on the paper."""
    scene = patch_scene([0.5] * 4)
    scene.materials = [Material(f"red{i}", (0.9, 0.08, 0.05, 1.0), specular_intensity=0.0) for i in range(4)]
    out = {}
    for s in (0.0, 0.3, 1.0):
        img = make_renderer(RW, RH, tonemap="clamp", hatching=True, hatching_saturation=s).render(
            scene, RAMP_CAMERA).image.astype(np.float64)
        out[s] = img[..., 0].mean() - img[..., 1].mean()
    assert abs(out[0.0]) < 1.0 and 5 < out[0.3] < out[1.0], out


# --- off: nothing runs ---------------------------------------------------------------------------

def test_off_launches_nothing_and_changes_nothing(make_renderer):
    scene = coloured_scene()
    default = make_renderer(48, 32).render(scene, COLOURED_CAMERA)
    off = make_renderer(48, 32, hatching=False, hatching_scale=3.0, hatching_saturation=0.9).render(
        scene, COLOURED_CAMERA)
    assert "hatching_ms" not in default.stats and "hatching_ms" not in off.stats
    assert "encode_ms" not in off.stats
    np.testing.assert_array_equal(default.image, off.image)
    np.testing.assert_array_equal(default.color, off.color)
    on = make_renderer(48, 32, hatching=True).render(scene, COLOURED_CAMERA)
    np.testing.assert_array_equal(on.color, default.color)         # Frame.color is the HDR colour
    assert not np.array_equal(on.image, default.image)
