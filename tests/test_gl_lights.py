"""Tests of the OpenGL deferred-lighting peer (bench/gl_lights.py) on a floor + box scene.

The GL color is compared with an independent float64 NumPy evaluation of clrender's lighting
model at the GL G-buffer's own values (depth, normal, albedo, specular intensity/power), so
only the lighting pass is under test, not the G-buffer rasterization.

Tolerances: with RGBA32F accumulators the GL result is float32 arithmetic on the same inputs:
|gl - ref| <= 1e-5 + 1e-4 |ref| (observed ~1e-6 absolute).  With the default RGBA16F
accumulators each additive blend rounds the running sum to 11 significant bits (relative
2^-11 = 4.9e-4 per light), so 3 lights give <= 1e-5 + 2e-3 |ref|.

Skipped when moderngl or a headless EGL context is unavailable.
"""
from __future__ import annotations

import os
import sys

import numpy as np
import pytest

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from clrender import Camera, Material, Scene  # noqa: E402

from helpers import in_ci  # noqa: E402

# In CI the peer must run (Mesa's EGL is installed there): its absence fails instead of skipping.
moderngl = __import__("moderngl") if in_ci() else pytest.importorskip("moderngl", reason="moderngl not installed")

from bench.gl_peer import GLPeer, gl_available  # noqa: E402
from bench.gl_lights import GLLightsPeer, evaluate_lighting, icosphere  # noqa: E402

_ok, _why = gl_available()
pytestmark = pytest.mark.skipif(not _ok and not in_ci(), reason=f"no headless EGL/OpenGL 4.5 context: {_why}")

W, H = 128, 96
# far = 12 clips the floor's far edge and puts the back of the last light's proxy beyond the
# far plane: depth clamping must keep that light on the floor in front of it.
CAM = Camera.look_at((0.0, 4.0, 7.0), (0.0, 0.0, 0.0), (0, 1, 0), fov_y_deg=60.0, near=0.1, far=12.0)

FLOOR = Material(name="floor", base_color=(0.8, 0.7, 0.6, 1.0), specular_intensity=0.3, specular_power=16.0)
BOX = Material(name="box", base_color=(0.2, 0.5, 0.9, 1.0), specular_intensity=0.8, specular_power=64.0,
               double_sided=False)


def floor_and_box() -> Scene:
    """Floor quad y = 0 over [-5, 5]^2 (material 0) and a box on it, x in [0.5, 2.5] (material 1),
    flat-shaded: every face has its own vertices and outward normal, CCW seen from outside."""
    verts = [(-5, 0, -5), (-5, 0, 5), (5, 0, 5), (5, 0, -5)]
    normals = [(0, 1, 0)] * 4
    faces = [(0, 1, 2), (0, 2, 3)]
    lo, hi = np.array([0.5, 0.0, -1.0]), np.array([2.5, 1.5, 1.0])
    for axis in range(3):
        for sign in (-1, 1):
            n = np.zeros(3)
            n[axis] = sign
            u, v = np.eye(3)[(axis + 1) % 3], np.eye(3)[(axis + 2) % 3]   # u x v = e_axis
            if sign < 0:
                u, v = v, u
            half = (hi - lo) / 2
            c = (lo + hi) / 2 + n * half
            k = len(verts)
            for a, b in ((-1, -1), (1, -1), (1, 1), (-1, 1)):
                verts.append(tuple(c + half * (a * u + b * v)))
                normals.append(tuple(n))
            faces += [(k, k + 1, k + 2), (k, k + 2, k + 3)]
    base = Scene.from_arrays(np.array(verts, float), faces, normals=np.array(normals, float))
    mat = np.array([0, 0] + [1] * 12, np.int32)
    scene = Scene(base.positions, base.normals, base.uvs, base.triangles, mat, [FLOOR, BOX])
    scene.ambient = 0.05
    scene.add_point_light((-1.5, 0.8, 0.5), (1.0, 0.6, 0.3), 2.5)
    scene.add_spot_light((1.0, 3.5, 2.0), (0.0, -1.0, -0.3), (0.3, 1.0, 0.6), 5.0, 15.0, 35.0)
    scene.add_point_light((0.0, 0.6, -3.2), (0.5, 0.5, 2.0), 2.5)
    return scene


