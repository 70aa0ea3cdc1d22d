"""One subject (lights from scene files; glTF and TOML share one glTF writer) in one file: 556 lines.

Lights from scene files: glTF KHR_lights_punctual and TOML [[light]] / [lights] / ambient.

Expected light placements are computed here independently of the loader: node world matrices are
composed from the JSON TRS by walking the parent chain, and rotations use the quaternion
sandwich formula (not the loader's quaternion -> matrix code).
"""
from __future__ import annotations

import base64
import contextlib
import dataclasses
import importlib.util
import json
import math
import os
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from clrender.abi import structs  # noqa: E402
from clrender.loaders import load_scene  # noqa: E402
from clrender.scene.model import Scene, SceneError  # noqa: E402
from helpers import assert_scene_error

REPO = Path(__file__).resolve().parents[1]
SCENES = REPO / "scenes"
SHARED = Path(__file__).resolve().parents[2] / "shared" / "scenes"
PUNCTUAL = SHARED / "lights-punctual-AnimateAllTheThings" / "24_animation_pointer.gltf"


# -- independent glTF math ---------------------------------------------------------------------------
def quat_rotate(q, v):
    """Rotate v by the unit quaternion q = [x, y, z, w]: v + 2w (u x v) + 2 u x (u x v)."""
    q = np.asarray(q, np.float64)
    q = q / np.linalg.norm(q)
    u, w = q[:3], q[3]
    v = np.asarray(v, np.float64)
    return v + 2 * w * np.cross(u, v) + 2 * np.cross(u, np.cross(u, v))


def node_apply(node, p, is_point=True):
    """Apply a node's local transform (TRS or column-major matrix) to a point or a vector."""
    if "matrix" in node:
        m = np.asarray(node["matrix"], np.float64).reshape(4, 4, order="F")
        return m[:3, :3] @ p + (m[:3, 3] if is_point else 0)
    p = np.asarray(p, np.float64) * node.get("scale", [1, 1, 1])
    p = quat_rotate(node.get("rotation", [0, 0, 0, 1]), p)
    return p + (np.asarray(node.get("translation", [0, 0, 0])) if is_point else 0)


def node_chain(doc, n):
    """[n, parent(n), ..., root] (assumes a tree)."""
    parents = {c: i for i, node in enumerate(doc["nodes"]) for c in node.get("children", [])}
    chain = [n]
    while chain[-1] in parents:
        chain.append(parents[chain[-1]])
    return chain


def world_light(doc, n):
    """(position, unit direction) of a light on node n: world origin and world -Z."""
    p, d = np.zeros(3), np.array([0.0, 0.0, -1.0])
    for k in node_chain(doc, n):
        p = node_apply(doc["nodes"][k], p, True)
        d = node_apply(doc["nodes"][k], d, False)
    return p, d / np.linalg.norm(d)


def light_nodes(doc, scene_index=None):
    """Nodes of the default scene that reference a light, depth-first pre-order."""
    roots = doc["scenes"][doc.get("scene", 0) if scene_index is None else scene_index]["nodes"]
    out, stack = [], list(reversed(roots))
    while stack:
        n = stack.pop()
        ext = doc["nodes"][n].get("extensions", {}).get("KHR_lights_punctual")
        if ext is not None:
            out.append((n, ext["light"]))
        stack.extend(reversed(doc["nodes"][n].get("children", [])))
    return out


# -- a small glTF writer: one unit right triangle mesh plus whatever nodes/lights the test wants ---------
TRI_POS = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.float32)
TRI_IDX = np.array([0, 1, 2], np.uint16)


