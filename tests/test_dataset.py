"""`clrender dataset` (clrender.dataset, clrender.cli.dataset): exports re-render bit for bit from their
written cameras (transforms.json and COLMAP), depth/mask files match the frame, the formats agree with
each other (and with pycolmap when installed), --resume re-renders only what is missing, layouts frame
the bounds, docs/datasets.md's example runs, and bad input fails in one line before anything renders."""
from __future__ import annotations

import json
import pickle
import re
from pathlib import Path

import imageio.v3 as iio
import numpy as np
import pytest

from clrender import Renderer, load_scene
from clrender.outputs import aov_io
from clrender.cli import app as cli
from clrender.batch.jobs import FrameTask, Outputs, scene_config
from clrender.dataset.views import (
    export_documents, layout_cameras, load_dataset, parse_documents, quaternion_from_rotation,
    rotation_from_quaternion)
from clrender.dataset.outputs import view_files

REPO = Path(__file__).resolve().parents[1]
DEMO = REPO / "scenes" / "demo.toml"
W, H, N = 96, 64, 3
AOVS = "depth,object_id,normal"


def _dataset(*args) -> int:
    return cli.main(["dataset", *map(str, args)])


@pytest.fixture(scope="module")
def exports(device, tmp_path_factory):
    """The same sphere layout exported as nerf and as colmap."""
    out = {}
    for fmt in ("nerf", "colmap"):
        folder = tmp_path_factory.mktemp(fmt)
        assert _dataset(DEMO, "-o", folder, "--views", N, "--layout", "sphere", "--format", fmt, "--width", W,
                        "--height", H, "--aov", AOVS, "--device", device.id, "-q") == 0
        out[fmt] = folder
    return out


@pytest.fixture(scope="module")
def demo_renderer(device):
    scene = load_scene(str(DEMO))
    return scene, Renderer(W, H, device=device.id, config=scene_config(scene, {}))


def _quat_matrix(qw, qx, qy, qz):
    """COLMAP's qvec2rotmat, written out again here so the test does not trust the module's."""
    n = np.sqrt(qw * qw + qx * qx + qy * qy + qz * qz)
    w, x, y, z = qw / n, qx / n, qy / n, qz / n
    return np.array([[1 - 2 * y * y - 2 * z * z, 2 * x * y - 2 * z * w, 2 * x * z + 2 * y * w],
                     [2 * x * y + 2 * z * w, 1 - 2 * x * x - 2 * z * z, 2 * y * z - 2 * x * w],
                     [2 * x * z - 2 * y * w, 2 * y * z + 2 * x * w, 1 - 2 * x * x - 2 * y * y]])


def _read_colmap(folder: Path) -> dict:
    """{image name: (K, R, t)} parsed from the text model, independently of clrender.dataset."""
    cams = {}
    for ln in (folder / "sparse/0/cameras.txt").read_text().splitlines():
        if ln and not ln.startswith("#"):
            cid, model, w, h, fx, fy, cx, cy = ln.split()
            assert (model, int(w), int(h)) == ("PINHOLE", W, H)
            cams[cid] = np.array([[float(fx), 0, float(cx)], [0, float(fy), float(cy)], [0, 0, 1]])
    body = [ln for ln in (folder / "sparse/0/images.txt").read_text().splitlines() if not ln.startswith("#")]
    out = {}
    for pose, points in zip(body[0::2], body[1::2]):
        assert points == ""                         # the (empty) 2D points line after each image
        iid, qw, qx, qy, qz, tx, ty, tz, cid, name = pose.split()
        out[name] = (cams[cid], _quat_matrix(*map(float, (qw, qx, qy, qz))), np.array([float(tx), float(ty),
                                                                                        float(tz)]))
    return out


