"""Motion blur (`motion_blur=True`, kernels/motion_blur.cl) and object motion (`Scene.set_transform`).

Truth by the accumulation-buffer method the report mentions (IV.2): the mean of 32 sharp renders
at sub-frame cameras spread over the exposure (`shutter` frame intervals centred on the current
frame; the camera extrapolated linearly from the previous one). The post-process blur must be
much closer to it than the sharp frame. The device's blur is also compared with an independent
NumPy implementation of the same algorithm (`reference_motion_blur`) on the frame's own colour
and velocity; object motion's velocity with the analytic reprojection of the moved surface.
"""
from __future__ import annotations

import numpy as np
import pytest

from helpers import pixel_far_points

import clrender
from clrender import Camera, Material, Scene
from clrender.scene.model import SceneError

W, H = 96, 64
FOV = 50.0
CAM = Camera.look_at((0, 0, 0), (0, 0, -1), fov_y_deg=FOV, near=0.1, far=50.0)
SHUTTER = 0.5
MAX_RADIUS, MIN_LENGTH, SOFT_Z = 32, 0.5, 0.02       # clrender/passes/motion_blur.py


def panned(dx: float, dy: float = 0.0) -> Camera:
    """CAM translated sideways (same orientation)."""
    return Camera.look_at((dx, dy, 0), (dx, dy, -1), fov_y_deg=FOV, near=0.1, far=50.0)


def quads(rects) -> tuple:
    """rects: (x0, x1, y0, y1, z, material, mesh): camera-facing quads, 4 vertices each."""
    pos, tris, mats, meshes = [], [], [], []
    for i, (x0, x1, y0, y1, z, m, mesh) in enumerate(rects):
        pos += [(x0, y0, z), (x1, y0, z), (x1, y1, z), (x0, y1, z)]
        tris += [(4 * i, 4 * i + 1, 4 * i + 2), (4 * i, 4 * i + 2, 4 * i + 3)]
        mats += [m, m]
        meshes += [mesh, mesh]
    pos = np.array(pos, np.float32)
    return pos, np.array(tris, np.int32), np.array(mats, np.int32), np.array(meshes, np.int32)


PALETTE = [Material("a", (0.9, 0.8, 0.2, 1.0), specular_intensity=0.0),
           Material("b", (0.05, 0.1, 0.4, 1.0), specular_intensity=0.0),
           Material("c", (0.8, 0.1, 0.1, 1.0), specular_intensity=0.0),
           Material("d", (0.1, 0.7, 0.3, 1.0), specular_intensity=0.0)]


def scene_of(rects, mesh_names) -> Scene:
    """Unlit (ambient 1): colour = albedo, so every sub-frame render shows the same surfaces."""
    pos, tris, mats, meshes = quads(rects)
    scene = Scene(pos, np.tile([[0.0, 0.0, 1.0]], (len(pos), 1)), np.zeros((len(pos), 2)), tris, mats,
                  materials=list(PALETTE), mesh_names=list(mesh_names), triangle_mesh=meshes)
    scene.ambient = 1.0
    return scene


def stripes(x0, x1, y0, y1, z, width, mats, mesh=0, seed=None) -> list:
    """Vertical stripes of alternating materials; `seed`: random widths in [0.5, 1.5]·width."""
    rng = None if seed is None else np.random.default_rng(seed)
    out, x, i = [], x0, 0
    while x < x1 - 1e-9:
        step = width if rng is None else width * rng.uniform(0.5, 1.5)
        out.append((x, min(x + step, x1), y0, y1, z, mats[i % len(mats)], mesh))
        x += step
        i += 1
    return out


def pan_scene() -> Scene:
    """A back wall (z = -10) and a panel in front (z = -5), both with stripes of random widths
    (2-10 px): a sideways pan moves them by different amounts (parallax, occlusion edges)."""
    return scene_of(stripes(-14, 14, -7, 7, -10.0, 0.6, (0, 1), seed=1)
                    + stripes(-2, 2, -1.5, 1.5, -5.0, 0.45, (2, 3), seed=2), ["scene"])