def write_gltf(path: Path, nodes, lights, roots=None, positions=TRI_POS) -> Path:
    positions = np.asarray(positions, np.float32)
    pos = positions.tobytes()
    idx = TRI_IDX.tobytes() + b"\0\0"
    blob = pos + idx
    doc = {
        "asset": {"version": "2.0"}, "scene": 0,
        "scenes": [{"nodes": list(range(len(nodes))) if roots is None else roots}],
        "nodes": nodes,
        "meshes": [{"name": "tri", "primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": len(positions), "type": "VEC3",
             "min": positions.min(0).tolist(), "max": positions.max(0).tolist()},
            {"bufferView": 1, "componentType": 5123, "count": 3, "type": "SCALAR"}],
        "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": len(pos)},
                        {"buffer": 0, "byteOffset": len(pos), "byteLength": 6}],
        "buffers": [{"byteLength": len(blob),
                     "uri": "data:application/octet-stream;base64," + base64.b64encode(blob).decode()}],
        "extensionsUsed": ["KHR_lights_punctual"],
        "extensions": {"KHR_lights_punctual": {"lights": lights}},
    }
    path.write_text(json.dumps(doc))
    return path


def light_ref(k):
    return {"KHR_lights_punctual": {"light": k}}


@contextlib.contextmanager
def no_warnings():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        yield


# -- glTF: the shared KHR_lights_punctual sample ---------------------------------------------------------
def test_gltf_punctual_sample():
    if not PUNCTUAL.is_file():
        pytest.skip(f"shared test scene {PUNCTUAL} is not available (needs ../shared/scenes next to the repo)")
    doc = json.loads(PUNCTUAL.read_text())
    lights = doc["extensions"]["KHR_lights_punctual"]["lights"]
    scene = load_directional_quietly(PUNCTUAL)
    assert scene.sun is not None            # its one directional light
    refs = light_nodes(doc)
    assert [lights[k]["type"] for _, k in refs].count("spot") == 3
    spots = [(n, k) for n, k in refs if lights[k]["type"] == "spot"]
    assert len(scene.lights) == 3 and (scene.lights["type"] == structs.LIGHT_SPOT).all()
    for rec, (n, k) in zip(scene.lights, spots):
        light = lights[k]
        pos, direction = world_light(doc, n)
        np.testing.assert_allclose(rec["position"], pos, atol=1e-5)
        np.testing.assert_allclose(rec["direction"], direction, atol=1e-5)
        np.testing.assert_allclose(rec["color"], np.multiply(light["color"], light["intensity"]), rtol=1e-6)
        assert rec["radius"] == pytest.approx(light["range"], rel=1e-6)
        assert rec["cos_inner"] == pytest.approx(math.cos(light["spot"]["innerConeAngle"]), abs=1e-6)
        assert rec["cos_outer"] == pytest.approx(math.cos(light["spot"]["outerConeAngle"]), abs=1e-6)
    # the sample's own intent: spot2 (node 12, child of LightTarget) points at "Target A" (node 9)
    target_a = world_light(doc, 9)[0]
    p, d = scene.lights[2]["position"].astype(np.float64), scene.lights[2]["direction"].astype(np.float64)
    t = -p[1] / d[1]
    np.testing.assert_allclose((p + t * d)[[0, 2]], target_a[[0, 2]], atol=0.02)
    # the directional light: node 4 is rotated 180 degrees about Y, so -Z becomes +Z
    (dn, dk), = [(n, k) for n, k in refs if lights[k]["type"] == "directional"]
    assert scene.settings["directional_lights"] == [pytest.approx({
        "direction": pytest.approx(world_light(doc, dn)[1].tolist(), abs=1e-6),
        "color": pytest.approx((np.multiply(lights[dk]["color"], lights[dk]["intensity"])).tolist())})]
    np.testing.assert_allclose(scene.settings["directional_lights"][0]["direction"], [0, 0, 1], atol=1e-6)


