"""Shadow maps (spot lights, the sun's cascades) against ray-cast truth and their contracts.

Truth is tests/reference/shadow_rays.py: rays from the G-buffer's world positions to the light
through trimesh/Embree (or NumPy), never clrender's maps.
"""
import numpy as np
import pytest

import clrender
from clrender import Camera, Material, Scene, Texture
from clrender.scene.model import SceneError
from reference.geometry import uv_sphere
from reference.shadow_rays import has_embree, near_edge, visibility
from bench.common import SPONZA, SPONZA_CAMERA

W, H = 128, 96
SPOT = dict(position=(-6.0, 5.0, 2.0), direction=(6.0, -5.0, -2.5), color=(30.0, 28.0, 25.0), radius=20.0,
            inner_deg=30.0, outer_deg=42.0)
SUN_DIR = (0.9, -0.6, -0.5)
CAMERA = Camera.look_at((7.0, 6.0, 9.0), (0.0, 0.5, 0.0), fov_y_deg=50, near=0.1, far=60)


def _box(lo, hi):
    """A box with its own 4 vertices per face, so the vertex normals are the flat face normals."""
    x0, y0, z0 = lo
    x1, y1, z1 = hi
    c = np.array([[x, y, z] for x in (x0, x1) for y in (y0, y1) for z in (z0, z1)], np.float32)
    quads = [[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4], [1, 5, 7, 3]]
    v = np.concatenate([c[q] for q in quads])
    f = np.concatenate([[[4 * k, 4 * k + 1, 4 * k + 2], [4 * k, 4 * k + 2, 4 * k + 3]] for k in range(6)])
    return v, f


def occluder_scene(floor_only=False) -> Scene:
    """A floor with a box, a sphere and a thin pole (double-sided white)."""
    parts = [(np.array([[-8, 0, -8], [8, 0, -8], [8, 0, 8], [-8, 0, 8]], np.float32), np.array([[0, 2, 1], [0, 3, 2]]))]
    if not floor_only:
        sv, sf, _ = uv_sphere(16, 32, radius=1.0, center=(-2.0, 1.2, 1.5))
        parts += [_box((-0.5, 0.0, -1.5), (1.5, 2.0, 0.0)), (sv, sf), _box((2.5, 0.0, 2.0), (2.7, 3.0, 2.2))]
    verts, faces, base = [], [], 0
    for v, f in parts:
        verts.append(v)
        faces.append(np.asarray(f) + base)
        base += len(v)
    return Scene.from_arrays(np.concatenate(verts), np.concatenate(faces))


def spot_scene(size=2048, **kw) -> Scene:
    scene = occluder_scene(**kw)
    scene.add_spot_light(SPOT["position"], SPOT["direction"], SPOT["color"], SPOT["radius"], SPOT["inner_deg"],
                         SPOT["outer_deg"], shadow=True, shadow_map_size=size)
    return scene


def in_spot(frame, camera):
    """Pixels inside the spot's radius and outer cone, with the surface facing it."""
    from reference.shadow_rays import face_normals, world_positions
    P = world_positions(frame, camera)
    L = np.asarray(SPOT["position"]) - P
    d = np.linalg.norm(L, axis=-1)
    L /= d[..., None]
    axis = np.asarray(SPOT["direction"]) / np.linalg.norm(SPOT["direction"])
    cos_a = -(L @ axis)
    return (frame.triangle_id >= 0) & (d < SPOT["radius"]) & (cos_a > np.cos(np.radians(SPOT["outer_deg"]))), L


def facing(scene, frame, L, min_cos=0.1):
    from reference.shadow_rays import face_normals
    tri = frame.triangle_id
    n = face_normals(scene)[np.maximum(tri, 0)]
    n *= np.sign((n * (frame.normal)).sum(-1, keepdims=True) + 1e-30)   # the side the camera sees
    return (tri >= 0) & ((n * L).sum(-1) > min_cos)