def wall_and_quad() -> Scene:
    """Mesh 0 "wall": stripes at z = -10; mesh 1 "quad": a 2×2 quad at z = -5 (rest pose at the centre)."""
    return scene_of(stripes(-14, 14, -7, 7, -10.0, 0.5, (0, 1)) + [(-1, 1, -1, 1, -5.0, 2, 1)], ["wall", "quad"])


def translation(x=0.0, y=0.0, z=0.0) -> np.ndarray:
    m = np.eye(4)
    m[:3, 3] = (x, y, z)
    return m


def rmse(a, b) -> float:
    return float(np.sqrt(np.mean((np.asarray(a, np.float64) - b) ** 2)))


# -- the algorithm in NumPy (float32, the kernel's operation order) ---------------------------------
def reference_vectors(velocity: np.ndarray, shutter: float) -> tuple[np.ndarray, np.ndarray]:
    """(V, inv_len): the half-vectors V = velocity·shutter/2 (0 where |2V| < MIN_LENGTH or not
    finite, shortened to MAX_RADIUS), and 1 / max(|V|, 1/2)."""
    f = np.float32
    v = velocity.astype(f) * (f(0.5) * f(shutter))
    l2 = v[..., 0] * v[..., 0] + v[..., 1] * v[..., 1]
    with np.errstate(invalid="ignore"):
        moving = (l2 >= f(0.25) * f(MIN_LENGTH) * f(MIN_LENGTH)) & (l2 < np.inf)
    v[~moving], l2[~moving] = 0, 0
    cap = f(MAX_RADIUS)
    long = l2 > cap * cap
    v[long] *= (cap / np.sqrt(l2[long]))[:, None]
    l2[long] = v[long][:, 0] * v[long][:, 0] + v[long][:, 1] * v[long][:, 1]
    return v, f(1) / np.maximum(np.sqrt(l2), f(0.5))


def longest(vectors: np.ndarray) -> np.ndarray:
    """The longest of (n, 2) vectors, ties by the larger x, then y (the kernel's total order)."""
    l2 = vectors[:, 0] * vectors[:, 0] + vectors[:, 1] * vectors[:, 1]
    best = np.lexsort((vectors[:, 1], vectors[:, 0], l2))[-1]
    return vectors[best] if l2[best] > 0 else np.zeros(2, np.float32)