# -- glTF: synthetic files -----------------------------------------------------------------------------------
def test_gltf_point_spot_defaults_and_hierarchy(tmp_path):
    q = [0.0, math.sin(math.radians(30)), 0.0, math.cos(math.radians(30))]   # 60 degrees about Y
    lights = [
        {"type": "point", "color": [1.0, 0.5, 0.25], "intensity": 4.0, "range": 3.0},
        {"type": "spot", "range": 7.5},                                         # defaults everywhere
        {"type": "spot", "color": [0.0, 1.0, 0.0], "intensity": 2.0, "range": 2.0,
         "spot": {"innerConeAngle": 0.2, "outerConeAngle": 0.5}},
    ]
    matrix = np.eye(4)
    matrix[:3, :3] = [[0, -1, 0], [1, 0, 0], [0, 0, 1]]       # Rz(90)
    matrix[:3, 3] = [1, 2, 3]
    nodes = [
        {"mesh": 0},
        {"translation": [5, 0, 0], "rotation": q, "scale": [2, 3, 0.5], "children": [2, 3]},
        {"translation": [0, 1, 0], "extensions": light_ref(0)},
        {"rotation": [math.sin(math.radians(-45)), 0, 0, math.cos(math.radians(-45))],   # -90 about X
         "extensions": light_ref(1), "children": [4]},
        {"matrix": matrix.T.reshape(-1).tolist(), "extensions": light_ref(2)},
        {"translation": [9, 9, 9], "extensions": light_ref(0)},                 # not in the scene
        {"extensions": light_ref(0), "translation": [-1, -1, -1]},             # second instance of light 0
    ]
    path = write_gltf(tmp_path / "l.gltf", nodes, lights, roots=[0, 1, 6])
    doc = json.loads(path.read_text())
    with no_warnings():
        scene = load_scene(path)
    assert len(scene.lights) == 4
    assert scene.lights["type"].tolist() == [structs.LIGHT_POINT, structs.LIGHT_SPOT, structs.LIGHT_SPOT,
                                             structs.LIGHT_POINT]
    for rec, n in zip(scene.lights, [2, 3, 4, 6]):
        pos, direction = world_light(doc, n)
        np.testing.assert_allclose(rec["position"], pos, atol=1e-5)
        if rec["type"] == structs.LIGHT_SPOT:
            np.testing.assert_allclose(rec["direction"], direction, atol=1e-5)
    # the point light: color x intensity; node scale does not change the range
    np.testing.assert_allclose(scene.lights[0]["color"], [4.0, 2.0, 1.0])
    assert scene.lights[0]["radius"] == pytest.approx(3.0) == scene.lights[3]["radius"]
    # spot defaults: white, intensity 1, inner 0, outer pi/4
    np.testing.assert_allclose(scene.lights[1]["color"], [1, 1, 1])
    assert scene.lights[1]["cos_inner"] == pytest.approx(1.0)
    assert scene.lights[1]["cos_outer"] == pytest.approx(math.cos(math.pi / 4))
    assert scene.lights[2]["cos_inner"] == pytest.approx(math.cos(0.2))
    assert scene.lights[2]["cos_outer"] == pytest.approx(math.cos(0.5))
    np.testing.assert_allclose(np.linalg.norm(scene.lights["direction"], axis=1), 1.0, atol=1e-6)
    # Rx(-90) turns -Z into -Y; the parent's non-uniform scale stretches it, the loader renormalizes
    np.testing.assert_allclose(scene.lights[1]["direction"], quat_rotate(q, [0, -1, 0]), atol=1e-6)
    assert "directional_lights" not in scene.settings and "lights_auto_radius" not in scene.settings


def test_gltf_infinite_range_radius(tmp_path):
    lights = [
        {"type": "point", "color": [0.5, 1.0, 0.25], "intensity": 9.0},         # sqrt(9 * 256) = 48
        {"type": "point", "intensity": 0.0},                                    # clamped up to 1e-3
        {"type": "spot", "intensity": 1e6},                                     # clamped to 4 x diagonal
        {"type": "point", "intensity": 0.01},                                   # sqrt(2.56) = 1.6
    ]
    nodes = [{"mesh": 0, "scale": [10, 10, 10]}] + [{"extensions": light_ref(k)} for k in range(4)]
    scene = load_scene(write_gltf(tmp_path / "inf.gltf", nodes, lights))
    diagonal = math.sqrt(10 ** 2 + 10 ** 2)
    assert scene.lights["radius"].tolist() == pytest.approx([48.0, 1e-3, 4 * diagonal, 1.6], rel=1e-6)
    assert scene.settings["lights_auto_radius"] == [0, 1, 2, 3]


