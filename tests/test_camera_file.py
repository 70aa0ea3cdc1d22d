"""Camera files (clrender.dataset.camera_file): what `clrender view` saves and `render --camera` /
`dataset --cameras` read. Entries round-trip bit for bit through JSON and TOML; appending keeps a
file's cameras (and a TOML file's text) and leaves the file untouched on any error; every key is
type-checked in one line naming the file and camera; `clrender render --camera` gives
Renderer.render's images for each camera at its time; `dataset --cameras` takes the new keys."""
from __future__ import annotations

import json
import math
import os
import re
import struct
from pathlib import Path

import imageio.v3 as iio
import numpy as np
import pytest

from clrender import Renderer, load_scene
from clrender.batch.jobs import scene_config
from clrender.cli import app as cli
from clrender.dataset.camera_file import (
    append_camera, camera_entry, entry_camera, file_cameras, read_camera_file)
from clrender.scene.camera import Camera

REPO = Path(__file__).resolve().parents[1]
DEMO = REPO / "scenes" / "demo.toml"
ORBIT = REPO / "scenes" / "orbit.toml"        # a light moving on keyframes: the image changes with time
W, H = 64, 48
BOUNDS = ((-1.0, -1.0, -1.0), (1.0, 1.0, 1.0))
FIELDS = ("eye", "target", "up", "fov_y_deg", "near", "far", "xmag", "ymag", "intrinsics")


@pytest.fixture(autouse=True)
def _no_debug(monkeypatch):
    monkeypatch.delenv(cli.ENV_DEBUG, raising=False)


def _bits(camera: Camera) -> dict:
    """Every float of a camera as its 8 bytes: -0.0 != 0.0 here, unlike ==."""
    def pack(v):
        if v is None or isinstance(v, str):
            return v
        if isinstance(v, tuple):
            return tuple(pack(x) for x in v)
        return struct.pack("<d", v)
    return {f: pack(getattr(camera, f)) for f in (*FIELDS, "projection")}


AWKWARD = [0.1 + 0.2, 1e-300, -0.0, 5e-324, 1.0 / 3.0, 2.0 ** 0.5 * 1e16, -123456.78901234567, 1e300 / 7]


def _cameras():
    """Look-at and orthographic cameras with awkward floats (fixed seed), xmag = ymag * W / H."""
    rng = np.random.default_rng(39)
    cams = [Camera.look_at(AWKWARD[:3], AWKWARD[3:6], (AWKWARD[6], 1.0, -0.0), 0.1 + 0.2 + 40, 0.1 + 0.2, 1e300 / 7),
            Camera.orthographic((-0.0, 1e-300, 3.0), (0.0, 0.0, 0.0), (0, 1, 0), (0.1 + 0.2) * W / H, 0.1 + 0.2,
                                0.0, 1.0 / 3.0)]
    for _ in range(12):
        eye = rng.standard_normal(3) * 10.0 ** rng.integers(-8, 8)
        target = eye + rng.standard_normal(3)
        near = float(rng.uniform(1e-6, 1.0))
        far = near + float(rng.uniform(1.0, 1e6))
        if rng.random() < 0.5:
            cams.append(Camera.look_at(eye, target, rng.standard_normal(3), float(rng.uniform(1.0, 170.0)), near, far))
        else:
            ymag = float(rng.uniform(1e-3, 1e3))
            cams.append(Camera.orthographic(eye, target, rng.standard_normal(3), ymag * W / H, ymag, near, far))
    return cams


# -- round trips ---------------------------------------------------------------------------------
def test_entry_round_trip_is_exact():
    for i, cam in enumerate(_cameras()):
        entry = camera_entry(cam, W, H, time=AWKWARD[i % len(AWKWARD)], name=f"shot {i}")
        assert all(type(v) in (float, str) or all(type(x) is float for x in v) for v in entry.values()), entry
        assert ("ortho" in entry) == cam.is_orthographic and ("fov_y_deg" in entry) != cam.is_orthographic
        back = entry_camera(json.loads(json.dumps(entry)), BOUNDS, W, H)
        assert back == cam and _bits(back) == _bits(cam), (entry, back, cam)


