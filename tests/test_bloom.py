"""Bloom (`bloom=True`, docs/post.md, report IV.1): what saturates, bright = max(color - threshold, 0)
per channel, blurred over a mip pyramid and added back to the linear HDR colour before tone mapping,
color' = color + strength * blur(bright). Checked against an independent float64 NumPy
implementation of the pyramid (2x2 means, normalized separable Gaussians, cascaded bilinear 2x
upsampling, equal level weights; clrender/passes/bloom.py states it), for energy conservation, a
single pixel's profile, and the effect's absence when nothing saturates or bloom is off."""
from __future__ import annotations

import math

import numpy as np
import pytest

import clrender
from clrender import Camera, Scene

CAMERA = Camera.look_at((0, 0, 0), (0, 0, -1), fov_y_deg=60.0, near=0.1, far=50.0)


# -- independent NumPy reference (float64) ---------------------------------------------------------

def pyramid_parameters(radius: float) -> tuple[int, float, np.ndarray]:
    """(L, sigma in coarse pixels, normalized taps k = -R..R) for bloom_radius `radius`:
    L = clamp(ceil(log2 r) - 1, 1, 12), sigma = r / 2^(L+1), R = max(1, ceil(3 sigma))."""
    levels = min(max(math.ceil(math.log2(radius)) - 1, 1), 12)
    sigma = radius / 2.0 ** (levels + 1)
    r = max(1, math.ceil(3 * sigma))
    k = np.arange(-r, r + 1, dtype=np.float64)
    taps = np.exp(-k**2 / (2 * sigma**2))
    return levels, sigma, taps / taps.sum()


