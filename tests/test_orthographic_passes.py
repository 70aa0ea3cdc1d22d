"""Orthographic cameras in the passes, against truth clrender did not compute, each in both
projections (the camera, raster and loaders: test_orthographic.py).

* shading equals the float64 NumPy shading reference (positions on parallel rays from the eye
  plane, V = -forward); every pipeline and light-accumulation variant agrees with it;
* light culling is conservative (tiled, 2.5D mask, quads, stencil), SSAO is ~1 on a flat floor,
  darker in a corner and correlates with ray-traced AO, spot and sun shadows match ray casts --
  each in both projections; transparency (A-buffer, peeling) matches the transparency reference;
  a panning orthographic camera has the analytic, uniform velocity.
"""
import numpy as np
import pytest

from helpers import SHADING_TOL
from clrender import Camera, Material
from ortho_cases import PROJECTIONS, _frame_of, raster_guard  # noqa: F401 (raster_guard: an autouse fixture)
from reference import shading as ref
from reference.raster import triangles_scene


# -- shading -------------------------------------------------------------------------------------------

from lighting_cases import light_array, random_lights, reference_scene_lights, room_scene  # noqa: E402

ROOM_EYE, ROOM_TARGET = (0.3, 2.0, 3.0), (0.0, 0.8, -3.0)
ROOM_CAMERAS = {
    "perspective": Camera.look_at(ROOM_EYE, ROOM_TARGET, fov_y_deg=55, near=0.1, far=30),
    "orthographic": Camera.orthographic(ROOM_EYE, (0.0, 1.5, -3.5), xmag=4.0, ymag=2.5, near=0.1, far=30),
}
RW, RH = 128, 96
_FRAMES = {}


def render(make_renderer, device, key, scene, camera, width=RW, height=RH, **opts):
    full = (device.id, key, camera.projection, width, height, repr(sorted(opts.items())))
    if full not in _FRAMES:
        _FRAMES[full] = make_renderer(width, height, **opts).render(scene, camera)
    return _FRAMES[full]


def lit_room():
    scene = room_scene()
    scene.lights = reference_scene_lights()
    return scene


def assert_shading_matches(frame, camera, scene, tol=SHADING_TOL):
    fg = frame.triangle_id >= 0
    assert fg.mean() > 0.8
    expect, info = ref.shade_frame(frame, camera, scene.lights, scene.ambient, details=True)
    assert np.all(frame.color[~fg] == 0)
    ok = fg & (info["min_abs_ndotl"] > 1e-4)
    assert ok.sum() > 0.95 * fg.sum()
    assert info["specular"][ok].max() > 0.1, "the view must exercise the specular term"
    peak = float(expect.max())
    err = np.abs(frame.color.astype(np.float64) - expect)
    err[~ok] = 0
    worst = np.unravel_index(np.argmax(err), err.shape)
    assert err.max() <= tol * peak, (f"max |color - reference| {err.max():.4g} at {worst}: got "
                                     f"{frame.color[worst]:.5g}, expected {expect[worst]:.5g} (peak {peak:.4g})")
    return info


def test_ortho_positions_rebuild_onto_the_floor_and_shading_matches_reference(make_renderer, device):
    cam = ROOM_CAMERAS["orthographic"]
    scene = lit_room()
    frame = render(make_renderer, device, "room", scene, cam, light_culling="tiled", light_tile_size=16)
    info = assert_shading_matches(frame, cam, scene)
    floor = np.isin(frame.triangle_id, np.arange(2 * 16))
    assert floor.sum() > 1000 and np.abs(info["positions"][floor][:, 1]).max() < 1e-3
    # the perspective reading of the same depths would not be on the floor: the test can fail
    persp = ref.world_positions(frame.depth, ROOM_CAMERAS["perspective"])
    assert np.abs(persp[floor][:, 1]).max() > 0.1
    # V = -forward, not towards the eye: the specular highlight moves
    assert frame.stats["lights"] == 6


@pytest.mark.parametrize("variant", [dict(light_culling="brute_force"), dict(light_culling="quads"),
                                     dict(light_culling="stencil"), dict(light_depth_mask=True),
                                     dict(pipeline="light_indexed"), dict(pipeline="light_prepass"),
                                     dict(pipeline="light_prepass", msaa=2)],
                         ids=["brute", "quads", "stencil", "depth-mask", "indexed", "prepass", "prepass-msaa2"])
