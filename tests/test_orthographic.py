"""Orthographic cameras (`Camera.orthographic`, docs/raster_contract.md §11) against truth clrender
did not compute, and the perspective path beside them.

* the camera: glTF semantics (the view box's half-height is ymag, its half-width ymag·aspect
  whatever xmag says), the GL orthographic matrix, bad input rejected with clear errors;
* raster: `triangle_id` equals the NumPy reference rasterizer's orthographic path bit for bit on
  seeded random soups (near-clipped, off-screen, far, degenerate, duplicate, NaN triangles) and on
  quantized soups full of exact ties; the reference itself against an analytic plane;
* the passes (shading, light culling, SSAO, shadows, velocity, transparency) in test_orthographic_passes.py;
* a renderer alternating projections gives the same frames as fresh ones; loaders (glTF, TOML)
  and the command line build orthographic cameras.
"""
import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

import clrender
from clrender import Camera
from ortho_cases import _frame_of, raster_guard  # noqa: F401 (raster_guard: an autouse fixture)
from reference.raster import rasterize, triangles_scene

DEPTH_RTOL = 1e-6


# -- the camera (no device) ----------------------------------------------------------------------------

def test_orthographic_matrix_is_gl_ortho_with_the_image_aspect():
    cam = Camera.orthographic((1.0, 2.0, 3.0), (1.0, 2.0, -1.0), (0, 1, 0), xmag=7.0, ymag=1.5, near=0.5, far=20.0)
    assert cam.is_orthographic and cam.projection == "orthographic" and (cam.xmag, cam.ymag) == (7.0, 1.5)
    aspect = 160 / 90
    P = cam.projection_matrix(aspect)
    r, t, n, f = 1.5 * aspect, 1.5, 0.5, 20.0
    expect = np.array([[1 / r, 0, 0, 0], [0, 1 / t, 0, 0], [0, 0, -2 / (f - n), -(f + n) / (f - n)], [0, 0, 0, 1]])
    np.testing.assert_allclose(P, expect, rtol=1e-15, atol=0)
    # xmag does not change the image (glTF viewers: the aspect decides the width)
    np.testing.assert_array_equal(replace(cam, xmag=0.1).projection_matrix(aspect), P)
    # the view box's corners land on the NDC cube's corners, w = 1
    right, up, fwd = _frame_of(cam)
    eye = np.asarray(cam.eye)
    M = cam.view_projection(160, 90)
    for sx in (-1, 1):
        for sy in (-1, 1):
            for d, z in ((n, -1.0), (f, 1.0)):
                p = eye + sx * r * right + sy * t * up + d * fwd
                np.testing.assert_allclose(M @ np.append(p, 1.0), (sx, sy, z, 1.0), atol=1e-12)
    # the raster matrix: x, y, w rows of the view-projection, z row = the view depth
    R = cam.raster_matrix(160, 90)
    np.testing.assert_array_equal(R[[0, 1, 3]], M[[0, 1, 3]])
    p = eye + 0.3 * right - 0.2 * up + 7.25 * fwd
    assert abs(R[2] @ np.append(p, 1.0) - 7.25) < 1e-12
    assert cam.half_extents(aspect) == (1.5 * aspect, 1.5)
    # a perspective camera's raster matrix is its view-projection, unchanged
    persp = Camera.look_at((1, 2, 3), (0, 0, 0), fov_y_deg=50)
    np.testing.assert_array_equal(persp.raster_matrix(64, 48), persp.view_projection(64, 48))


@pytest.mark.parametrize("kwargs, message", [
    (dict(xmag=0.0), "xmag must be a positive finite number"),
    (dict(xmag=-1.0), "xmag must be a positive finite number"),
    (dict(ymag=0.0), "ymag must be a positive finite number"),
    (dict(ymag=-2.0), "ymag must be a positive finite number"),
    (dict(ymag=float("nan")), "ymag must be a positive finite number"),
    (dict(ymag=float("inf")), "ymag must be a positive finite number"),
    (dict(xmag=None), "xmag must be a positive finite number"),
    (dict(ymag=True), "ymag must be a positive finite number"),
    (dict(near=5.0, far=5.0), "0 <= near < far"),
    (dict(near=6.0, far=5.0), "0 <= near < far"),
    (dict(near=-0.1), "0 <= near < far"),
    (dict(far=float("inf")), "0 <= near < far < inf"),
])
def test_bad_orthographic_cameras_are_rejected(kwargs, message):
    args = dict(xmag=1.0, ymag=1.0, near=0.1, far=10.0) | kwargs
    with pytest.raises(ValueError, match=message):
        Camera.orthographic((0, 0, 5), (0, 0, 0), (0, 1, 0), **args)


