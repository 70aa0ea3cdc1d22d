"""G-buffer attributes against truth clrender did not compute.

Normals and depth: pixel-center rays cast in NumPy (float64) against the triangle the frame
says is visible; velocity: the analytic reprojection of the same hit points into the previous
camera; albedo: the OpenGL peer (a real GL pipeline with trilinear sRGB textures).
"""
import sys
from pathlib import Path

import numpy as np
import pytest

import clrender
from clrender import Camera, Material, Scene
from helpers import skip_or_fail
from reference.geometry import uv_sphere

REPO = Path(__file__).resolve().parents[1]


def pixel_rays(camera: Camera, width: int, height: int):
    """World-space origin and unit directions through every pixel center (float64)."""
    inv = np.linalg.inv(camera.view_projection(width, height))
    ys, xs = np.mgrid[0:height, 0:width] + 0.5
    ndc = np.stack([xs / width * 2 - 1, 1 - ys / height * 2, np.ones_like(xs), np.ones_like(xs)], -1)
    far = ndc @ inv.T
    far = far[..., :3] / far[..., 3:]
    eye = np.asarray(camera.eye, np.float64)
    d = far - eye
    return eye, d / np.linalg.norm(d, axis=-1, keepdims=True)


def ray_hits(scene: Scene, camera: Camera, triangle_id: np.ndarray):
    """Barycentrics (b0,b1,b2), hit points and ray parameters for each pixel's visible triangle."""
    h, w = triangle_id.shape
    eye, dirs = pixel_rays(camera, w, h)
    fg = triangle_id >= 0
    tri = scene.triangles[triangle_id[fg]]
    p0, p1, p2 = (scene.positions[tri[:, k]].astype(np.float64) for k in range(3))
    d = dirs[fg]
    e1, e2 = p1 - p0, p2 - p0
    pv = np.cross(d, e2)
    det = (e1 * pv).sum(1)
    tv = eye - p0
    u = (tv * pv).sum(1) / det
    qv = np.cross(tv, e1)
    v = (d * qv).sum(1) / det
    t = (e2 * qv).sum(1) / det
    bary = np.stack([1 - u - v, u, v], 1)
    return fg, bary, eye + d * t[:, None], tri


def view_depth(camera: Camera, points: np.ndarray) -> np.ndarray:
    _, _, back = camera.basis()
    return -((points - np.asarray(camera.eye)) @ back)


@pytest.fixture
def sphere_scene():
    positions, faces, normals = uv_sphere()
    return Scene.from_arrays(positions, faces, normals=normals)


def test_normals_and_depth_match_ray_cast(make_renderer, sphere_scene):
    cam = Camera.look_at((0.3, 0.5, 0), (0, 0, -4), fov_y_deg=40, near=0.1, far=20)
    frame = make_renderer(96, 80).render(sphere_scene, cam)
    fg, bary, hit, tri = ray_hits(sphere_scene, cam, frame.triangle_id)
    assert fg.mean() > 0.3
    inside = (bary > 0.02).all(1)          # away from edges, where snapping can change the winner
    n_ref = sum(bary[:, k:k + 1] * sphere_scene.normals[tri[:, k]] for k in range(3))
    n_ref /= np.linalg.norm(n_ref, axis=1, keepdims=True)
    angle = np.degrees(np.arccos(np.clip((frame.normal[fg] * n_ref).sum(1), -1, 1)))
    assert np.percentile(angle[inside], 99) < 0.1 and angle[inside].max() < 0.5
    rel = np.abs(frame.depth[fg] - view_depth(cam, hit)) / view_depth(cam, hit)
    assert np.percentile(rel[inside], 99) < 1e-4
    assert np.all(np.isinf(frame.depth[~fg])) and np.all(frame.normal[~fg] == 0)


def test_visible_back_face_of_double_sided_material_is_flipped(make_renderer):
    # A quad wound clockwise as seen from the camera (its normal points away from it).
    quad = np.array([[-1, -1, -3], [-1, 1, -3], [1, 1, -3], [1, -1, -3]], np.float32)
    faces = [[0, 1, 2], [0, 2, 3]]
    cam = Camera.look_at((0, 0, 0), (0, 0, -1))
    two_sided = Scene.from_arrays(quad, faces)
    assert np.allclose(two_sided.normals, (0, 0, -1))
    frame = make_renderer(32, 32).render(two_sided, cam)
    fg = frame.triangle_id >= 0
    assert fg.sum() > 100
    np.testing.assert_allclose(frame.normal[fg], np.broadcast_to((0, 0, 1), frame.normal[fg].shape), atol=1e-3)
    one_sided = Scene.from_arrays(quad, faces, material=Material(double_sided=False))
    frame = make_renderer(32, 32).render(one_sided, cam)
    assert (frame.triangle_id < 0).all() and frame.stats["culled_backface"] == 2


def test_velocity_is_reprojection_into_previous_camera(make_renderer, sphere_scene):
    cam = Camera.look_at((0, 0, 0), (0, 0, -4), fov_y_deg=50, near=0.1, far=20)
    prev = Camera.look_at((0.6, -0.4, 0.5), (0, 0, -4), fov_y_deg=50, near=0.1, far=20)
    w, h = 80, 64
    frame = make_renderer(w, h).render(sphere_scene, cam, previous_camera=prev)
    fg, bary, hit, _ = ray_hits(sphere_scene, cam, frame.triangle_id)
    clip = np.c_[hit, np.ones(len(hit))] @ prev.view_projection(w, h).T
    ndc = clip[:, :2] / clip[:, 3:]
    prev_px = np.stack([(ndc[:, 0] + 1) / 2 * w, (1 - ndc[:, 1]) / 2 * h], 1)
    ys, xs = np.nonzero(fg)
    expect = np.stack([xs + 0.5, ys + 0.5], 1) - prev_px
    got = frame.velocity[fg]
    assert np.abs(expect).max() > 2, "the camera move must produce visible motion"
    err = np.abs(got - expect)
    assert np.percentile(err, 99) < 0.02 and err.max() < 0.1      # half floats + surface interpolation
    still = make_renderer(w, h).render(sphere_scene, cam)
    assert np.all(still.velocity == 0)


@pytest.mark.skipif(not (REPO / "scenes" / "demo.toml").is_file(), reason="bundled demo scene missing")
def test_textured_albedo_matches_opengl_peer(make_renderer):
    # bench/ is imported from this checkout whatever the import order of other test modules.
    if str(REPO) not in sys.path:
        sys.path.insert(0, str(REPO))
    try:
        from bench import gl_peer
    except ImportError as exc:
        skip_or_fail(f"OpenGL peer not importable: {exc}")
    ok, why = gl_peer.gl_available()
    if not ok:
        skip_or_fail(f"OpenGL peer unavailable: {why}")
    scene = clrender.load_scene(REPO / "scenes" / "demo.toml")
    w, h = 320, 180
    frame = make_renderer(w, h).render(scene, scene.camera)
    peer = gl_peer.GLPeer(w, h)
    peer.upload(scene)
    gl = peer.render(scene.camera)
    same = (frame.triangle_id == gl["triangle_id"]) & (frame.triangle_id >= 0)
    assert same.mean() > 0.5
    mse = np.mean((frame.albedo[same] - gl["albedo"][same]) ** 2)
    psnr = 10 * np.log10(1.0 / max(mse, 1e-12))
    assert psnr > 35, f"albedo PSNR vs OpenGL {psnr:.1f} dB"
    assert np.ptp(frame.albedo[same]) > 0.5, "a textured frame, not a flat one"
