"""Deferred shading + tone mapping against truth clrender did not compute (tiled light culling:
test_light_culling.py; the room and its lights: lighting_cases.py).

* shading == the float64 NumPy reference (tests/reference/shading.py) on the frame's own decoded
  G-buffer, so only float32-vs-float64 differences remain;
* attenuation is exactly zero from d = r on; tone mapping matches.
"""
import numpy as np
import pytest

from helpers import SHADING_TOL
import clrender
from clrender import Camera
from clrender.abi import structs
from lighting_cases import (AMBIENT, CAMERA, first_hit, light_array, pixel_ray, reference_scene_lights, render,
                            rim_lights, room_scene, special_lights, tiled)
from reference import shading as ref


# -- pure-NumPy checks of the reference itself ---------------------------------------------------

def test_reference_shading_hand_computed():
    cam = Camera.look_at((0, 0, 0), (0, 0, -1), fov_y_deg=90)
    one = lambda v: np.asarray(v, np.float32).reshape((1, 1) + np.shape(v))
    fields = dict(normal=one([0, 0, 1]), albedo=one([0.5, 0.5, 0.5]), specular_intensity=one(0.5),
                  specular_power=one(8.0), depth=one(2.0), triangle_id=np.zeros((1, 1), np.int32))
    # P = (0, 0, -2); light 1 away at (0, .6, .8) from P: A = (1 - 1/4)^3, N·L = .8, (N·H)^2 = .9
    point = light_array([dict(position=(0, 0.6, -1.2), radius=2.0, color=(1, 1, 1))])
    got = ref.shade(**fields, camera=cam, lights=point, ambient=0.1)
    a = 0.75 ** 3
    expect = 0.5 * (0.1 + a * 0.8) + a * 0.5 * 0.9 ** 4
    np.testing.assert_allclose(got[0, 0], expect, rtol=1e-6)
    # the same light as a spot: dot(-L, (0,-1,0)) = 0.6, t = (0.6 - 0.5)/(0.7 - 0.5) = 0.5, S = 0.25
    spot = point.copy()
    spot["type"], spot["direction"] = structs.LIGHT_SPOT, (0, -1, 0)
    spot["cos_outer"], spot["cos_inner"] = 0.5, 0.7
    got = ref.shade(**fields, camera=cam, lights=spot, ambient=0.1)
    expect = 0.5 * (0.1 + 0.25 * a * 0.8) + 0.25 * a * 0.5 * 0.9 ** 4
    np.testing.assert_allclose(got[0, 0], expect, rtol=1e-6)
    # beyond the radius: ambient only; background: 0
    far = point.copy()
    far["radius"] = 1.0
    np.testing.assert_allclose(ref.shade(**fields, camera=cam, lights=far, ambient=0.1)[0, 0], 0.05)
    fields["triangle_id"] = np.full((1, 1), -1, np.int32)
    assert np.all(ref.shade(**fields, camera=cam, lights=point, ambient=0.1) == 0)


def test_reference_tonemap_curves():
    c = np.array([0.0, 1.0, 3.0])
    np.testing.assert_allclose(ref.tonemap_curve(c, "reinhard"), [0.0, 0.5, 0.75])
    np.testing.assert_allclose(ref.tonemap_curve(c, "reinhard", 2.0), [0.0, 2 / 3, 6 / 7])
    np.testing.assert_allclose(ref.tonemap_curve(c[:2], "aces"), [0.0, 2.54 / 3.16])
    assert ref.tonemap_curve(np.array([100.0]), "aces")[0] == 1.0
    assert ref.tonemap(np.array([1.0]), "reinhard")[0] == 188        # sRGB(0.5) = 0.7354 -> 187.5 -> 188


def test_room_lights_hit_what_they_aim_at():
    """The analytic ray caster that places the special lights agrees with itself (no device)."""
    recs = special_lights(CAMERA, 160, 120)
    assert len(recs) >= 17
    eye = np.asarray(CAMERA.eye)
    assert np.linalg.norm(recs[0]["position"] - eye) < recs[0]["radius"]   # camera inside
    for px, py in [(64, 32), (32, 64), (96, 32)]:
        assert first_hit(eye, pixel_ray(CAMERA, 160, 120, px, py)) is not None
    for w, h in [(160, 120), (100, 72)]:
        assert len(rim_lights(CAMERA, w, h)) == 4, "every rim light lands on the back wall"