def test_projection_fields_are_validated():
    assert Camera.orthographic((0, 0, 5), (0, 0, 0), near=0.0, far=1.0).near == 0.0   # glTF allows znear = 0
    with pytest.raises(ValueError, match="projection must be one of"):
        Camera((0, 0, 5), (0, 0, 0), projection="fisheye")
    with pytest.raises(ValueError, match="apply to orthographic cameras"):
        Camera((0, 0, 5), (0, 0, 0), xmag=1.0, ymag=1.0)
    with pytest.raises(ValueError, match="0 < near < far"):
        Camera.look_at((0, 0, 5), (0, 0, 0), near=0.0)


# -- the raster against the NumPy reference --------------------------------------------------------------

def ortho_soup(rng, n, width, height, single_fraction=0.3):
    """An orthographic camera and overlapping triangles of all sizes: some crossing the near plane,
    some off screen, behind the eye plane or past the far plane, degenerate, duplicated, NaN/Inf."""
    ymag = rng.uniform(2.0, 8.0)
    near = rng.uniform(0.0, 1.0)
    far = rng.uniform(12.0, 40.0)
    eye = rng.uniform(-3, 3, 3) + np.array([0.0, 0.0, 9.0])
    cam = Camera.orthographic(eye, rng.uniform(-2, 2, 3), (0.0, 1.0, 0.0), xmag=rng.uniform(1, 9), ymag=ymag,
                              near=near, far=far)
    right, up, fwd = (np.asarray(v) for v in _frame_of(cam))
    half_w = ymag * width / height
    kinds = rng.choice(["scene", "near", "offscreen", "far", "degenerate", "duplicate", "bad"], n,
                       p=[0.55, 0.15, 0.08, 0.06, 0.06, 0.06, 0.04])
    tris = np.zeros((n, 3, 3))
    for i, kind in enumerate(kinds):
        if kind == "duplicate" and i > 0:
            tris[i] = tris[rng.integers(i)]
            if rng.integers(2):
                tris[i] = tris[i][[0, 2, 1]]
            continue
        lateral = right * rng.uniform(-half_w, half_w) + up * rng.uniform(-ymag, ymag)
        if kind == "near":
            center, scale = eye + fwd * (near + rng.uniform(-1.0, 1.0)) + lateral, ymag * rng.uniform(0.05, 0.4)
        elif kind == "offscreen":
            if rng.integers(2):
                center = eye - fwd * rng.uniform(1, 10) + lateral                          # behind the eye plane
            else:
                center = eye + fwd * rng.uniform(2, 10) + right * rng.choice([-1, 1]) * half_w * rng.uniform(1.5, 4)
            scale = rng.uniform(0.1, 1.0)
        elif kind == "far":
            center, scale = eye + fwd * far * rng.uniform(0.9, 1.2) + lateral, rng.uniform(0.5, 3.0)
        else:
            center = eye + fwd * rng.uniform(near, far * 0.8) + lateral
            scale = ymag * float(np.exp(rng.uniform(np.log(0.01), np.log(0.5))))
        tris[i] = center + rng.normal(size=(3, 3)) * scale
        if kind == "degenerate":
            if rng.integers(2):
                tris[i, 2] = tris[i, rng.integers(2)]
            else:
                tris[i, 2] = tris[i, 0] + rng.uniform(-1, 2) * (tris[i, 1] - tris[i, 0])
        elif kind == "bad":
            tris[i, rng.integers(3), rng.integers(3)] = rng.choice([np.nan, np.inf, -np.inf])
    return triangles_scene(tris, single_sided=rng.random(n) < single_fraction), cam