def agreement(frame_vis, ref_vis, tested, edge_radius=2):
    """(fraction agreeing, disagreeing pixels not near a reference edge)."""
    got = frame_vis > 0.5
    ref_img = np.zeros(tested.shape, bool)
    ref_img[tested] = ref_vis
    agree = (got == ref_img) | ~tested
    far_from_edge = ~near_edge(ref_img, tested, edge_radius)
    return float(agree[tested].mean()), int((~agree & far_from_edge).sum())


def ray_reference(scene, frame, camera, mask, **light):
    ref = np.zeros(mask.shape, bool)
    vis, idx = visibility(scene, frame, camera, pixels=np.flatnonzero(mask), **light)
    ref.reshape(-1)[idx] = vis
    return ref[mask]


def test_spot_hard_shadows_match_ray_casting(make_renderer):
    scene = spot_scene()
    frame = make_renderer(W, H, shadow_filter="hard").render(scene, CAMERA)
    assert frame.shadow.shape == (H, W, 1) and frame.shadow.dtype == np.float32
    lit, L = in_spot(frame, CAMERA)
    tested = lit & facing(scene, frame, L)
    assert tested.sum() > 2000
    ref = ray_reference(scene, frame, CAMERA, tested, light_pos=SPOT["position"])
    assert 0.1 < 1 - ref.mean() < 0.6, "the scene must have shadows to compare"
    frac, stray = agreement(frame.shadow[..., 0], ref, tested)
    assert frac >= 0.97, frac
    assert stray == 0, f"{stray} disagreeing pixels away from shadow edges"


def test_sun_cascades_match_ray_casting(make_renderer):
    scene = occluder_scene()
    scene.set_sun(SUN_DIR, (2.0, 1.9, 1.7), shadow_map_size=2048)
    frame = make_renderer(W, H, shadow_filter="hard").render(scene, CAMERA)
    assert frame.shadow.shape == (H, W, 1)
    L = -np.asarray(SUN_DIR) / np.linalg.norm(SUN_DIR)
    tested = facing(scene, frame, np.broadcast_to(L, (H, W, 3)))
    ref = ray_reference(scene, frame, CAMERA, tested, sun_dir=SUN_DIR)
    assert 0.05 < 1 - ref.mean() < 0.6
    frac, stray = agreement(frame.shadow[..., 0], ref, tested)
    assert frac >= 0.97, frac
    assert stray == 0


def test_one_and_three_cascades_agree_away_from_edges(make_renderer):
    scene = occluder_scene()
    scene.set_sun(SUN_DIR, (2.0, 1.9, 1.7), shadow_map_size=1024)
    one = make_renderer(W, H, shadow_filter="hard", sun_cascades=1).render(scene, CAMERA).shadow[..., 0]
    three = make_renderer(W, H, shadow_filter="hard", sun_cascades=3).render(scene, CAMERA).shadow[..., 0]
    fg = np.ones(one.shape, bool)
    differ = (one > 0.5) != (three > 0.5)
    assert differ.mean() < 0.02
    assert not (differ & ~near_edge(three > 0.5, fg, 2)).any()


def test_spot_shadow_stays_inside_its_cone(make_renderer):
    scene = spot_scene(size=512)
    frame = make_renderer(W, H).render(scene, CAMERA)
    lit, _ = in_spot(frame, CAMERA)
    vis = frame.shadow[..., 0]
    assert (vis[~lit] == 1.0).all()
    assert (vis[lit] < 0.5).sum() > 100


@pytest.mark.parametrize("filt", ["hard", "pcf3x3", "poisson"])
def test_unoccluded_light_casts_no_shadow(make_renderer, filt):
    """A floor seen by a spot and the sun: no acne, visibility exactly 1 (bias and normal offset)."""
    scene = spot_scene(size=1024, floor_only=True)
    scene.set_sun(SUN_DIR, (1.0, 1.0, 1.0), shadow_map_size=1024)
    frame = make_renderer(W, H, shadow_filter=filt).render(scene, CAMERA)
    assert frame.shadow.shape == (H, W, 2)
    assert (frame.shadow == 1.0).all()


