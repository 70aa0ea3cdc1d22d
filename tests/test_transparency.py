"""Transparency (docs/transparency.md): the A-buffer against the independent NumPy reference
tests/reference/transparency.py.

* A-buffer == reference on random soups (hypothesis) of overlapping transparent triangles (random
  alpha and colours, vertex normals varying across each triangle, single- and double-sided, some
  crossing the near plane) with opaque occluders, a back wall, point and spot lights:
  fragment_count exact, transmittance within 1e-5, color within COLOR_TOL of the frame's brightest
  reference value. The opaque colour under the layers is the float64 reference shading of the
  frame's own (opaque-only) G-buffer, whose triangle_id must equal the reference's opaque raster;
* lights reaching only a glass (every culling option), early stop, shadows cast by glass (ray-cast
  visibility), far plane and background, coplanar ties, alpha-0 texels, SSAO, fragment shading ==
  opaque shading (sun cascades, shadowed spot, texture), tile sizes, odd image sizes, reuse.

The reference on its own: test_transparency_reference.py; order independence, depth peeling,
max_fragments_per_pixel, overflow, opaque scenes in every mode, the Khronos scene and bad input:
test_transparency_modes.py; screen door: test_screen_door.py; refraction: test_refraction.py.
"""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import clrender
from clrender import Camera, Material, Scene
from reference import shading as ref_shading
from reference import transparency as ref
from reference.raster import pixel_exact_camera, screen_to_world
from transparency_cases import (AMBIENT, CAMERA, PX_CAM, SIZE, H, W, assert_matches_reference, build_scene, expected,
                                point_lights, quad, random_soup, screen_quad, wall)

SETTINGS = dict(derandomize=True, deadline=None, print_blob=True,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large,
                                       HealthCheck.function_scoped_fixture])


# -- A-buffer against the reference -----------------------------------------------------------------

@settings(max_examples=20, **SETTINGS)
@given(seed=st.integers(0, 2**31 - 1), crossing=st.booleans())
def test_abuffer_matches_reference(make_renderer, seed, crossing):
    scene = random_soup(seed, crossing=crossing)
    frame = make_renderer(W, H).render(scene, CAMERA)
    exp, ok = expected(frame, scene)
    assert exp.fragment_count.sum() > 0
    assert_matches_reference(frame, scene, exp, ok, f"soup {seed} (crossing the near plane: {crossing})")


def test_near_clipped_transparent_triangles(make_renderer, device):
    """Transparent triangles crossing the near plane: their pieces' fragments (barycentrics carried
    by the clip) match the reference."""
    hits = 0
    for seed in (1, 2, 5):
        scene = random_soup(seed, crossing=True)
        frame = make_renderer(W, H).render(scene, CAMERA)
        exp, ok = expected(frame, scene)
        clipped = np.zeros((H, W), bool)
        clipped[exp.fragments.row[exp.fragments.clipped], exp.fragments.col[exp.fragments.clipped]] = True
        hits += int(clipped.sum())
        assert_matches_reference(frame, scene, exp, ok, f"soup {seed} with near-clipped layers")
    assert hits > 200, "the crossing triangles must put clipped fragments on screen"


def test_reference_barycentrics_agree():
    """The reference's barycentrics (contract edge functions) agree with ray casting against the
    unsnapped triangles up to the 1/256-pixel snapping, for whole and near-clipped triangles."""
    scene = random_soup(4, crossing=True)
    fr = ref.fragments(scene, CAMERA, W, H)
    assert len(fr) > 500 and fr.clipped.sum() > 100
    eye = np.asarray(CAMERA.eye, np.float64)
    dirs = ref_shading.pixel_directions(CAMERA, W, H)
    world = scene.positions.astype(np.float64)
    worst = 0.0
    for t in np.unique(fr.tri):
        sel = fr.tri == t
        ray = ref._ray_barycentrics(world[scene.triangles[t]], eye, dirs[fr.row[sel], fr.col[sel]])
        worst = max(worst, float(np.abs(ray - fr.bary[sel]).max()))
        assert (fr.bary[sel] > -1e-3).all() and np.allclose(fr.bary[sel].sum(-1), 1.0)
    assert worst < 2e-3, worst