# -- shading equals the NumPy reference ----------------------------------------------------------

def test_shading_matches_reference(make_renderer, device):
    w, h = 128, 96
    scene = room_scene()
    scene.lights = reference_scene_lights()
    frame = render(make_renderer, device, "reference", scene, CAMERA, w, h, **tiled(16))
    fg = frame.triangle_id >= 0
    assert fg.mean() > 0.8
    expect, info = ref.shade_frame(frame, CAMERA, scene.lights, AMBIENT, details=True)
    # the reference's depth reading is right: floor pixels reconstruct onto y = 0
    floor = np.isin(frame.triangle_id, np.arange(2 * 16))
    assert floor.sum() > 1000 and np.abs(info["positions"][floor][:, 1]).max() < 1e-3
    assert np.all(frame.color[~fg] == 0), "background must be black"
    # The specular term jumps at N·L = 0 (model), so pixels where some light sits at N·L ~ 0 are ambiguous.
    ok = fg & (info["min_abs_ndotl"] > 1e-4)
    assert ok.sum() > 0.95 * fg.sum()
    assert info["specular"][ok].max() > 0.2, "the scene must exercise the specular term"
    peak = float(expect.max())
    err = np.abs(frame.color.astype(np.float64) - expect)
    err[~ok] = 0
    worst = np.unravel_index(np.argmax(err), err.shape)
    assert err.max() <= SHADING_TOL * peak, (
        f"max |color - reference| {err.max():.4g} at (y, x, c) {worst}: got {frame.color[worst]:.5g}, "
        f"expected {expect[worst]:.5g} (brightest {peak:.4g}); mean error {err[ok].mean():.3g}")


def test_lights_brighten_the_frame(make_renderer, device):
    """A black (or ambient-only) frame must fail, whatever the reference says."""
    w, h = 128, 96
    scene = room_scene()
    scene.lights = reference_scene_lights()
    frame = render(make_renderer, device, "reference", scene, CAMERA, w, h, **tiled(16))
    fg = frame.triangle_id >= 0
    ambient_only = frame.albedo * np.float32(AMBIENT)
    # where the lights are: pixels within half a radius of some light (and facing it) are well lit
    P = ref.world_positions(frame.depth, CAMERA)
    P[~fg] = 0.0
    near = np.zeros(fg.shape, bool)
    for light in scene.lights:
        if light["type"] == structs.LIGHT_POINT:
            lv = light["position"].astype(np.float64) - P
            d = np.linalg.norm(lv, axis=-1)
            facing = (frame.normal * lv).sum(-1) > 0.3 * d
            near |= fg & (d < 0.5 * light["radius"]) & facing
    assert near.sum() > 100
    assert np.all(frame.color[near].sum(-1) > 2 * ambient_only[near].sum(-1))
    assert np.all(frame.color[fg] >= ambient_only[fg] * (1 - 1e-6))
    assert frame.image[fg].mean() > 40 and frame.image[near].min() > 0


# -- attenuation reaches exactly zero at the radius ------------------------------------------------

FLOOR_CAM = Camera.look_at((0.0, 4.0, 2.0), (0.0, 0.0, -2.5), fov_y_deg=60, near=0.1, far=30)


