"""The glTF material reference tests/reference/material.py on its own (no device): it must be right
before it judges the kernels (texel centres, wrap and LOD, the metallic-roughness mapping,
perspective-correct interpolation, the analytic bump).
"""
from __future__ import annotations

import numpy as np
import pytest

from clrender import Material
from clrender.scene.model import Texture
from materials_cases import (BUMP_CAMERA, FRONT, FULL_MATERIAL, bump_errors, bump_scene, bump_texture, describe,
                             quad_scene, reference_ids, textures_for)
from reference import material as ref


def test_reference_texel_centres_wrap_and_lod():
    w, h = 16, 8
    img = np.zeros((h, w, 4), np.uint8)
    img[..., 0] = (np.arange(w) * 16)[None, :]
    img[..., 1] = (np.arange(h) * 32)[:, None]
    img[..., 3] = 255
    zero = np.zeros((1, 2))
    for wrap_s, edge in (("repeat", 120.0), ("clamp", 0.0), ("mirror", 0.0)):
        tex = Texture("coords", img, wrap_s, "clamp", srgb=False)
        uv = np.array([[(3.5) / w, (2.5) / h],      # a texel centre: that texel
                       [4.0 / w, 2.5 / h],          # between texels 3 and 4
                       [0.0, 0.0],                  # the s edge: wrap-dependent; t clamps to row 0
                       [-0.5 / w, 7.5 / h]])        # half a texel before the start
        got = np.vstack([ref.sample(tex, uv[i:i + 1], zero, zero, srgb=False) for i in range(4)]) * 255
        np.testing.assert_allclose(got[0, :2], [48, 64], atol=1e-9)
        np.testing.assert_allclose(got[1, :2], [56, 64], atol=1e-9)
        np.testing.assert_allclose(got[2, :2], [edge, 0], atol=1e-9)
        np.testing.assert_allclose(got[3, :2], [{"repeat": 240.0, "clamp": 0.0, "mirror": 0.0}[wrap_s], 224],
                                   atol=1e-9)
    # mirror: texel index -2 reads texel 1, index w + 1 reads w - 2
    tex = Texture("coords", img, "mirror", "clamp", srgb=False)
    got = ref.sample(tex, np.array([[-1.5 / w, 0.5 / h], [(w + 1.5) / w, 0.5 / h]]), np.zeros((2, 2)),
                     np.zeros((2, 2)), srgb=False) * 255
    np.testing.assert_allclose(got[:, 0], [16, (w - 2) * 16], atol=1e-9)
    # LOD: a footprint of 4 level-0 texels along x is level 2, of 0.5 texels level 0 (clamped)
    np.testing.assert_allclose(ref.texture_lod((w, h), np.array([[4 / w, 0]]), np.array([[0, 1 / h]])), [2.0])
    np.testing.assert_allclose(ref.texture_lod((w, h), np.array([[0.5 / w, 0]]), np.array([[0, 0.5 / h]])), [-1.0])
    # the kernels' fast log2 is exact at powers of two and within 0.09 elsewhere
    x = np.geomspace(1e-6, 1e6, 2001)
    assert np.abs(ref._fast_log2(x) - np.log2(x)).max() < 0.0861
    # sRGB slots decode before filtering: the midpoint of codes 0 and 255 is linear 0.5
    bw = np.zeros((1, 2, 4), np.uint8)
    bw[0, 1] = 255
    got = ref.sample(Texture("bw", bw, "clamp", "clamp"), np.array([[0.5, 0.5]]), zero, zero, srgb=True)
    np.testing.assert_allclose(got[0], [0.5, 0.5, 0.5, 0.5], atol=1e-7)