def load_directional_quietly(path):
    """Load, failing on any warning about directional lights (one is the sun: nothing to say)."""
    with warnings.catch_warnings(record=True) as record:
        warnings.simplefilter("always")
        scene = load_scene(path)
    assert not [w for w in record if "directional" in str(w.message)], [str(w.message) for w in record]
    return scene


def test_gltf_directional_light_is_kept_and_becomes_the_sun(tmp_path):
    lights = [{"type": "directional", "color": [1.0, 0.5, 0.0], "intensity": 2.0},
              {"type": "point", "range": 1.0}]
    nodes = [{"mesh": 0},
             {"rotation": [math.sin(math.radians(-45)), 0, 0, math.cos(math.radians(-45))],  # -Z -> -Y
              "extensions": light_ref(0)},
             {"translation": [0, 1, 0], "extensions": light_ref(1)}]
    scene = load_directional_quietly(write_gltf(tmp_path / "d.gltf", nodes, lights))
    np.testing.assert_allclose(scene.sun.direction, [0, -1, 0], atol=1e-6)
    assert len(scene.lights) == 1 and scene.lights[0]["type"] == structs.LIGHT_POINT
    (sun,) = scene.settings["directional_lights"]
    np.testing.assert_allclose(sun["direction"], [0, -1, 0], atol=1e-6)
    assert sun["color"] == [2.0, 1.0, 0.0]


def test_gltf_outer_cone_of_90_degrees_is_clamped(tmp_path):
    lights = [{"type": "spot", "range": 1.0, "spot": {"innerConeAngle": math.pi / 2, "outerConeAngle": math.pi / 2}}]
    with pytest.warns(UserWarning, match="clamped"):
        scene = load_scene(write_gltf(tmp_path / "c.gltf", [{"mesh": 0}, {"extensions": light_ref(0)}], lights))
    assert scene.lights[0]["cos_outer"] == pytest.approx(math.cos(math.radians(89.9)))
    assert scene.lights[0]["cos_inner"] == pytest.approx(scene.lights[0]["cos_outer"])


@pytest.mark.parametrize("lights, node_ext, words", [
    ([{"type": "spot", "spot": {"innerConeAngle": 0.6, "outerConeAngle": 0.5}}], light_ref(0),
     ["innerConeAngle", "outerConeAngle", "light 0"]),
    ([{"type": "point", "range": -2.0}], light_ref(0), ["range", "> 0"]),
    ([{"type": "point", "range": 0}], light_ref(0), ["range"]),
    ([{"type": "point", "intensity": -1}], light_ref(0), ["intensity"]),
    ([{"type": "point", "color": [1, 1]}], light_ref(0), ["color"]),
    ([{"type": "area"}], light_ref(0), ["type", "area"]),
    ([{"type": "spot", "spot": {"outerConeAngle": 2.0}}], light_ref(0), ["outerConeAngle"]),
    ([{"type": "point"}], light_ref(3), ["node 1", "light 3"]),
    ([{"type": "point"}], {"KHR_lights_punctual": {}}, ["node 1", "light"]),
])
def test_gltf_light_errors(tmp_path, lights, node_ext, words):
    path = write_gltf(tmp_path / "bad.gltf", [{"mesh": 0}, {"extensions": node_ext}], lights)
    assert_scene_error(path, words)


def test_gltf_light_on_a_zero_scale_spot_node_is_an_error(tmp_path):
    path = write_gltf(tmp_path / "z.gltf", [{"mesh": 0}, {"scale": [0, 0, 0], "extensions": light_ref(0)}],
                      [{"type": "spot"}])
    with pytest.raises(SceneError, match="zero scale"):
        load_scene(path)


# -- TOML -----------------------------------------------------------------------------------------------------------
def unlit(scene: Scene) -> Scene:
    """A copy of `scene` without lights (to replay add_random_lights on the same geometry)."""
    return dataclasses.replace(scene, lights=np.zeros(0, structs.light_dtype), settings={})


def write_toml(tmp_path, text, name="s.toml") -> Path:
    write_gltf(tmp_path / "t.gltf", [{"mesh": 0}], [])
    path = tmp_path / name
    path.write_text(text)
    return path