@pytest.mark.parametrize("culling", ["tiled", "brute_force"])
def test_attenuation_is_exactly_zero_beyond_radius(make_renderer, device, culling):
    w, h = 128, 96
    r = 2.0
    scene = room_scene(with_sphere=False, with_wall=False)
    center = np.array([0.3, 0.0, -2.5])
    scene.lights = light_array([dict(position=center + (0, 0.4 * r, 0), radius=r, color=(3.0, 2.5, 2.0))])
    opts = dict(light_culling=culling, tonemap="aces")
    frame = render(make_renderer, device, "disk", scene, FLOOR_CAM, w, h, **opts)
    fg = frame.triangle_id >= 0
    assert fg.mean() > 0.7
    P = ref.world_positions(frame.depth, FLOOR_CAM)
    P[~fg] = np.nan
    d = np.linalg.norm(P - scene.lights["position"][0].astype(np.float64), axis=-1)
    outside, inside = fg & ~(d <= r * (1 + 1e-4)), fg & (d < 0.9 * r)
    assert outside.sum() > 1000 and inside.sum() > 500
    ambient_only = frame.albedo * np.float32(AMBIENT)
    bad = outside & (frame.color != ambient_only).any(-1)
    assert not bad.any(), (f"{int(bad.sum())} pixels beyond the radius are lit, e.g. d/r = "
                           f"{(d[bad] / r).min():.6f}: color {frame.color[bad][0]} vs ambient·albedo "
                           f"{ambient_only[bad][0]}")
    assert np.all(frame.color[inside] > ambient_only[inside])
    # a light r (+ a little) above the floor reaches nothing at all
    scene.lights = light_array([dict(position=center + (0, r * 1.001, 0), radius=r, color=(50.0, 50.0, 50.0))])
    frame = make_renderer(w, h, **opts).render(scene, FLOOR_CAM)
    expect = frame.albedo * np.float32(AMBIENT)
    expect[~fg] = 0
    assert np.array_equal(frame.color, expect)


@pytest.mark.parametrize("culling", ["tiled", "brute_force"])
def test_no_lights_is_ambient_times_albedo(make_renderer, device, culling):
    w, h = 96, 64
    scene = room_scene()
    assert len(scene.lights) == 0
    frame = make_renderer(w, h, light_culling=culling, tonemap="reinhard").render(scene, CAMERA)
    fg = frame.triangle_id >= 0
    assert fg.mean() > 0.8
    expect = frame.albedo * np.float32(AMBIENT)
    expect[~fg] = 0
    assert np.array_equal(frame.color, expect)
    assert np.all(frame.light_count == 0)
    assert frame.stats["lights"] == 0


# -- tone mapping -------------------------------------------------------------------------------

@pytest.mark.parametrize("operator,exposure", [("reinhard", 1.0), ("reinhard", 0.6), ("aces", 1.0),
                                               ("aces", 1.7)])
def test_tonemap_matches_reference(make_renderer, device, operator, exposure):
    w, h = 128, 96
    scene = room_scene()
    lights = reference_scene_lights()
    lights["color"] *= 3.0                          # HDR: plenty of pixels above 1
    scene.lights = lights
    frame = render(make_renderer, device, "hdr", scene, CAMERA, w, h,
                   light_culling="tiled", tonemap=operator, exposure=exposure)
    assert frame.image.shape == (h, w, 3) and frame.image.dtype == np.uint8
    assert (frame.color > 1).any(-1).mean() > 0.05, "the frame must have HDR values to map"
    expect = ref.tonemap(frame.color, operator, exposure)
    diff = np.abs(frame.image.astype(int) - expect.astype(int))
    worst = np.unravel_index(np.argmax(diff), diff.shape)
    assert diff.max() <= 1, (f"{operator} exposure {exposure}: image off by {diff.max()} codes at {worst} "
                             f"(color {frame.color[worst]:.5g}: got {frame.image[worst]}, expected {expect[worst]})")
    # ±1 only where float32 rounding lands on the other side of a code boundary: rare
    assert (diff == 0).mean() > 0.99, f"{operator} exposure {exposure}: {(diff != 0).mean():.1%} of codes differ"
    assert len(np.unique(frame.image)) > 100
    # exposure and operator act on the image only: color is the same linear HDR radiance
    base = render(make_renderer, device, "hdr", scene, CAMERA, w, h,
                  light_culling="tiled", tonemap="reinhard", exposure=1.0)
    np.testing.assert_array_equal(frame.color, base.color)
    if (operator, exposure) != ("reinhard", 1.0):
        assert (frame.image != base.image).mean() > 0.3, "the tone map settings must change the image"


def test_unknown_options_are_rejected(device):
    with pytest.raises(ValueError, match="filmic"):
        clrender.Renderer(16, 16, device=device.id, tonemap="filmic")
    with pytest.raises(ValueError, match="clustered"):
        clrender.Renderer(16, 16, device=device.id, light_culling="clustered")