def test_light_reaching_only_a_transparent_surface(make_renderer, device):
    """A small light in front of a transparent quad, far from the wall: light culling must take the
    fragments' depths into each tile's range (docs/transparency.md), with every culling option."""
    glass = Material("glass", (0.9, 0.9, 0.9, 1.0), opacity=0.6, specular_intensity=0.5, specular_power=16.0)
    scene = build_scene([wall(-20.0), (quad(-2, 2, -1.5, 1.5, -3.0), None, glass)],
                        lights=point_lights([((0.7, 0.3, -2.4), (3.0, 2.0, 1.0), 1.2),
                                             ((-0.9, -0.5, -2.7), (1.0, 2.0, 3.0), 0.8)]))
    frames = {}
    for opts in (dict(light_culling="brute_force"), dict(light_tile_size=8), dict(light_tile_size=16),
                 dict(light_tile_size=32), dict(light_tile_size=16, light_depth_mask=True)):
        frame = make_renderer(W, H, **opts).render(scene, CAMERA)
        exp, ok = expected(frame, scene)
        lit = exp.color.max(-1) > 1.5 * (np.asarray(glass.base_color[:3]).max() * AMBIENT)
        assert lit.sum() > 30, "the lights must visibly light the glass"
        assert_matches_reference(frame, scene, exp, ok, f"lights on glass only, {opts}")
        frames[repr(opts)] = frame
    base = frames[repr(dict(light_culling="brute_force"))]
    for k, f in frames.items():
        np.testing.assert_allclose(f.color, base.color, rtol=0, atol=1e-5 * base.color.max(), err_msg=k)


def test_early_stop(make_renderer, device):
    """Behind T < 1e-4 nothing is shaded: the 3rd layer (alpha 0.5) of a pixel whose first two leave
    T = 2.5e-5 changes neither colour nor transmittance; fragment_count still counts it."""
    size = SIZE
    dense = Material("dense", (0.2, 0.4, 0.6, 0.995), alpha_mode="BLEND", specular_intensity=0.0)
    bright = Material("bright", (1.0, 1.0, 1.0, 0.5), alpha_mode="BLEND", specular_intensity=0.0)
    parts = [(screen_quad(0, size, 0, size, 12.0), None, Material("wall", (1.0, 1.0, 1.0, 1.0)))]
    parts += [(screen_quad(4, 28, 4, 28, 3.0), None, dense), (screen_quad(4, 28, 4, 28, 4.0), None, dense),
              (screen_quad(0, 32, 0, 32, 5.0), None, bright)]
    scene = build_scene(parts, ambient=40.0)
    for opts in (dict(), dict(transparency="depth_peeling", peel_layers=3)):
        frame = make_renderer(size, size, **opts).render(scene, PX_CAM)
        exp, ok = expected(frame, scene, camera=PX_CAM, width=size, height=size)
        inner = np.zeros((size, size), bool)
        inner[4:28, 4:28] = True
        assert np.all(exp.fragment_count[inner] == 3) and np.all(exp.shaded[inner] == 2)
        np.testing.assert_array_equal(frame.fragment_count, exp.fragment_count)
        np.testing.assert_allclose(frame.transmittance[inner], 0.005 ** 2, rtol=1e-3,
                                   err_msg=f"{opts}: T must stop at the 2nd layer (1.25e-5 means the 3rd was blended)")
        np.testing.assert_allclose(frame.transmittance[~inner], 0.5)
        assert_matches_reference(frame, scene, exp, ok, f"early stop {opts}")