def downsample(a: np.ndarray) -> np.ndarray:
    """2x2 mean, (h, w, 3) -> (ceil(h/2), ceil(w/2), 3); odd sizes repeat the edge pixel."""
    h, w = a.shape[:2]
    ys, xs = 2 * np.arange((h + 1) // 2), 2 * np.arange((w + 1) // 2)
    y1, x1 = np.minimum(ys + 1, h - 1), np.minimum(xs + 1, w - 1)
    return (a[ys][:, xs] + a[ys][:, x1] + a[y1][:, xs] + a[y1][:, x1]) / 4


def gaussian(a: np.ndarray, taps: np.ndarray) -> np.ndarray:
    """Separable blur, rows then columns, clamp-to-edge."""
    r = len(taps) // 2
    h, w = a.shape[:2]
    rows = sum(t * a[:, np.clip(np.arange(w) + k, 0, w - 1)] for k, t in zip(range(-r, r + 1), taps))
    return sum(t * rows[np.clip(np.arange(h) + k, 0, h - 1)] for k, t in zip(range(-r, r + 1), taps))


def upsample2(a: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """Bilinear to the finer grid `shape` (h, w): fine x reads (x + 0.5) / 2 - 0.5, clamp-to-edge."""
    def axis(n_fine, n_coarse):
        u = np.clip((np.arange(n_fine) + 0.5) / 2 - 0.5, 0, n_coarse - 1)
        i0 = np.floor(u).astype(int)
        return i0, np.minimum(i0 + 1, n_coarse - 1), u - i0
    j0, j1, ay = axis(shape[0], a.shape[0])
    i0, i1, ax = axis(shape[1], a.shape[1])
    ax = ax[None, :, None]
    rows = a[:, i0] * (1 - ax) + a[:, i1] * ax
    return rows[j0] * (1 - ay[:, None, None]) + rows[j1] * ay[:, None, None]


def bloom_blur(bright: np.ndarray, radius: float) -> np.ndarray:
    """blur(bright) = (1/L) sum_l U^l G_l D_l bright, (H, W, 3) float64."""
    levels, _, taps = pyramid_parameters(radius)
    pyramid = [np.asarray(bright, np.float64)]
    for _ in range(levels):
        pyramid.append(downsample(pyramid[-1]))
    acc = gaussian(pyramid[levels], taps)
    for level in range(levels - 1, 0, -1):
        acc = gaussian(pyramid[level], taps) + upsample2(acc, pyramid[level].shape[:2])
    return upsample2(acc, bright.shape[:2]) / levels


def bloom_reference(color: np.ndarray, threshold: float, strength: float, radius: float):
    """(color + strength * blur(bright), strength * blur(bright)) for an (H, W, 3) HDR colour."""
    bright = np.maximum(color.astype(np.float64) - np.float32(threshold), 0.0)
    added = strength * bloom_blur(bright, radius)
    return color + added, added


def assert_bloom_matches(on_color, off_color, threshold, strength, radius, rel=1e-5):
    """The kernel's added bloom against the reference: within rel of its peak (plus the final
    float32 addition's rounding, half an ulp of the colour)."""
    _, added = bloom_reference(off_color, threshold, strength, radius)
    peak = float(added.max())
    assert peak > 0, "something must bloom"
    got = on_color.astype(np.float64) - off_color
    np.testing.assert_allclose(got, added, rtol=0, atol=rel * peak + float(np.spacing(off_color.max())))
    return added


def test_reference_conserves_energy_and_is_normalized():
    """The reference itself: a constant image stays constant (weights total 1 everywhere the clamps
    repeat, even at borders), and interior content keeps its sum exactly."""
    ones = np.ones((37, 53, 3))
    np.testing.assert_allclose(bloom_blur(ones, 16.0), ones, rtol=1e-12)
    spot = np.zeros((128, 128, 3))
    spot[60:66, 58:63] = (3.0, 1.0, 0.5)
    for r in (3.0, 8.0, 16.0):
        np.testing.assert_allclose(bloom_blur(spot, r).sum(axis=(0, 1)), spot.sum(axis=(0, 1)), rtol=1e-12)


# -- scenes and the pass on its own ------------------------------------------------------------------

def spot_scene(light=(0.3, -0.2, -4.5), color=(30.0, 24.0, 18.0), radius=0.8, extra=()) -> Scene:
    """A white wall filling the view at z = -5 (ambient 0.03: far below the threshold) and a
    strong point light 0.5 in front of it: a bright disc (its attenuation is 0 beyond the radius)."""
    wall = np.array([[-20, -20, -5], [20, -20, -5], [20, 20, -5], [-20, 20, -5]], np.float32)
    scene = Scene.from_arrays(wall, [[0, 1, 2], [0, 2, 3]])
    scene.add_point_light(light, color, radius)
    for args in extra:
        scene.add_point_light(*args)
    return scene


def border_scene() -> Scene:
    """Bright discs in the middle, at the right edge and over the top-left corner."""
    return spot_scene((0.0, 0.0, -4.2), (20.0, 18.0, 16.0), 1.5,
                      extra=[((-4.0, 2.6, -4.5), (8.0, 6.0, 9.0), 1.0), ((3.8, -1.0, -4.6), (5.0, 2.0, 1.0), 1.5)])


def run_bloom_pass(device, color: np.ndarray, **opts) -> np.ndarray:
    """BloomPass alone on an (H, W, 3) colour; returns its (H, W, 3) output."""
    import pyopencl.array as cla
    from clrender.device.core import Device
    from clrender.passes.base import Resources
    from clrender.passes.bloom import BloomPass
    dev = Device.get(device)
    h, w = color.shape[:2]
    p = BloomPass(dev, clrender.RenderConfig(bloom=True, **opts))
    p.allocate(w, h)
    src = cla.to_device(dev.queue, np.ascontiguousarray(np.moveaxis(color.astype(np.float32), -1, 0)).reshape(-1))
    res = Resources(buffers={"color": src}, values={"width": w, "height": h})
    p.publish(res)
    p.run(res)
    return np.moveaxis(res["color"].get(queue=dev.queue).reshape(3, h, w), 0, -1)


def distance_to(mask: np.ndarray) -> np.ndarray:
    """Euclidean distance of every pixel to the nearest True pixel of `mask` (brute force, small masks)."""
    ys, xs = np.nonzero(mask)
    gy, gx = np.mgrid[: mask.shape[0], : mask.shape[1]]
    d2 = (gy[..., None] - ys) ** 2 + (gx[..., None] - xs) ** 2
    return np.sqrt(d2.min(axis=-1))


# -- tests ---------------------------------------------------------------------------------------------

def test_energy_is_conserved(make_renderer):
    """Away from the borders the bloom adds strength x the thresholded energy (within 1 %; the
    pyramid is exactly energy-preserving, so the error is float rounding)."""
    w, h, strength = 160, 120, 0.5
    scene = spot_scene()
    off = make_renderer(w, h).render(scene, CAMERA)
    on = make_renderer(w, h, bloom=True, bloom_strength=strength).render(scene, CAMERA)
    bright = np.maximum(off.color.astype(np.float64) - 1.0, 0.0)
    lit = bright.max(-1) > 0
    ys, xs = np.nonzero(lit)
    assert lit.sum() > 50 and bright.sum() > 100, "a strongly saturated spot"
    # r = 16: L = 3, coarsest blocks 8 px, taps reach 3 blocks, the upsampling 1 more: 8 blocks of margin
    assert min(xs.min(), ys.min(), w - 1 - xs.max(), h - 1 - ys.max()) >= 40, "the spot stays away from the borders"
    added = on.color.astype(np.float64) - off.color
    expected = strength * bright.sum()
    error = abs(added.sum() - expected) / expected
    assert error < 0.01, f"bloom added {added.sum()} instead of {expected} (error {error:.2e})"
    per_channel = added.sum(axis=(0, 1)) / (strength * bright.sum(axis=(0, 1)))
    np.testing.assert_allclose(per_channel, 1.0, rtol=0.01)
    # it spread: a good part lands outside the saturated pixels, and all around them the colour rose
    assert added[~lit].sum() > 0.25 * added.sum()
    assert (added.max(-1)[distance_to(lit) == 5] > 0).all()
    assert "bloom_ms" in on.stats


@pytest.mark.parametrize("radius", [3.0, 16.0, 40.0])
def test_matches_numpy_pyramid(make_renderer, radius):
    """Odd frame sizes (the clamped 2x2 means), content across the borders (the clamps), every
    level count from 1 (r = 3) to 5 (r = 40): the kernel's added bloom is the reference's."""
    w, h, threshold, strength = 101, 67, 0.5, 0.3
    scene = border_scene()
    off = make_renderer(w, h).render(scene, CAMERA)
    on = make_renderer(w, h, bloom=True, bloom_threshold=threshold, bloom_strength=strength,
                       bloom_radius=radius).render(scene, CAMERA)
    lit = off.color.max(-1) > threshold
    assert lit[0, 0] and lit[:, -1].any() and lit[h // 2, w // 2], "bright at a corner, an edge and the centre"
    assert_bloom_matches(on.color, off.color, threshold, strength, radius)


def test_single_pixel_profile(device):
    """One bright pixel spreads into the stated profile: the mean of L bumps, bump l centred on its
    level-l block's centre with per-axis variance 4^l (s2 + 1/4) - 1/4 (s2: the taps' variance);
    its falloff is monotonic and it holds the pixel's energy."""
    n, p, radius, value = 128, 64, 16.0, 100.0
    color = np.zeros((n, n, 3), np.float32)
    color[p, p] = (1.0 + value, 1.0 + value / 2, 0.5)          # threshold 1: blue stays below
    out = run_bloom_pass(device, color, bloom_threshold=1.0, bloom_strength=1.0, bloom_radius=radius)
    added = out.astype(np.float64) - color
    expect = assert_bloom_matches(out, color, 1.0, 1.0, radius)
    assert not added[..., 2].any(), "a channel below the threshold does not bloom"
    np.testing.assert_allclose(added[..., :2].sum(axis=(0, 1)), (value, value / 2), rtol=1e-5)
    np.testing.assert_allclose(expect[..., 1], expect[..., 0] / 2, rtol=1e-12)

    levels, _, taps = pyramid_parameters(radius)
    assert levels == 3
    k = np.arange(len(taps)) - len(taps) // 2
    s2 = float((k**2 * taps).sum())
    centres = np.array([p + (2**l - 1) / 2 for l in range(1, levels + 1)])     # p is a multiple of 2^L
    variances = np.array([4**l * (s2 + 0.25) - 0.25 for l in range(1, levels + 1)])
    mean = centres.mean()
    var = (variances + centres**2).mean() - mean**2
    prof = added[..., 0] / value
    coord = np.arange(n)
    for axis in (0, 1):
        marginal = prof.sum(axis=1 - axis)
        got_mean = (coord * marginal).sum()
        np.testing.assert_allclose(got_mean, mean, rtol=0, atol=1e-3)
        np.testing.assert_allclose(((coord - got_mean) ** 2 * marginal).sum(), var, rtol=1e-4)
    assert radius / 2 <= np.sqrt(variances[-1]) <= 0.6 * radius     # the reach: the coarsest bump, sigma ~ r/2

    # monotonic falloff: beyond the bumps' centres every bump decreases, so their mean does too
    lo, hi = int(np.floor(centres.min())), int(np.ceil(centres.max()))
    for line in (prof[p], prof[:, p], np.diagonal(prof)):
        assert (np.diff(line[hi:]) <= 1e-9).all() and (np.diff(line[: lo + 1]) >= -1e-9).all()
        assert line[hi + 8] < 0.5 * line[hi] and line[hi + 40] < 1e-3 * line[hi]
    # radial: mean over rings around the profile's centre, non-increasing from the core out to 3 r
    gy, gx = np.mgrid[:n, :n]
    ring = np.hypot(gy - mean, gx - mean).astype(int)
    rings = np.bincount(ring.ravel(), prof.ravel()) / np.bincount(ring.ravel())
    assert (np.diff(rings[2:48]) < 0).all(), rings[:48]


def test_nothing_below_the_threshold_blooms(make_renderer):
    """A frame whose colour is everywhere at or below bloom_threshold is bit-identical with bloom on
    and off (the kernels still run)."""
    w, h = 64, 48
    scene = spot_scene(color=(3.0, 2.5, 2.0))
    off = make_renderer(w, h).render(scene, CAMERA)
    peak = float(off.color.max())
    assert peak > 0.5
    for threshold in (peak, 2 * peak):          # exactly the brightest value: max(c - t, 0) = 0
        on = make_renderer(w, h, bloom=True, bloom_threshold=threshold, bloom_strength=5.0).render(scene, CAMERA)
        assert "bloom_ms" in on.stats
        np.testing.assert_array_equal(on.color, off.color)
        np.testing.assert_array_equal(on.image, off.image)
    # just below the peak, the brightest pixels do bloom
    on = make_renderer(w, h, bloom=True, bloom_threshold=0.9 * peak, bloom_strength=5.0).render(scene, CAMERA)
    assert (on.color > off.color).any() and (on.color >= off.color).all()


def test_bloom_off_launches_nothing(make_renderer):
    w, h = 64, 48
    scene = spot_scene()
    default = make_renderer(w, h).render(scene, CAMERA)
    off = make_renderer(w, h, bloom=False, bloom_threshold=0.1, bloom_strength=2.0,
                        bloom_radius=3.0).render(scene, CAMERA)
    assert "bloom_ms" not in off.stats and "bloom_ms" not in default.stats
    assert not any(p.name == "bloom" for p in make_renderer(w, h).pipeline.passes)
    np.testing.assert_array_equal(off.color, default.color)
    np.testing.assert_array_equal(off.image, default.image)
    on = make_renderer(w, h, bloom=True).render(scene, CAMERA)
    assert not np.array_equal(on.image, default.image), "the bloom shows in the tone-mapped image"


def test_larger_radius_spreads_farther(make_renderer):
    w, h, small = 160, 120, 4.0
    scene = spot_scene()
    off = make_renderer(w, h).render(scene, CAMERA)
    far = distance_to(off.color.max(-1) > 1.0) > small
    outside = {}
    for radius in (small, 32.0):
        on = make_renderer(w, h, bloom=True, bloom_radius=radius).render(scene, CAMERA)
        added = (on.color.astype(np.float64) - off.color).sum(-1)
        assert_bloom_matches(on.color, off.color, 1.0, 0.1, radius)
        outside[radius] = added[far].sum() / added.sum()
    # r = 4: sigmas 2 and 1 px, almost nothing beyond 4 px of the spot; r = 32: sigmas 16, 8, 4, 2 px
    assert outside[small] < 0.02 and outside[32.0] > 0.25, outside


def test_bloom_follows_the_supersample_resolve(make_renderer):
    """With supersample=2 the bloom runs at the output resolution on the resolved colour."""
    w, h = 48, 32
    scene = border_scene()
    plain = make_renderer(w, h, supersample=2).render(scene, CAMERA)
    on = make_renderer(w, h, supersample=2, bloom=True, bloom_threshold=0.5, bloom_radius=8.0).render(scene, CAMERA)
    assert on.color.shape == (h, w, 3)
    assert_bloom_matches(on.color, plain.color, 0.5, 0.1, 8.0)