def _check_files(view, frame):
    """The view's depth, depth PNG, mask and normal files against the re-rendered frame."""
    depth = frame.depth
    np.testing.assert_array_equal(np.load(view.depth).view(np.uint32), depth.view(np.uint32))
    png = iio.imread(view.depth_png)
    assert png.dtype == np.uint16
    fg = np.isfinite(depth)
    assert fg.sum() > 200 and (~fg).sum() > 200
    assert np.all(png[~fg] == 0) and np.all(png[fg] > 0)
    assert np.abs(png[fg] / 1000.0 - depth[fg].astype(np.float64)).max() <= 0.5e-3 + 1e-9
    mask = iio.imread(view.mask)
    assert mask.dtype == np.uint16
    np.testing.assert_array_equal(mask, frame.object_id + 1)
    assert len(np.unique(mask)) >= 3                 # background and at least two objects
    root = view.image.parent.parent
    np.testing.assert_array_equal(np.load(root / "aovs" / f"{view.image.stem}.normal.npy"), frame.normal)


def _check_projection(K, R, t, frame):
    """Foreground pixels unprojected with the float depth and the written K, R, t are the frame's
    world positions, and project back onto their pixel centres."""
    v, u = np.nonzero(np.isfinite(frame.depth))
    z = frame.depth[v, u].astype(np.float64)
    centres = np.stack([u + 0.5, v + 0.5, np.ones(len(u))])
    X = R.T @ (np.linalg.inv(K) @ centres * z - t[:, None])
    np.testing.assert_allclose(X.T, frame.position[v, u], atol=1e-5 * z.max(), rtol=0)
    for points in (X, frame.position[v, u].astype(np.float64).T):
        p = K @ (R @ points + t[:, None])
        assert np.abs(p[:2] / p[2] - centres[:2]).max() < 1e-3


def test_nerf_transforms_as_nerfstudio_reads_them(exports):
    doc = json.loads((exports["nerf"] / "transforms.json").read_text())
    assert doc["camera_model"] == "OPENCV" and (doc["w"], doc["h"]) == (W, H)
    assert all(doc[k] == 0.0 for k in ("k1", "k2", "p1", "p2"))
    assert doc["cx"] == W / 2 and doc["cy"] == H / 2 and doc["fl_x"] == doc["fl_y"] > 0
    lo, hi = load_scene(str(DEMO)).bounds().astype(np.float64)
    eyes = []
    for i, f in enumerate(doc["frames"]):
        assert f["file_path"] == f"images/{i:04d}.png" and (exports["nerf"] / f["file_path"]).is_file()
        assert f["depth_file_path"] == f"depth/{i:04d}.png" and f["mask_path"] == f"masks/{i:04d}.png"
        m = np.array(f["transform_matrix"])
        assert m.shape == (4, 4) and np.array_equal(m[3], [0, 0, 0, 1])
        np.testing.assert_allclose(m[:3, :3] @ m[:3, :3].T, np.eye(3), atol=1e-12)
        to_centre = (lo + hi) / 2 - m[:3, 3]           # OpenGL: the camera looks down its -z column
        np.testing.assert_allclose(-m[:3, 2], to_centre / np.linalg.norm(to_centre), atol=1e-9)
        assert m[1, 1] > 0                              # y up: the view's up leans to +Y
        eyes.append(m[:3, 3])
    assert len({tuple(e) for e in eyes}) == N


def test_nerf_views_rerender_bit_for_bit(exports, demo_renderer):
    scene, renderer = demo_renderer
    views = load_dataset(exports["nerf"])
    assert [v.index for v in views] == list(range(N))
    for view in views:
        frame = renderer.render(scene, view.camera)
        np.testing.assert_array_equal(iio.imread(view.image), frame.image)
        _check_files(view, frame)
        _check_projection(view.K, view.R, view.t, frame)