def quantized_ortho_soup(rng, n, size):
    """Axis-aligned orthographic camera over a square image, ymag = 1: world x, y on a 1/16 grid
    snap exactly, edges pass through pixel centres, coplanar overlaps tie in depth (1, 2 or 4)."""
    cam = Camera.orthographic((0.0, 0.0, 0.0), (0.0, 0.0, -1.0), (0.0, 1.0, 0.0), xmag=1.0, ymag=1.0, near=0.5,
                              far=50.0)
    tris = np.zeros((n, 3, 3))
    for i in range(n):
        if i > 0 and rng.random() < 0.1:
            tris[i] = tris[rng.integers(i)]
            continue
        d = np.full(3, rng.choice([1.0, 2.0, 4.0])) if rng.random() < 0.8 else rng.choice([1.0, 2.0, 4.0], 3)
        center = rng.integers(-20, 21, 2) / 16.0
        span = rng.integers(1, 12) / 16.0
        xy = center + rng.integers(-4, 5, (3, 2)) / 4.0 * span
        tris[i, :, :2] = xy
        tris[i, :, 2] = -d
    return triangles_scene(tris, single_sided=rng.random(n) < 0.3), cam


def assert_raster_matches(frame, expect, stats_keys=("invalid", "culled_near", "triangles_in")):
    ref_ids, ref_depth, ref_stats = expect
    diff = np.argwhere(frame.triangle_id != ref_ids)
    if len(diff):
        r, c = diff[0]
        pytest.fail(f"triangle_id differs on {len(diff)} of {ref_ids.size} pixels, e.g. (row {r}, col {c}): "
                    f"got {frame.triangle_id[r, c]}, reference {ref_ids[r, c]}")
    fg = ref_ids >= 0
    assert np.all(np.isposinf(frame.depth[~fg]))
    np.testing.assert_allclose(frame.depth[fg], ref_depth[fg], rtol=DEPTH_RTOL, atol=1e-6 * float(ref_depth[fg].max()))
    for key in stats_keys:
        assert frame.stats[key] == ref_stats[key], (key, frame.stats[key], ref_stats[key])


def test_reference_ortho_depth_is_the_plane_along_parallel_rays():
    """The reference on its own: a tilted plane seen orthographically; depth at each covered pixel
    is where the pixel's parallel ray meets the plane (analytic, float64)."""
    w, h = 40, 30
    cam = Camera.orthographic((0.0, 0.0, 0.0), (0.0, 0.0, -1.0), xmag=1.0, ymag=1.5, near=0.1, far=50.0)
    # plane z = -(4 + 0.5 x + 0.25 y), a quad over x, y in [-1.5, 1.5]
    corners = np.array([[x, y, -(4 + 0.5 * x + 0.25 * y)] for x, y in ((-1.5, -1.5), (1.5, -1.5), (1.5, 1.5),
                                                                        (-1.5, 1.5))])
    scene = triangles_scene(corners[[[0, 1, 2], [0, 2, 3]]])
    ids, depth, stats = rasterize(scene, cam, w, h)
    assert stats["prims"] == 2
    x = ((np.arange(w) + 0.5) / w * 2 - 1) * 1.5 * w / h         # pixel centres' view x, y: parallel rays
    y = (1 - (np.arange(h) + 0.5) / h * 2) * 1.5
    inside = np.broadcast_to((np.abs(x) < 1.5)[None, :] & (np.abs(y) < 1.5)[:, None], ids.shape)
    np.testing.assert_array_equal(ids >= 0, inside)           # the quad's columns: 5 .. 34 of 40
    assert inside.sum() == 30 * h
    analytic = np.broadcast_to(4 + 0.5 * x[None, :] + 0.25 * y[:, None], depth.shape)
    np.testing.assert_allclose(depth[inside], analytic[inside], rtol=2e-6)


def test_ortho_soup_generators_stay_in_reference_scope():
    for seed in range(12):
        scene, cam = ortho_soup(np.random.default_rng(seed), 150, 97, 61)
        rasterize(scene, cam, 97, 61)


@pytest.mark.parametrize("seed", range(6))
def test_random_ortho_soup_matches_reference(make_renderer, seed):
    size = [(64, 48), (97, 61), (128, 128)][seed % 3]
    scene, cam = ortho_soup(np.random.default_rng(100 + seed), 160, *size)
    expect = rasterize(scene, cam, *size)
    assert (expect[0] >= 0).mean() > 0.2 and expect[2]["culled_near"] > 0
    frame = make_renderer(*size).render(scene, cam)
    assert frame.stats["clipped"] > 0, "the soup must exercise the near clip"
    assert_raster_matches(frame, expect)