def reference_neighbor_max(v: np.ndarray) -> np.ndarray:
    """(tiles_y, tiles_x, 2): per MAX_RADIUS² tile, the longest V of the 3×3 tiles around it."""
    t = MAX_RADIUS
    h, w = v.shape[:2]
    ty, tx = -(-h // t), -(-w // t)
    out = np.zeros((ty, tx, 2), np.float32)
    for j in range(ty):
        for i in range(tx):
            block = v[max(j - 1, 0) * t:(j + 2) * t, max(i - 1, 0) * t:(i + 2) * t].reshape(-1, 2)
            out[j, i] = longest(block)
    return out


def reference_motion_blur(color: np.ndarray, velocity: np.ndarray, depth: np.ndarray, shutter: float,
                          samples: int) -> np.ndarray:
    """(H, W, 3) blurred colour from the sharp colour, the G-buffer velocity (pixels) and linear
    depth (+inf on background): McGuire et al.'s reconstruction, as kernels/motion_blur.cl states it."""
    f = np.float32
    h, w = velocity.shape[:2]
    v, inv = reference_vectors(velocity, shutter)
    m = np.repeat(np.repeat(reference_neighbor_max(v), MAX_RADIUS, 0), MAX_RADIUS, 1)[:h, :w]
    ys, xs = np.mgrid[0:h, 0:w]
    z = depth.astype(f)
    with np.errstate(divide="ignore"):
        kx = f(1) / (f(SOFT_Z) * z)                         # r = (z_Y - z_X) / (SOFT_Z z_X)
    weight = inv.copy()
    total = color.astype(f) * inv[..., None]
    for i in range(samples):
        t = f(2 * i + 1) / f(samples) - f(1)
        ox = np.floor(t * m[..., 0] + f(0.5)).astype(int)
        oy = np.floor(t * m[..., 1] + f(0.5)).astype(int)
        qx, qy = np.clip(xs + ox, 0, w - 1), np.clip(ys + oy, 0, h - 1)
        dx, dy = (qx - xs).astype(f), (qy - ys).astype(f)
        d = np.sqrt(dx * dx + dy * dy)
        zy, iy = z[qy, qx], inv[qy, qx]
        with np.errstate(invalid="ignore", divide="ignore"):
            r = np.where(zy == z, f(0), zy * kx - f(1) / f(SOFT_Z))
        front, behind = np.clip(f(1) - r, 0, 1), np.clip(f(1) + r, 0, 1)
        a = (front * np.clip(f(1) - d * iy, 0, 1) + behind * np.clip(f(1) - d * inv, 0, 1)
             + f(2) * (cylinder(d * iy) * cylinder(d * inv)))
        a[(qx == xs) & (qy == ys)] = 0                    # the pixel itself: counted once
        weight += a
        total += a[..., None] * color[qy, qx]
    out = total / weight[..., None]
    static = (m == 0).all(-1)
    out[static] = color[static]
    return out


def cylinder(x: np.ndarray) -> np.ndarray:
    """The cylinder's fall-off at x = d/L: clamp((1.05 - x) · 10, 0, 1) in float32."""
    return np.clip((np.float32(1.05) - x) * np.float32(10), 0, 1)


def accumulation_truth(make_renderer, scene, camera, previous, shutter, n=32, **opts) -> np.ndarray:
    """The mean of n sharp renders over the exposure: camera(τ) = camera + τ·(camera − previous),
    τ = ((i + 1/2)/n − 1/2)·shutter (the frame interval is 1, the current frame at τ = 0)."""
    r = make_renderer(W, H, **opts)
    eye, prev_eye = np.array(camera.eye), np.array(previous.eye)
    target, prev_target = np.array(camera.target), np.array(previous.target)
    acc = np.zeros((H, W, 3))
    for i in range(n):
        tau = ((i + 0.5) / n - 0.5) * shutter
        cam = Camera.look_at(eye + tau * (eye - prev_eye), target + tau * (target - prev_target),
                             camera.up, camera.fov_y_deg, camera.near, camera.far)
        acc += r.render(scene, cam).color
    return acc / n


# -- camera motion -----------------------------------------------------------------------------------
@pytest.mark.parametrize("samples", [8, 16])
def test_camera_pan_approaches_accumulation_truth(make_renderer, samples):
    """Sideways pan (back wall ~14 px/frame, panel ~27 px/frame): the post blur's RMSE against the
    32-render accumulation truth is at least 70 % below the sharp frame's (measured on PoCL: sharp
    0.279, blur 0.066 with 8 taps, 77 % lower; 0.058, 79 %, with 16). The margin rejects wrong
    lengths: the same filter with twice the shutter is only 49 % / 57 % lower, with half 41 %."""
    scene, prev = pan_scene(), panned(-2.0)
    truth = accumulation_truth(make_renderer, scene, CAM, prev, SHUTTER)
    sharp = make_renderer(W, H).render(scene, CAM, previous_camera=prev)
    blurred = make_renderer(W, H, motion_blur=True, shutter=SHUTTER, motion_blur_samples=samples).render(
        scene, CAM, previous_camera=prev)
    assert np.abs(sharp.velocity[..., 0]).min() > 10, "every pixel must move"
    e_sharp, e_blur = rmse(sharp.color, truth), rmse(blurred.color, truth)
    print(f"samples={samples}: RMSE vs accumulation truth: sharp {e_sharp:.4f}, motion blur {e_blur:.4f} "
          f"({1 - e_blur / e_sharp:.0%} lower)")
    assert e_blur <= 0.3 * e_sharp, (e_sharp, e_blur)
    # The same algorithm in NumPy, on this frame's sharp colour and velocity.
    expect = reference_motion_blur(sharp.color, sharp.velocity, sharp.linear_depth, SHUTTER, samples)
    np.testing.assert_allclose(blurred.color, expect, rtol=1e-5, atol=1e-6)
    assert "motion_blur_ms" in blurred.stats
    np.testing.assert_array_equal(blurred.velocity, sharp.velocity)


def test_longer_shutter_blurs_more(make_renderer):
    scene, prev = pan_scene(), panned(-1.0)
    sharp = make_renderer(W, H).render(scene, CAM, previous_camera=prev).color
    short = make_renderer(W, H, motion_blur=True, shutter=0.25).render(scene, CAM, previous_camera=prev).color
    full = make_renderer(W, H, motion_blur=True, shutter=1.0).render(scene, CAM, previous_camera=prev).color
    assert 0 < rmse(short, sharp) < rmse(full, sharp)
    # Blur spreads the stripes' steps into ramps: less gradient energy along the rows (the total
    # variation can stay the same, a ramp climbs as high as the step it replaces).
    energy = [float((np.diff(c, axis=1) ** 2).mean()) for c in (full, short, sharp)]
    assert energy[0] < 0.5 * energy[1] and energy[1] < 0.95 * energy[2], energy


def test_static_camera_is_bit_identical(make_renderer):
    """previous_camera equal to the camera (velocity: reprojection noise ~1e-3 px) or None: the
    frame is exactly motion_blur=False's."""
    scene = pan_scene()
    off = make_renderer(W, H).render(scene, CAM)
    on = make_renderer(W, H, motion_blur=True)
    for previous in (None, CAM, panned(0.0)):
        f = on.render(scene, CAM, previous_camera=previous)
        assert "motion_blur_ms" in f.stats
        np.testing.assert_array_equal(f.color, off.color)
        np.testing.assert_array_equal(f.image, off.image)


def test_off_launches_nothing_and_keeps_frames(make_renderer):
    """motion_blur off (the default): no kernel; a previous camera changes the velocity AOV only."""
    scene, prev = pan_scene(), panned(-1.0)
    default = make_renderer(W, H).render(scene, CAM, previous_camera=prev)
    still = make_renderer(W, H).render(scene, CAM)
    assert not any(k.startswith("motion_blur") for k in default.stats)
    assert np.abs(default.velocity).max() > 5
    np.testing.assert_array_equal(default.color, still.color)
    np.testing.assert_array_equal(default.image, still.image)
    assert clrender.RenderConfig().motion_blur is False


def test_blur_after_supersample_resolve(make_renderer):
    """With supersample=2 the pass sees the resolved colour and output-pixel velocity."""
    scene, prev = pan_scene(), panned(-1.0)
    sharp = make_renderer(W, H, supersample=2).render(scene, CAM, previous_camera=prev)
    blurred = make_renderer(W, H, supersample=2, motion_blur=True).render(scene, CAM, previous_camera=prev)
    expect = reference_motion_blur(sharp.color, sharp.velocity, sharp.linear_depth, SHUTTER, 8)
    np.testing.assert_allclose(blurred.color, expect, rtol=1e-5, atol=1e-6)
    assert not np.array_equal(blurred.color, sharp.color)


def test_pass_on_synthetic_velocity_matches_reference(device):
    """MotionBlurPass alone on a hand-made G-buffer: sub-threshold noise, diagonal and opposite
    motions meeting, a vector beyond the MAX_RADIUS cap, inf/NaN halves (static), image borders,
    three depth layers and background (+inf), equal lengths in different directions (the ties)."""
    import pyopencl.array as cla
    from clrender.abi import gbuffer as layout
    from clrender.device.core import Device
    from clrender.passes import Resources
    from clrender.passes.motion_blur import MotionBlurPass
    dev = Device.get(device)
    w, h = 147, 102                                        # 5 × 4 tiles, partial tiles and runs
    rng = np.random.default_rng(7)
    vel = rng.normal(scale=0.1, size=(h, w, 2)).astype(np.float32)          # |b| < 0.5: static
    vel[5:20, 10:30] = (24.0, 0.0)
    vel[10:40, 25:35] = (-9.0, 13.0)
    vel[45:60, 40:70] = (200.0, -90.0)                     # beyond the cap
    vel[60:70, 0:6] = (-30.0, 4.0)                         # at the left border
    vel[96:101, 66:72], vel[96:101, 74:80] = (0.0, -20.0), (0.0, 20.0)    # equally long: a tie
    vel[30, 60] = (np.inf, 0.0)
    vel[31, 61] = (np.nan, 1.0)
    depth = np.full((h, w), 0.5, np.float32)
    depth[:, 20:] = 0.2
    depth[40:, 50:] = np.inf                               # background
    depth[5:20, 10:30] = 0.1                               # the fast patch in front
    color = rng.uniform(0, 4, (h, w, 3)).astype(np.float32)
    planes = np.zeros((len(layout.PLANES), h * w), np.uint32)
    planes[layout.PLANES.index("velocity")] = vel.astype(np.float16).reshape(-1, 2).view(np.uint32).reshape(-1)
    planes[layout.PLANES.index("depth")] = depth.reshape(-1).view(np.uint32)
    shutter, samples = 0.75, 7
    config = clrender.RenderConfig(motion_blur=True, shutter=shutter, motion_blur_samples=samples)
    mb = MotionBlurPass(dev, config)
    mb.allocate(w, h)
    res = Resources(buffers={"color": cla.to_device(dev.queue, np.ascontiguousarray(np.moveaxis(color, -1, 0))),
                             "gbuffer": cla.to_device(dev.queue, planes.reshape(-1))},
                    values={"width": w, "height": h})
    mb.publish(res)
    mb.run(res)
    got = np.moveaxis(res["color"].get(queue=dev.queue).reshape(3, h, w), 0, -1)
    half = vel.astype(np.float16).astype(np.float32)
    expect = reference_motion_blur(color, half, depth, shutter, samples)
    np.testing.assert_allclose(got, expect, rtol=1e-5, atol=1e-5)
    v, _ = reference_vectors(half, shutter)
    assert np.abs(np.hypot(v[..., 0], v[..., 1]) - MAX_RADIUS).min() < 1e-3     # the cap applied
    m = reference_neighbor_max(v)
    np.testing.assert_array_equal(m[3, 2], (0.0, 7.5))     # the tie: the larger y wins
    static = np.repeat(np.repeat((m == 0).all(-1), MAX_RADIUS, 0), MAX_RADIUS, 1)[:h, :w]
    assert 0.05 < static.mean() < 0.5
    np.testing.assert_array_equal(got[static], color[static])
    # Pixels that move blur, static ones out of reach do not. Not all of them: a slow patch next to
    # the capped one samples along the fast motion, at taps farther than its own blur reaches (the
    # filter's known limit, docs/post.md): 86 % here.
    moving = (v != 0).any(-1)
    assert (np.abs(got - color).max(-1)[moving] > 0).mean() > 0.8


# -- object motion -----------------------------------------------------------------------------------
def plane_hits(camera: Camera, z: float) -> np.ndarray:
    """(H, W, 3) float64: where each pixel centre's ray meets the plane z = const."""
    far = pixel_far_points(camera, W, H)
    eye = np.asarray(camera.eye, np.float64)
    t = (z - eye[2]) / (far[..., 2] - eye[2])
    return eye + t[..., None] * (far - eye)


def reprojected_velocity(points: np.ndarray, previous_points: np.ndarray, previous: Camera) -> np.ndarray:
    clip = np.concatenate([previous_points, np.ones(previous_points.shape[:-1] + (1,))], -1) @ \
        previous.view_projection(W, H).T
    ndc = clip[..., :2] / clip[..., 3:]
    prev_px = np.stack([(ndc[..., 0] + 1) / 2 * W, (1 - ndc[..., 1]) / 2 * H], -1)
    ys, xs = np.mgrid[0:H, 0:W] + 0.5
    return np.stack([xs, ys], -1) - prev_px


@pytest.mark.parametrize("previous_camera", [None, "panned"])
def test_moving_quad_velocity_is_analytic_reprojection(make_renderer, previous_camera):
    scene = wall_and_quad()
    move = np.array([1.2, 0.3, 0.0])                  # world units over the frame interval
    scene.set_transform("quad", translation(*(move + (0.5, 0, 0))), previous=translation(0.5))
    assert scene.previous_positions is not None
    prev_cam = CAM if previous_camera is None else panned(-0.3, 0.1)
    f = make_renderer(W, H).render(scene, CAM, previous_camera=None if previous_camera is None else prev_cam)
    quad = np.isin(f.triangle_id, (scene.triangle_count - 2, scene.triangle_count - 1))
    wall = (f.triangle_id >= 0) & ~quad
    assert quad.sum() > 150 and wall.sum() > 3000
    hit_q, hit_w = plane_hits(CAM, -5.0), plane_hits(CAM, -10.0)
    expect_q = reprojected_velocity(hit_q, hit_q - move, prev_cam)[quad]
    expect_w = reprojected_velocity(hit_w, hit_w, prev_cam)[wall]
    assert np.abs(expect_q).max() > 10
    for got, expect in ((f.velocity[quad], expect_q), (f.velocity[wall], expect_w)):
        err = np.abs(got - expect)
        assert np.percentile(err, 99) < 0.02 and err.max() < 0.1, err.max()


def test_moving_quad_blurs_around_it_and_nowhere_else(make_renderer):
    """A quad moving ~16 px/frame sideways over a static striped wall: its blur spreads over the
    wall beside its silhouette (the dilated velocity), and the wall beyond the blur's reach and
    the rows above and below are bit-identical to the sharp frame."""
    scene = wall_and_quad()
    scene.set_transform("quad", translation(0.6), previous=translation(-0.6))
    sharp = make_renderer(W, H).render(scene, CAM)
    blurred = make_renderer(W, H, motion_blur=True).render(scene, CAM)
    quad = np.isin(sharp.triangle_id, (scene.triangle_count - 2, scene.triangle_count - 1))
    vx = float(np.median(sharp.velocity[quad][:, 0]))
    assert 14 < vx < 19, vx
    reach = int(np.floor(abs(vx) * SHUTTER * 0.5 + 0.5))             # pixels the blur reaches beyond it
    rows, cols = np.nonzero(quad)
    near = np.zeros_like(quad)
    near[rows.min():rows.max() + 1, max(cols.min() - reach, 0):cols.max() + reach + 1] = True
    changed = np.abs(blurred.color - sharp.color).max(-1) > 1e-3
    ring = near & ~quad
    assert changed[ring].mean() > 0.5, "the quad's blur must extend beyond its silhouette"
    # The quad's own pixels near its sides: the filter reveals the wall behind pixel X at centre
    # distances d < |V_X| = reach, so the reach - 1 columns nearest each side.
    band = np.zeros_like(quad)
    band[:, cols.min():cols.min() + reach - 1] = band[:, cols.max() + 2 - reach:cols.max() + 1] = True
    assert changed[quad & band].mean() > 0.9, "the quad's sides must blur into the wall"
    assert not changed[~near].any()
    np.testing.assert_array_equal(blurred.color[~near], sharp.color[~near])
    expect = reference_motion_blur(sharp.color, sharp.velocity, sharp.linear_depth, SHUTTER, 8)
    np.testing.assert_allclose(blurred.color, expect, rtol=1e-5, atol=1e-6)


def test_set_transform_geometry_and_no_motion(make_renderer):
    scene = wall_and_quad()
    before = make_renderer(W, H).render(scene, CAM)
    rest = scene.positions.copy()
    # Identity: the same geometry, no previous positions, the same frame bit for bit.
    scene.set_transform("quad", np.eye(4))
    assert scene.previous_positions is None
    np.testing.assert_array_equal(scene.positions, rest)
    again = make_renderer(W, H).render(scene, CAM)
    np.testing.assert_array_equal(again.gbuffer, before.gbuffer)
    np.testing.assert_array_equal(again.color, before.color)
    # Transforms apply to the rest pose, not cumulatively; normals follow the rotation.
    rot = np.eye(4)
    rot[:3, :3] = [[0, 0, 1], [0, 1, 0], [-1, 0, 0]]                # 90 degrees about y
    rot[:3, 3] = (0, 0, -5)
    scene.set_transform(1, translation(3.0))
    scene.set_transform(1, rot @ translation(0, 0, 5), previous=rot @ translation(0, 0, 5))
    assert scene.previous_positions is None
    quad = scene.triangles[scene.triangle_mesh == 1].ravel()
    np.testing.assert_allclose(scene.positions[quad][:, 0], 0.0, atol=1e-6)   # now in the plane x = 0
    np.testing.assert_allclose(scene.normals[quad], np.tile([1.0, 0, 0], (len(quad), 1)), atol=1e-6)
    np.testing.assert_array_equal(scene.positions[scene.triangles[scene.triangle_mesh == 0].ravel()],
                                  rest[scene.triangles[scene.triangle_mesh == 0].ravel()])
    # A mirror keeps the faces' orientation by flipping their winding.
    scene.set_transform("quad", np.diag([-1.0, 1.0, 1.0, 1.0]))
    tri = scene.triangles[scene.triangle_mesh == 1]
    p = scene.positions
    n = np.cross(p[tri[:, 1]] - p[tri[:, 0]], p[tri[:, 2]] - p[tri[:, 0]])
    assert (n[:, 2] > 0).all()


def test_set_transform_duplicates_shared_vertices():
    v = np.array([[0, 0, -5], [1, 0, -5], [1, 1, -5], [0, 1, -5], [2, 0, -5]], np.float32)
    scene = Scene(v, np.tile([[0.0, 0, 1]], (5, 1)), np.zeros((5, 2)), np.array([[0, 1, 2], [1, 4, 2]]),
                  np.zeros(2, np.int32), mesh_names=["left", "right"], triangle_mesh=np.array([0, 1]))
    scene.set_transform("right", translation(0, 0, 1), previous=translation())
    assert len(scene.positions) == 7 and scene.triangle_count == 2
    np.testing.assert_array_equal(scene.positions[scene.triangles[0]], v[[0, 1, 2]])       # left unmoved
    np.testing.assert_array_equal(scene.positions[scene.triangles[1]], v[[1, 4, 2]] + (0, 0, 1))
    np.testing.assert_array_equal(scene.previous_positions[scene.triangles[1]], v[[1, 4, 2]])
    np.testing.assert_array_equal(scene.previous_positions[scene.triangles[0]], v[[0, 1, 2]])
    scene.mesh_names.append("empty")
    with pytest.raises(SceneError, match="'empty' has no triangles"):
        scene.set_transform("empty", np.eye(4))


@pytest.mark.parametrize("mesh, matrix, previous, message", [
    ("nope", np.eye(4), None, "no mesh named 'nope'"),
    (2, np.eye(4), None, "mesh index 2 out of range"),
    (True, np.eye(4), None, "a name or an index"),
    ("quad", np.eye(3), None, "finite 4x4"),
    ("quad", np.full((4, 4), np.nan), None, "finite 4x4"),
    ("quad", np.eye(4)[[0, 1, 2, 2]], None, "affine"),
    ("quad", np.diag([1.0, 0.0, 1.0, 1.0]), None, "singular"),
    ("quad", np.eye(4), "x", "previous must be a 4x4"),
    ("quad", np.eye(4), np.ones((4, 4)), "previous must be affine"),
])
def test_set_transform_rejects_bad_input(mesh, matrix, previous, message):
    scene = wall_and_quad()
    positions = scene.positions
    with pytest.raises(SceneError, match=message):
        scene.set_transform(mesh, matrix, previous)
    assert scene.positions is positions and scene.previous_positions is None


def test_bad_previous_positions_are_a_scene_error(make_renderer):
    scene = wall_and_quad()
    scene.previous_positions = np.zeros((3, 3), np.float32)
    with pytest.raises(SceneError, match="previous_positions must have shape"):
        make_renderer(W, H).render(scene, CAM)
