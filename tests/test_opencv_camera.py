"""OpenCV pinhole cameras (Camera.from_opencv / to_opencv) and the asymmetric frustum in every pass.

Truth: a world point X lands at K(RX + t) / z with pixel centres at integer + 0.5 (clrender/scene/camera.py);
the crop test renders a centred camera at twice the size and an off-centre one seeing a window of
it: the window's rays are the same rays, so every pass that forgot the principal point (light
culling, light quads, stencil, the variants' lighting, the environment background) shows up as a
difference; SSAO and spot shadows are checked against ray-cast references (tests/reference).
"""
from __future__ import annotations

import numpy as np
import pytest

from clrender import Camera, Scene
from clrender.scene.model import SceneObject
from reference.geometry import uv_sphere
from reference import shading as ref

import lighting_cases as lighting
import test_shadows as shadows


def random_rotation(rng) -> np.ndarray:
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q *= np.sign(np.diag(r))
    return q * np.sign(np.linalg.det(q))


def random_k(rng, w, h) -> np.ndarray:
    fx = rng.uniform(0.7, 1.1) * w
    return np.array([[fx, 0.0, rng.uniform(0.3, 0.7) * w],
                     [0.0, fx * rng.uniform(0.8, 1.25), rng.uniform(0.3, 0.7) * h],
                     [0.0, 0.0, 1.0]])


def spheres_scene(centres, radii) -> Scene:
    """One object per sphere (mesh k = object k)."""
    verts, faces, normals, tri_mesh, base = [], [], [], [], 0
    for k, (c, r) in enumerate(zip(centres, radii)):
        v, f, n = uv_sphere(24, 48, radius=float(r), center=tuple(c))
        verts.append(v)
        normals.append(n)
        faces.append(np.asarray(f) + base)
        tri_mesh.append(np.full(len(f), k, np.int32))
        base += len(v)
    names = [f"sphere{k}" for k in range(len(centres))]
    return Scene(np.concatenate(verts), np.concatenate(normals), np.zeros((base, 2), np.float32),
                 np.concatenate(faces), np.zeros(sum(len(f) for f in faces), np.int32), mesh_names=names,
                 triangle_mesh=np.concatenate(tri_mesh))


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_sphere_centres_project_to_k_r_t_within_0_3_px(make_renderer, seed):
    rng = np.random.default_rng(seed)
    w, h = 320, 240
    K, R, t = random_k(rng, w, h), random_rotation(rng), rng.normal(size=3)
    # points in front of the camera, spread over the image, at depths 4..8
    n = 12
    uv = np.c_[rng.uniform(0.12, 0.88, n) * w, rng.uniform(0.12, 0.88, n) * h]
    z = rng.uniform(4.0, 8.0, n)
    cam_pts = np.c_[(uv[:, 0] - K[0, 2]) / K[0, 0] * z, (uv[:, 1] - K[1, 2]) / K[1, 1] * z, z]
    X = (cam_pts - t) @ R                                    # world = Rᵀ(x_cam - t)
    radii = 5.0 * z / K[0, 0]                                # ~5 px on screen
    scene = spheres_scene(X, radii)
    camera = Camera.from_opencv(K, R, t, w, h, near=0.5, far=20.0)
    frame = make_renderer(w, h).render(scene, camera)
    oid = frame.object_id
    expect = (K @ (R @ X.T + t[:, None])).T
    expect = expect[:, :2] / expect[:, 2:]
    ys, xs = np.mgrid[0:h, 0:w] + 0.5
    for k in range(n):
        mine = oid == k
        assert mine.sum() > 40, f"sphere {k} covers {mine.sum()} pixels"
        got = np.array([xs[mine].mean(), ys[mine].mean()])
        err = np.linalg.norm(got - expect[k])
        assert err < 0.3, f"sphere {k}: centroid {got} vs K(RX+t) {expect[k]}: {err:.3f} px"
    assert set(np.unique(oid)) == set(range(-1, n))