def test_transparent_layers_cast_shadows(make_renderer, device):
    """A shadowed spot at the eye: the front glass is lit, the glass behind it and the wall lie in its
    (full) shadow, elsewhere lit; fragments against the reference with ray-cast visibility."""
    from reference.shadow_rays import occluded
    size = 64
    cam = pixel_exact_camera(far=50.0)
    front = Material("front", (0.9, 0.8, 0.3, 1.0), opacity=0.4, specular_intensity=0.3, specular_power=8.0)
    back = Material("back", (0.3, 0.8, 0.9, 1.0), opacity=0.5, specular_intensity=0.3, specular_power=8.0)
    sq = lambda x0, x1, y0, y1, d: np.array([[screen_to_world(x0, y1, size, d), screen_to_world(x1, y1, size, d),
                                             screen_to_world(x1, y0, size, d)],
                                            [screen_to_world(x0, y1, size, d), screen_to_world(x1, y0, size, d),
                                             screen_to_world(x0, y0, size, d)]], np.float64)
    parts = [(sq(0, size, 0, size, 12.0), None, Material("wall", (0.8, 0.8, 0.8, 1.0), specular_intensity=0.1)),
             (sq(20, 44, 20, 44, 4.0), None, front), (sq(8, 56, 8, 56, 8.0), None, back)]
    scene = build_scene(parts, ambient=0.05)
    scene.add_spot_light((0.0, 0.0, 0.0), (0.0, 0.0, -1.0), (30.0, 30.0, 30.0), 40.0, 50.0, 60.0, shadow=True,
                         shadow_map_size=512)
    scene.add_point_light((2.0, 1.0, -6.0), (0.5, 0.5, 0.5), 10.0)
    frame = make_renderer(size, size).render(scene, cam)
    assert frame.shadow.shape == (size, size, 1)
    vis_opaque = frame.shadow[..., 0].astype(np.float64)
    behind_front = np.zeros((size, size), bool)
    behind_front[20:44, 20:44] = True
    assert vis_opaque[behind_front].max() < 0.05, "transparent surfaces cast full shadows on the wall"
    assert vis_opaque[2, 2] > 0.95

    def light_visibility(points, i):
        if i != 0:
            return np.ones(len(points))
        v = -points                                      # the spot sits at the origin
        dist = np.linalg.norm(v, axis=1)
        dirs = v / dist[:, None]
        return (~occluded(scene, points + 1e-3 * dirs, dirs, dist - 2e-3)).astype(np.float64)

    # the opaque colour with the frame's own visibility for the spot (as the G-buffer, taken as given)
    lights = scene.lights
    sh = lambda ls: ref_shading.shade_frame(frame, cam, ls, scene.ambient)
    opaque = sh(lights[1:]) + vis_opaque[..., None] * (sh(lights[:1]) - sh(lights[:0]))
    exp = ref.blend(scene, cam, size, size, opaque, light_visibility=light_visibility)
    edge = np.zeros((size, size), bool)                 # PCF and the map's texels blur 2 pixels around
    edge[18:46, 18:46] = True
    edge[22:42, 22:42] = False
    ok = ~edge & ~exp.ambiguous
    assert np.all(exp.fragment_count[behind_front] == 2)
    assert_matches_reference(frame, scene, exp, ok, "shadowed spot through two glass layers", min_ok=0.88)
    # and the back glass really is darker behind the front one than beside it (not just the reference)
    no_shadow = ref.blend(scene, cam, size, size, opaque)
    assert np.abs(no_shadow.color - exp.color)[behind_front].max() > 0.05 * exp.color.max()


def test_far_plane_and_background(make_renderer, device):
    """A glass tilted through the far plane over the background (no opaque surface: opaque depth
    +inf, colour 0): fragments stop at z <= far; over nothing the colour is the layers' alone."""
    cam = Camera.look_at((0.0, 0.0, 0.0), (0.0, 0.0, -1.0), fov_y_deg=60.0, near=0.1, far=9.0)
    t = np.radians(60.0)
    rot = np.array([[np.cos(t), 0, np.sin(t)], [0, 1, 0], [-np.sin(t), 0, np.cos(t)]])
    q = quad(-6, 6, -3, 3, 0.0) @ rot.T + np.array([0.0, 0.0, -8.0])
    glass = Material("glass", (0.3, 0.9, 0.6, 1.0), opacity=0.7, specular_intensity=0.3, specular_power=10.0)
    scene = build_scene([(quad(-20, -8, -8, 8, -6.0), None, Material("post")), (q, None, glass)],
                        lights=point_lights([((0.0, 2.0, -6.0), (2.0, 2.0, 2.0), 8.0)]))
    frame = make_renderer(W, H).render(scene, cam)
    exp, ok = expected(frame, scene, camera=cam)
    beyond = (frame.triangle_id < 0) & (exp.fragment_count == 0)
    layered = (frame.triangle_id < 0) & (exp.fragment_count > 0)
    assert layered.sum() > 200 and beyond.sum() > 100
    # the far plane cuts the glass: some of its pixels lie beyond it (the reference raster says where)
    assert_matches_reference(frame, scene, exp, ok, "glass through the far plane")
    assert np.all(frame.color[beyond] == 0) and np.all(frame.transmittance[beyond] == 1.0)
    assert frame.color[layered].min() > 0


