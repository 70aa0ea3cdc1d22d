"""Scene.cameras: every camera a scene file defines, in order (glTF camera nodes, TOML [camera]).

Truth: each camera node's world matrix is computed here from the node JSON the test writes (its own
quaternion -> matrix, T·R·S, parent · child), not through the loader's scene graph; a camera looks
down its node's -Z with +Y up (glTF spec).
"""
from __future__ import annotations

import json
import math

import numpy as np
import pytest

from clrender import cli
from clrender.errors import SceneError
from clrender.loaders import load_scene
from gltf_files import write_gltf


def quat(axis, deg) -> list:
    a = np.asarray(axis, np.float64) / np.linalg.norm(axis)
    h = math.radians(deg) / 2
    return [*(a * math.sin(h)), math.cos(h)]           # glTF order: x, y, z, w


def quat_matrix(q) -> np.ndarray:
    x, y, z, w = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def trs(t=(0, 0, 0), q=(0, 0, 0, 1), s=(1, 1, 1)) -> np.ndarray:
    m = np.eye(4)
    m[:3, :3] = quat_matrix(q) * np.asarray(s, np.float64)    # R · diag(S)
    m[:3, 3] = t
    return m


PARENT = trs((1.0, 2.0, -3.0), quat((1, 1, 0), 30), (2.0, 2.0, 2.0))
CAMERAS = [
    {"name": "wide", "type": "perspective", "perspective": {"yfov": 0.9, "znear": 0.05, "zfar": 40.0}},
    {"name": "Top ortho", "type": "orthographic",
     "orthographic": {"xmag": 2.5, "ymag": 1.5, "znear": 0.0, "zfar": 20.0}},
    {"type": "perspective", "perspective": {"yfov": 0.5, "znear": 0.2, "zfar": 30.0}},
]
NODES = [
    {"name": "Quad", "mesh": 0},
    {"name": "Front", "camera": 0, "translation": [0.3, 0.5, 4.0], "rotation": quat((0, 1, 0), 10)},
    {"camera": 1, "translation": [0.0, 6.0, 0.0], "rotation": quat((1, 0, 0), -90)},       # named by its camera
    {"name": "Rig", "matrix": PARENT.T.reshape(-1).tolist(), "children": [4]},            # column-major
    {"camera": 2, "translation": [0.0, 0.5, 3.0], "rotation": quat((0, 1, 0), -20)},      # no name anywhere
]
ROOTS = [3, 0, 2, 1]       # traversal: 3, 4 (its child), 0, 2, 1
# (name, node, camera) in traversal order, and each camera node's world matrix
EXPECTED = [("camera 2", 4, 2), ("Top ortho", 2, 1), ("Front", 1, 0)]
WORLD = {1: trs(NODES[1]["translation"], NODES[1]["rotation"]),
         2: trs(NODES[2]["translation"], NODES[2]["rotation"]),
         4: PARENT @ trs(NODES[4]["translation"], NODES[4]["rotation"])}


def write_cameras_gltf(path, cameras=CAMERAS, **kw):
    def edit(doc):
        doc["cameras"] = cameras
        doc["scenes"] = [{"nodes": ROOTS}]
    return write_gltf(path, nodes=[dict(n) for n in NODES], edit=edit, **kw)


def check_camera(cam, world: np.ndarray, spec: dict):
    eye, forward, up = world[:3, 3], -world[:3, 2], world[:3, 1]
    forward, up = forward / np.linalg.norm(forward), up / np.linalg.norm(up)
    np.testing.assert_allclose(cam.eye, eye, rtol=0, atol=1e-9)
    direction = np.subtract(cam.target, cam.eye)
    np.testing.assert_allclose(direction / np.linalg.norm(direction), forward, rtol=0, atol=1e-9)
    _, cam_up, back = cam.basis()
    np.testing.assert_allclose(cam_up, up, rtol=0, atol=1e-9)       # the node's +Y is orthogonal to -Z here
    np.testing.assert_allclose(back, -forward, rtol=0, atol=1e-9)
    kind = spec["type"]
    p = spec[kind]
    assert cam.projection == kind
    assert (cam.near, cam.far) == pytest.approx((p["znear"], p["zfar"]), rel=1e-12)
    if kind == "perspective":
        assert cam.fov_y_deg == pytest.approx(math.degrees(p["yfov"]), rel=1e-12)
    else:
        assert (cam.xmag, cam.ymag) == (p["xmag"], p["ymag"])


def test_gltf_cameras_every_camera_node_in_traversal_order(tmp_path):
    scene = load_scene(write_cameras_gltf(tmp_path / "cams.gltf"), default_environment=False)
    assert [name for name, _ in scene.cameras] == [name for name, _, _ in EXPECTED]
    for (name, cam), (_, node, index) in zip(scene.cameras, EXPECTED):
        check_camera(cam, WORLD[node], CAMERAS[index])
    assert scene.camera == scene.cameras[0][1]        # the default camera is the first, as before
    summary = scene.summary()
    assert [c["name"] for c in summary["cameras"]] == [name for name, _, _ in EXPECTED]
    assert summary["cameras"][0] == {"name": "camera 2", **summary["camera"]}
    assert summary["cameras"][1]["projection"] == "orthographic"


def test_gltf_camera_names_fall_back_from_node_to_camera_to_index(tmp_path):
    cams = [dict(c) for c in CAMERAS]
    cams[2] = {**cams[2], "name": "cam two"}
    scene = load_scene(write_cameras_gltf(tmp_path / "named.gltf", cameras=cams), default_environment=False)
    assert [name for name, _ in scene.cameras] == ["cam two", "Top ortho", "Front"]