def test_to_opencv_round_trips():
    rng = np.random.default_rng(5)
    for _ in range(20):
        w, h = int(rng.integers(16, 2000)), int(rng.integers(16, 2000))
        K, R, t = random_k(rng, w, h), random_rotation(rng), rng.normal(size=3) * 5
        K2, R2, t2 = Camera.from_opencv(K, R, t, w, h).to_opencv(w, h)
        assert np.allclose(K2, K, rtol=1e-12, atol=1e-9) and np.allclose(R2, R, atol=1e-12)
        assert np.allclose(t2, t, atol=1e-9)
    # a look-at camera through OpenCV and back projects the same points
    cam = Camera.look_at((1, 2, 3), (0, 0.5, -1), fov_y_deg=50, near=0.2, far=40)
    back = Camera.from_opencv(*cam.to_opencv(640, 360), 640, 360, near=0.2, far=40)
    assert np.allclose(back.view_projection(640, 360), cam.view_projection(640, 360), atol=1e-12)
    K, _, _ = cam.to_opencv(640, 360)
    assert K[0, 2] == 320 and K[1, 2] == 180 and np.isclose(K[0, 0], K[1, 1])


@pytest.mark.parametrize("K,R,t,words", [
    ([[0, 0, 10], [0, 100, 10], [0, 0, 1]], np.eye(3), (0, 0, 0), "focal lengths must be positive"),
    ([[100, 0, 10], [0, -100, 10], [0, 0, 1]], np.eye(3), (0, 0, 0), "focal lengths must be positive"),
    ([[100, 0, 10], [0, 100, 10], [0, 0, 0]], np.eye(3), (0, 0, 0), "no skew"),
    ([[100, 3, 10], [0, 100, 10], [0, 0, 1]], np.eye(3), (0, 0, 0), "no skew"),
    ([[100, 0, 10], [0, 100, 10], [0, 0, 1]], np.diag([1, 1, 1.001]), (0, 0, 0), "not a rotation"),
    ([[100, 0, 10], [0, 100, 10], [0, 0, 1]], np.diag([1, 1, -1]), (0, 0, 0), "not a rotation"),
    ([[100, 0, np.nan], [0, 100, 10], [0, 0, 1]], np.eye(3), (0, 0, 0), "NaN"),
    ([[100, 0, 10], [0, 100, 10], [0, 0, 1]], np.eye(3), (0, np.inf, 0), "NaN or infinite"),
    ([[100, 0, 10], [0, 100, 10]], np.eye(3), (0, 0, 0), "shape"),
])
def test_bad_opencv_input_is_one_line_error(K, R, t, words):
    with pytest.raises(ValueError, match=words) as info:
        Camera.from_opencv(K, R, t, 64, 48)
    assert "\n" not in str(info.value)


def test_bad_image_size_and_orthographic():
    K = [[100, 0, 10], [0, 100, 10], [0, 0, 1]]
    for w, h in ((0, 48), (64, -1), (64.5, 48), (True, 48)):
        with pytest.raises(ValueError, match="image size"):
            Camera.from_opencv(K, np.eye(3), (0, 0, 0), w, h)
    with pytest.raises(ValueError, match="orthographic"):
        Camera.orthographic((0, 0, 5), (0, 0, 0)).to_opencv(64, 48)


# -- the asymmetric frustum in every pass: a window of a centred camera's image ---------------------
BIG_W, BIG_H, X0, Y0, W, H = 256, 192, 32, 48, 128, 96     # window offsets: multiples of the 16-px light tiles


def window_cameras():
    """A centred camera at BIG_W × BIG_H and the off-centre one seeing its window (X0, Y0, W, H)."""
    K, R, t = lighting.CAMERA.to_opencv(BIG_W, BIG_H)
    small = K.copy()
    small[0, 2] -= X0
    small[1, 2] -= Y0
    big = Camera.from_opencv(K, R, t, BIG_W, BIG_H, near=0.1, far=30)
    return big, Camera.from_opencv(small, R, t, W, H, near=0.1, far=30)