def test_coplanar_layers_tie_order(make_renderer, device):
    """Exactly coplanar layers (the same vertices): ordered by triangle id, then prim; depth peeling
    peels them one by one and equals the A-buffer."""
    size = SIZE
    mats = [Material(f"c{k}", (*np.eye(3)[k % 3] * 0.8 + 0.1, 1.0), opacity=0.3 + 0.2 * k, specular_intensity=0.0)
            for k in range(3)]
    base = screen_quad(4, 28, 4, 28, 5.0)
    parts = [(screen_quad(0, size, 0, size, 12.0), None, Material("wall", (1.0, 1.0, 1.0, 1.0)))]
    parts += [(base, None, mats[k]) for k in (2, 0, 1)]           # ids 2-3 / 4-5 / 6-7: materials 2, 0, 1
    scene = build_scene(parts, ambient=1.0)
    abuf = make_renderer(size, size).render(scene, PX_CAM)
    exp, ok = expected(abuf, scene, camera=PX_CAM, width=size, height=size)
    assert (exp.fragment_count == 3).sum() == 24 * 24
    assert_matches_reference(abuf, scene, exp, ok, "coplanar layers")
    # the same layers listed in another order blend in that order (ties go to the lower id)
    other = build_scene(parts[:1] + [(base, None, mats[k]) for k in (0, 1, 2)], ambient=1.0)
    f2 = make_renderer(size, size).render(other, PX_CAM)
    exp2, ok2 = expected(f2, other, camera=PX_CAM, width=size, height=size)
    assert_matches_reference(f2, other, exp2, ok2, "coplanar layers, other order")
    assert np.abs(exp2.color - exp.color).max() > 0.05, "the tie order must matter in this scene"
    peeled = make_renderer(size, size, transparency="depth_peeling", peel_layers=3).render(scene, PX_CAM)
    np.testing.assert_array_equal(peeled.color, abuf.color, err_msg="coplanar fragments must peel one by one")
    np.testing.assert_array_equal(peeled.transmittance, abuf.transmittance)


def test_coplanar_with_opaque_is_not_in_front(make_renderer, device):
    """A glass with the opaque wall's own vertices has the same depths: not strictly in front, no fragment."""
    size = SIZE
    wall_q = screen_quad(0, size, 0, size, 8.0)
    glass = Material("glass", (1.0, 0.0, 0.0, 1.0), opacity=0.5)
    scene = build_scene([(wall_q, None, Material("wall")), (wall_q.copy(), None, glass),
                         (screen_quad(8, 24, 8, 24, 6.0), None, glass)])
    frame = make_renderer(size, size).render(scene, PX_CAM)
    exp, ok = expected(frame, scene, camera=PX_CAM, width=size, height=size)
    inner = np.zeros((size, size), bool)
    inner[8:24, 8:24] = True
    assert np.array_equal(exp.fragment_count, inner.astype(np.int32))
    assert_matches_reference(frame, scene, exp, ok, "glass coplanar with the wall")


def test_alpha_zero_texels_are_fragments(make_renderer, device):
    """Alpha does not decide whether a fragment exists: a texture whose left half has alpha 0 gives
    fragments over the whole quad, contributing nothing (T = 1) on that half."""
    from clrender import Texture
    size = SIZE
    rgba = np.full((8, 8, 4), 255, np.uint8)
    rgba[:, :4, 3] = 0
    rgba[:, 4:, 3] = 128
    q = screen_quad(8, 24, 8, 24, 4.0)
    uv = np.array([[[0, 1], [1, 1], [1, 0]], [[0, 1], [1, 0], [0, 0]]], np.float32)   # matches screen_quad's corners
    parts = [(screen_quad(0, size, 0, size, 8.0), None, Material("wall")),
             (q, None, Material("decal", (1.0, 1.0, 1.0, 1.0), base_color_texture=0, alpha_mode="BLEND"))]
    scene = build_scene(parts, uvs=np.concatenate([np.zeros((6, 2)), uv.reshape(-1, 2)]),
                        textures=[Texture("half", rgba, wrap_s="clamp", wrap_t="clamp")])
    frame = make_renderer(size, size).render(scene, PX_CAM)
    inner = np.zeros((size, size), bool)
    inner[8:24, 8:24] = True
    np.testing.assert_array_equal(frame.fragment_count, inner.astype(np.int32))
    left, right = inner.copy(), inner.copy()
    left[:, 14:] = False                       # texel columns 0-3 (away from the bilinear seam)
    right[:, :18] = False
    np.testing.assert_array_equal(frame.transmittance[left], 1.0)
    np.testing.assert_allclose(frame.transmittance[right], 1.0 - 128 / 255, atol=2e-3)
    np.testing.assert_array_equal(frame.transmittance[~inner], 1.0)