def test_toml_lights(tmp_path):
    path = write_toml(tmp_path, """
ambient = 0.05
[[mesh]]
path = "t.gltf"
transform = { scale = 10 }
[[light]]
type = "point"
position = [1, 2, 3]
color = [1.0, 0.5, 0.25]
intensity = 4
radius = 5
[[light]]
type = "point"
position = [0, 1, 0]
range = 2.5
[[light]]
type = "spot"
name = "key"
position = [0, 5, 0]
direction = [0, -2, 0]
color = [0.5, 0.5, 1.0]
intensity = 2
radius = 8
inner_cone_deg = 10
outer_cone_deg = 30
[[light]]
type = "spot"
position = [0, 5, 0]
direction = [1, 0, 0]
[[light]]
type = "directional"
direction = [0, -3, -4]
color = [1, 1, 0.5]
intensity = 2
""")
    scene = load_directional_quietly(path)
    assert scene.ambient == 0.05
    L = scene.lights
    assert L["type"].tolist() == [structs.LIGHT_POINT, structs.LIGHT_POINT, structs.LIGHT_SPOT, structs.LIGHT_SPOT]
    np.testing.assert_allclose(L["position"], [[1, 2, 3], [0, 1, 0], [0, 5, 0], [0, 5, 0]])
    np.testing.assert_allclose(L["color"], [[4, 2, 1], [1, 1, 1], [1, 1, 2], [1, 1, 1]])
    # radius, range (a synonym), radius, and the infinite-range rule sqrt(256 * 1) = 16 for the last
    np.testing.assert_allclose(L["radius"], [5, 2.5, 8, 16])
    np.testing.assert_allclose(L["direction"][2:], [[0, -1, 0], [1, 0, 0]])
    assert L["cos_inner"][2] == pytest.approx(math.cos(math.radians(10)))
    assert L["cos_outer"][2] == pytest.approx(math.cos(math.radians(30)))
    assert L["cos_inner"][3] == pytest.approx(1.0) and L["cos_outer"][3] == pytest.approx(math.cos(math.pi / 4))
    assert scene.settings["lights_auto_radius"] == [3]
    assert scene.settings["directional_lights"] == [{"direction": pytest.approx([0, -0.6, -0.8]),
                                                     "color": [2.0, 2.0, 1.0]}]
    # the tables as written stay in settings["lights"]
    assert [t["type"] for t in scene.settings["lights"]] == ["point", "point", "spot", "spot", "directional"]
    assert scene.settings["lights"][2]["name"] == "key"


def test_toml_defaults_no_lights(tmp_path):
    with no_warnings():
        scene = load_scene(write_toml(tmp_path, '[[mesh]]\npath = "t.gltf"\n'))
    assert len(scene.lights) == 0 and scene.lights.dtype == structs.light_dtype
    assert scene.ambient == 0.03
    assert scene.settings == {}


def test_toml_random_lights(tmp_path):
    path = write_toml(tmp_path, """
[[mesh]]
path = "t.gltf"
[[mesh]]
path = "t.gltf"
transform = { translate = [4, 0, -2] }
[lights]
random = { count = 20, seed = 3, radius = [0.25, 0.75], intensity = 2.5 }
[[light]]
type = "point"
position = [0, 0, 1]
radius = 1
""")
    scene = load_scene(path)
    assert len(scene.lights) == 21
    # the [[light]] tables come first, then the random lights over the bounds of all meshes
    np.testing.assert_allclose(scene.lights[0]["position"], [0, 0, 1])
    expected = unlit(scene)
    expected.add_random_lights(20, 3, radius=(0.25, 0.75), intensity=2.5)
    np.testing.assert_array_equal(scene.lights[1:], expected.lights)
    lo, hi = scene.bounds()
    assert (scene.lights["position"][1:] >= lo - 1e-6).all() and (scene.lights["position"][1:] <= hi + 1e-6).all()
    assert hi[0] == pytest.approx(5.0)     # the random lights saw the second, moved mesh
    # defaults: seed 0, radius [0.5, 2.0], intensity 1; a scalar radius is fixed
    a = load_scene(write_toml(tmp_path, '[[mesh]]\npath = "t.gltf"\n[lights]\nrandom = { count = 5 }\n', "a.toml"))
    b = unlit(a)
    b.add_random_lights(5, 0)
    np.testing.assert_array_equal(a.lights, b.lights)
    c = load_scene(write_toml(tmp_path, '[[mesh]]\npath = "t.gltf"\n[lights]\nrandom = { count = 4, radius = 0.3 }\n',
                              "c.toml"))
    np.testing.assert_allclose(c.lights["radius"], 0.3)