@pytest.mark.parametrize("suffix", [".json", ".toml"])
def test_file_round_trip_is_exact(tmp_path, suffix):
    path = tmp_path / f"shots{suffix}"
    cams = _cameras()
    for i, cam in enumerate(cams):
        n = append_camera(path, camera_entry(cam, W, H, time=AWKWARD[i % len(AWKWARD)], name=f'"{i}" \\ é'), W, H)
        assert n == i + 1
    cf = read_camera_file(path)
    assert (cf.width, cf.height, len(cf.entries)) == (W, H, len(cams))
    back = file_cameras(cf, BOUNDS, W, H)
    assert [_bits(c) for c in back] == [_bits(c) for c in cams]
    times = [cf.entries[i]["time"] for i in range(len(cams))]
    assert [struct.pack("<d", t) for t in times] == [struct.pack("<d", AWKWARD[i % len(AWKWARD)])
                                                     for i in range(len(cams))]
    assert cf.entries[3]["name"] == '"3" \\ é'
    assert not [p for p in tmp_path.iterdir() if p.name != path.name], "a temporary file was left"


def _project(camera: Camera, point, width: int, height: int) -> np.ndarray:
    clip = camera.view_projection(width, height) @ np.append(point, 1.0)
    ndc = clip[:2] / clip[3]
    return np.array([(ndc[0] + 1) / 2 * width, (1 - ndc[1]) / 2 * height])


def test_principal_point_is_a_pinhole_with_square_pixels():
    """principal_point [cx, cy] in pixels of the file's size (kw x kh), fov vertical: a point on the
    optical axis lands on (cx, cy); one at x_cam/z = 0.1 lands f * 0.1 pixels right of it, f = (kh/2)
    / tan(fov/2) (the pinhole formula, written out here), all scaled to the render size."""
    eye, fov, kw, kh = (0.0, 0.0, 5.0), 40.0, 128, 96
    entry = {"eye": list(eye), "target": [0.0, 0.0, 0.0], "fov_y_deg": fov, "principal_point": [40.0, 70.5],
             "near": 0.5, "far": 20.0}
    cam = entry_camera(entry, BOUNDS, W, H, kw=kw, kh=kh)
    f = kh / 2 / math.tan(math.radians(fov) / 2)
    s = W / kw                                             # the render size is half the file's
    np.testing.assert_allclose(_project(cam, (0.0, 0.0, 0.0), W, H), [40.0 * s, 70.5 * s], atol=1e-9)
    np.testing.assert_allclose(_project(cam, (0.5, -0.25, 0.0), W, H), [(40.0 + f * 0.1) * s, (70.5 + f * 0.05) * s],
                               atol=1e-9)
    centred = entry_camera({**entry, "principal_point": [kw / 2, kh / 2]}, BOUNDS, W, H, kw=kw, kh=kh)
    np.testing.assert_allclose(centred.view_projection(W, H),
                               Camera.look_at(eye, (0, 0, 0), fov_y_deg=fov, near=0.5, far=20.0).view_projection(W, H),
                               rtol=1e-12, atol=1e-15)
    # written back: fov and principal point in pixels of the size asked for (close, not exact: tan/atan)
    back = camera_entry(cam, kw, kh)
    assert abs(back["fov_y_deg"] - fov) < 1e-12 and np.allclose(back["principal_point"], [40.0, 70.5], atol=1e-12)
    # non-square pixels (an OpenCV K with fx != fy) cannot be a fov and a principal point: K, R, t
    K = [[60.0, 0.0, 30.0], [0.0, 50.0, 25.0], [0.0, 0.0, 1.0]]
    pinhole = Camera.from_opencv(K, np.diag([1.0, -1.0, -1.0]), [0.0, 0.0, 5.0], W, H, 0.5, 20.0)
    entry = camera_entry(pinhole, W, H)
    assert set(entry) == {"K", "R", "t", "near", "far"}
    np.testing.assert_allclose(entry["K"], K, atol=1e-12)
    again = entry_camera(entry, BOUNDS, W, H)
    np.testing.assert_allclose(again.intrinsics, pinhole.intrinsics, atol=1e-15)