def test_filters_are_bounded_and_soften_only_edges(make_renderer):
    scene = spot_scene(size=1024)
    scene.set_sun(SUN_DIR, (1.0, 1.0, 1.0), shadow_map_size=1024)
    hard = make_renderer(W, H, shadow_filter="hard").render(scene, CAMERA).shadow
    fg = np.ones(hard.shape[:2], bool)
    for filt in ("pcf3x3", "poisson"):
        soft = make_renderer(W, H, shadow_filter=filt).render(scene, CAMERA).shadow
        assert soft.min() >= 0.0 and soft.max() <= 1.0
        for k in range(hard.shape[2]):
            h, s = hard[..., k], soft[..., k]
            partial = (s > 0.0) & (s < 1.0)
            assert partial.any(), f"{filt} never softens an edge"
            assert not (partial & ~near_edge(h > 0.5, fg, 3)).any(), f"{filt}: soft values away from edges"
            assert abs(float(s.mean()) - float(h.mean())) < 0.02
            assert np.mean(np.abs(s - h) > 0.5) < 0.02


def test_pcf_is_monotone_across_a_straight_edge(make_renderer):
    """The sun over a tall wall: along image columns crossing the shadow's straight edge the
    PCF visibility goes from 1 to 0 without oscillating."""
    wall_v, wall_f = _box((-6.0, 0.0, -0.1), (6.0, 4.0, 0.1))
    floor = np.array([[-8, 0, -8], [8, 0, -8], [8, 0, 8], [-8, 0, 8]], np.float32)
    scene = Scene.from_arrays(np.concatenate([floor, wall_v]), np.concatenate([[[0, 2, 1], [0, 3, 2]], wall_f + 4]))
    scene.set_sun((0.0, -1.0, 0.8), (1.0, 1.0, 1.0), shadow_map_size=512)
    cam = Camera.look_at((0.0, 14.0, 10.0), (0.0, 0.0, 5.0), fov_y_deg=45, near=0.1, far=60)
    frame = make_renderer(64, 64, shadow_filter="pcf3x3", sun_cascades=1).render(scene, cam)
    vis = frame.shadow[..., 0]
    floor_px = frame.triangle_id < 2
    checked = 0
    for x in range(8, 56):
        col = vis[:, x][floor_px[:, x]]
        if col.min() < 0.1 and col.max() > 0.9:
            steps = np.diff(col)
            assert (steps[steps > 0] < 0.05).all() or (steps[steps < 0] > -0.05).all(), col
            checked += 1
    assert checked > 20


def test_alpha_masked_quad_casts_a_masked_shadow(make_renderer):
    """A MASK quad whose left half is transparent: the floor below is shadowed only under its
    opaque half (points chosen away from the edge; the spot is straight above)."""
    rgba = np.zeros((8, 8, 4), np.uint8)
    rgba[..., :3] = 200
    rgba[:, 4:, 3] = 255
    quad = np.array([[-1, 2, 1], [1, 2, 1], [1, 2, -1], [-1, 2, -1]], np.float32)
    floor = np.array([[-4, 0, -4], [4, 0, -4], [4, 0, 4], [-4, 0, 4]], np.float32)
    uvs = np.array([[0, 1], [1, 1], [1, 0], [0, 0], [0, 0], [0, 0], [0, 0], [0, 0]], np.float32)
    scene = Scene(np.concatenate([quad, floor]), np.tile([[0, 1, 0]], (8, 1)), uvs,
                  np.array([[0, 1, 2], [0, 2, 3], [4, 6, 5], [4, 7, 6]]), np.array([0, 0, 1, 1], np.int32),
                  materials=[Material("leaf", base_color_texture=0, alpha_mode="MASK", alpha_cutoff=0.5),
                             Material("floor")], textures=[Texture("mask", rgba)])
    scene.add_spot_light((0, 8, 0), (0, -1, 0), (10, 10, 10), 20, 30, 40, shadow=True, shadow_map_size=512)
    cam = Camera.look_at((0, 6, 7), (0, 0, 0), fov_y_deg=40, near=0.1, far=50)
    frame = make_renderer(64, 64, shadow_filter="hard").render(scene, cam)
    vis = frame.shadow[..., 0]
    floor_px = frame.triangle_id >= 2
    from reference.shadow_rays import world_positions
    P = world_positions(frame, cam)
    # floor point -> where its ray to the light crosses y = 2 (the quad's plane)
    t = (2.0 - P[..., 1]) / (8.0 - P[..., 1])
    qx = P[..., 0] + t * (0.0 - P[..., 0])
    qz = P[..., 2] + t * (0.0 - P[..., 2])
    inside = (np.abs(qx) < 0.9) & (np.abs(qz) < 0.9) & floor_px
    opaque = inside & (qx > 0.1)            # u > 0.55 of the quad: opaque texels
    clear = inside & (qx < -0.1)
    assert opaque.sum() > 20 and clear.sum() > 20
    assert (vis[opaque] == 0.0).all()
    assert (vis[clear] == 1.0).all()