@pytest.mark.parametrize("tile_size", [8, 32])
@pytest.mark.parametrize("seed", [0, 1])
def test_quantized_ortho_soup_with_ties_matches_reference(make_renderer, seed, tile_size):
    scene, cam = quantized_ortho_soup(np.random.default_rng(seed), 150, 64)
    expect = rasterize(scene, cam, 64, 64)
    frame = make_renderer(64, 64, tile_size=tile_size).render(scene, cam)
    assert_raster_matches(frame, expect, ("invalid", "culled_near", "degenerate", "culled_backface", "triangles_in"))


def test_ortho_sub_sample_visibility_matches_reference(device):
    """light_prepass with msaa=4: each sub-sample's visibility (the ORTHO setup and raster at the
    sample points) equals the reference at that sample point (contract §10 and §11)."""
    from clrender.passes.second_geometry import SampleGeometryPass, sample_offsets
    size = (61, 47)
    scene, cam = ortho_soup(np.random.default_rng(44), 120, *size)
    r = clrender.Renderer(*size, device=device.id, pipeline="light_prepass", msaa=4, shadows=False)
    r.render(scene, cam)
    geo = next(p for p in r.pipeline.passes if isinstance(p, SampleGeometryPass))
    planes = geo.raster.vis_prim.get().reshape(4, -1)
    prims = geo.sub["prims"].get()
    for s, (dx, dy) in enumerate(sample_offsets(4)):
        vis = planes[s][: size[0] * size[1]].reshape(size[1], size[0])
        got = np.where(vis >= 0, prims["tri"][np.maximum(vis, 0)], -1)
        expect, _, _ = rasterize(scene, cam, *size, sample=(dx, dy))
        assert (expect >= 0).mean() > 0.2
        np.testing.assert_array_equal(got, expect, err_msg=f"sample {s} at ({dx}, {dy})/256")


def test_switching_projection_keeps_perspective_frames(make_renderer, device):
    """One renderer alternating perspective and orthographic cameras gives the frames fresh
    renderers give (the pipeline kind follows the camera; nothing leaks between them)."""
    scene, ortho = ortho_soup(np.random.default_rng(7), 120, 64, 48)
    persp = Camera.look_at(ortho.eye, ortho.target, ortho.up, 60.0, near=0.2, far=ortho.far)
    shared = make_renderer(64, 48)
    a = shared.render(scene, persp)
    b = shared.render(scene, ortho)
    c = shared.render(scene, persp)
    fresh = clrender.Renderer(64, 48, device=device.id)
    np.testing.assert_array_equal(a.gbuffer, fresh.render(scene, persp).gbuffer)
    np.testing.assert_array_equal(a.gbuffer, c.gbuffer)
    np.testing.assert_array_equal(b.gbuffer, clrender.Renderer(64, 48, device=device.id).render(scene, ortho).gbuffer)
    assert not np.array_equal(a.triangle_id, b.triangle_id)


# -- loaders and the command line --------------------------------------------------------------------------------

CAMERAS_GLTF = Path(__file__).resolve().parents[2] / "shared" / "scenes" / "khronos-Cameras" / "Cameras.gltf"


@pytest.mark.skipif(not CAMERAS_GLTF.is_file(), reason=f"{CAMERAS_GLTF} not found (shared scenes absent)")
def test_gltf_perspective_and_orthographic_cameras(tmp_path):
    import shutil
    persp = clrender.load_scene(CAMERAS_GLTF).camera
    assert persp.projection == "perspective" and persp.near == pytest.approx(0.01)
    assert persp.fov_y_deg == pytest.approx(np.degrees(0.7))
    # the same file with the orthographic camera's node first in traversal order
    doc = json.loads(CAMERAS_GLTF.read_text())
    cam_nodes = [n for n in doc["scenes"][0]["nodes"] if "camera" in doc["nodes"][n]]
    ortho_node = next(n for n in cam_nodes if doc["cameras"][doc["nodes"][n]["camera"]]["type"] == "orthographic")
    doc["scenes"][0]["nodes"] = [ortho_node] + [n for n in doc["scenes"][0]["nodes"] if n != ortho_node]
    for b in doc.get("buffers", []):
        shutil.copy(CAMERAS_GLTF.parent / b["uri"], tmp_path / b["uri"])
    (tmp_path / "Cameras.gltf").write_text(json.dumps(doc))
    ortho = clrender.load_scene(tmp_path / "Cameras.gltf").camera
    spec = doc["cameras"][doc["nodes"][ortho_node]["camera"]]["orthographic"]
    assert ortho.is_orthographic and (ortho.xmag, ortho.ymag) == (spec["xmag"], spec["ymag"])
    assert (ortho.near, ortho.far) == (spec["znear"], spec["zfar"])
    np.testing.assert_allclose(ortho.eye, doc["nodes"][ortho_node]["translation"])
    np.testing.assert_allclose(np.subtract(ortho.target, ortho.eye), (0, 0, -1), atol=1e-12)   # local -Z
    # a bad one is a clear error
    doc["cameras"][doc["nodes"][ortho_node]["camera"]]["orthographic"]["ymag"] = 0.0
    (tmp_path / "Cameras.gltf").write_text(json.dumps(doc))
    with pytest.raises(Exception, match="ymag must be a positive"):
        clrender.load_scene(tmp_path / "Cameras.gltf")