# -- appending -----------------------------------------------------------------------------------
LOOK = {"eye": [0.0, 2.0, 8.0], "target": [0.0, 1.0, 0.0], "fov_y_deg": 45.0}


def test_append_keeps_a_toml_file_and_its_comments(tmp_path):
    path = tmp_path / "cams.toml"
    text = ("# my shots\nwidth = 64\nheight = 48\n\n[[cameras]]   # from COLMAP\n"
            "K = [[50.0, 0.0, 32.0], [0.0, 50.0, 24.0], [0.0, 0.0, 1.0]]\n"
            "R = [[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]]\nt = [0.0, 1.0, 10.0]")   # no final newline
    path.write_text(text)
    assert append_camera(path, {**LOOK, "name": "front"}, W, H) == 2
    new = path.read_text()
    assert new.startswith(text + "\n") and "# from COLMAP" in new
    cf = read_camera_file(path)
    assert cf.entries[1] == {**LOOK, "name": "front"} and "K" in cf.entries[0]
    # cameras as an inline array: written again as [[cameras]] tables
    path.write_text('width = 64\nheight = 48\ncameras = [{eye = [0, 0, 5], target = [0, 0, 0]}]\n')
    assert append_camera(path, LOOK, W, H) == 2
    assert read_camera_file(path).entries == ({"eye": [0, 0, 5], "target": [0, 0, 0]}, LOOK)


def test_append_keeps_a_json_file(tmp_path):
    path = tmp_path / "cams.json"
    path.write_text(json.dumps({"width": 64, "height": 48, "note": "mine", "cameras": [LOOK]}))
    assert append_camera(path, {**LOOK, "time": 1.5}, W, H) == 2
    data = json.loads(path.read_text())
    assert data["note"] == "mine" and data["cameras"] == [LOOK, {**LOOK, "time": 1.5}]


APPEND_ERRORS = {
    "size": ('{"width": 32, "height": 48, "cameras": [{"eye": [0, 0, 5], "target": [0, 0, 0]}]}', ".json",
             LOOK, "cameras for 32x48, not 64x48"),
    "no size": ('[{"eye": [0, 0, 5], "target": [0, 0, 0]}]', ".json", LOOK, "no width and height"),
    "corrupt json": ('{"width": 64, "height": 48, "cameras": [', ".json", LOOK, "not valid JSON"),
    "corrupt toml": ("width = 64\nheight = 48\n[[cameras]\n", ".toml", LOOK, "not valid TOML"),
    "bad camera in the file": ('{"width": 64, "height": 48, "cameras": [{"eye": [0, 0], "target": [0, 0, 0]}]}',
                               ".json", LOOK, "camera 0: eye must be 3 finite numbers"),
    "bad entry": ('{"width": 64, "height": 48, "cameras": [{"eye": [0, 0, 5], "target": [0, 0, 0]}]}', ".json",
                  {**LOOK, "fov_y_deg": 200}, "the new camera: fov_y_deg must be degrees in (0, 180)"),
    "degenerate entry": ("width = 64\nheight = 48\n", ".toml", {"eye": [1, 1, 1], "target": [1, 1, 1]},
                         "the new camera: camera eye and target coincide"),
    "suffix": ("", ".yaml", LOOK, "a camera file is .json or .toml"),
}


