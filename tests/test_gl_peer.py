"""Tests of the OpenGL benchmark peer (bench/gl_peer.py) on small analytic scenes.

Skipped when moderngl or a headless EGL context is unavailable.
"""
from __future__ import annotations

import os
import sys

import numpy as np
import pytest

# bench/ is not part of the installed package: import it (and clrender) from this checkout.
sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from clrender import Camera, Material, Scene, Texture

from helpers import in_ci  # noqa: E402

# In CI the peer must run (Mesa's EGL is installed there): its absence fails instead of skipping.
moderngl = __import__("moderngl") if in_ci() else pytest.importorskip("moderngl", reason="moderngl not installed")

from bench.gl_peer import GLPeer, compare_gbuffers, gl_available  # noqa: E402

_ok, _why = gl_available()
pytestmark = pytest.mark.skipif(not _ok and not in_ci(), reason=f"no headless EGL/OpenGL 4.5 context: {_why}")

W = H = 64
# Camera at the origin looking down -Z with fov 90 and aspect 1: a view-space point
# (x, y, -d) lands at NDC (x/d, y/d), so geometry can be placed directly in NDC.
CAM = Camera.look_at((0, 0, 0), (0, 0, -1), (0, 1, 0), fov_y_deg=90.0, near=0.1, far=100.0)


@pytest.fixture(scope="module")
def peer():
    p = GLPeer(W, H)
    yield p
    p.release()


def ndc_tri(pts_ndc, d):
    """View-space (= world-space here) vertices at depth d for NDC xy points."""
    return [(x * d, y * d, -d) for x, y in pts_ndc]


def pixel_ndc():
    """NDC of each pixel center, row 0 = top: (ndc_x[W], ndc_y[H])."""
    c = (np.arange(W) + 0.5) / W * 2 - 1
    r = 1 - (np.arange(H) + 0.5) / H * 2
    return c, r


def full_quad(d=2.0, uv_scale=1.0):
    """Screen-filling quad at depth d (CCW, facing the camera); uv (0,0) at the top-left."""
    ext = 1.2
    v = ndc_tri([(-ext, ext), (-ext, -ext), (ext, -ext), (ext, ext)], d)
    s = uv_scale * (ext + 1) / 2  # uv 0 at NDC x = -1 (left) / y = +1 (top), 1 at the other side
    o = uv_scale * (1 - ext) / 2
    uv = [(o, o), (o, s), (s, s), (s, o)]
    return np.array(v, np.float32), np.array([[0, 1, 2], [0, 2, 3]]), np.array(uv, np.float32)


def test_context_is_llvmpipe(peer):
    assert "llvmpipe" in peer.renderer.lower()


def test_orientation_depth_and_ids(peer):
    # Triangle 0 (CCW in NDC) in the upper-left quadrant at depth 2.
    v = ndc_tri([(-0.9, 0.9), (-0.9, 0.1), (-0.1, 0.9)], 2.0)
    scene = Scene.from_arrays(v, [[0, 1, 2]])
    peer.upload(scene)
    g = peer.render(CAM)
    assert g["depth"].shape == (H, W) and g["depth"].dtype == np.float32
    assert g["triangle_id"].dtype == np.int32
    assert g["normal"].shape == (H, W, 3) and g["albedo"].shape == (H, W, 3)
    fg = g["triangle_id"] >= 0
    rows, cols = np.nonzero(fg)
    assert fg.sum() > 100
    assert rows.max() < H // 2 and cols.max() < W // 2       # upper-left quadrant only
    assert fg[4, 4] and not fg[H - 5, W - 5]
    assert np.all(g["triangle_id"][fg] == 0)
    assert np.all(np.isinf(g["depth"][~fg]))
    np.testing.assert_allclose(g["depth"][fg], 2.0, rtol=1e-4)
    # Front-facing: normal (0, 0, 1) as given, albedo white.
    np.testing.assert_allclose(g["normal"][fg], np.tile([0, 0, 1], (fg.sum(), 1)), atol=2e-3)
    np.testing.assert_allclose(g["albedo"][fg], 1.0, atol=1e-3)


def test_depth_on_tilted_plane_matches_analytic(peer):
    # Plane z_view = -(c + s * x_view): view depth at NDC x is c / (1 - s * x).
    c, s = 3.0, 0.5
    ext = 1.5
    xs = np.array([-ext, ext])
    d_edge = c / (1 - s * xs)
    v = []
    for y in (ext, -ext):
        for x, d in zip(xs, d_edge):
            v.append((x * d, y * d, -d))
    scene = Scene.from_arrays(np.array(v), [[0, 2, 3], [0, 3, 1]])
    peer.upload(scene)
    g = peer.render(CAM)
    assert np.all(g["triangle_id"] >= 0)
    nx, _ = pixel_ndc()
    expect = np.broadcast_to(c / (1 - s * nx), (H, W))
    np.testing.assert_allclose(g["depth"], expect, rtol=1e-4)