@pytest.mark.parametrize("opts", [
    dict(light_culling="tiled"), dict(light_culling="tiled", light_depth_mask=True), dict(light_culling="quads"),
    dict(light_culling="stencil"), dict(pipeline="light_prepass"), dict(pipeline="light_indexed"),
], ids=["tiled", "depth-mask", "quads", "stencil", "light-prepass", "light-indexed"])
def test_off_centre_window_equals_the_centred_image(make_renderer, opts):
    scene = lighting.lit_scene(64, W, H)
    big_cam, cam = window_cameras()
    assert cam.principal_offset() != (0.0, 0.0)
    big = make_renderer(BIG_W, BIG_H, tonemap="reinhard", **opts).render(scene, big_cam)
    small = make_renderer(W, H, tonemap="reinhard", **opts).render(scene, cam)
    window = (slice(Y0, Y0 + H), slice(X0, X0 + W))
    same = big.triangle_id[window] == small.triangle_id
    assert same.mean() > 0.995, f"{(~same).sum()} pixels see another triangle"
    fg = same & (small.triangle_id >= 0)
    assert fg.mean() > 0.8
    assert np.allclose(small.depth[fg], big.depth[window][fg], rtol=1e-5)
    assert np.array_equal(small.light_count > 0, big.light_count[window] > 0) or opts.get("light_culling") in (
        "quads", "stencil") or "pipeline" in opts
    a, b = small.color[fg].astype(np.float64), big.color[window][fg].astype(np.float64)
    peak = float(b.max())
    assert peak > 0.2 and (a.max(-1) > 0.05).mean() > 0.5, "the lights must light the window"
    err = np.abs(a - b).max()
    assert err <= 1e-4 * peak, f"colour differs by {err:.3g} (peak {peak:.3g})"


def test_off_centre_environment_background_is_the_same_rays(make_renderer):
    scene = lighting.room_scene(with_wall=False)
    scene.set_environment("studio")
    big_cam, cam = window_cameras()
    big = make_renderer(BIG_W, BIG_H).render(scene, big_cam)
    small = make_renderer(W, H).render(scene, cam)
    window = (slice(Y0, Y0 + H), slice(X0, X0 + W))
    bg = (small.triangle_id < 0) & (big.triangle_id[window] < 0)
    assert bg.sum() > 500
    a, b = small.color[bg], big.color[window][bg]
    assert np.abs(a - b).max() <= 1e-4 * float(b.max()) and b.std() > 0


def test_off_centre_spot_shadow_matches_ray_casting(make_renderer):
    rng = np.random.default_rng(11)
    K, R, t = shadows.CAMERA.to_opencv(shadows.W, shadows.H)
    K[0, 2] += 0.3 * shadows.W * rng.choice([-1, 1])
    K[1, 2] += 0.25 * shadows.H
    K[1, 1] *= 1.15
    camera = Camera.from_opencv(K, R, t, shadows.W, shadows.H, near=0.1, far=60)
    scene = shadows.spot_scene()
    frame = make_renderer(shadows.W, shadows.H, shadow_filter="hard").render(scene, camera)
    lit, L = shadows.in_spot(frame, camera)
    tested = lit & shadows.facing(scene, frame, L)
    assert tested.sum() > 1500
    expect = shadows.ray_reference(scene, frame, camera, tested, light_pos=shadows.SPOT["position"])
    assert 0.05 < 1 - expect.mean() < 0.7, "the view must hold shadows to compare"
    frac, stray = shadows.agreement(frame.shadow[..., 0], expect, tested)
    assert frac >= 0.97 and stray == 0, (frac, stray)