def test_ortho_variants_match_reference(make_renderer, device, variant):
    cam = ROOM_CAMERAS["orthographic"]
    scene = lit_room()
    base = render(make_renderer, device, "room", scene, cam, light_culling="tiled", light_tile_size=16)
    frame = render(make_renderer, device, "room", scene, cam, light_tile_size=16, **variant)
    if variant.get("msaa", 1) > 1:
        np.testing.assert_array_equal(frame.triangle_id, base.triangle_id)
        # every sample of a pixel whose 3×3 neighbourhood shows one triangle sees that triangle:
        # the colour is the one-sample colour there; only edge pixels change
        ids = np.pad(base.triangle_id, 1, mode="edge")
        interior = np.ones(base.triangle_id.shape, bool)
        for dy in range(3):
            for dx in range(3):
                interior &= ids[dy:dy + RH, dx:dx + RW] == base.triangle_id
        one = render(make_renderer, device, "room", scene, cam, light_tile_size=16, pipeline="light_prepass")
        peak = float(one.color.max())
        diff = np.abs(frame.color - one.color).max(-1)
        assert interior.mean() > 0.5 and diff[interior].max() <= 1e-4 * peak
        assert (diff[~interior] > 1e-3 * peak).any(), "msaa must change some edge pixel"
        return
    np.testing.assert_array_equal(frame.triangle_id, base.triangle_id)
    assert_shading_matches(frame, cam, scene)
    if "pipeline" not in variant:
        assert frame.stats["light_pairs_useful"] == base.stats["light_pairs_useful"] > 0


# -- light culling, both projections ---------------------------------------------------------------------

def culling_scene():
    scene = room_scene()
    recs = random_lights(300, seed=21)
    recs += [dict(position=(x, 0.4, z), radius=0.8, color=(1, 1, 1)) for x in (-3.0, -1.0, 1.0, 3.0)
             for z in (-6.0, -3.0, 0.0)]                                   # small lights resting on the floor
    recs.append(dict(position=ROOM_EYE, radius=2.0, color=(0.2, 0.2, 0.2)))          # around the eye
    scene.lights = light_array(recs)
    return scene


@pytest.mark.parametrize("culling", ["tiled", "16+depth-mask", "quads", "stencil"])
@pytest.mark.parametrize("projection", PROJECTIONS)
def test_tile_lists_hold_every_light_reaching_a_pixel(make_renderer, device, projection, culling):
    cam = ROOM_CAMERAS[projection]
    scene = culling_scene()
    tile = 16
    opts = dict(light_tile_size=tile, light_culling="tiled" if culling == "16+depth-mask" else culling,
                light_depth_mask=culling == "16+depth-mask")
    frame = render(make_renderer, device, "culling", scene, cam, **opts)
    per_tile = frame.light_count[::tile, ::tile]
    truth = ref.tile_light_truth(frame, cam, scene.lights, tile)
    assert truth.max() > 3
    short = np.argwhere(per_tile < truth)
    assert not len(short), (f"{len(short)} tiles got fewer lights than reach them, e.g. tile {tuple(short[0])}: "
                            f"{per_tile[tuple(short[0])]} < {truth[tuple(short[0])]}")
    assert frame.stats["lights_per_tile_avg"] < 0.5 * len(scene.lights), "culling must cull"
    brute = render(make_renderer, device, "culling", scene, cam, light_culling="brute_force")
    peak = float(brute.color.max())
    assert np.abs(frame.color.astype(np.float64) - brute.color).max() <= 1e-4 * peak


# -- SSAO, both projections --------------------------------------------------------------------------------

from test_ssao import FLOOR, RADIUS, flat_scene  # noqa: E402
from test_ssao import room as ssao_room  # noqa: E402

SSAO_EYE, SSAO_TARGET = (3.5, 5.0, 6.0), (-1.5, 0.5, -2.5)
SSAO_CAMERAS = {
    "perspective": Camera.look_at(SSAO_EYE, SSAO_TARGET, fov_y_deg=55, near=0.1, far=50),
    "orthographic": Camera.orthographic(SSAO_EYE, SSAO_TARGET, xmag=6.0, ymag=4.0, near=0.1, far=50),
}


def pixel_of(point, camera, width, height):
    clip = camera.view_projection(width, height) @ np.append(point, 1.0)
    x, y = clip[:2] / clip[3]
    return int((1 - y) * 0.5 * height), int((x + 1) * 0.5 * width)


