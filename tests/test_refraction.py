"""Refraction of transparent layers (docs/transparency.md): the displaced lookup of the opaque image,
clamping, depth peeling, back faces, face-on and strength 0.
"""
from __future__ import annotations

import numpy as np
import pytest

from clrender import Material, Scene
from reference import transparency as ref
from reference.raster import pixel_exact_camera
from transparency_cases import build_scene, quad


def refraction_scene(tilt_deg, strength):
    """A striped opaque wall (4-pixel stripes) and a 50 % quad in front of it, turned about the y axis."""
    stripes = []
    light_m, dark_m = Material("light", (0.9, 0.9, 0.9, 1.0), specular_intensity=0.0), \
        Material("dark", (0.05, 0.1, 0.3, 1.0), specular_intensity=0.0)
    # pixel_exact_camera, square image: view x at depth 10 maps to pixel (x/10 + 1)/2·size
    size = 48
    for k in range(size // 4):
        x0, x1 = (8 * k / size * 2 - 1) * 10, ((8 * k + 4) / size * 2 - 1) * 10
        stripes.append((quad(x0, x1, -12, 12, -10.0), None, light_m))
        x2 = ((8 * k + 8) / size * 2 - 1) * 10
        stripes.append((quad(x1, x2, -12, 12, -10.0), None, dark_m))
    t = np.radians(tilt_deg)
    rot = np.array([[np.cos(t), 0, np.sin(t)], [0, 1, 0], [-np.sin(t), 0, np.cos(t)]])
    q = quad(-1.8, 1.8, -1.8, 1.8, 0.0) @ rot.T + np.array([0, 0, -4.0])
    glass = Material("glass", (0.3, 0.8, 0.4, 1.0), opacity=0.5, specular_intensity=0.0, refraction=strength)
    scene = build_scene(stripes + [(q, None, glass)], ambient=0.5)
    normal = rot @ np.array([0.0, 0.0, 1.0])
    return scene, normal, size


@pytest.mark.parametrize("strength", [0.08, 1.0])
def test_refraction_displaces_the_opaque_image(make_renderer, device, strength):
    """The opaque colour read behind each glass pixel is the opaque image's near p + s·height·(n_x, -n_y)
    (clamped to the image: strength 1 reaches 27 pixels); depth peeling composites the same way."""
    scene, normal, size = refraction_scene(35.0, strength)
    cam = pixel_exact_camera(far=50.0)
    plain = make_renderer(size, size).render(scene, cam)
    bent = make_renderer(size, size, refraction=True).render(scene, cam)
    layered = plain.fragment_count > 0
    assert layered.sum() > 200
    np.testing.assert_array_equal(bent.fragment_count, plain.fragment_count)
    np.testing.assert_array_equal(bent.transmittance, plain.transmittance)
    np.testing.assert_array_equal(bent.color[~layered], plain.color[~layered])
    changed = np.abs(bent.color - plain.color).max(-1) > 1e-3
    assert changed[layered].mean() > 0.3, "refraction must change the colour behind a tilted quad"
    # the opaque colour read behind each pixel: (bent - plain)/T + opaque(p) = opaque(p + offset)
    n_glass = int(ref.blend_mask(scene).sum())
    opaque_only = Scene(scene.positions, scene.normals, scene.uvs, scene.triangles[:-n_glass],
                        scene.triangle_material[:-n_glass], scene.materials, ambient=scene.ambient)
    O = make_renderer(size, size).render(opaque_only, cam).color.astype(np.float64)
    T = plain.transmittance.astype(np.float64)[..., None]
    looked_up = (bent.color - plain.color) / T + O
    right, up, back = (np.asarray(v) for v in cam.basis())
    n = normal if normal @ back > 0 else -normal                # facing the camera
    dx, dy = strength * size * (n @ right), -strength * size * (n @ up)
    assert abs(dx) > 2.0
    bad = []
    for y, x in np.argwhere(layered):
        tx, ty = np.clip(x + dx, 0, size - 1), np.clip(y + dy, 0, size - 1)
        xs = slice(max(int(np.floor(tx)) - 1, 0), min(int(np.ceil(tx)) + 2, size))
        ys = slice(max(int(np.floor(ty)) - 1, 0), min(int(np.ceil(ty)) + 2, size))
        lo, hi = O[ys, xs].reshape(-1, 3).min(0), O[ys, xs].reshape(-1, 3).max(0)
        v = looked_up[y, x]
        if np.any(v < lo - 1e-4) or np.any(v > hi + 1e-4):
            bad.append((y, x, v, lo, hi))
    assert not bad, (f"{len(bad)} of {layered.sum()} pixels read an opaque colour not found near p + "
                     f"({dx:.2f}, {dy:.2f}) px, e.g. (y, x, read, min, max) {bad[0]}")
    peeled = make_renderer(size, size, refraction=True, transparency="depth_peeling", peel_layers=2).render(scene, cam)
    np.testing.assert_array_equal(peeled.color, bent.color)
    # seen from behind (reversed winding, double-sided): the normal faces the camera, the same offset
    n_tri = scene.triangle_count
    flipped_tris = scene.triangles.copy()
    flipped_tris[n_tri - n_glass:] = flipped_tris[n_tri - n_glass:, ::-1]
    flipped_normals = scene.normals.copy()
    flipped_normals[scene.triangles[n_tri - n_glass:].ravel()] *= -1
    flipped = Scene(scene.positions, flipped_normals, scene.uvs, flipped_tris, scene.triangle_material,
                    scene.materials, ambient=scene.ambient)
    assert ref.fragments(flipped, cam, size, size).backface.all()
    back = make_renderer(size, size, refraction=True).render(flipped, cam)
    np.testing.assert_array_equal(back.fragment_count, bent.fragment_count)
    np.testing.assert_allclose(back.color, bent.color, rtol=0, atol=1e-5 * bent.color.max())


def test_refraction_face_on_changes_nothing(make_renderer, device):
    scene, _, size = refraction_scene(0.0, 0.08)
    cam = pixel_exact_camera(far=50.0)
    plain = make_renderer(size, size).render(scene, cam)
    bent = make_renderer(size, size, refraction=True).render(scene, cam)
    assert (plain.fragment_count > 0).sum() > 200
    np.testing.assert_allclose(bent.color, plain.color, rtol=0, atol=1e-6 * plain.color.max())
    # and strength 0 (the default) changes nothing even when tilted
    scene0, _, _ = refraction_scene(35.0, 0.0)
    a = make_renderer(size, size).render(scene0, cam)
    b = make_renderer(size, size, refraction=True).render(scene0, cam)
    np.testing.assert_array_equal(a.color, b.color)