@pytest.mark.parametrize("case", sorted(APPEND_ERRORS))
def test_append_errors_leave_the_file_alone(tmp_path, case):
    text, suffix, entry, message = APPEND_ERRORS[case]
    path = tmp_path / f"cams{suffix}"
    path.write_text(text)
    before = path.read_bytes(), path.stat().st_mtime_ns
    with pytest.raises(ValueError) as err:
        append_camera(path, entry, W, H)
    assert message in str(err.value) and str(path) in str(err.value) and "\n" not in str(err.value), err.value
    assert (path.read_bytes(), path.stat().st_mtime_ns) == before
    assert [p.name for p in tmp_path.iterdir()] == [path.name]


def test_append_creates_no_file_on_a_bad_entry(tmp_path):
    with pytest.raises(ValueError, match="unknown key 'fov'"):
        append_camera(tmp_path / "new.toml", {**LOOK, "fov": 3}, W, H)
    assert list(tmp_path.iterdir()) == []


# -- bad input, per key --------------------------------------------------------------------------
NaN, INF = float("nan"), float("inf")
BAD_KEYS = {
    "eye short": ({"eye": [0, 0]}, "eye must be 3 finite numbers"),
    "eye text": ({"eye": [0, "1", 5]}, "eye must be 3 finite numbers"),
    "eye NaN": ({"eye": [0, NaN, 5]}, "eye must be 3 finite numbers"),
    "target bool": ({"target": [True, 0, 0]}, "target must be 3 finite numbers"),
    "up inf": ({"up": [0, INF, 0]}, "up must be 3 finite numbers"),
    "fov 0": ({"fov_y_deg": 0}, "fov_y_deg must be degrees in (0, 180)"),
    "fov 180": ({"fov_y_deg": 180.0}, "fov_y_deg must be degrees in (0, 180)"),
    "fov text": ({"fov_y_deg": "45"}, "fov_y_deg must be degrees in (0, 180)"),
    "fov bool": ({"fov_y_deg": True}, "fov_y_deg must be degrees in (0, 180)"),
    "ortho 0": ({"ortho": 0.0}, "ortho must be a positive half-height"),
    "ortho negative": ({"ortho": -2}, "ortho must be a positive half-height"),
    "principal point short": ({"principal_point": [32.0]}, "principal_point must be 2 finite numbers"),
    "principal point NaN": ({"principal_point": [32.0, NaN]}, "principal_point must be 2 finite numbers"),
    "near text": ({"near": "0.1"}, "near must be a finite number"),
    "far inf": ({"far": INF}, "far must be a finite number"),
    "time NaN": ({"time": NaN}, "time must be a finite number of seconds"),
    "time text": ({"time": "1s"}, "time must be a finite number of seconds"),
    "name empty": ({"name": ""}, "name must be a non-empty string"),
    "name number": ({"name": 3}, "name must be a non-empty string"),
    "name newline": ({"name": "a\nb"}, "name must be a non-empty string without control characters"),
    "unknown": ({"fov": 40}, "unknown key 'fov'"),
    "ortho and fov": ({"ortho": 2.0, "fov_y_deg": 40}, "ortho (orthographic) and fov_y_deg (perspective) exclude"),
    "ortho and principal point": ({"ortho": 2.0, "fov_y_deg": None, "principal_point": [1, 2]},
                                  "principal_point is for perspective"),
    "K and principal point": ({"eye": None, "target": None, "fov_y_deg": None,
                               "K": [[50, 0, 32], [0, 50, 24], [0, 0, 1]], "R": [[1, 0, 0], [0, -1, 0], [0, 0, -1]],
                               "t": [0, 0, 5], "principal_point": [1, 2]},
                              "principal_point goes with eye/target, not with K/R/t"),
    "K and eye": ({"K": [[50, 0, 32], [0, 50, 24], [0, 0, 1]], "R": [[1, 0, 0], [0, -1, 0], [0, 0, -1]],
                   "t": [0, 0, 5]}, "give either eye and target"),
    "no target": ({"target": None}, "give either eye and target"),
}