def test_colmap_views_rerender_and_reproject(exports, demo_renderer):
    scene, renderer = demo_renderer
    folder = exports["colmap"]
    lines = (folder / "sparse/0/images.txt").read_text().splitlines()
    assert lines[1] == "#   IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME"
    assert (folder / "sparse/0/points3D.txt").read_text().splitlines()[-1] == \
        "# Number of points: 0, mean track length: 0"
    written = _read_colmap(folder)
    views = load_dataset(folder)
    assert sorted(written) == [v.image.name for v in views] == [f"{i:04d}.png" for i in range(N)]
    for view in views:
        frame = renderer.render(scene, view.camera)
        np.testing.assert_array_equal(iio.imread(view.image), frame.image)
        _check_files(view, frame)
        K, R, t = written[view.image.name]
        _check_projection(K, R, t, frame)


def test_nerf_and_colmap_agree(exports):
    nerf, colmap = load_dataset(exports["nerf"]), load_dataset(exports["colmap"])
    assert len(nerf) == len(colmap) == N
    for a, b in zip(nerf, colmap):
        for x, y in ((a.K, b.K), (a.R, b.R), (a.t, b.t), (a.c2w, b.c2w)):
            np.testing.assert_allclose(x, y, rtol=0, atol=1e-9)
        assert (a.camera.near, a.camera.far) == (b.camera.near, b.camera.far)


def test_pycolmap_reads_the_model(exports):
    pycolmap = pytest.importorskip("pycolmap", reason="pycolmap is not installed (pip install pycolmap)")
    rec = pycolmap.Reconstruction(str(exports["colmap"] / "sparse" / "0"))
    views = {v.image.name: v for v in load_dataset(exports["colmap"])}
    assert len(rec.images) == N and len(rec.points3D) == 0
    for image in rec.images.values():
        view = views[image.name]
        pose = image.cam_from_world() if callable(image.cam_from_world) else image.cam_from_world
        np.testing.assert_allclose(pose.rotation.matrix(), view.R, atol=1e-9)
        np.testing.assert_allclose(pose.translation, view.t, atol=1e-9)
        np.testing.assert_allclose(rec.cameras[image.camera_id].calibration_matrix(), view.K, atol=1e-9)


@pytest.mark.parametrize("doc", ["docs/datasets.md"])
def test_docs_example_runs(exports, tmp_path, monkeypatch, capsys, doc):
    text = (REPO / doc).read_text()
    code = re.search(r"<!-- example: load-nerf-export -->\n```python\n(.*?)```", text, re.S).group(1)
    (tmp_path / "out").symlink_to(exports["nerf"], target_is_directory=True)
    monkeypatch.chdir(tmp_path)
    exec(compile(code, doc, "exec"), {"__name__": "__main__"})
    assert "lie on view b's surface" in capsys.readouterr().out


def test_resume_renders_only_what_is_missing(device, tmp_path, capsys):
    args = [DEMO, "-o", tmp_path, "--views", N, "--layout", "random", "--seed", 5, "--width", W, "--height", H,
            "--format", "colmap", "--device", device.id]
    assert _dataset(*args) == 0
    files = {p: p.read_bytes() for p in tmp_path.rglob("*") if p.is_file() and p.name != "manifest.json"}
    first = {r["frame"]: r["run"] for r in json.loads((tmp_path / "manifest.json").read_text())["frames"]}
    (tmp_path / "images" / "0001.png").unlink()
    capsys.readouterr()
    assert _dataset(*args, "--resume") == 0
    assert f"1 rendered, {N - 1} already complete, 0 failed" in capsys.readouterr().err
    records = {r["frame"]: r for r in json.loads((tmp_path / "manifest.json").read_text())["frames"]}
    second = records[1]["run"]
    assert second != first[1] and "skipped_by" not in records[1]
    assert all(records[i]["run"] == first[i] and records[i]["skipped_by"] == [second] for i in range(N) if i != 1)
    assert {p: p.read_bytes() for p in files} == files
    # another job (other views) in the same folder: refused before its camera files are written
    assert _dataset(*args[:4], 6, *args[5:], "--resume") == 1
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "different job" in err and "views" in err
    assert (tmp_path / "sparse/0/images.txt").read_bytes() == files[tmp_path / "sparse/0/images.txt"]