def test_off_centre_ssao_correlates_with_ray_traced_ao(make_renderer):
    import test_ssao as ssao
    from reference.ao import ray_traced_ao
    rng = np.random.default_rng(3)
    K, R, t = ssao.CAMERA.to_opencv(ssao.W, ssao.H)
    K[0, 2] -= 0.3 * ssao.W
    K[1, 2] += 0.2 * ssao.H
    camera = Camera.from_opencv(K, R, t, ssao.W, ssao.H, near=ssao.CAMERA.near, far=ssao.CAMERA.far)
    scene = ssao.room()
    frame = make_renderer(ssao.W, ssao.H, ssao=True, ssao_radius=ssao.RADIUS, ssao_blur=False).render(scene, camera)
    sel = np.zeros((ssao.H, ssao.W), bool)
    sel[::3, ::3] = True
    sel &= frame.triangle_id >= 0
    points = ref.world_positions(frame.depth, camera)[sel]
    expect = ray_traced_ao(points, frame.normal[sel], scene.positions, scene.triangles, ssao.RADIUS, ssao.RAYS,
                           seed=int(rng.integers(100)))
    corr = np.corrcoef(frame.ao[sel], expect)[0, 1]
    assert corr >= ssao.MIN_CORRELATION, corr


# -- world positions ---------------------------------------------------------------------------------
@pytest.mark.parametrize("kind", ["look_at", "opencv", "orthographic"])
def test_position_is_the_depth_on_the_pixel_ray(make_renderer, kind):
    w, h = 120, 90
    scene = lighting.room_scene()
    if kind == "opencv":
        K, R, t = lighting.CAMERA.to_opencv(w, h)
        K[0, 2] += 17.0
        K[1, 1] *= 0.9
        camera = Camera.from_opencv(K, R, t, w, h, near=0.1, far=30)
    elif kind == "orthographic":
        camera = Camera.orthographic((0.3, 4.0, 3.0), (0.0, 0.5, -3.0), ymag=3.0, near=0.1, far=30)
    else:
        camera = lighting.CAMERA
    frame = make_renderer(w, h).render(scene, camera)
    p = frame.position
    assert p.shape == (h, w, 3) and p.dtype == np.float32
    bg = frame.triangle_id < 0
    assert np.isnan(p[bg]).all() and np.isfinite(p[~bg]).all() and (~bg).mean() > 0.5
    expect = ref.world_positions(frame.depth, camera)
    assert np.allclose(p[~bg], expect[~bg], rtol=0, atol=1e-5 * 30)
    floor = np.isin(frame.triangle_id, np.arange(2 * 16))       # the floor lies on y = 0
    assert floor.sum() > 300 and np.abs(p[floor][:, 1]).max() < 2e-3
    if kind != "orthographic":                                   # and projects back to its pixel centre
        K, R, t = camera.to_opencv(w, h)
        q = (K @ (R @ p[~bg].astype(np.float64).T + t[:, None])).T
        ys, xs = np.nonzero(~bg)
        assert np.abs(q[:, 0] / q[:, 2] - (xs + 0.5)).max() < 2e-3
        assert np.abs(q[:, 1] / q[:, 2] - (ys + 0.5)).max() < 2e-3


def test_moved_opencv_camera_keeps_its_k():
    from clrender.scene.camera import with_overrides
    K = np.array([[300.0, 0, 100], [0, 280, 70], [0, 0, 1]])
    cam = Camera.from_opencv(K, np.eye(3), (0, 0, 5), 320, 240)
    moved = with_overrides(cam, np.array([[-1, -1, -1], [1, 1, 1.0]]), eye=(0, 0, 8))
    assert moved.intrinsics == cam.intrinsics and moved.eye == (0, 0, 8)
    assert np.allclose(moved.to_opencv(320, 240)[0], K)
    assert with_overrides(cam, None, fov=40).intrinsics is None


def test_scene_objects_validate():
    scene = spheres_scene([(0, 0, -4), (1, 0, -4)], [0.3, 0.3])
    assert [o.name for o in scene.objects] == ["sphere0", "sphere1"]
    assert np.array_equal(np.unique(scene.triangle_object), [0, 1])
    from clrender.errors import SceneError
    with pytest.raises(SceneError, match="mesh_object"):
        Scene(scene.positions, scene.normals, scene.uvs, scene.triangles, scene.triangle_material,
              mesh_names=scene.mesh_names, triangle_mesh=scene.triangle_mesh, objects=[SceneObject("a", "a", "a")],
              mesh_object=np.array([0, 1]))