def reference(g: dict, camera: Camera, lights, ambient: float) -> dict:
    """The lighting model in float64 at the G-buffer's values (independent of bench/gl_lights.py)."""
    tid = g["triangle_id"]
    fg = tid >= 0
    h, w = tid.shape
    right, up, back = camera.basis()
    t = np.tan(np.radians(camera.fov_y_deg) / 2)
    xs = (np.arange(w) + 0.5) / w * 2 - 1
    ys = 1 - (np.arange(h) + 0.5) / h * 2
    ray = -back + xs[None, :, None] * t * (w / h) * right + ys[:, None, None] * t * up
    P = np.asarray(camera.eye) + np.where(fg, g["depth"], 0.0)[..., None] * ray
    N = g["normal"].astype(np.float64)
    N /= np.linalg.norm(N, axis=-1, keepdims=True).clip(1e-30)
    V = np.asarray(camera.eye) - P
    V /= np.linalg.norm(V, axis=-1, keepdims=True).clip(1e-30)
    diffuse = np.zeros((h, w, 3))
    specular = np.zeros((h, w, 3))
    for li in lights:
        Lv = li["position"].astype(np.float64) - P
        d = np.linalg.norm(Lv, axis=-1)
        r = float(li["radius"])
        L = Lv / d.clip(1e-30)[..., None]
        A = np.where(fg & (d < r), (1 - (d / r) ** 2) ** 3, 0.0)
        if li["type"] == 1:
            cos_a = -(L @ li["direction"].astype(np.float64))
            co, ci = float(li["cos_outer"]), float(li["cos_inner"])
            s = np.clip((cos_a - co) / max(ci - co, 1e-4), 0, 1)
            A *= s * s
        ndl = np.maximum(np.sum(N * L, -1), 0)
        Hv = L + V
        Hv /= np.linalg.norm(Hv, axis=-1, keepdims=True).clip(1e-30)
        ndh = np.maximum(np.sum(N * Hv, -1), 0)
        spec = np.where(ndl > 0, g["specular_intensity"] * ndh ** g["specular_power"].astype(np.float64), 0)
        diffuse += (A * ndl)[..., None] * li["color"]
        specular += (A * spec)[..., None] * li["color"]
    color = np.where(fg[..., None], g["albedo"], 0) * (ambient + diffuse) + specular
    return {"diffuse": diffuse, "specular": specular, "color": color, "P": P, "fg": fg}


@pytest.fixture(scope="module")
def scene():
    return floor_and_box()


@pytest.fixture(scope="module")
def peer32():
    p = GLLightsPeer(W, H, normal_dtype="f4", albedo_dtype="f4", accum_dtype="f4")
    yield p
    p.release()


def test_icosphere_contains_unit_sphere():
    for level in range(3):
        v, f, inr = icosphere(level)
        assert len(f) == 20 * 4 ** level
        np.testing.assert_allclose(np.linalg.norm(v, axis=1), 1.0, atol=1e-12)
        p0, p1, p2 = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
        n = np.cross(p1 - p0, p2 - p0)
        assert np.all(np.einsum("ij,ij->i", n, p0) > 0)         # CCW seen from outside
        assert 0.79 < inr < 1.0


def test_gbuffer_carries_specular_and_matches_glpeer(scene, peer32):
    peer32.upload(scene)
    g = peer32.render(CAM)
    tid = g["triangle_id"]
    floor, box = (tid >= 0) & (tid < 2), tid >= 2
    assert floor.sum() > 1000 and box.sum() > 200 and (tid < 0).sum() > 0
    np.testing.assert_allclose(g["specular_intensity"][floor], 0.3, rtol=1e-6)
    np.testing.assert_allclose(g["specular_power"][floor], 16.0, rtol=1e-6)
    np.testing.assert_allclose(g["specular_intensity"][box], 0.8, rtol=1e-6)
    np.testing.assert_allclose(g["specular_power"][box], 64.0, rtol=1e-6)
    assert np.all(g["color"][tid < 0] == 0)
    # The G-buffer itself is GLPeer's, unchanged.
    plain = GLPeer(W, H, normal_dtype="f4", albedo_dtype="f4")
    try:
        plain.upload(scene)
        ref = plain.render(CAM)
    finally:
        plain.release()
    for key in ("depth", "normal", "albedo", "triangle_id"):
        assert np.array_equal(ref[key], g[key]), key