def test_ssao_does_not_apply_to_fragments(make_renderer, device):
    """With SSAO the opaque colour carries ao, the fragments do not (ambient · albedo)."""
    scene = random_soup(3, n_transparent=8)
    scene.ambient = 0.4                                         # a visible ambient term
    frame = make_renderer(W, H, ssao=True, ssao_radius=3.0).render(scene, CAMERA)
    assert frame.ao.min() < 0.9, "the scene must be occluded somewhere"
    opaque, info = ref_shading.shade_frame(frame, CAMERA, scene.lights, scene.ambient, details=True)
    opaque -= frame.albedo * (np.float32(scene.ambient) * (1.0 - frame.ao.astype(np.float64)))[..., None]
    exp = ref.blend(scene, CAMERA, W, H, opaque)
    fg = frame.triangle_id >= 0
    ok = ~exp.ambiguous & ~(fg & (info["min_abs_ndotl"] < 1e-4) & (exp.transmittance > 1e-3))
    assert_matches_reference(frame, scene, exp, ok, "SSAO on")


def textured_sphere(center, radius, n_lat=12, n_lon=24):
    """(positions, faces, normals, uvs) of a UV sphere, counter-clockwise seen from outside."""
    lat = np.linspace(0, np.pi, n_lat + 1)
    lon = np.linspace(0, 2 * np.pi, n_lon + 1)
    la, lo = np.meshgrid(lat, lon, indexing="ij")
    normals = np.stack([np.sin(la) * np.cos(lo), np.cos(la), -np.sin(la) * np.sin(lo)], -1).reshape(-1, 3)
    uvs = np.stack([lo / (2 * np.pi), la / np.pi], -1).reshape(-1, 2)
    idx = np.arange((n_lat + 1) * (n_lon + 1)).reshape(n_lat + 1, n_lon + 1)
    a, b, c, d = idx[:-1, :-1], idx[:-1, 1:], idx[1:, :-1], idx[1:, 1:]
    faces = np.concatenate([np.stack([a, c, b], -1).reshape(-1, 3), np.stack([b, c, d], -1).reshape(-1, 3)])
    return normals * radius + np.asarray(center), faces, normals, uvs


def lit_sphere_scene(opacity):
    """A textured single-sided sphere (opacity: BLEND when < 1) over nothing, an opaque box that
    shadows part of it from the sun, a shadowed sun (cascades), a shadowed spot and point lights."""
    from clrender import Texture
    rng = np.random.default_rng(2)
    rgba = np.full((16, 16, 4), 255, np.uint8)
    rgba[..., :3] = np.where(((np.arange(16)[:, None] // 4 + np.arange(16)[None, :] // 4) % 2)[..., None] == 1,
                             rng.integers(120, 255, 3), rng.integers(20, 120, 3))
    sp, sf, sn, su = textured_sphere((0.0, 0.0, -5.0), 1.6)
    box_p = np.array([[x, y, z] for x in (-2.6, -1.6) for y in (2.0, 2.6) for z in (-5.5, -4.5)], np.float64)
    box_f = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1], [2, 3, 7], [2, 7, 6],
                      [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])
    positions = np.concatenate([sp, box_p])
    normals = np.concatenate([sn, box_p / np.linalg.norm(box_p, axis=1, keepdims=True)])
    uvs = np.concatenate([su, np.zeros((len(box_p), 2))])
    faces = np.concatenate([sf, box_f + len(sp)])
    mats = [Material("glass", (1.0, 0.9, 0.8, 1.0), base_color_texture=0, specular_intensity=0.5,
                     specular_power=24.0, double_sided=False, opacity=opacity),
            Material("box", (0.6, 0.6, 0.6, 1.0))]
    scene = Scene(positions, normals, uvs, faces, np.r_[np.zeros(len(sf), np.int32), np.ones(12, np.int32)], mats,
                  textures=[Texture("checker", rgba)])
    scene.ambient = 0.15
    scene.set_sun((0.6, -1.0, -0.2), (1.2, 1.1, 1.0), shadow=True, shadow_map_size=512)
    scene.add_spot_light((2.5, 1.5, -2.0), (-2.5, -1.5, -3.0), (4.0, 3.0, 2.0), 10.0, 15.0, 30.0, shadow=True,
                         shadow_map_size=512)
    scene.add_point_light((-1.5, -1.0, -2.5), (0.6, 0.8, 1.5), 5.0)
    return scene