def test_two_overlapping_triangles_nearest_wins(peer):
    far_tri = ndc_tri([(-0.8, 0.8), (-0.8, -0.8), (0.8, -0.8)], 5.0)   # id 0, lower-left half
    near_tri = ndc_tri([(-0.5, 0.5), (-0.5, -0.5), (0.5, 0.5)], 3.0)   # id 1, nearer
    scene = Scene.from_arrays(np.array(far_tri + near_tri), [[0, 1, 2], [3, 4, 5]])
    peer.upload(scene)
    g = peer.render(CAM)
    tid, depth = g["triangle_id"], g["depth"]
    # Pixel (row, col) -> NDC (x, y) = ((col+.5)/32 - 1, 1 - (row+.5)/32)
    assert tid[H // 2 - 4, W // 2 - 12] == 1   # inside both: near wins
    assert tid[H - 10, W // 2] == 0            # only the far one
    assert tid[4, W - 4] == -1                 # neither
    np.testing.assert_allclose(depth[tid == 1], 3.0, rtol=1e-4)
    np.testing.assert_allclose(depth[tid == 0], 5.0, rtol=1e-4)
    # Same with the near triangle first in id order (visibility is by depth, not order).
    scene = Scene.from_arrays(np.array(near_tri + far_tri), [[0, 1, 2], [3, 4, 5]])
    peer.upload(scene)
    g2 = peer.render(CAM)
    assert np.array_equal(np.where(tid >= 0, 1 - tid, -1), g2["triangle_id"])


def test_triangle_ids_survive_material_sorting(peer):
    # A 10x10 grid of cells, two triangles each, materials interleaved (so the material sort
    # permutes triangles and both id paths -- direct and SSBO lookup -- are used).
    n = 10
    verts, faces = [], []
    for j in range(n):
        for i in range(n):
            x0, x1 = -1 + 2 * i / n, -1 + 2 * (i + 1) / n
            y0, y1 = 1 - 2 * j / n, 1 - 2 * (j + 1) / n
            k = len(verts)
            verts += ndc_tri([(x0, y0), (x0, y1), (x1, y1), (x1, y0)], 4.0)
            faces += [[k, k + 1, k + 2], [k, k + 2, k + 3]]
    verts, faces = np.array(verts), np.array(faces)
    t = len(faces)
    rng = np.random.default_rng(1)
    tri_mat = rng.integers(0, 3, t).astype(np.int32)
    tri_mat[: t // 4] = 3          # a contiguous run: the direct path
    colors = [(1, 0, 0, 1), (0, 1, 0, 1), (0, 0, 1, 1), (0.5, 0.25, 0.125, 1)]
    mats = [Material(name=f"m{i}", base_color=c) for i, c in enumerate(colors)]
    base = Scene.from_arrays(verts, faces)
    scene = Scene(base.positions, base.normals, base.uvs, base.triangles, tri_mat, mats)
    peer.upload(scene)
    info = peer.info()
    assert info["draw_calls"] == 4 and 1 <= info["draws_with_id_lookup"] <= 3
    g = peer.render(CAM)
    # Expected id at every pixel from the grid geometry (cell; lower-left or upper-right half).
    nx, ny = pixel_ndc()
    X, Y = np.meshgrid(nx, ny)
    i = np.floor((X + 1) / 2 * n).astype(int)
    j = np.floor((1 - Y) / 2 * n).astype(int)
    fx = (X + 1) / 2 * n - i
    fy = (1 - Y) / 2 * n - j
    upper_right = fx > fy     # triangle (k, k+2, k+3) covers the part above the diagonal
    expect = 2 * (j * n + i) + upper_right
    interior = np.abs(fx - fy) > 0.1
    tid = g["triangle_id"]
    assert np.all(tid >= 0)
    assert np.array_equal(tid[interior], expect[interior])
    # Albedo matches each triangle's material.
    want = np.array(colors)[tri_mat[tid]][..., :3]
    np.testing.assert_allclose(g["albedo"], want, atol=1e-3)


TL, TR, BL, BR = (255, 0, 0, 255), (0, 255, 0, 255), (0, 0, 255, 255), (255, 255, 255, 255)


def textured_quad_scene(rgba, wrap="clamp", uv_scale=1.0, **mat_kw):
    v, f, uv = full_quad(2.0, uv_scale)
    base = Scene.from_arrays(v, f, uvs=uv)
    tex = Texture("t", np.array(rgba, np.uint8), wrap_s=wrap, wrap_t=wrap)
    mat = Material(name="tex", base_color_texture=0, **mat_kw)
    return Scene(base.positions, base.normals, base.uvs, base.triangles,
                 base.triangle_material, [mat], [tex])


def test_texture_orientation_top_left_texel_at_uv_origin(peer):
    # Image row 0 is the top: [[TL, TR], [BL, BR]].  glTF uv (0,0) = top-left of the image,
    # and the quad maps uv (0,0) to the top-left of the screen.
    peer.upload(textured_quad_scene([[TL, TR], [BL, BR]]))
    g = peer.render(CAM)
    a = g["albedo"]
    np.testing.assert_allclose(a[0, 0], [1, 0, 0], atol=1e-3)            # top-left: red
    np.testing.assert_allclose(a[0, W - 1], [0, 1, 0], atol=1e-3)        # top-right: green
    np.testing.assert_allclose(a[H - 1, 0], [0, 0, 1], atol=1e-3)        # bottom-left: blue
    np.testing.assert_allclose(a[H - 1, W - 1], [1, 1, 1], atol=1e-3)    # bottom-right: white
    # Quadrant centers are dominated by their texel.
    q = H // 4
    assert np.argmax(a[q, q]) == 0 and np.argmax(a[q, 3 * q]) == 1 and np.argmax(a[3 * q, q]) == 2


def test_srgb_texels_are_decoded_to_linear(peer):
    peer.upload(textured_quad_scene([[(128, 64, 255, 255)]], base_color=(0.5, 1, 1, 1)))
    g = peer.render(CAM)
    s = np.array([128, 64, 255]) / 255.0
    lin = np.where(s <= 0.04045, s / 12.92, ((s + 0.055) / 1.055) ** 2.4) * [0.5, 1, 1]
    np.testing.assert_allclose(g["albedo"].reshape(-1, 3), np.tile(lin, (H * W, 1)), atol=2e-3)


def test_minified_texture_is_filtered_in_linear_space(peer):
    # A 1-texel black/white checker at 4 texels per pixel (trilinear, LOD 2): every mip
    # level averages in linear space, so the result is 0.5, not decode(0.5) = 0.214.
    checker = ((np.indices((64, 64)).sum(0) % 2) * 255).astype(np.uint8)
    rgba = np.dstack([checker] * 3 + [np.full_like(checker, 255)])
    peer.upload(textured_quad_scene(rgba, wrap="repeat", uv_scale=4.0))
    a = peer.render(CAM)["albedo"]
    np.testing.assert_allclose(np.median(a), 0.5, atol=0.02)


def test_mirror_and_repeat_wrap(peer):
    # One row, two texels [TL(red), TR(green)], uv u in [0, 2] across the screen.
    # Repeat: u = 1.25 -> 0.25 (red); mirror: u = 1.25 -> 0.75 (green).
    nx, _ = pixel_ndc()
    u = (nx + 1) / 2 * 2.0
    col = int(np.argmin(np.abs(u - 1.25)))
    for wrap, expect in (("repeat", [1, 0, 0]), ("mirror", [0, 1, 0])):
        peer.upload(textured_quad_scene([[TL, TR]], wrap=wrap, uv_scale=2.0))
        a = peer.render(CAM)["albedo"]
        assert np.argmax(a[H // 2, col]) == np.argmax(expect), (wrap, a[H // 2, col])


def test_single_sided_culling_and_double_sided_flip(peer):
    front = ndc_tri([(-0.9, 0.9), (-0.9, 0.1), (-0.1, 0.9)], 2.0)   # CCW: front, upper-left
    back = ndc_tri([(0.1, -0.1), (0.9, -0.1), (0.1, -0.9)], 2.0)    # CW: back, lower-right
    verts = np.array(front + back)
    normals = np.tile([0, 0, 1], (6, 1)).astype(np.float32)
    for double_sided in (False, True):
        scene = Scene.from_arrays(verts, [[0, 1, 2], [3, 4, 5]], normals=normals,
                                  material=Material(double_sided=double_sided))
        peer.upload(scene)
        g = peer.render(CAM)
        tid = g["triangle_id"]
        assert (tid == 0).sum() > 100
        if double_sided:
            assert (tid == 1).sum() == (tid == 0).sum()
            np.testing.assert_allclose(g["normal"][tid == 1], np.tile([0, 0, -1], ((tid == 1).sum(), 1)),
                                       atol=2e-3)
            np.testing.assert_allclose(g["normal"][tid == 0], np.tile([0, 0, 1], ((tid == 0).sum(), 1)),
                                       atol=2e-3)
        else:
            assert (tid == 1).sum() == 0


def test_mask_discard(peer):
    # Near quad textured [transparent | opaque] with MASK over a far opaque quad.
    v, f, uv = full_quad(2.0)
    v_far, f_far, _ = full_quad(6.0)
    verts = np.concatenate([v, v_far])
    faces = np.concatenate([f, f_far + 4])
    uvs = np.concatenate([uv, uv])
    base = Scene.from_arrays(verts, faces, uvs=uvs)
    tex = Texture("a", np.array([[(255, 255, 255, 0), (255, 255, 255, 255)]], np.uint8), "clamp", "clamp")
    mats = [Material(name="masked", base_color_texture=0, alpha_mode="MASK", alpha_cutoff=0.5),
            Material(name="far", base_color=(0.2, 0.2, 0.2, 1.0))]
    scene = Scene(base.positions, base.normals, base.uvs, base.triangles,
                  np.array([0, 0, 1, 1], np.int32), mats, [tex])
    peer.upload(scene)
    g = peer.render(CAM)
    tid, depth = g["triangle_id"], g["depth"]
    left, right = np.s_[:, : W // 2 - 2], np.s_[:, W // 2 + 2:]
    assert np.all(tid[left] >= 2) and np.all(tid[right] <= 1) and np.all(tid >= 0)
    np.testing.assert_allclose(depth[left], 6.0, rtol=1e-4)
    np.testing.assert_allclose(depth[right], 2.0, rtol=1e-4)
    # The factor's alpha counts too: alpha 0.3 < 0.5 discards everything of the near quad.
    mats[0] = Material(name="masked", base_color=(1, 1, 1, 0.3), alpha_mode="MASK", alpha_cutoff=0.5)
    scene.materials = mats
    peer.upload(scene)
    assert np.all(peer.render(CAM)["triangle_id"] >= 2)


def test_compare_gbuffers(peer):
    v = ndc_tri([(-0.9, 0.9), (-0.9, -0.9), (0.9, 0.9)], 2.0)
    peer.upload(Scene.from_arrays(v, [[0, 1, 2]]))
    g = peer.render(CAM)
    m = compare_gbuffers(g, g)
    assert m["coverage_agreement"] == 1.0 and m["depth_agree_frac"] == 1.0
    assert m["triangle_id_equal_frac"] == 1.0 and m["albedo_psnr_db"] == float("inf")
    assert m["normal_angle_p99_deg"] < 0.1
    h = {k: np.array(x, copy=True) for k, x in g.items()}
    h["depth"] *= 1.01
    h["triangle_id"][:, : W // 2] = -1
    m = compare_gbuffers(g, h)
    assert m["depth_agree_frac"] == 0.0 and m["depth_rel_diff_p99"] == pytest.approx(0.01, rel=1e-3)
    assert 0.0 < m["coverage_agreement"] < 1.0 and 0.0 < m["triangle_id_equal_frac"] < 1.0


def test_timing_api(peer):
    v = ndc_tri([(-0.9, 0.9), (-0.9, -0.9), (0.9, 0.9)], 2.0)
    peer.upload(Scene.from_arrays(v, [[0, 1, 2]]))
    t = peer.time_frame(CAM, repeats=3, warmup=1)
    tr = peer.time_frame_with_readback(CAM, repeats=3, warmup=1)
    assert len(t) == 3 and len(tr) == 3 and all(x > 0 for x in t + tr)


SPONZA = "/work/shared/scenes/sponza-crytek/Sponza.gltf"


@pytest.mark.slow
@pytest.mark.skipif(not os.path.exists(SPONZA), reason="shared Sponza scene not present")
def test_sponza_timing():
    try:
        from clrender import load_scene
        scene = load_scene(SPONZA)
    except (ImportError, AttributeError, NotImplementedError) as exc:
        pytest.skip(f"clrender.load_scene not usable yet: {exc}")
    cam = Camera.look_at((-16.64, 5.48, -0.79), (13.97, 6.55, -0.79), fov_y_deg=60.0, near=0.1, far=100.0)
    p = GLPeer(1280, 720)
    try:
        p.upload(scene)
        g = p.render(cam)
        assert (g["triangle_id"] >= 0).mean() > 0.9
        times = p.time_frame(cam, repeats=10, warmup=3)
        print(f"\nGLPeer Sponza 1280x720 on {p.renderer}: median {np.median(times):.1f} ms/frame")
    finally:
        p.release()