@pytest.mark.parametrize("accum", ["f4", "f2"])
def test_color_matches_float64_model(scene, accum):
    p = GLLightsPeer(W, H, normal_dtype="f4", albedo_dtype="f4", accum_dtype=accum)
    try:
        p.upload(scene)
        g = p.render(CAM)
    finally:
        p.release()
    ref = reference(g, CAM, scene.lights, scene.ambient)
    rtol = 1e-4 if accum == "f4" else 2e-3
    for key in ("diffuse", "specular", "color"):
        np.testing.assert_allclose(g[key], ref[key], rtol=rtol, atol=1e-5, err_msg=f"{key} ({accum})")
    # Every light lights something, and the image is more than ambient.
    fg = ref["fg"]
    assert (g["diffuse"].sum(-1) > 0).sum() > 0.2 * fg.sum()
    assert g["specular"].max() > 0.01
    # bench.gl_lights.evaluate_lighting is the same model.
    ev = evaluate_lighting(g, CAM, scene.lights, scene.ambient)
    np.testing.assert_allclose(ev["color"], ref["color"], rtol=1e-9, atol=1e-12)


def test_contribution_is_exactly_zero_beyond_radius(scene, peer32):
    peer32.upload(scene)
    for i, light in enumerate(scene.lights):
        peer32.set_lights(scene.lights[i:i + 1], scene.ambient)
        g = peer32.render(CAM)
        ref = reference(g, CAM, scene.lights[i:i + 1], scene.ambient)
        fg = ref["fg"]
        d = np.linalg.norm(ref["P"] - light["position"].astype(np.float64), axis=-1)
        r = float(light["radius"])
        # float32 reconstruction of P differs from float64 by ~1e-6 of the scene scale
        outside = fg & (d >= r * (1 + 1e-4))
        assert outside.sum() > 500
        assert np.all(g["diffuse"][outside] == 0.0) and np.all(g["specular"][outside] == 0.0), i
        amb = g["albedo"][outside] * np.float32(scene.ambient)
        assert np.array_equal(g["color"][outside], amb), i
        # ... and the proxy does not cut the sphere short: lit wherever the model says > 0.
        lit = ref["diffuse"].sum(-1) > 1e-6
        assert lit.sum() > 100
        assert np.all(g["diffuse"][lit].sum(-1) > 0), i
    peer32.set_lights(scene.lights, scene.ambient)


def test_camera_inside_light_volume(scene, peer32):
    # A light around the camera: its proxy's front faces are behind the near plane / culled,
    # its back faces cover the screen, so everything within the radius is lit.
    peer32.upload(scene)
    light = scene.lights[:1].copy()
    light["position"] = CAM.eye
    light["radius"] = 8.0
    peer32.set_lights(light, 0.0)
    g = peer32.render(CAM)
    ref = reference(g, CAM, light, 0.0)
    np.testing.assert_allclose(g["color"], ref["color"], rtol=1e-4, atol=1e-5)
    assert (g["diffuse"].sum(-1) > 0).sum() > 0.5 * ref["fg"].sum()
    peer32.set_lights(scene.lights, scene.ambient)


def test_no_lights_is_ambient_only_and_timing(scene, peer32):
    peer32.upload(scene)
    peer32.set_lights(scene.lights[:0], 0.25)
    g = peer32.render(CAM)
    assert np.all(g["diffuse"] == 0) and np.all(g["specular"] == 0)
    assert np.array_equal(g["color"], g["albedo"] * np.float32(0.25))
    t = peer32.time_frame(CAM, repeats=2, warmup=1)
    tg = peer32.time_frame_gbuffer_only(CAM, repeats=2, warmup=1)
    assert len(t) == 2 and len(tg) == 2 and all(x > 0 for x in t + tg)
    info = peer32.info()
    assert info["lights"] == 0 and info["accum_format"] == "RGBA32F"
    peer32.set_lights(scene.lights, scene.ambient)
    assert peer32.info()["lights"] == 3