def test_reference_metallic_roughness_numbers():
    albedo, si, sp = ref.mr_to_blinn_phong(np.array([[0.5, 0.5, 0.5], [1, 1, 1], [0.8, 0.2, 0.1], [0.3, 0.3, 0.3]]),
                                           np.array([0.0, 1.0, 0.5, 0.0]), np.array([1.0, 0.5, 0.1, 0.0]))
    np.testing.assert_allclose(albedo, [[0.5, 0.5, 0.5], [0, 0, 0], [0.4, 0.1, 0.05], [0.3, 0.3, 0.3]])
    lum = 0.2126 * 0.8 + 0.7152 * 0.2 + 0.0722 * 0.1
    np.testing.assert_allclose(si, [0.04, 1.0, 0.02 + 0.5 * lum, 0.04])
    # r = 1: 2/1 - 2 = 0 -> clamped to 1; r = 0.5: alpha = 0.25 -> 2/0.0625 - 2 = 30; r = 0.1, 0: capped
    np.testing.assert_allclose(sp, [1.0, 30.0, 2048.0, 2048.0])
    # the host helper (clrender.scene) agrees with the reference for the factor-only case
    from clrender.scene.model import metallic_roughness_to_blinn_phong
    rng = np.random.default_rng(3)
    for _ in range(20):
        base, m, r = rng.random(3), rng.random(), rng.random()
        _, si1, sp1 = ref.mr_to_blinn_phong(base, m, r)
        si2, sp2 = metallic_roughness_to_blinn_phong(base, m, r)
        assert si1 == pytest.approx(si2, rel=1e-12) and sp1 == pytest.approx(sp2, rel=1e-12)

def test_reference_interpolation_is_perspective_correct():
    """On the quad, uv is an affine function of the world position (u = (x+1)/2, v = (1-y)/2):
    the reference's ray-plane barycentrics must give exactly that at every pixel, and its
    neighbour-ray derivatives the finite differences of it."""
    rng = np.random.default_rng(1)
    scene = quad_scene(Material(**FULL_MATERIAL), textures_for(rng, 32))
    ids = reference_ids(scene, FRONT, 64, 64)
    ev = ref.evaluate(scene, FRONT, 64, 64, ids)
    m = ev["mask"]
    assert m.sum() > 1500
    P = ev["position"][m]
    np.testing.assert_allclose(P[:, 2], 0.0, atol=1e-9)
    np.testing.assert_allclose(ev["uv"][m][:, 0], np.stack([(P[:, 0] + 1) / 2, (1 - P[:, 1]) / 2], -1), atol=1e-9)
    # TEXCOORD_1 is another affine map of the same points
    u1 = 0.15 + 0.7 * (1 - P[:, 1]) / 2
    v1 = 0.9 - 0.85 * (P[:, 0] + 1) / 2
    np.testing.assert_allclose(ev["uv"][m][:, 1], np.stack([u1, v1], -1), atol=1e-6)
    # the per-slot LOD is finite and magnified-ish: 32 texels over ~55 px
    assert np.nanmax(ev["lod"][m][:, 0]) < 1.5


def test_reference_analytic_bump():
    """The reference's normal-mapped normals equal the analytic bump's (8-bit texels, bilinear):
    within 0.6° everywhere (measured 0.44°); and a map with its green channel flipped is far off
    (so the 2° bound of the device test can fail)."""
    scene = bump_scene()
    ids = reference_ids(scene, BUMP_CAMERA, 96, 96)
    ev = ref.evaluate(scene, BUMP_CAMERA, 96, 96, ids)
    region = ev["mask"] & ~ref.boundary_mask(ids, 1)
    err = bump_errors(ev["normal"], ev, region)
    assert err.max() < 0.6, describe(err)
    flipped = bump_texture()
    rgba = flipped.rgba.copy()
    rgba[..., 1] = 255 - rgba[..., 1]
    scene.textures = [Texture("flipped", rgba, "clamp", "clamp", srgb=False)]
    bad = bump_errors(ref.evaluate(scene, BUMP_CAMERA, 96, 96, ids)["normal"], ev, region)
    assert np.percentile(bad, 90) > 4.0, describe(bad)