@pytest.mark.parametrize("suffix", [".json", ".toml"])
@pytest.mark.parametrize("case", sorted(BAD_KEYS))
def test_bad_key_is_one_line_naming_file_and_camera(tmp_path, case, suffix):
    change, message = BAD_KEYS[case]
    bad = {k: v for k, v in {**LOOK, **change}.items() if v is not None}
    path = tmp_path / f"cams{suffix}"
    if suffix == ".json":
        path.write_text(json.dumps({"cameras": [LOOK, bad]}))
    else:                  # JSON values are TOML values, but for NaN and infinity
        path.write_text("[[cameras]]\neye = [0, 0, 5]\ntarget = [0, 0, 0]\n[[cameras]]\n" + "".join(
            f"{k} = {json.dumps(v).replace('NaN', 'nan').replace('Infinity', 'inf')}\n" for k, v in bad.items()))
    with pytest.raises(ValueError) as err:
        read_camera_file(path)
    text = str(err.value)
    assert text.startswith(f"{path}: camera 1: ") and message in text and "\n" not in text, text
    # the same check guards entry_camera (the viewer's entries) and camera_entry's time and name
    with pytest.raises(ValueError, match=re.escape(message)):
        entry_camera(bad, BOUNDS, W, H)


def test_camera_entry_checks_time_and_name():
    cam = Camera.look_at((0, 0, 5), (0, 0, 0))
    with pytest.raises(ValueError, match="time must be a finite number"):
        camera_entry(cam, W, H, time=float("inf"))
    with pytest.raises(ValueError, match="name must be a non-empty string"):
        camera_entry(cam, W, H, name="")


def test_old_imports_still_work():
    from clrender.dataset import file_cameras as a, read_camera_file as b
    from clrender.dataset.views import CAMERA_KEYS, CameraFile, bounding_sphere, near_far, read_camera_file
    assert (a, b) == (file_cameras, read_camera_file) and {"ortho", "time", "name"} <= CAMERA_KEYS
    assert CameraFile and bounding_sphere and near_far


# -- clrender render --camera ---------------------------------------------------------------------
def _render(*args) -> int:
    return cli.main(["render", *map(str, args)])


def _reference(device, path, camera, t, width=W, height=H):
    scene = load_scene(str(path))
    if scene.animation is not None:
        scene.pose(t)
    return Renderer(width, height, device=device.id, config=scene_config(scene, {})).render(scene, camera, time=t).image


def test_render_camera_file_matches_renderer(device, tmp_path, capsys):
    """A perspective and an orthographic camera of a TOML file (its size, no --width/--height):
    OUT/<scene>.NNNN.png equal Renderer(W, H).render(scene, camera) bit for bit."""
    persp = Camera.look_at((3.0, 2.5, 7.0), (0.0, 0.8, 0.0), fov_y_deg=45.0, near=0.5, far=40.0)
    ortho = Camera.orthographic((-6.0, 4.0, 5.0), (0.0, 0.8, 0.0), (0, 1, 0), 2.5 * W / H, 2.5, 0.5, 40.0)
    cams = tmp_path / "shots.toml"
    append_camera(cams, camera_entry(persp, W, H), W, H)
    append_camera(cams, camera_entry(ortho, W, H, name="side"), W, H)
    out = tmp_path / "out"
    assert _render(DEMO, "--camera", cams, "-o", f"{out}/", "--device", device.id) == 0, capsys.readouterr().err
    err = capsys.readouterr().err
    assert "camera 1 (side) at t=0" in err, err
    images = [iio.imread(out / f"demo.{i:04d}.png") for i in range(2)]
    assert sorted(p.name for p in out.iterdir()) == ["demo.0000.png", "demo.0001.png"]
    for image, cam in zip(images, (persp, ortho)):
        expect = _reference(device, DEMO, entry_camera(camera_entry(cam, W, H), BOUNDS, W, H), 0.0)
        assert image.shape[:2] == (H, W)
        np.testing.assert_array_equal(image, expect[..., :image.shape[-1]])
    assert not np.array_equal(images[0], images[1]) and min(np.ptp(i) for i in images) > 50