def test_dask_workers_write_the_same_export(exports, device, tmp_path):
    pytest.importorskip("distributed", reason="--workers needs dask[distributed] (pip install -e .[test])")
    out = tmp_path / "out"
    assert _dataset(DEMO, "-o", out, "--views", N, "--layout", "sphere", "--width", W, "--height", H, "--aov", AOVS,
                    "--device", device.id, "--workers", 1, "-q") == 0
    ref = exports["nerf"]
    names = sorted(p.relative_to(ref) for p in ref.rglob("*") if p.is_file() and p.name != "manifest.json")
    assert names == sorted(p.relative_to(out) for p in out.rglob("*") if p.is_file() and p.name != "manifest.json")
    for name in names:
        assert (out / name).read_bytes() == (ref / name).read_bytes(), name
    workers = {r["worker"] for r in json.loads((out / "manifest.json").read_text())["frames"]}
    assert len(workers) == 1 and not workers & {r["worker"] for r in json.loads(
        (ref / "manifest.json").read_text())["frames"]}                 # rendered in another process

@pytest.mark.parametrize("layout", ["orbit", "sphere", "random"])
def test_layouts_frame_the_bounds(layout):
    bounds = np.array([[-3.0, -0.5, 1.0], [5.0, 2.0, 4.0]])
    centre = bounds.mean(0)
    corners = np.array([[x, y, z] for x in bounds[:, 0] for y in bounds[:, 1] for z in bounds[:, 2]])
    n, w, h = 9, 120, 80
    cams = layout_cameras(layout, n, bounds, w, h, seed=11)
    files = [view_files(f"{i:04d}", ("depth",), False) for i in range(n)]
    views = parse_documents(export_documents("colmap", cams, w, h, files, {}), "out")  # as rendered
    eyes = np.array([v.c2w[:3, 3] for v in views])
    assert len(np.unique(np.round(eyes, 9), axis=0)) == n
    for v in views:
        to_centre = centre - v.c2w[:3, 3]
        np.testing.assert_allclose(v.R[2], to_centre / np.linalg.norm(to_centre), atol=1e-9)
        cam = v.R @ corners.T + v.t[:, None]
        assert np.all(cam[2] > v.camera.near) and np.all(cam[2] < v.camera.far)
        uv = (v.K @ cam)[:2] / cam[2]
        assert np.all(uv >= 0) and np.all(uv[0] <= w) and np.all(uv[1] <= h)
    if layout == "sphere":
        assert np.all(eyes[:, 1] > centre[1])                          # the upper hemisphere
    if layout == "orbit":
        assert np.ptp(eyes[:, 1]) < 1e-9                                 # one ring
    if layout == "random":
        same = layout_cameras(layout, n, bounds, w, h, seed=11)
        other = layout_cameras(layout, n, bounds, w, h, seed=12)
        assert same == cams and other != cams
        assert np.any(eyes[:, 1] < centre[1]) and np.any(eyes[:, 1] > centre[1])   # the whole sphere


def test_quaternions_round_trip():
    rng = np.random.default_rng(0)
    for _ in range(200):
        q = rng.standard_normal(4)
        q /= np.linalg.norm(q)
        R = rotation_from_quaternion(q)
        back = quaternion_from_rotation(R)
        np.testing.assert_allclose(back, q * np.sign(q[0]), atol=1e-12)
        np.testing.assert_allclose(rotation_from_quaternion(back), R, atol=1e-12)