@pytest.mark.parametrize("projection", PROJECTIONS)
def test_ssao_flat_floor_open_and_corner_dark(make_renderer, projection):
    from reference.ao import ray_traced_ao
    cam = SSAO_CAMERAS[projection]
    w, h = 128, 96
    r = make_renderer(w, h, ssao=True, ssao_radius=RADIUS, ssao_blur=False)
    flat = r.render(flat_scene([FLOOR]), cam)
    floor = flat.triangle_id >= 0
    assert floor.mean() > 0.5 and flat.ao[floor].min() >= 1.0 - 1e-6

    scene = ssao_room()
    frame = r.render(scene, cam)
    corner, open_floor = pixel_of((-5.85, 0.0, -5.85), cam, w, h), pixel_of((3.5, 0.0, 0.0), cam, w, h)
    assert frame.triangle_id[corner] >= 0 and frame.triangle_id[open_floor] >= 0
    assert frame.ao[corner] < frame.ao[open_floor] - 0.2 and frame.ao[open_floor] > 0.99
    sel = np.zeros((h, w), bool)
    sel[::3, ::3] = True
    sel &= frame.triangle_id >= 0
    truth = ray_traced_ao(ref.world_positions(frame.depth, cam)[sel], frame.normal[sel], scene.positions,
                          scene.triangles, RADIUS, 96, seed=7)
    corr = np.corrcoef(frame.ao[sel], truth)[0, 1]
    assert corr >= 0.8, f"Pearson correlation with ray-traced AO {corr:.3f} < 0.8"


# -- shadows, both projections -------------------------------------------------------------------------------

from test_shadows import (SPOT, SUN_DIR, agreement, facing, in_spot, occluder_scene, ray_reference,  # noqa: E402
                          spot_scene)

SHADOW_EYE, SHADOW_TARGET = (7.0, 6.0, 9.0), (0.0, 0.5, 0.0)
SHADOW_CAMERAS = {
    "perspective": Camera.look_at(SHADOW_EYE, SHADOW_TARGET, fov_y_deg=50, near=0.1, far=60),
    "orthographic": Camera.orthographic(SHADOW_EYE, SHADOW_TARGET, xmag=7.0, ymag=5.5, near=0.1, far=60),
}


@pytest.mark.parametrize("projection", PROJECTIONS)
def test_spot_shadow_matches_ray_casting(make_renderer, projection):
    cam = SHADOW_CAMERAS[projection]
    scene = spot_scene()
    frame = make_renderer(128, 96, shadow_filter="hard").render(scene, cam)
    lit, L = in_spot(frame, cam)
    tested = lit & facing(scene, frame, L)
    assert tested.sum() > 1500
    expect = ray_reference(scene, frame, cam, tested, light_pos=SPOT["position"])
    assert 0.1 < 1 - expect.mean() < 0.6
    frac, stray = agreement(frame.shadow[..., 0], expect, tested)
    assert frac >= 0.97 and stray == 0, (frac, stray)


@pytest.mark.parametrize("projection", PROJECTIONS)
def test_sun_cascades_match_ray_casting(make_renderer, projection):
    cam = SHADOW_CAMERAS[projection]
    scene = occluder_scene()
    scene.set_sun(SUN_DIR, (2.0, 1.9, 1.7), shadow_map_size=1024)
    frame = make_renderer(128, 96, shadow_filter="hard").render(scene, cam)
    L = -np.asarray(SUN_DIR) / np.linalg.norm(SUN_DIR)
    tested = facing(scene, frame, np.broadcast_to(L, (96, 128, 3)))
    expect = ray_reference(scene, frame, cam, tested, sun_dir=SUN_DIR)
    assert 0.05 < 1 - expect.mean() < 0.6
    frac, stray = agreement(frame.shadow[..., 0], expect, tested)
    assert frac >= 0.97 and stray == 0, (frac, stray)


def test_ortho_cascades_fit_slabs_of_the_view_box():
    """Host-side fitting: an orthographic camera's cascades split its depth range uniformly, and
    each map fits its slab of the view box -- a box, not a frustum widening with depth: every
    corner of the slab lies in the map, and the map is no larger than the slab needs (but for the
    PCF border, the 8/7 that lets a snapped centre cover it and one 2^(1/8) ladder step)."""
    from clrender.passes import shadow_views
    from clrender.scene.model import Sun
    cam = Camera.orthographic((7.0, 6.0, 9.0), (0.0, 0.5, 0.0), xmag=3.0, ymag=2.0, near=0.1, far=40)
    aspect = 4 / 3
    bounds = ((-50.0, -1.0, -50.0), (50.0, 4.0, 50.0))      # much wider than the view: no clamping
    sun = Sun((0.3, -1.0, 0.2), (1.0, 1.0, 1.0), True, 512)
    views = shadow_views.sun_views(sun, cam, aspect, bounds, 3, 0.75)
    right, up, fwd = (np.asarray(v) for v in _frame_of(cam))
    box = np.array([[x, y, z] for x in (-50, 50) for y in (-1, 4) for z in (-50, 50)])
    depths = (box - cam.eye) @ fwd
    lo, hi = max(cam.near, depths.min()), min(cam.far, depths.max())
    edges = lo + (hi - lo) * np.arange(4) / 3
    np.testing.assert_allclose([v.split for v in views[:-1]], edges[1:3], rtol=1e-12)
    for c, v in enumerate(views):
        corners = np.array([np.asarray(cam.eye) + d * fwd + sx * 2.0 * aspect * right + sy * 2.0 * up
                            for d in edges[c:c + 2] for sx in (-1, 1) for sy in (-1, 1)])
        q = (v.matrix.astype(np.float64) @ np.c_[corners, np.ones(8)].T).T
        ndc = np.abs(q[:, :2] / q[:, 3:])
        assert ndc.max() <= 1.0 + 1e-6, (c, ndc.max())
        assert ndc.max() > 1 / ((1 + 4 / 512) * 8 / 7 * 2 ** 0.125) - 1e-6, \
            f"cascade {c}: the map is {1 / ndc.max():.2f}x larger than its slab needs"