def test_deterministic(make_renderer):
    scene = spot_scene(size=512)
    scene.set_sun(SUN_DIR, (1.0, 1.0, 1.0), shadow_map_size=512)
    r = make_renderer(W, H, shadow_filter="poisson")
    a, b = r.render(scene, CAMERA), r.render(scene, CAMERA)
    assert np.array_equal(a.shadow, b.shadow) and np.array_equal(a.color, b.color)


def test_shadows_off_launch_nothing(make_renderer):
    scene = spot_scene(size=512)
    scene.set_sun(SUN_DIR, (1.0, 1.0, 1.0))
    off = make_renderer(W, H, shadows=False)
    assert "shadow" not in [p.name for p in off.pipeline.passes]
    frame = off.render(scene, CAMERA)
    assert frame.shadow.shape == (H, W, 0) and "shadow_ms" not in frame.stats
    # shadows on, but nothing casts: no shadow pass runs, K = 0; the sun still lights
    plain = occluder_scene()
    plain.add_spot_light(SPOT["position"], SPOT["direction"], SPOT["color"], 20, 30, 42)   # unshadowed
    plain.set_sun(SUN_DIR, (1.0, 1.0, 1.0), shadow=False)
    frame = make_renderer(W, H).render(plain, CAMERA)
    assert frame.shadow.shape == (H, W, 0) and "shadow_ms" not in frame.stats
    assert frame.color.max() > 0.5


def test_shadowed_light_equals_unshadowed_where_visible(make_renderer):
    """The shadowed spot is a light like any other: where visibility is 1 the color is the same."""
    lit_scene = spot_scene(size=512)
    plain = occluder_scene()
    plain.add_spot_light(SPOT["position"], SPOT["direction"], SPOT["color"], SPOT["radius"], SPOT["inner_deg"],
                         SPOT["outer_deg"])
    r = make_renderer(W, H)
    a, b = r.render(lit_scene, CAMERA), r.render(plain, CAMERA)
    full = a.shadow[..., 0] == 1.0
    np.testing.assert_array_equal(a.color[full], b.color[full])
    dark = a.shadow[..., 0] == 0.0
    assert (a.color[dark] <= b.color[dark]).all()            # back faces: dark in both
    assert (a.color[dark].sum(-1) < b.color[dark].sum(-1)).mean() > 0.5


def test_atlas_packs_many_sizes_and_fails_loudly(make_renderer):
    scene = occluder_scene()
    scene.set_sun(SUN_DIR, (1.0, 1.0, 1.0), shadow_map_size=256)
    for k, size in enumerate((512, 128, 256, 512)):
        scene.add_spot_light((2.0 - k, 7.0, 3.0), SPOT["direction"], (5, 5, 5), 20, 30, 42, shadow=True,
                             shadow_map_size=size)
    scene.add_random_lights(50, seed=3, radius=(0.5, 1.5))
    frame = make_renderer(W, H).render(scene, CAMERA)
    assert frame.shadow.shape == (H, W, 5) and frame.stats["shadow_maps"] == 3 + 4
    # the same light alone (another place in another atlas) gives the same visibility
    alone = occluder_scene()
    alone.add_spot_light((1.0, 7.0, 3.0), SPOT["direction"], (5, 5, 5), 20, 30, 42, shadow=True,
                         shadow_map_size=128)
    np.testing.assert_array_equal(make_renderer(W, H).render(alone, CAMERA).shadow[..., 0], frame.shadow[..., 2])
    with pytest.raises(ValueError, match="shadow atlas"):
        make_renderer(W, H, shadow_atlas_max=512).render(scene, CAMERA)