def test_gltf_unusable_first_camera_raises_a_later_one_is_left_out(tmp_path):
    bad = {"type": "orthographic", "orthographic": {"xmag": 1.0, "znear": 0.0, "zfar": 5.0}}    # no ymag
    first_bad = [dict(c) for c in CAMERAS]
    first_bad[2] = bad                          # node 4's camera: the first in traversal order
    path = write_cameras_gltf(tmp_path / "first.gltf", cameras=first_bad)
    with pytest.raises(SceneError, match=r"first\.gltf.*camera 2 \(node 4\) is not usable: 'ymag'"):
        load_scene(path, default_environment=False)
    later_bad = [dict(c) for c in CAMERAS]
    later_bad[1] = bad                          # node 2's: the second
    with pytest.warns(UserWarning, match=r"camera 1 \(node 2\) is not usable: 'ymag'.*left out"):
        scene = load_scene(write_cameras_gltf(tmp_path / "later.gltf", cameras=later_bad),
                           default_environment=False)
    assert [name for name, _ in scene.cameras] == ["camera 2", "Front"]


def test_gltf_animated_camera_list_keeps_the_rest_pose(tmp_path):
    animations = [{"channels": [{"sampler": 0, "target": {"node": 4, "path": "translation"}}],
                   "samplers": [{"input": np.array([0.0, 1.0], np.float32),
                                 "output": np.array([[0.0, 0.5, 3.0], [0.0, 0.5, 6.0]], np.float32)}]}]
    scene = load_scene(write_cameras_gltf(tmp_path / "anim.gltf", animations=animations), default_environment=False)
    rest = list(scene.cameras)
    scene.pose(1.0)
    moved = PARENT @ trs([0.0, 0.5, 6.0], NODES[4]["rotation"])
    np.testing.assert_allclose(scene.camera.eye, moved[:3, 3], rtol=0, atol=1e-6)
    assert scene.cameras == rest
    check_camera(scene.cameras[0][1], WORLD[4], CAMERAS[2])


def write_toml(path, body: str):
    path.write_text(body)
    return path


def test_toml_camera_table_and_mesh_file_cameras(tmp_path):
    write_cameras_gltf(tmp_path / "cams.gltf")
    mesh = '[[mesh]]\npath = "cams.gltf"\nname = "set"\ntransform = { translate = [1.0, 0.0, -2.0] }\n'
    with_table = write_toml(tmp_path / "a.toml", mesh + '[camera]\neye = [0, 1, 5]\ntarget = [0, 0, 0]\n'
                                                       'fov_y_deg = 40\n')
    scene = load_scene(with_table)
    assert [name for name, _ in scene.cameras] == ["camera"]
    cam = scene.cameras[0][1]
    assert (cam.eye, cam.target, cam.fov_y_deg) == ((0.0, 1.0, 5.0), (0.0, 0.0, 0.0), 40.0)
    assert scene.camera == cam
    # no [camera]: the mesh file's cameras, moved by its transform, named "<mesh>/<camera>"
    scene = load_scene(write_toml(tmp_path / "b.toml", mesh))
    assert [name for name, _ in scene.cameras] == [f"set/{name}" for name, _, _ in EXPECTED]
    shift = trs((1.0, 0.0, -2.0))
    for (_, cam), (_, node, index) in zip(scene.cameras, EXPECTED):
        check_camera(cam, shift @ WORLD[node], CAMERAS[index])
    assert scene.camera == scene.cameras[0][1]


def test_scenes_without_cameras_and_bad_entries(tmp_path):
    from clrender import Camera, Scene
    scene = Scene.from_arrays([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]])
    assert scene.cameras == [] and scene.summary()["cameras"] == []
    assert load_scene(write_gltf(tmp_path / "plain.gltf"), default_environment=False).cameras == []
    scene.cameras = [("a", Camera.look_at((0, 0, 3), (0, 0, 0)))]
    scene.validate()
    scene.cameras = [("a", "not a camera")]
    with pytest.raises(SceneError, match=r"cameras\[0\] must be a \(name, Camera\) pair"):
        scene.validate()


def test_info_lists_the_cameras(tmp_path, capsys):
    path = write_cameras_gltf(tmp_path / "cams.gltf")
    assert cli.main(["info", str(path), "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert [c["name"] for c in info["cameras"]] == [name for name, _, _ in EXPECTED]
    for c, (_, node, index) in zip(info["cameras"], EXPECTED):
        np.testing.assert_allclose(c["eye"], WORLD[node][:3, 3], rtol=0, atol=1e-9)
        if CAMERAS[index]["type"] == "perspective":
            assert c["fov_y_deg"] == pytest.approx(math.degrees(CAMERAS[index]["perspective"]["yfov"]))
        else:
            assert (c["projection"], c["xmag"], c["ymag"]) == ("orthographic", 2.5, 1.5)
    assert info["camera"] == {k: v for k, v in info["cameras"][0].items() if k != "name"}
    assert cli.main(["info", str(path)]) == 0
    text = capsys.readouterr().out
    assert [line.split() for line in text.splitlines() if line.startswith("cameras ")] == [["cameras", "3"]]
    rows = [line for line in text.splitlines() if line.lstrip().startswith(("0 ", "1 ", "2 "))]
    assert [r.split("'")[1] for r in rows] == [name for name, _, _ in EXPECTED]
    assert "orthographic xmag 2.5 ymag 1.5" in rows[1] and "fov 28.6479 deg" in rows[0]