def _toml(tmp_path, camera: str) -> Path:
    quad = tmp_path / "quad.obj"
    quad.write_text("v -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\nf 1 2 3\nf 1 3 4\n")
    path = tmp_path / "scene.toml"
    path.write_text(f'[[mesh]]\npath = "quad.obj"\n\n[camera]\neye = [0, 0, 5]\ntarget = [0, 0, 0]\n{camera}')
    return path


def test_toml_orthographic_camera(tmp_path):
    cam = clrender.load_scene(_toml(tmp_path, 'projection = "orthographic"\nxmag = 2\nymag = 1.5\nnear = 0\n')).camera
    assert cam.is_orthographic and (cam.xmag, cam.ymag, cam.near, cam.far) == (2.0, 1.5, 0.0, 100.0)
    from clrender.scene.model import SceneError
    for text, message in (('projection = "orthographic"\nymag = 1\n', "needs 'xmag'"),
                          ('projection = "orthographic"\nxmag = 1\nymag = 0\n', "must be > 0"),
                          ('projection = "orthographic"\nxmag = 1\nymag = 1\nfov_y_deg = 40\n', "fov_y_deg applies"),
                          ('xmag = 1\n', "xmag applies to orthographic"),
                          ('projection = "fisheye"\n', "projection must be"),
                          ('projection = "orthographic"\nxmag = 1\nymag = 1\nnear = 5\nfar = 5\n', "near < far"),
                          ('projection = "orthographic"\nxmag = 1\nymag = 1\nzoom = 2\n', "unknown key 'zoom'")):
        with pytest.raises(SceneError, match=message):
            clrender.load_scene(_toml(tmp_path, text))


def test_cli_ortho_flag(tmp_path, capsys):
    from clrender.cli import app as cli
    path = _toml(tmp_path, 'projection = "orthographic"\nxmag = 2\nymag = 1.5\n')
    assert cli.main(["info", str(path), "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["camera"]["projection"] == "orthographic" and info["camera"]["ymag"] == 1.5
    assert cli.main(["info", str(path)]) == 0
    assert "orthographic xmag 2 ymag 1.5" in capsys.readouterr().out
    out = ["-o", str(tmp_path / "out.png")]
    args = cli.build_parser().parse_args(["render", str(path), *out, "--ortho", "3", "--camera-eye", "0,1,5"])
    cam = cli._camera(clrender.load_scene(path), args)
    assert cam.is_orthographic and cam.ymag == 3.0 and cam.xmag == pytest.approx(4.0) and cam.eye == (0.0, 1.0, 5.0)
    args = cli.build_parser().parse_args(["render", str(path), *out, "--fov", "40"])
    assert not cli._camera(clrender.load_scene(path), args).is_orthographic
    with pytest.raises(cli.CLIError, match="exclude each other"):
        cli._camera(clrender.load_scene(path), cli.build_parser().parse_args(["render", str(path), *out, "--fov",
                                                                             "40", "--ortho", "2"]))
    with pytest.raises(cli.CLIError, match="positive half-height"):
        cli.build_parser().parse_args(["render", str(path), *out, "--ortho", "0"])
    # the whole command: an orthographic render of the scene written to the image
    assert cli.main(["render", str(path), *out, "--ortho", "1.2", "--width", "32", "--height", "24", "-q"]) == 0
    assert (tmp_path / "out.png").stat().st_size > 0
