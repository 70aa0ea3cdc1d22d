"""Deep scene graphs load and render in linear time, and nothing a file controls recurses (issue 34
item 4): glTF node chains 100,000 deep, a chain where every node draws, an animated chain, deeply
nested JSON / TOML (a one-line SceneError, never a RecursionError) and `clrender info` on a deep chain.

World positions are checked against a float64 reference computed here from the node JSON (its own
quaternion-to-matrix code, parent times child down the chain). Times are process CPU time (the
machine may be shared), with generous bounds: the property checked is linear growth, also by
comparing a chain with one 4x as deep.
"""
from __future__ import annotations

import json
import time

import numpy as np
import pytest

from clrender import Camera, SceneError
from clrender.cli import app as cli
from clrender.loaders import load_scene
from clrender.loaders.gltf import geometry as gltf_geometry
from gltf_files import primitive, write_gltf

SEED = 34


def _quat_matrix(q) -> np.ndarray:
    """3x3 of a unit quaternion (x, y, z, w), written independently of clrender's."""
    x, y, z, w = np.asarray(q, np.float64) / np.linalg.norm(q)
    return np.array([[w * w + x * x - y * y - z * z, 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), w * w - x * x + y * y - z * z, 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), w * w - x * x - y * y + z * z]])


def _local(node: dict, rotation=None) -> np.ndarray:
    if "matrix" in node:
        return np.asarray(node["matrix"], np.float64).reshape(4, 4).T
    m = np.eye(4)
    q = rotation if rotation is not None else node.get("rotation", [0, 0, 0, 1])
    m[:3, :3] = _quat_matrix(q) * np.asarray(node.get("scale", [1, 1, 1]), np.float64)
    m[:3, 3] = node.get("translation", [0, 0, 0])
    return m


def _chain_nodes(depth: int, every_mesh: bool = False, seed: int = SEED) -> list:
    """A chain 0 -> 1 -> ... -> depth-1 of small random rotations and translations (some nodes given
    by a matrix, some without a transform); the leaf (or every node) draws mesh 0."""
    rng = np.random.default_rng(seed)
    axes = rng.normal(size=(depth, 3))
    axes /= np.linalg.norm(axes, axis=1, keepdims=True)
    angles = rng.uniform(0.01, 0.08, depth)
    quats = np.concatenate([axes * np.sin(angles / 2)[:, None], np.cos(angles / 2)[:, None]], 1)
    steps = rng.uniform(-0.02, 0.02, (depth, 3))
    nodes = []
    for i in range(depth):
        node: dict = {"name": f"n{i}"}
        if i % 7 == 3:
            m = np.eye(4)
            m[:3, :3] = _quat_matrix(quats[i])
            m[:3, 3] = steps[i]
            node["matrix"] = m.T.reshape(-1).tolist()
        elif i % 11 != 5:           # every 11th node from 5 on has no transform (an identity edge)
            node["rotation"] = quats[i].tolist()
            node["translation"] = steps[i].tolist()
        if i + 1 < depth:
            node["children"] = [i + 1]
        if every_mesh or i == depth - 1:
            node["mesh"] = 0
        nodes.append(node)
    return nodes


def _world(nodes: list, root_rotation=None) -> list:
    """float64 world matrices down the chain."""
    out, w = [], np.eye(4)
    for i, node in enumerate(nodes):
        w = w @ _local(node, root_rotation if i == 0 else None)
        out.append(w)
    return out


def _write_chain(path, depth: int, every_mesh: bool = False, **top_level):
    nodes = _chain_nodes(depth, every_mesh)
    return write_gltf(path, primitives=[primitive(uvs=None)], nodes=nodes, **top_level), nodes


def _piece_positions(scene, k: int) -> np.ndarray:
    """The world positions of Scene mesh piece k's quad, in the file's vertex order."""
    tris = scene.triangles[scene.triangle_mesh == k]
    return scene.positions[np.sort(np.unique(tris))].astype(np.float64)


def _expected(world: np.ndarray) -> np.ndarray:
    quad = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], np.float64)
    return quad @ world[:3, :3].T + world[:3, 3]