# -- velocity, transparency ------------------------------------------------------------------------------------

def test_panning_ortho_camera_has_uniform_analytic_velocity(make_renderer):
    """An orthographic camera moved by s along its right axis moves every surface point by
    s·W/(2·ymag·aspect) pixels, whatever its depth."""
    cam = ROOM_CAMERAS["orthographic"]
    right = np.asarray(cam.basis()[0])
    shift = 0.37
    prev = Camera.orthographic(np.asarray(cam.eye) + shift * right, np.asarray(cam.target) + shift * right, cam.up,
                               cam.xmag, cam.ymag, cam.near, cam.far)
    frame = make_renderer(RW, RH).render(room_scene(), cam, previous_camera=prev)
    fg = frame.triangle_id >= 0
    expect = shift * RW / (2 * cam.ymag * RW / RH)
    np.testing.assert_allclose(frame.velocity[fg][:, 0], expect, rtol=2e-3)
    np.testing.assert_allclose(frame.velocity[fg][:, 1], 0.0, atol=2e-3 * expect)
    assert np.all(frame.velocity[~fg] == 0)


@pytest.mark.parametrize("mode", ["abuffer", "depth_peeling"])
def test_ortho_transparency_matches_reference(make_renderer, device, mode):
    from reference import transparency as tref
    rng = np.random.default_rng(4)
    cam = Camera.orthographic((0.0, 0.0, 2.0), (0.0, 0.0, -1.0), xmag=3.0, ymag=2.5, near=0.5, far=30.0)
    wall = np.array([[[-6, -6, -10], [6, -6, -10], [6, 6, -10]], [[-6, -6, -10], [6, 6, -10], [-6, 6, -10]]])
    n = 24
    centers = rng.uniform((-2.5, -2.0, -8.0), (2.5, 2.0, 1.0), (n, 1, 3))
    glass = centers + rng.normal(scale=1.5, size=(n, 3, 3))                # some cross the near plane
    tris = np.concatenate([wall, glass])
    scene = triangles_scene(tris)
    scene.materials = [Material("wall", (0.7, 0.6, 0.5, 1.0), specular_intensity=0.3, specular_power=16.0),
                       Material("glass", (0.4, 0.8, 0.9, 1.0), opacity=0.45, double_sided=True,
                                specular_intensity=0.4, specular_power=12.0)]
    scene.triangle_material = np.array([0, 0] + [1] * n, np.int32)
    scene.lights = light_array([dict(position=(0.5, 1.0, -3.0), radius=8.0, color=(2.0, 1.8, 1.5)),
                                dict(position=(-2.0, -1.0, -6.0), radius=6.0, color=(0.5, 0.8, 1.5))])
    scene.ambient = 0.1
    w, h = 96, 80
    frame = make_renderer(w, h, transparency=mode, peel_layers=16).render(scene, cam)
    opaque = tref.opaque_color_from_frame(frame, cam, scene.lights, scene.ambient)
    exp = tref.blend(scene, cam, w, h, opaque)
    np.testing.assert_array_equal(frame.triangle_id, exp.fragments.opaque_id)
    np.testing.assert_array_equal(frame.fragment_count, exp.fragment_count)
    assert exp.fragment_count.max() >= 3 and exp.fragments.clipped.any()
    ok = ~exp.ambiguous
    assert ok.mean() > 0.97
    np.testing.assert_allclose(frame.transmittance[ok], exp.transmittance[ok], atol=1e-5)
    err = np.abs(frame.color.astype(np.float64) - exp.color)[ok]
    assert err.max() <= SHADING_TOL * float(exp.color.max()), err.max()