def test_atlas_beyond_device_memory_is_a_clear_error(device, monkeypatch):
    """The atlas is sized by the scene's lights at render time: checked before allocating."""
    import clrender.device.limits
    import clrender.render.memory
    scene = occluder_scene()
    scene.add_spot_light((1.0, 7.0, 3.0), SPOT["direction"], (5, 5, 5), 20, 30, 42, shadow=True,
                         shadow_map_size=1024)
    renderer = clrender.Renderer(W, H, device=device.id)     # its own: the limit applies after construction
    monkeypatch.setattr(clrender.device.limits, "limits", lambda dev: (1 << 40, 1 << 20))
    with pytest.raises(clrender.render.memory.DeviceMemoryError, match=r"shadow atlas .* needs 4194304 bytes"):
        renderer.render(scene, CAMERA)


def test_shadow_tile_size_changes_nothing_but_speed(device):
    """The maps' raster tiles (shadow_tile_size 8, 16, 32; the default: 32 on CPUs) give the same
    atlas bit for bit, sun cascades and spots (the masked case: test_alpha_masked_quad_...)."""
    scene = spot_scene(size=256)
    scene.set_sun(SUN_DIR, (1.0, 1.0, 1.0), shadow_map_size=256)
    frames, atlases = {}, {}
    for tile in (8, 16, 32, None):
        r = clrender.Renderer(W, H, device=device.id, shadow_tile_size=tile)
        frames[tile] = r.render(scene, CAMERA)
        atlases[tile] = r.pipeline.shadow.atlas.get()
    assert (frames[8].shadow < 0.5).any(axis=(0, 1)).all(), "every map must cast some shadow here"
    for tile in (16, 32, None):
        np.testing.assert_array_equal(atlases[tile], atlases[8], err_msg=str(tile))
        np.testing.assert_array_equal(frames[tile].color, frames[8].color, err_msg=str(tile))


def test_sun_cascades_are_kept_when_the_camera_moves_less_than_their_grid(device):
    """A cascade's side is on a ladder and its centre on a grid of 1/8 of the side
    (shadow_views.py), so a camera nudged by less than the grid gives the same cascades: every
    map is kept (none rendered), and the frame still equals a fresh renderer's bit for bit."""
    scene = spot_scene(size=256)
    scene.set_sun(SUN_DIR, (1.0, 1.0, 1.0), shadow_map_size=256)
    r = clrender.Renderer(W, H, device=device.id)
    r.render(scene, CAMERA)
    shift = np.array([2e-3, 0.0, 1e-3])
    nudged = Camera.look_at(np.add(CAMERA.eye, shift), np.add(CAMERA.target, shift), fov_y_deg=50, near=0.1, far=60)
    frame = r.render(scene, nudged)
    assert frame.stats["shadow_maps"] == 4 and frame.stats["shadow_maps_reused"] == 4   # none rendered
    fresh = clrender.Renderer(W, H, device=device.id).render(scene, nudged)
    np.testing.assert_array_equal(frame.shadow, fresh.shadow)
    np.testing.assert_array_equal(frame.color, fresh.color)
    assert (frame.shadow[..., 0] < 0.5).any(), "the sun must cast some shadow here"