def _facing_camera(world: np.ndarray) -> Camera:
    """A camera 3 units in front of the quad placed by `world` (on its +Z side: the side it faces)."""
    center = _expected(world).mean(0)
    normal = world[:3, 2] / np.linalg.norm(world[:3, 2])
    return Camera.look_at(center + 3.0 * normal, center, world[:3, 1], 45.0)


@pytest.fixture(scope="module")
def deep_chain(tmp_path_factory):
    """A 100,000-deep chain (written once for the module) and its node JSON."""
    return _write_chain(tmp_path_factory.mktemp("deep") / "deep.gltf", 100_000)


def _cpu(fn):
    t0 = time.process_time()
    out = fn()
    return out, time.process_time() - t0


def test_100000_deep_chain_loads_and_renders_in_linear_time(tmp_path, make_renderer, deep_chain):
    deep, nodes = deep_chain
    quarter, _ = _write_chain(tmp_path / "quarter.gltf", 25_000)
    load_scene(_write_chain(tmp_path / "warm.gltf", 10)[0])       # warm the imports
    _, t_quarter = _cpu(lambda: load_scene(quarter))
    scene, t_deep = _cpu(lambda: load_scene(deep))
    assert t_deep < 20.0, f"a 100,000-deep chain took {t_deep:.1f} s of CPU to load"
    # linear: 4x the depth costs about 4x (quadratic would be 16x); 8x leaves room for noise
    assert t_deep < 8.0 * max(t_quarter, 0.05), (t_quarter, t_deep)
    np.testing.assert_allclose(_piece_positions(scene, 0), _expected(_world(nodes)[-1]), atol=2e-5)
    frame, t_render = _cpu(lambda: make_renderer(32, 24).render(scene, camera=_facing_camera(_world(nodes)[-1])))
    assert t_render < 20.0
    assert (frame.triangle_id >= 0).any()
    assert len(scene.objects) == 1 and scene.objects[0].node == 99_999
    path = scene.objects[0].path
    assert len(path) < 2000 and path.startswith("n0/n1/") and path.endswith("/n99998/n99999"), path


def test_every_node_drawing_chain(tmp_path, make_renderer):
    depth = 3000
    path, nodes = _write_chain(tmp_path / "all.gltf", depth, every_mesh=True)
    scene, t_load = _cpu(lambda: load_scene(path))
    assert t_load < 20.0
    world = _world(nodes)
    assert len(scene.objects) == depth
    for k in (0, 1, 31, 32, 33, 100, 1999, depth - 1):
        np.testing.assert_allclose(_piece_positions(scene, k), _expected(world[k]), atol=2e-5, err_msg=f"node {k}")
    # object paths are bounded (an abbreviated middle), so 3000 of them are not O(depth^2) characters
    total = sum(len(o.path) for o in scene.objects)
    assert total < 3000 * 600, total
    assert scene.objects[10].path == "/".join(f"n{i}" for i in range(11))
    assert scene.objects[-1].path.startswith("n0/") and scene.objects[-1].path.endswith(f"/n{depth - 1}")
    frame, t_render = _cpu(lambda: make_renderer(32, 24).render(scene, camera=_facing_camera(world[-1])))
    assert t_render < 20.0 and (frame.triangle_id >= 0).any()


def test_short_chains_match_trimesh_bit_for_bit(tmp_path, monkeypatch):
    """Up to gltf_geometry.EXACT_CHAIN kept edges the world matrices are trimesh's (np.linalg.multi_dot)
    bit for bit; deeper ones are the parent's product times the edge, within float rounding."""
    depth = gltf_geometry.EXACT_CHAIN + 12
    path, nodes = _write_chain(tmp_path / "short.gltf", depth, every_mesh=True)
    ours = load_scene(path)
    monkeypatch.setenv(gltf_geometry.ENV_TRIMESH, "1")
    ref = load_scene(path)
    world = _world(nodes)
    kept = 0
    for k, node in enumerate(nodes):
        kept += any(key in node for key in ("matrix", "rotation", "translation"))
        a, b = _piece_positions(ours, k), _piece_positions(ref, k)
        if kept <= gltf_geometry.EXACT_CHAIN:
            assert np.array_equal(a, b), f"node {k}"
        else:
            np.testing.assert_allclose(a, b, atol=1e-6, err_msg=f"node {k}")
        np.testing.assert_allclose(a, _expected(world[k]), atol=1e-6, err_msg=f"node {k}")