def test_toml_merges_mesh_lights_in_order(tmp_path):
    """Lights: first mesh file's, second (moved) mesh file's, [[light]] tables, then random ones."""
    write_gltf(tmp_path / "a.gltf", [{"mesh": 0}, {"translation": [0, 2, 0], "extensions": light_ref(0)},
                                     {"extensions": light_ref(1)}],
               [{"type": "point", "range": 1.5, "intensity": 3},
                {"type": "directional", "intensity": 0.5}])
    write_gltf(tmp_path / "b.gltf", [{"mesh": 0},
                                     {"translation": [1, 1, 0], "extensions": light_ref(0)},
                                     {"translation": [0, 0, 1], "extensions": light_ref(1)}],
               [{"type": "spot", "range": 2.0, "spot": {"innerConeAngle": 0.1, "outerConeAngle": 0.3}},
                {"type": "point", "intensity": 1e6}])                      # infinite range: clamped
    (tmp_path / "s.toml").write_text("""
[[mesh]]
path = "a.gltf"
[[mesh]]
path = "b.gltf"
transform = { translate = [10, 0, 0], rotate_deg = [0, 90, 0], scale = 2 }
[[light]]
type = "point"
position = [0, 0, 5]
intensity = 1e6
[[light]]
type = "directional"
direction = [1, 0, 0]
[lights]
random = { count = 3, seed = 1 }
""")
    with pytest.warns(UserWarning, match=r"1 of 2 directional light\(s\) not rendered \(the first is the sun"):
        scene = load_scene(tmp_path / "s.toml")     # a.gltf's and the table's: the second is not rendered
    L = scene.lights
    assert len(L) == 1 + 2 + 1 + 3
    assert L["type"].tolist()[:4] == [structs.LIGHT_POINT, structs.LIGHT_SPOT, structs.LIGHT_POINT,
                                      structs.LIGHT_POINT]
    # a.gltf, untransformed
    np.testing.assert_allclose(L[0]["position"], [0, 2, 0])
    np.testing.assert_allclose(L[0]["color"], [3, 3, 3])
    assert L[0]["radius"] == pytest.approx(1.5)
    # b.gltf through T(10, 0, 0) . Ry(90) . S(2): (x, y, z) -> (2z + 10, 2y, -2x)
    np.testing.assert_allclose(L[1]["position"], [10, 2, -2], atol=1e-6)
    np.testing.assert_allclose(L[1]["direction"], [-1, 0, 0], atol=1e-6)     # -Z -> -X
    assert L[1]["radius"] == pytest.approx(2.0)                               # not scaled
    assert L[1]["cos_outer"] == pytest.approx(math.cos(0.3))
    np.testing.assert_allclose(L[2]["position"], [12, 0, 0], atol=1e-6)
    # the TOML table
    np.testing.assert_allclose(L[3]["position"], [0, 0, 5])
    # infinite-range radii are clamped against the final scene, not against b.gltf alone
    lo, hi = scene.bounds().astype(np.float64)
    diagonal = float(np.linalg.norm(hi - lo))
    assert diagonal > 10
    assert scene.settings["lights_auto_radius"] == [2, 3]
    np.testing.assert_allclose(L["radius"][[2, 3]], 4 * diagonal, rtol=1e-6)
    # random lights last
    expected = unlit(scene)
    expected.add_random_lights(3, 1)
    np.testing.assert_array_equal(L[4:], expected.lights)
    # directional lights: a.gltf's (unmoved), then the table's
    suns = scene.settings["directional_lights"]
    assert len(suns) == 2
    np.testing.assert_allclose(suns[0]["direction"], [0, 0, -1], atol=1e-6)
    np.testing.assert_allclose(suns[0]["color"], [0.5, 0.5, 0.5])
    np.testing.assert_allclose(suns[1]["direction"], [1, 0, 0])