def test_sun_cascades_cover_their_slices_for_random_cameras():
    """Host-side: for random perspective cameras, every corner of each cascade's slice of the view
    frustum (inside the scene's bounds) projects inside its map, with the PCF border to spare."""
    from clrender.passes import shadow_views
    from clrender.scene.model import Sun
    rng = np.random.default_rng(5)
    bounds = ((-200.0, -200.0, -200.0), (200.0, 200.0, 200.0))   # wider than every view: no clamping
    sun = Sun(SUN_DIR, (1.0, 1.0, 1.0), True, 512)
    for _ in range(40):
        eye = rng.uniform(-5, 5, 3) + (0.0, 10.0, 0.0)
        cam = Camera.look_at(eye, eye + rng.normal(size=3), fov_y_deg=float(rng.uniform(20, 80)), near=0.1,
                             far=float(rng.uniform(5, 30)))
        aspect = float(rng.uniform(0.5, 2.0))
        views = shadow_views.sun_views(sun, cam, aspect, bounds, 3, 0.75)
        right, up, back = (np.asarray(v, np.float64) for v in cam.basis())
        tan_x, tan_y = cam.half_extents(aspect)
        splits = [cam.near] + [v.split for v in views[:-1]] + [cam.far]
        for c, v in enumerate(views):
            pts = np.array([np.asarray(cam.eye) + d * (-back + sx * tan_x * right + sy * tan_y * up)
                            for d in splits[c:c + 2] for sx in (-1, 1) for sy in (-1, 1)])
            q = (v.matrix.astype(np.float64) @ np.c_[pts, np.ones(8)].T).T
            assert np.abs(q[:, :2] / q[:, 3:]).max() <= 1.0 - 3.0 / v.size, c


def test_static_maps_are_reused_across_frames_and_match_fresh_renders(device):
    """A static spot's map is not rendered again when only the camera moves (the sun's cascades
    follow the camera); moving the light, or another map taking its atlas square, redraws it.
    Every frame equals what a fresh renderer gives, bit for bit."""
    def fresh(scene, camera):
        return clrender.Renderer(W, H, device=device.id).render(scene, camera)

    scene = spot_scene(size=512)
    scene.set_sun(SUN_DIR, (1.0, 1.0, 1.0), shadow_map_size=256)
    moved = Camera.look_at((-6.0, 7.0, 8.0), (0.0, 0.5, 0.0), fov_y_deg=50, near=0.1, far=60)
    r = clrender.Renderer(W, H, device=device.id)
    first = r.render(scene, CAMERA)
    assert first.stats["shadow_maps_reused"] == 0
    second = r.render(scene, moved)
    assert second.stats["shadow_maps_reused"] == 1 and second.stats["shadow_maps"] == 4
    expected = fresh(scene, moved)
    np.testing.assert_array_equal(second.shadow, expected.shadow)
    np.testing.assert_array_equal(second.color, expected.color)

    lights = scene.lights.copy()                      # the spot moves: its map is redrawn
    lights["position"][0] += (0.5, 0.0, 0.0)
    scene.lights = lights
    third = r.render(scene, moved)
    assert third.stats["shadow_maps_reused"] == 3     # same camera: only the cascades are kept
    np.testing.assert_array_equal(third.shadow, fresh(scene, moved).shadow)

    sun = scene.sun                                   # without the sun the spot takes its square
    scene.sun = None
    np.testing.assert_array_equal(r.render(scene, moved).shadow, fresh(scene, moved).shadow)
    scene.sun = sun                                   # and back: the spot's old square was overwritten
    back = r.render(scene, moved)
    np.testing.assert_array_equal(back.shadow, fresh(scene, moved).shadow)
    assert (back.shadow < 0.5).any(axis=(0, 1)).all(), "every map must cast some shadow here"
    never = clrender.Renderer(W, H, device=device.id, shadow_map_reuse=False)
    never.render(scene, moved)
    assert never.render(scene, moved).stats["shadow_maps_reused"] == 0


def test_shadow_options_are_validated():
    for bad in (dict(shadow_filter="pcf5"), dict(sun_cascades=0), dict(sun_cascades=5), dict(shadow_bias=-1),
                dict(shadows=1), dict(shadow_atlas_max=8), dict(shadow_map_reuse="yes"), dict(shadow_tile_size=12),
                dict(shadow_tile_size=64)):
        with pytest.raises(ValueError):
            clrender.RenderConfig.from_options(**bad)
    scene = occluder_scene()
    with pytest.raises(SceneError):
        scene.add_spot_light((0, 1, 0), (0, -1, 0), (1, 1, 1), 5, 10, 20, shadow=True, shadow_map_size=8)
    with pytest.raises(SceneError):
        scene.set_sun((0, 0, 0), (1, 1, 1))


