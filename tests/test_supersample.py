"""Over-sampling (`supersample=k`, docs/post.md): the resolve against independent NumPy filters of
the same scene rendered at k·W × k·H, and the AOVs' nearest-centre sample."""
from __future__ import annotations

import numpy as np
import pytest

import clrender
from clrender import Camera, Material, Scene
from clrender.render import memory

W, H = 40, 28


def hard_edged_scene(shadow_map_size: int = 256) -> Scene:
    """A rotated square, thin bars and a triangle of distinct colours over a wall; two point lights
    and a spot light with a shadow map, so colour, light_count and shadow vary across edges."""
    rng = np.random.default_rng(4)
    parts, mats = [], [Material("wall", (0.6, 0.6, 0.6, 1.0), specular_intensity=0.3)]
    verts = [np.array([[-6, -4, -8], [6, -4, -8], [6, 4, -8], [-6, 4, -8]], np.float32)]
    faces = [np.array([[0, 1, 2], [0, 2, 3]])]
    t = np.radians(17.0)
    sq = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]]) @ np.array([[np.cos(t), np.sin(t)], [-np.sin(t), np.cos(t)]])
    verts.append(np.c_[sq * 1.3 + (-1.8, 0.4), np.full(4, -5.0)].astype(np.float32))
    faces.append(np.array([[0, 1, 2], [0, 2, 3]]) + 4)
    for i, x in enumerate((0.9, 1.5, 2.2)):
        verts.append(np.array([[x, -2.5, -4.5], [x + 0.07 * (i + 1), -2.5, -4.5], [x + 0.07 * (i + 1) + 0.6, 2.5, -4.5],
                               [x + 0.6, 2.5, -4.5]], np.float32))
        faces.append(np.array([[0, 1, 2], [0, 2, 3]]) + 4 * len(faces))
    scene = Scene.from_arrays(np.vstack(verts), np.vstack(faces))
    scene.materials = mats + [Material(f"m{i}", (*rng.uniform(0.1, 1.0, 3), 1.0), specular_intensity=0.5,
                                       specular_power=20.0) for i in range(4)]
    scene.triangle_material = np.array([0, 0, 1, 1, 2, 2, 3, 3, 4, 4], np.int32)
    scene.add_point_light((-2, 1, -2), (3, 2.5, 2), 9.0)
    scene.add_point_light((2.5, -1, -3), (0.5, 1.5, 3), 7.0)
    scene.add_spot_light((0, 0, 0), (0, 0, -1), (4, 4, 4), 20.0, 25.0, 40.0, shadow=True,
                         shadow_map_size=shadow_map_size)
    scene.ambient = 0.1
    return scene


CAMERA = Camera.look_at((0, 0, 0), (0, 0, -1), fov_y_deg=70.0, near=0.1, far=50.0)


def filter_weights(name: str, k: int, n_out: int) -> np.ndarray:
    """(n_out, k·n_out) normalized weights of the separable resolve filter (independent NumPy)."""
    d = (np.arange(k * n_out)[None, :] + 0.5) / k - (np.arange(n_out)[:, None] + 0.5)
    a = np.abs(d)
    if name == "box":
        w = (a < 0.5).astype(np.float64)
    elif name == "lanczos2":
        w = np.where(a < 2, np.sinc(d) * np.sinc(d / 2), 0.0)
    else:
        b = c = 1.0 / 3.0
        w = np.where(a < 1, ((12 - 9 * b - 6 * c) * a**3 + (-18 + 12 * b + 6 * c) * a**2 + (6 - 2 * b)) / 6,
                     np.where(a < 2, ((-b - 6 * c) * a**3 + (6 * b + 30 * c) * a**2 + (-12 * b - 48 * c) * a
                                      + (8 * b + 24 * c)) / 6, 0.0))
    return w / w.sum(axis=1, keepdims=True)