def test_render_camera_file_times(device, tmp_path, capsys):
    """Each camera at its own time (else --time): orbit.toml's light moves between t = 0 and t = 3."""
    cam = Camera.look_at((0.0, 4.0, 9.0), (0.0, 0.8, 0.0), fov_y_deg=50.0, near=0.5, far=40.0)
    cams = tmp_path / "shots.json"
    for i, t in enumerate((0.0, 3.0, None)):
        append_camera(cams, camera_entry(cam, W, H, time=t, name=f"t{i}"), W, H)
    out = tmp_path / "out"
    assert _render(ORBIT, "--camera", cams, "-o", out / "{name}_{camera:02d}", "--time", 6.0, "--width", W,
                   "--height", H, "--device", device.id, "-q") == 0, capsys.readouterr().err
    names = ["t0_00.png", "t1_01.png", "t2_02.png"]
    assert sorted(p.name for p in out.iterdir()) == names
    images = [iio.imread(out / n) for n in names]
    for image, t in zip(images, (0.0, 3.0, 6.0)):
        np.testing.assert_array_equal(image, _reference(device, ORBIT, cam, t)[..., :image.shape[-1]])
    assert not np.array_equal(images[0], images[1]) and not np.array_equal(images[1], images[2])


def _file(tmp_path, cameras, name="cams.json", **top):
    path = tmp_path / name
    path.write_text(json.dumps({**top, "cameras": cameras}))
    return path


TWO = [LOOK, {**LOOK, "eye": [1.0, 2.0, 8.0]}]
RENDER_BAD = {
    "eye flag": (lambda p: ["--camera", _file(p, TWO), "--camera-eye", "0,0,5"], "--camera and --camera-eye exclude"),
    "target flag": (lambda p: ["--camera", _file(p, TWO), "--camera-target", "0,0,0"],
                    "--camera and --camera-target exclude"),
    "fov flag": (lambda p: ["--camera", _file(p, TWO), "--fov", "30"], "--camera and --fov exclude"),
    "ortho flag": (lambda p: ["--camera", _file(p, TWO), "--ortho", "2"], "--camera and --ortho exclude"),
    "frames flag": (lambda p: ["--camera", _file(p, TWO), "--frames", "0:2"], "--camera and --frames exclude"),
    "one file, two cameras": (lambda p: ["--camera", _file(p, TWO), "-o", p / "out" / "x.png"],
                              "has 2 cameras but one output file"),
    "missing file": (lambda p: ["--camera", p / "nope.toml"], "nope.toml: cannot read it"),
    "bad key": (lambda p: ["--camera", _file(p, [LOOK, {**LOOK, "fov_y_deg": -1}])],
                "cams.json: camera 1: fov_y_deg must be degrees"),
    "no name": (lambda p: ["--camera", _file(p, [{**LOOK, "name": "a"}, LOOK]), "-o", p / "out" / "{name}.png"],
                "camera 1 of"),
    "name with a slash": (lambda p: ["--camera", _file(p, [{**LOOK, "name": "../a"}]), "-o", p / "out" / "{name}"],
                          "not a file name"),
    "same name": (lambda p: ["--camera", _file(p, [{**LOOK, "name": "a"}, {**LOOK, "name": "a"}]), "-o",
                             p / "out" / "{name}.png"], "two outputs would be written"),
    "pattern field": (lambda p: ["--camera", _file(p, TWO), "-o", p / "out" / "{index}.png"],
                      "use {camera} and {name} only"),
    "two scenes": (lambda p: [DEMO, "--camera", _file(p, TWO)], "--camera renders one scene, got 2"),
}