def test_toml_moves_gltf_directional_lights(tmp_path):
    write_gltf(tmp_path / "a.gltf", [{"mesh": 0}, {"extensions": light_ref(0)}], [{"type": "directional"}])
    (tmp_path / "s.toml").write_text('[[mesh]]\npath = "a.gltf"\ntransform = { rotate_deg = [0, 90, 0] }\n')
    scene = load_directional_quietly(tmp_path / "s.toml")
    np.testing.assert_allclose(scene.settings["directional_lights"][0]["direction"], [-1, 0, 0], atol=1e-6)
    np.testing.assert_allclose(scene.sun.direction, [-1, 0, 0], atol=1e-6)


def test_toml_sun_table_makes_every_directional_light_unrendered(tmp_path):
    write_gltf(tmp_path / "a.gltf", [{"mesh": 0}, {"extensions": light_ref(0)}], [{"type": "directional"}])
    (tmp_path / "s.toml").write_text('[[mesh]]\npath = "a.gltf"\n[sun]\ndirection = [0, -1, 0]\n')
    with pytest.warns(UserWarning, match=r"1 of 1 directional light\(s\) not rendered \(the \[sun\] table"):
        scene = load_scene(tmp_path / "s.toml")
    np.testing.assert_allclose(scene.sun.direction, [0, -1, 0], atol=1e-6)


@pytest.mark.parametrize("text, words", [
    ('[[light]]\ntype = "spot"\nposition = [0, 1, 0]\ndirection = [0, -1, 0]\n'
     'inner_cone_deg = 40\nouter_cone_deg = 30\n', ["light[0]", "inner_cone_deg", "outer_cone_deg"]),
    ('[[light]]\ntype = "spot"\nposition = [0, 1, 0]\ndirection = [0, -1, 0]\ninner_cone_deg = 50\n',
     ["inner_cone_deg", "outer_cone_deg"]),     # default outer is 45
    ('[[light]]\ntype = "spot"\nposition = [0, 1, 0]\ndirection = [0, -1, 0]\nouter_cone_deg = 90\n',
     ["outer_cone_deg", "< 90"]),
    ('[[light]]\ntype = "spot"\nposition = [0, 1, 0]\ndirection = [0, -1, 0]\ninner_cone_deg = -1\n',
     ["inner_cone_deg"]),
    ('[[light]]\ntype = "point"\nposition = [0, 1, 0]\nradius = -2\n', ["light[0].radius", "> 0"]),
    ('[[light]]\ntype = "point"\nposition = [0, 1, 0]\nrange = 0\n', ["light[0].range", "> 0"]),
    ('[[light]]\ntype = "point"\nposition = [0, 1, 0]\nradius = 1\nrange = 1\n', ["radius", "range"]),
    ('[[light]]\ntype = "point"\nposition = [0, 1, 0]\nintensity = -1\n', ["intensity"]),
    ('[[light]]\ntype = "point"\nposition = [0, 1, 0]\ncolor = [1, -1, 0]\n', ["color"]),
    ('[[light]]\ntype = "point"\nposition = [0, 1, 0]\nbrightness = 3\n', ["brightness"]),
    ('[[light]]\ntype = "point"\nposition = [0, 1, 0]\ndirection = [0, -1, 0]\n', ["direction", "point"]),
    ('[[light]]\ntype = "directional"\ndirection = [0, -1, 0]\nradius = 3\n', ["radius", "directional"]),
    ('[[light]]\ntype = "point"\n', ["light[0]", "position"]),
    ('[[light]]\ntype = "spot"\nposition = [0, 1, 0]\n', ["light[0]", "direction"]),
    ('[[light]]\ntype = "directional"\ndirection = [0, 0, 0]\n', ["direction", "zero"]),
    ('[[light]]\ntype = "point"\nposition = [0, 1]\n', ["position"]),
    ('[[light]]\ntype = "point"\nposition = [0, 1, 0]\nname = 3\n', ["name"]),
    ('[lights]\nrandom = { count = 4, sed = 2 }\n', ["sed", "lights.random"]),
    ('[lights]\nrandom = { seed = 2 }\n', ["count"]),
    ('[lights]\nrandom = { count = -1 }\n', ["count"]),
    ('[lights]\nrandom = { count = 2.5 }\n', ["count"]),
    ('[lights]\nrandom = { count = 4, radius = [2, 1] }\n', ["radius"]),
    ('[lights]\nrandom = { count = 4, radius = [0, 1] }\n', ["radius"]),
    ('[lights]\nrandom = { count = 4, radius = [1, 2, 3] }\n', ["radius"]),
    ('[lights]\nrandom = { count = 4, intensity = -1 }\n', ["intensity"]),
    ('[lights]\nrandom = 4\n', ["lights.random", "table"]),
    ('[lights]\ncount = 4\n', ["count", "[lights]"]),
    ('[lights]\n', ["[lights]", "random"]),
    ('ambient = -0.1\n', ["ambient"]),
    ('ambient = "dim"\n', ["ambient"]),
    ('[render]\nwidth = 10\nambient = 0.1\n', ["ambient", "[render]", "top-level"]),
    ('[[mesh]]\npath = "t.gltf"\ntransform = { scale = 0 }\n[[light]]\ntype = "point"\n'
     'position = [0, 0, 0]\n', None),   # a zero-scale mesh without lights loads fine
])
def test_toml_light_errors(tmp_path, text, words):
    path = write_toml(tmp_path, text)
    if words is None:
        load_scene(path)
        return
    assert_scene_error(path, words)