def test_camera_file_views(device, tmp_path):
    """Both kinds of file camera; K given for 192x128 and rendered at 96x64 scales with the size."""
    K = [[150.0, 0.0, 90.0], [0.0, 140.0, 70.0], [0.0, 0.0, 1.0]]
    R = [[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]]        # at +Z looking down -Z, y down
    (tmp_path / "cams.toml").write_text(f"width = 192\nheight = 128\n[[cameras]]\neye = [0.0, 6.0, 14.0]\n"
                                        f"target = [0.0, 1.0, 0.0]\nfov_y_deg = 40\n[[cameras]]\nK = {K}\nR = {R}\n"
                                        f"t = [0.0, 1.0, 20.0]\nnear = 1.0\nfar = 60.0\n")
    out = tmp_path / "out"
    assert _dataset(DEMO, "-o", out, "--cameras", tmp_path / "cams.toml", "--width", W, "--height", H, "--aov",
                    "none", "--exr", "--device", device.id, "-q") == 0
    doc = json.loads((out / "transforms.json").read_text())
    assert "depth_file_path" not in doc["frames"][0] and not (out / "depth").exists()
    a, b = load_dataset(out)
    np.testing.assert_allclose(a.c2w[:3, 3], [0.0, 6.0, 14.0], atol=1e-12)
    assert abs(a.K[1, 1] - H / 2 / np.tan(np.radians(20))) < 1e-9
    np.testing.assert_allclose(b.K, np.array(K) * [[0.5], [0.5], [1]], atol=1e-12)    # per-frame fl_x ...
    assert doc["frames"][1]["fl_y"] == 70.0 and doc["frames"][1]["cy"] == 35.0
    np.testing.assert_allclose(b.R, R, atol=1e-12)
    np.testing.assert_allclose(b.t, [0.0, 1.0, 20.0], atol=1e-12)
    assert (b.camera.near, b.camera.far) == (1.0, 60.0)
    assert all(v.image.is_file() for v in (a, b))
    exr = aov_io.read_exr(b.exr)                       # --exr: the colour layers (no float AOV asked)
    assert b.exr == out / "exr" / "0001.exr" and sorted(exr) == ["color.B", "color.G", "color.R"]
    assert exr["color.R"].shape == (H, W)


def test_frame_task_with_a_view_pickles():
    cam = layout_cameras("orbit", 1, [[0, 0, 0], [1, 1, 1]], 4, 3)[0]
    task = FrameTask(scene="s.gltf", frame=0, time=0.0, dt=1.0, image="out/images/0000.png", view=cam,
                     outputs=Outputs(("depth", "object_id"), layout="dataset"))
    assert pickle.loads(pickle.dumps(task)) == task
    assert [p.as_posix() for p in task.paths()] == ["out/images/0000.png", "out/depth/0000.npy",
                                                     "out/depth/0000.png", "out/masks/0000.png"]


# -- bad input: one line, exit status != 0, nothing written --------------------------------------
BIG_OBJ = "v -100 0 -100\nv 100 0 -100\nv 0 0 100\nf 1 2 3\n"


def _camera_file(tmp_path, body, suffix=".json"):
    path = tmp_path / f"cams{suffix}"
    path.write_text(body)
    return path


def _cam(**kw):
    base = {"K": [[50.0, 0.0, 48.0], [0.0, 50.0, 32.0], [0.0, 0.0, 1.0]],
            "R": [[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]], "t": [0.0, 1.0, 20.0]}
    return json.dumps({"cameras": [{**base, **kw}]}).replace('"NaN"', "NaN")