@pytest.mark.parametrize("case", sorted(RENDER_BAD))
def test_render_camera_bad_input_is_one_line_before_rendering(tmp_path, capsys, case):
    make, message = RENDER_BAD[case]
    extra = [str(a) for a in make(tmp_path)]
    if "-o" not in extra:
        extra += ["-o", str(tmp_path / "out")]
    rc = _render(DEMO, *extra, "--width", W, "--height", H, "-q")
    err = capsys.readouterr().err.strip()
    assert rc != 0 and len(err.splitlines()) == 1 and err.startswith("clrender: error:"), err
    assert message in err, err
    assert not (tmp_path / "out").exists()


# -- clrender dataset --cameras -------------------------------------------------------------------
def test_dataset_takes_the_new_keys(device, tmp_path, capsys):
    """principal_point, name and time in a dataset's camera file: each view renders at its time
    (dataset.json records it), from the camera the reader builds, bit for bit; ortho is refused
    (transforms.json and COLMAP are pinhole models); --resume refuses views rendered at other times."""
    from clrender.dataset.views import load_dataset
    base = {"eye": [0.0, 4.0, 9.0], "target": [0.0, 0.8, 0.0], "fov_y_deg": 50.0, "near": 0.5, "far": 40.0}
    cams = _file(tmp_path, [{**base, "name": "a"}, {**base, "principal_point": [30.0, 20.0], "time": 3.0}],
                 width=W, height=H)
    out = tmp_path / "out"
    args = ["dataset", str(ORBIT), "-o", str(out), "--cameras", str(cams), "--aov", "none", "--device", device.id,
            "-q"]
    assert cli.main(args) == 0, capsys.readouterr().err
    meta = json.loads((out / "dataset.json").read_text())
    assert [v["time"] for v in meta["views"]] == [0.0, 3.0] and "time" not in meta
    assert meta["views"][0]["name"] == "a" and "name" not in meta["views"][1]
    views = load_dataset(out)
    np.testing.assert_allclose(views[1].K[:2, 2], [30.0, 20.0], atol=1e-9)
    for v, t in zip(views, (0.0, 3.0)):
        np.testing.assert_array_equal(iio.imread(v.image), _reference(device, ORBIT, v.camera, t)[..., :3])
    # --resume with a view's time changed: refused before anything is rewritten
    cams.write_text(cams.read_text().replace('"time": 3.0', '"time": 4.0'))
    before = (out / "dataset.json").read_text()
    assert cli.main(args + ["--resume"]) == 1
    err = capsys.readouterr().err.strip()
    assert "view 1 was rendered at time 3.0, not 4" in err and len(err.splitlines()) == 1, err
    assert (out / "dataset.json").read_text() == before
    ortho = _file(tmp_path, [{"eye": [0, 4, 9], "target": [0, 0.8, 0], "ortho": 3.0}], name="ortho.toml.json")
    assert cli.main(["dataset", str(ORBIT), "-o", str(tmp_path / "o2"), "--cameras", str(ortho), "-q"]) == 1
    err = capsys.readouterr().err.strip()
    assert "camera 0: ortho: a nerf dataset holds pinhole cameras only" in err, err
    assert not (tmp_path / "o2").exists()
    assert os.path.exists(cams)


def test_docs_camera_file_example_reads(tmp_path):
    """docs/datasets.md's TOML example is a camera file whose cameras build."""
    text = (REPO / "docs" / "datasets.md").read_text()
    section = text[text.index("## Camera files"):text.index("## The folder")]
    path = tmp_path / "cams.toml"
    path.write_text(re.search(r"```toml\n(.*?)```", section, re.S).group(1))
    cf = read_camera_file(path)
    cams = file_cameras(cf, BOUNDS, 800, 600)
    assert [c.projection for c in cams] == ["perspective", "orthographic", "perspective"]
    assert cams[0].intrinsics[2:] == (410.0 / 800, 0.5) and cams[1].ymag == 3.0 and cams[2].intrinsics is not None