def test_toml_zero_scale_transform_of_a_spot_light_is_an_error(tmp_path):
    write_gltf(tmp_path / "a.gltf", [{"mesh": 0}, {"extensions": light_ref(0)}], [{"type": "spot", "range": 1}])
    (tmp_path / "s.toml").write_text('[[mesh]]\npath = "a.gltf"\ntransform = { scale = 0 }\n')
    with pytest.raises(SceneError, match=r"mesh\[0\]\.transform.*direction"):
        load_scene(tmp_path / "s.toml")


# -- the bundled demo -------------------------------------------------------------------------------------------------
def make_demo_module():
    spec = importlib.util.spec_from_file_location("make_demo", SCENES / "make_demo.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_demo_toml_lights():
    demo = make_demo_module()
    assert (SCENES / "demo.toml").read_text() == demo.DEMO_TOML
    with no_warnings():
        scene = load_scene(SCENES / "demo.toml")
    assert scene.ambient == pytest.approx(0.04)
    L = scene.lights
    assert L["type"].tolist()[:4] == [structs.LIGHT_POINT] * 3 + [structs.LIGHT_SPOT]
    assert len(L) == 4 + 64 and (L["type"][4:] == structs.LIGHT_POINT).all()
    assert "directional_lights" not in scene.settings and "lights_auto_radius" not in scene.settings
    # every hand-placed light reaches the floor (y = 0) below it: a visible pool
    for rec in L[:3]:
        assert 0 < rec["position"][1] < rec["radius"]
    # the spot looks at the sphere (centre (0, 0.8, 0), radius 0.8) and reaches it
    spot = L[3]
    to_sphere = np.array([0.0, 0.8, 0.0]) - spot["position"]
    cos_angle = to_sphere @ spot["direction"] / np.linalg.norm(to_sphere)
    assert cos_angle > spot["cos_inner"] and np.linalg.norm(to_sphere) + 0.8 < spot["radius"]
    # the random lights are Scene.add_random_lights(64, 7, (1.0, 2.0), 0.8) over the whole demo
    expected = unlit(scene)
    expected.add_random_lights(64, 7, radius=(1.0, 2.0), intensity=0.8)
    np.testing.assert_array_equal(L[4:], expected.lights)