def resolve_reference(color: np.ndarray, name: str, k: int) -> np.ndarray:
    """(H, W, 3) from (kH, kW, 3): rows then columns, float64."""
    kh, kw = color.shape[:2]
    wx, wy = filter_weights(name, k, kw // k), filter_weights(name, k, kh // k)
    return np.einsum("yj,jxc->yxc", wy, np.einsum("xi,jic->jxc", wx, color.astype(np.float64)))


@pytest.mark.parametrize("k", [2, 3, 4])
@pytest.mark.parametrize("name", ["box", "lanczos2", "mitchell"])
def test_resolve_matches_numpy_filter(make_renderer, k, name):
    scene = hard_edged_scene()
    big = make_renderer(k * W, k * H).render(scene, CAMERA)
    frame = make_renderer(W, H, supersample=k, supersample_filter=name).render(scene, CAMERA)
    expect = resolve_reference(big.color, name, k)
    peak = float(expect.max())
    assert peak > 0.1 and frame.color.std() > 0.01, "a lit frame with edges"
    np.testing.assert_allclose(frame.color, expect, rtol=0, atol=2e-6 * peak)
    # not the nearest sample: the filter really averages across edges
    assert np.abs(frame.color - big.color[k // 2::k, k // 2::k]).max() > 0.01


@pytest.mark.parametrize("k", [2, 3, 4])
def test_aovs_take_the_sample_nearest_the_centre(make_renderer, k):
    scene = hard_edged_scene()
    big = make_renderer(k * W, k * H, ssao=True).render(scene, CAMERA)
    frame = make_renderer(W, H, supersample=k, ssao=True).render(scene, CAMERA)
    s = np.s_[k // 2::k, k // 2::k]
    np.testing.assert_array_equal(frame.gbuffer[[0, 1, 2, 4]], big.gbuffer[[0, 1, 2, 4]][(slice(None),) + s])
    for aov in ("triangle_id", "depth", "normal", "albedo", "light_count", "ao", "shadow"):
        np.testing.assert_array_equal(getattr(frame, aov), getattr(big, aov)[s], err_msg=aov)
    assert frame.shadow.shape == (H, W, 1) and (frame.shadow < 0.5).any()
    assert frame.stats["supersample"] == k


@pytest.mark.parametrize("k", [2, 4])
def test_velocity_in_output_pixels(make_renderer, k):
    scene = hard_edged_scene()
    prev = Camera.look_at((0.3, 0.1, 0), (0.3, 0.1, -1), fov_y_deg=70.0, near=0.1, far=50.0)
    big = make_renderer(k * W, k * H).render(scene, CAMERA, previous_camera=prev)
    frame = make_renderer(W, H, supersample=k).render(scene, CAMERA, previous_camera=prev)
    expect = big.velocity[k // 2::k, k // 2::k] / k
    assert np.abs(expect).max() > 1.0
    np.testing.assert_array_equal(frame.velocity, expect.astype(np.float16).astype(np.float32))


def test_transparency_aovs_resolved(make_renderer):
    scene = hard_edged_scene()
    scene.materials[2] = Material("glass", (0.2, 0.9, 0.3, 1.0), opacity=0.4)
    big = make_renderer(2 * W, 2 * H).render(scene, CAMERA)
    frame = make_renderer(W, H, supersample=2).render(scene, CAMERA)
    assert frame.fragment_count.max() == 1
    np.testing.assert_array_equal(frame.fragment_count, big.fragment_count[1::2, 1::2])
    np.testing.assert_array_equal(frame.transmittance, big.transmittance[1::2, 1::2])
    np.testing.assert_allclose(frame.color, resolve_reference(big.color, "box", 2), rtol=0,
                               atol=2e-6 * float(big.color.max()))


def test_supersample_1_is_the_plain_frame(make_renderer):
    scene = hard_edged_scene()
    a = make_renderer(W, H).render(scene, CAMERA)
    b = make_renderer(W, H, supersample=1, supersample_filter="mitchell").render(scene, CAMERA)
    np.testing.assert_array_equal(a.color, b.color)
    np.testing.assert_array_equal(a.image, b.image)
    assert "resolve_ms" not in b.stats


def test_memory_check_counts_the_internal_size(device, monkeypatch):
    monkeypatch.setattr(memory, "limits", lambda dev: (2**30, 2**30))         # a 1 GiB device
    clrender.Renderer(1200, 1200, device=device.id)                          # fits
    with pytest.raises(memory.DeviceMemoryError, match=r"at supersample 4 \(\d+x\d+ internally\) needs about \d+ "
                                                       r"bytes .* has 1073741824 bytes"):
        clrender.Renderer(1200, 1200, device=device.id, supersample=4)
    internal = memory.estimate(640, 400, clrender.RenderConfig())["total"]
    ss2 = memory.estimate(320, 200, clrender.RenderConfig(supersample=2))["total"]
    assert ss2 == internal + 12 * 320 * 400 + (12 + 24) * 320 * 200     # + the resolve's rows, colour, G-buffer


@pytest.mark.parametrize("bad", [0, 5, 2.0, True, "2"])
def test_bad_supersample(bad):
    with pytest.raises(ValueError, match="supersample"):
        clrender.RenderConfig(supersample=bad)
    with pytest.raises(ValueError, match="supersample_filter"):
        clrender.RenderConfig(supersample_filter="gauss")


@pytest.mark.oclgrind
@pytest.mark.parametrize("name", ["box", "lanczos2"])
def test_resolve_kernels_tiny_frame(device, capfd, name):
    """Oclgrind tier: resolve_rows/resolve_cols/decimate_gbuffer on a 12x8 frame at supersample 2
    (odd sizes of the internal frame's tiles), against the NumPy filter and nearest sample."""
    from test_oclgrind_tier import assert_no_device_diagnostics
    scene = hard_edged_scene(shadow_map_size=64)      # both frames share it; 256² took minutes in Oclgrind
    prev = Camera.look_at((0.2, 0, 0), (0.2, 0, -1), fov_y_deg=70.0, near=0.1, far=50.0)
    big = clrender.Renderer(24, 16, device=device.id).render(scene, CAMERA, previous_camera=prev)
    frame = clrender.Renderer(12, 8, device=device.id, supersample=2, supersample_filter=name).render(
        scene, CAMERA, previous_camera=prev)
    np.testing.assert_allclose(frame.color, resolve_reference(big.color, name, 2), rtol=0,
                               atol=2e-6 * float(big.color.max()))
    np.testing.assert_array_equal(frame.triangle_id, big.triangle_id[1::2, 1::2])
    np.testing.assert_array_equal(frame.velocity, (big.velocity[1::2, 1::2] / 2).astype(np.float16).astype(np.float32))
    assert_no_device_diagnostics(capfd)