@pytest.mark.skipif(not SPONZA.is_file(), reason=f"Sponza not found at {SPONZA} (shared scenes absent)")
@pytest.mark.skipif(not has_embree(), reason="embreex not installed: Sponza ray casting needs Embree")
def test_sponza_sun_and_spot_match_ray_casting(device):
    scene = clrender.load_scene(SPONZA)
    cam = Camera.look_at(**SPONZA_CAMERA)
    sun_dir = (0.45, -1.0, 0.35)            # through the atrium onto the floor and the right gallery
    scene.set_sun(sun_dir, (3.0, 2.8, 2.5), shadow_map_size=2048)
    spot_pos, spot_dir = (-9.0, 9.5, -0.8), (0.35, -1.0, 0.0)   # above the floor, columns cast shadows
    scene.add_spot_light(spot_pos, spot_dir, (30, 28, 25), 20, 25, 40, shadow=True, shadow_map_size=2048)
    w, h = 384, 216
    frame = clrender.Renderer(w, h, device=device.id, shadow_filter="hard").render(scene, cam)
    for k, light in enumerate((dict(sun_dir=sun_dir), dict(light_pos=spot_pos))):
        if "sun_dir" in light:
            L = np.broadcast_to(-np.asarray(sun_dir) / np.linalg.norm(sun_dir), (h, w, 3))
            tested = facing(scene, frame, L, 0.15)
        else:
            from reference.shadow_rays import world_positions
            P = world_positions(frame, cam)
            L = np.asarray(spot_pos) - P
            d = np.linalg.norm(L, axis=-1)
            L = L / d[..., None]
            cos_a = -(L @ (np.asarray(spot_dir) / np.linalg.norm(spot_dir)))
            tested = facing(scene, frame, np.nan_to_num(L), 0.15) & (d < 20) & (cos_a > np.cos(np.radians(40)))
        assert tested.sum() > 3000
        ref = ray_reference(scene, frame, cam, tested, **light)
        frac, stray = agreement(frame.shadow[..., k], ref, tested)
        print(f"Sponza {'sun' if k == 0 else 'spot'}: {frac:.4f} of {tested.sum()} pixels agree, "
              f"{stray} disagree away from edges, {1 - ref.mean():.3f} shadowed")
        assert frac >= 0.97, (k, frac)
        # Away from visibility edges only alpha-masked leaves (opaque to the rays) may disagree.
        assert stray <= 0.01 * tested.sum(), (k, stray)


def test_toml_sun_and_shadowed_spot(tmp_path):
    scene_file = tmp_path / "s.toml"
    scene_file.write_text('''
[sun]
direction = [0, -2, 0]
color = [1.0, 0.5, 0.25]
intensity = 2.0
shadow_map_size = 512

[[light]]
type = "spot"
position = [0, 5, 0]
direction = [0, -1, 0]
radius = 10
shadow = true
shadow_map_size = 256

[[light]]
type = "spot"
position = [1, 5, 0]
direction = [0, -1, 0]
radius = 10
''')
    scene = clrender.load_scene(scene_file)
    assert scene.sun == clrender.Sun((0, -1, 0), (2.0, 1.0, 0.5), True, 512)
    assert scene.lights["shadow_size"].tolist() == [256, 0]
    bad = tmp_path / "bad.toml"
    bad.write_text('[sun]\ndirection = [0, -1, 0]\nshadow = "yes"\n')
    with pytest.raises(SceneError, match="shadow"):
        clrender.load_scene(bad)


def test_gltf_first_directional_light_becomes_the_sun(tmp_path):
    from test_loaders_lights import light_ref, write_gltf
    lights = [{"type": "directional", "color": [1.0, 0.5, 0.0], "intensity": 2.0}, {"type": "directional"}]
    nodes = [{"mesh": 0}, {"extensions": light_ref(0)}, {"extensions": light_ref(1)}]
    with pytest.warns(UserWarning, match="the first is the sun"):
        scene = clrender.load_scene(write_gltf(tmp_path / "d.gltf", nodes, lights))
    assert scene.sun is not None and scene.sun.shadow
    np.testing.assert_allclose(scene.sun.direction, (0, 0, -1), atol=1e-6)     # glTF lights point down -Z
    assert scene.sun.color == (2.0, 1.0, 0.0)