def test_fragment_shading_matches_opaque_shading(make_renderer, device):
    """A fragment is lit by the same code as an opaque pixel (sun and its cascades, shadowed spot,
    point light, texture, specular): a 50 % glass sphere over nothing shows 0.5 × the colour of the
    same sphere opaque, up to the G-buffer's quantization of the opaque one (normals, albedo)."""
    glass = make_renderer(W, H).render(lit_sphere_scene(0.5), CAMERA)
    solid = make_renderer(W, H).render(lit_sphere_scene(1.0), CAMERA)
    n_sphere = 2 * 12 * 24
    on = np.isin(solid.triangle_id, np.arange(n_sphere))
    assert on.sum() > 300 and np.all(glass.fragment_count[on] == 1)
    np.testing.assert_array_equal(glass.triangle_id[on], -1)
    np.testing.assert_allclose(glass.transmittance[on], 0.5, rtol=1e-6)
    assert glass.shadow.shape[-1] == solid.shadow.shape[-1] >= 2
    # the sun's and the spot's shadows reach the sphere (so both lookups are exercised)
    assert (solid.shadow[on] < 0.5).any(axis=0).all(), "sun and spot must each shadow part of the sphere"
    peak = float(solid.color[on].max())
    err = np.abs(2.0 * glass.color[on].astype(np.float64) - solid.color[on]).max(-1)
    assert np.median(err) < 2e-3 * peak, f"median |2·glass - opaque| {np.median(err):.3g} (peak {peak:.3g})"
    assert np.mean(err < 1e-2 * peak) > 0.97, (
        f"{np.mean(err >= 1e-2 * peak):.1%} of sphere pixels differ by more than 1 % of the peak "
        f"(worst {err.max():.3g}): fragments are not lit like opaque pixels")


def test_tile_sizes_change_nothing(make_renderer, device):
    """The raster tile size (8/16/32) changes neither the fragment lists' content nor their order."""
    scene = random_soup(11, n_transparent=12)
    frames = [make_renderer(W, H, tile_size=t).render(scene, CAMERA) for t in (8, 16, 32)]
    for f in frames[1:]:
        np.testing.assert_array_equal(f.fragment_count, frames[0].fragment_count)
        np.testing.assert_array_equal(f.color, frames[0].color)
        np.testing.assert_array_equal(f.transmittance, frames[0].transmittance)
    peeled = [make_renderer(W, H, tile_size=t, transparency="depth_peeling", peel_layers=2).render(scene, CAMERA)
              for t in (8, 32)]
    np.testing.assert_array_equal(peeled[0].color, peeled[1].color)


@pytest.mark.parametrize("size", [(37, 29), (61, 45)])
def test_odd_image_sizes(make_renderer, device, size):
    """Partial raster, light and resolve tiles at the image's right and bottom edges."""
    w, h = size
    for seed in (5, 6):
        scene = random_soup(seed, n_transparent=12)
        for opts in (dict(), dict(transparency="depth_peeling", peel_layers=3)):
            # light tiles of 8: partial ones at both edges of both sizes, and the programs the tier builds
            frame = make_renderer(w, h, light_tile_size=8, **opts).render(scene, CAMERA)
            exp, ok = expected(frame, scene, width=w, height=h, layers=opts.get("peel_layers"))
            assert_matches_reference(frame, scene, exp, ok, f"{w}x{h}, soup {seed}, {opts}")


def test_renderer_reuse_across_scenes(device):
    """One renderer: a transparent scene, an opaque one, the transparent one again: nothing leaks
    between frames (fragment lists, transmittance, grown buffers)."""
    r = clrender.Renderer(W, H, device=device.id)
    soup = random_soup(3, n_transparent=12)
    first = r.render(soup, CAMERA)
    opaque = build_scene([wall()], lights=soup.lights)
    plain = r.render(opaque, CAMERA)
    assert np.all(plain.fragment_count == 0) and np.all(plain.transmittance == 1.0)
    fresh = clrender.Renderer(W, H, device=device.id).render(opaque, CAMERA)
    np.testing.assert_array_equal(plain.color, fresh.color)
    again = r.render(soup, CAMERA)
    np.testing.assert_array_equal(again.color, first.color)
    np.testing.assert_array_equal(again.fragment_count, first.fragment_count)
    np.testing.assert_array_equal(again.transmittance, first.transmittance)