def test_animated_10000_deep_chain(tmp_path, make_renderer):
    depth = 10_000
    spin = np.array([0, 0, np.sin(np.pi / 4), np.cos(np.pi / 4)])         # 90 degrees about Z
    anim = [{"samplers": [{"input": np.array([0.0, 1.0], np.float32),
                           "output": np.array([[0, 0, 0, 1], spin], np.float32)}],
             "channels": [{"sampler": 0, "target": {"node": 0, "path": "rotation"}}]}]
    path, nodes = _write_chain(tmp_path / "anim.gltf", depth, animations=anim)
    scene, t_load = _cpu(lambda: load_scene(path))
    assert t_load < 20.0 and scene.animation is not None
    _, t_pose = _cpu(lambda: scene.pose(0.5, dt=0.1))
    assert t_pose < 10.0
    half = np.array([0, 0, np.sin(np.pi / 8), np.cos(np.pi / 8)])          # slerp halfway: 45 degrees
    np.testing.assert_allclose(_piece_positions(scene, 0), _expected(_world(nodes, half)[-1]), atol=2e-5)
    camera = _facing_camera(_world(nodes, half)[-1])
    frame, t_render = _cpu(lambda: make_renderer(32, 24).render(scene, camera=camera))
    assert t_render < 20.0 and (frame.triangle_id >= 0).any()


def test_info_on_a_deep_chain_is_quick(deep_chain, capsys):
    path, _ = deep_chain
    code, t = _cpu(lambda: cli.main(["info", str(path), "--json"]))
    assert code == 0 and t < 20.0
    info = json.loads(capsys.readouterr().out)
    assert info["triangles"] == 2 and len(info["object_list"]) == 1


# -- nesting ----------------------------------------------------------------------------------------
def _one_line_error(path, match: str) -> str:
    with pytest.raises(SceneError) as err:
        load_scene(path)
    msg = str(err.value)
    assert msg.startswith(str(path)) and "\n" not in msg and match in msg, msg
    return msg


@pytest.mark.parametrize("depth", [150, 100_000])
@pytest.mark.parametrize("where", ["extras", "extensions"])
def test_deeply_nested_gltf_json_is_a_scene_error(tmp_path, depth, where):
    text = "[" * depth + "]" * depth

    def edit(doc):
        doc["nodes"][0][where] = "@NESTED@"

    path = write_gltf(tmp_path / "nested.gltf", edit=edit)
    path.write_text(path.read_text().replace('"@NESTED@"', text if where == "extras" else "{\"X\": " + text + "}"))
    _one_line_error(path, "nested")


def test_moderately_nested_extras_load_and_print(tmp_path, capsys):
    """Nesting within the limit is kept as it is and `clrender info` prints it (no recursion limit)."""
    value: object = "leaf"
    for _ in range(45):                         # 90 levels: within the limit of 100
        value = {"k": [value]}
    path = write_gltf(tmp_path / "ok.gltf", nodes=[{"mesh": 0, "extras": value}])
    scene = load_scene(path)
    assert scene.objects[0].extras == value
    assert cli.main(["info", str(path), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["object_list"][0]["extras"] == value


@pytest.mark.parametrize("depth", [150, 100_000])
def test_deeply_nested_toml_is_a_scene_error(tmp_path, depth):
    path = tmp_path / "nested.toml"
    path.write_text("x = " + "[" * depth + "]" * depth + "\n")
    _one_line_error(path, "nested")


def test_deeply_nested_camera_file_and_manifest_are_one_line_errors(tmp_path):
    from clrender.dataset import views as dataset
    from clrender.batch.manifest import Manifest

    deep = "[" * 100_000 + "]" * 100_000
    for name, text in (("cams.json", deep), ("cams.toml", "x = " + deep)):
        (tmp_path / name).write_text(text)
        with pytest.raises(ValueError, match="nested too deeply") as err:
            dataset.read_camera_file(tmp_path / name)
        assert "\n" not in str(err.value) and name in str(err.value)
    (tmp_path / "manifest.json").write_text(deep)
    with pytest.raises(ValueError, match="--resume: .*manifest.json: nested too deeply"):
        Manifest.open(tmp_path / "manifest.json", {}, "1", resume=True)