BAD = {
    "views 0": (lambda p: ["--views", "0"], 2, "expected a positive integer"),
    "views negative": (lambda p: ["--views", "-3"], 2, "expected a positive integer"),
    "no views": (lambda p: [], 1, "give --views N"),
    "layout": (lambda p: ["--views", "2", "--layout", "spiral"], 2, "invalid choice"),
    "format": (lambda p: ["--views", "2", "--format", "blender"], 2, "invalid choice"),
    "elevation": (lambda p: ["--views", "2", "--elevation", "95"], 1, "--elevation"),
    "seed without random": (lambda p: ["--views", "2", "--seed", "3"], 1, "--seed goes with --layout random"),
    "elevation without orbit": (lambda p: ["--views", "2", "--layout", "sphere", "--elevation", "10"], 1,
                                "--elevation goes with --layout orbit"),
    "missing file": (lambda p: ["--cameras", p / "nope.json"], 1, "cannot read"),
    "bad json": (lambda p: ["--cameras", _camera_file(p, '{"cameras": [')], 1, "not valid JSON"),
    "bad toml": (lambda p: ["--cameras", _camera_file(p, "[[cameras]\neye = 1", ".toml")], 1, "not valid TOML"),
    "empty": (lambda p: ["--cameras", _camera_file(p, '{"cameras": []}')], 1, "non-empty list"),
    "zero focal": (lambda p: ["--cameras", _camera_file(p, _cam(K=[[0, 0, 48], [0, 50, 32], [0, 0, 1]]))], 1,
                   "focal lengths must be positive"),
    "singular K": (lambda p: ["--cameras", _camera_file(p, _cam(K=[[0, 0, 0], [0, 0, 0], [0, 0, 1]]))], 1,
                   "focal lengths must be positive"),
    "negative focal": (lambda p: ["--cameras", _camera_file(p, _cam(K=[[-50, 0, 48], [0, 50, 32], [0, 0, 1]]))],
                       1, "focal lengths must be positive"),
    "not a rotation": (lambda p: ["--cameras", _camera_file(p, _cam(R=[[1.01, 0, 0], [0, -1, 0], [0, 0, -1]]))], 1,
                       "R is not a rotation"),
    "NaN": (lambda p: ["--cameras", _camera_file(p, _cam(t=[0.0, "NaN", 20.0]))], 1, "NaN"),
    "unknown key": (lambda p: ["--cameras", _camera_file(p, _cam(fov=40))], 1, "unknown key 'fov'"),
    "half a camera": (lambda p: ["--cameras", _camera_file(p, '[{"eye": [0, 1, 5]}]')], 1, "eye and target"),
    "layout and file": (lambda p: ["--cameras", _camera_file(p, _cam()), "--layout", "orbit"], 1,
                        "--layout places generated views"),
    "views vs file": (lambda p: ["--cameras", _camera_file(p, _cam()), "--views", "3"], 1, "has 1 cameras"),
    "aov": (lambda p: ["--views", "2", "--aov", "depth,bogus"], 2, "unknown AOV 'bogus'"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_input_is_one_line_before_rendering(case, tmp_path, capsys):
    extra, code, message = BAD[case]
    out = tmp_path / "out"
    rc = _dataset(DEMO, "-o", out, "--width", W, "--height", H, "-q", *extra(tmp_path))
    err = capsys.readouterr().err.strip()
    assert rc == code and len(err.splitlines()) == 1 and err.startswith("clrender: error:"), err
    assert message in err, err
    assert not out.exists()


def test_output_that_is_not_a_writable_folder(tmp_path, capsys):
    blocker = tmp_path / "file.txt"
    blocker.write_text("x")
    for out, message in ((blocker, "is not a folder"), (blocker / "sub", "not writable")):
        rc = _dataset(DEMO, "-o", out, "--views", 2, "--width", W, "--height", H, "-q")
        err = capsys.readouterr().err.strip()
        assert rc == 1 and len(err.splitlines()) == 1 and message in err, err


def test_depth_beyond_the_png_range_is_refused_then_scaled(device, tmp_path, capsys):
    scene = tmp_path / "big.obj"
    scene.write_text(BIG_OBJ)
    out = tmp_path / "out"
    args = [scene, "-o", out, "--views", 1, "--width", 32, "--height", 32, "--device", device.id, "-q"]
    assert _dataset(*args) == 1
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "65.535" in err and "--depth-scale 100 or less" in err, err
    assert not (out / "images").exists() and not (out / "transforms.json").exists()
    assert _dataset(*args, "--depth-scale", 100) == 0
    view = load_dataset(out)[0]
    z, png = np.load(view.depth), iio.imread(view.depth_png)
    fg = np.isfinite(z)
    assert fg.any() and z[fg].max() > 65.535
    assert np.abs(png[fg] / 100.0 - z[fg]).max() <= 0.5e-2 + 1e-6
    assert view.depth_scale == 100 and json.loads((out / "transforms.json").read_text())[
        "depth_unit_scale_factor"] == 0.01

