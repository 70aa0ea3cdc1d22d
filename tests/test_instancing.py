"""EXT_mesh_gpu_instancing (clrender/loaders/gltf/instancing.py): each instance of a mesh node is
expanded into its own Scene meshes and its own object "<node>#<i>".

The reference positions are the extension's formula, WorldPosition = NodeWorld · Instance · p with
Instance = T · R · S, built here in float64 from the values this test writes, with SciPy's rotation
(an implementation independent of the loader's quaternion code) and the node hierarchy composed by
hand. (tests/gltf_files.py writes the files; the instance accessors are appended to its buffer.)
"""
from __future__ import annotations

import base64
import json
import warnings

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from clrender import SceneError, load_scene
from gltf_files import COMPONENT_TYPES, QUAD_POSITIONS, primitive, write_gltf

EXT = "EXT_mesh_gpu_instancing"
RNG = np.random.default_rng(37)
K = 5
TRANSLATION = RNG.uniform(-3, 3, (K, 3)).astype(np.float32)
ROTATION = Rotation.random(K, random_state=37).as_quat().astype(np.float32)      # x, y, z, w
SCALE = RNG.uniform(0.5, 2.0, (K, 3)).astype(np.float32)
PARENT = {"translation": [1.0, -2.0, 0.5], "rotation": [0.0, 0.0, np.sin(0.3), np.cos(0.3)], "scale": [2, 2, 2]}
CHILD = {"translation": [0.0, 1.0, 0.0], "rotation": [np.sin(0.2), 0.0, 0.0, np.cos(0.2)], "scale": [1, 0.5, 1]}
TRIANGLE = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.float32)


def _with_accessors(arrays: dict, attach) -> callable:
    """write_gltf's `edit`: append `arrays` {key: array} to the buffer as accessors, then
    attach(doc, {key: accessor index})."""
    def edit(doc):
        buf = doc["buffers"][0]
        blob = bytearray(base64.b64decode(buf["uri"].split(",", 1)[1]))
        index = {}
        for key, a in arrays.items():
            a = np.ascontiguousarray(a)
            blob.extend(b"\0" * (-len(blob) % 4))
            doc["bufferViews"].append({"buffer": 0, "byteOffset": len(blob), "byteLength": a.nbytes})
            blob.extend(a.tobytes())
            acc = {"bufferView": len(doc["bufferViews"]) - 1, "componentType": COMPONENT_TYPES[a.dtype],
                   "count": len(a), "type": {3: "VEC3", 4: "VEC4"}[a.shape[1]]}
            if a.dtype.kind == "i":
                acc["normalized"] = True
            doc["accessors"].append(acc)
            index[key] = len(doc["accessors"]) - 1
        buf["uri"] = "data:application/octet-stream;base64," + base64.b64encode(bytes(blob)).decode()
        buf["byteLength"] = len(blob)
        attach(doc, index)
    return edit


def _write(path, attributes=None, rotation=ROTATION, **kw):
    """node 0 'parent' (TRS) -> node 1 'grove' (TRS, mesh 0 of two primitives, instanced);
    node 2 'plain' draws mesh 0 once."""
    arrays = {"TRANSLATION": TRANSLATION, "ROTATION": rotation, "SCALE": SCALE}
    names = list(arrays) if attributes is None else attributes

    def attach(doc, index):
        doc["nodes"][1].setdefault("extensions", {})[EXT] = {"attributes": {n: index[n] for n in names}}
        doc.setdefault("extensionsUsed", []).append(EXT)
    nodes = [{"name": "parent", "children": [1], **PARENT}, {"name": "grove", "mesh": 0, **CHILD},
             {"name": "plain", "mesh": 0, "translation": [10, 0, 0]}]
    prims = [primitive(), primitive(positions=TRIANGLE + np.float32([0, 0, 1]), indices=np.array([0, 1, 2], np.uint16),
                                    normals=np.tile(np.float32([0, 0, 1]), (3, 1)), uvs=None)]
    return write_gltf(path, primitives=prims, nodes=nodes,
                      edit=_with_accessors({k: arrays[k] for k in names}, attach), **kw)


def _trs(t, q, s) -> np.ndarray:
    m = np.eye(4)
    m[:3, :3] = Rotation.from_quat(np.asarray(q, np.float64)).as_matrix() @ np.diag(np.asarray(s, np.float64))
    m[:3, 3] = t
    return m


def _reference(path):
    """Per instance, per primitive: the world positions the extension's formula gives."""
    j = json.loads(path.read_text())
    world = _trs(PARENT["translation"], PARENT["rotation"], PARENT["scale"]) @ _trs(
        CHILD["translation"], CHILD["rotation"], CHILD["scale"])
    out = []
    for k in range(K):
        inst = _trs(TRANSLATION[k].astype(np.float64), ROTATION[k].astype(np.float64), SCALE[k].astype(np.float64))
        for local in (QUAD_POSITIONS, TRIANGLE + np.float32([0, 0, 1])):
            p = np.c_[np.asarray(local, np.float64), np.ones(len(local))]
            out.append((world @ inst @ p.T).T[:, :3])
    assert len(j["nodes"]) == 3
    return out


def test_every_instance_is_its_own_object_placed_by_the_spec(tmp_path):
    path = _write(tmp_path / "grove.gltf")
    scene = load_scene(path)
    names = [o.name for o in scene.objects]
    assert names == [f"grove#{k}" for k in range(K)] + ["plain"]
    assert [o.path for o in scene.objects[:2]] == ["parent/grove#0", "parent/grove#1"]
    assert len(scene.mesh_names) == 2 * K + 2
    assert scene.mesh_names[:3] == ["grove#0/mesh0/0", "grove#0/mesh0/1", "grove#1/mesh0/0"]
    ref = _reference(path)
    for mesh, want in enumerate(ref):          # instance-major: instance k's two primitives together
        tris = np.flatnonzero(scene.triangle_mesh == mesh)
        got = scene.positions[np.unique(scene.triangles[tris])]
        np.testing.assert_allclose(got, want, atol=1e-5, rtol=1e-5, err_msg=f"mesh {mesh}")
    objects = scene.triangle_object
    per_instance = [set(objects[scene.triangle_mesh // 2 == k].tolist()) for k in range(K)]
    assert per_instance == [{k} for k in range(K)]      # ids distinct per instance, one per instance
    assert scene.triangle_count == K * 3 + 3


def test_normals_follow_each_instance(tmp_path):
    scene = load_scene(_write(tmp_path / "grove.gltf"))
    world = _trs(PARENT["translation"], PARENT["rotation"], PARENT["scale"]) @ _trs(
        CHILD["translation"], CHILD["rotation"], CHILD["scale"])
    for k in range(K):
        m = (world @ _trs(TRANSLATION[k], ROTATION[k], SCALE[k]))[:3, :3]
        n = np.linalg.inv(m).T @ [0.0, 0.0, 1.0]
        n /= np.linalg.norm(n)
        v = scene.triangles[np.flatnonzero(scene.triangle_mesh == 2 * k)[0], 0]
        np.testing.assert_allclose(scene.normals[v], n, atol=1e-5)


def test_missing_attributes_default_and_normalized_rotation(tmp_path):
    """Only TRANSLATION: R = S = identity. ROTATION as normalized SHORT (the spec allows it)."""
    scene = load_scene(_write(tmp_path / "t.gltf", attributes=["TRANSLATION"]))
    world = _trs(PARENT["translation"], PARENT["rotation"], PARENT["scale"]) @ _trs(
        CHILD["translation"], CHILD["rotation"], CHILD["scale"])
    v = scene.triangles[np.flatnonzero(scene.triangle_mesh == 2 * 3)[0], 1]     # instance 3, quad vertex 1
    np.testing.assert_allclose(scene.positions[v], (world @ np.r_[TRANSLATION[3] + [1, 0, 0], 1])[:3], atol=1e-5)
    shorts = np.round(ROTATION * 32767).astype(np.int16)
    scene = load_scene(_write(tmp_path / "s.gltf", attributes=["ROTATION"], rotation=shorts))
    q = shorts.astype(np.float64) / 32767
    v = scene.triangles[np.flatnonzero(scene.triangle_mesh == 2 * 2)[0], 1]
    np.testing.assert_allclose(scene.positions[v], (world @ _trs([0, 0, 0], q[2], [1, 1, 1]) @ [1, 0, 0, 1])[:3],
                               atol=1e-5)


def test_bad_instance_attributes_are_one_line_errors(tmp_path):
    with pytest.raises(SceneError, match="SCALE has 4 entries") as info:
        _bad = {"TRANSLATION": TRANSLATION, "SCALE": SCALE[:4]}

        def attach(doc, index):
            doc["nodes"][0]["extensions"] = {EXT: {"attributes": index}}
        load_scene(write_gltf(tmp_path / "count.gltf", edit=_with_accessors(_bad, attach)))
    assert "\n" not in str(info.value)

    def attach_vec4(doc, index):
        doc["nodes"][0]["extensions"] = {EXT: {"attributes": {"TRANSLATION": index["T"]}}}
    with pytest.raises(SceneError, match="TRANSLATION .* must be VEC3"):
        load_scene(write_gltf(tmp_path / "type.gltf", edit=_with_accessors({"T": ROTATION}, attach_vec4)))


def test_instancing_on_a_morphing_node_warns_and_draws_once(tmp_path):
    """Morph targets (and skins) are posed on the device per node: such a node is drawn once."""
    def attach(doc, index):
        doc["nodes"][0]["extensions"] = {EXT: {"attributes": index}}
    prim = primitive(targets=[{"POSITION": np.zeros((4, 3), np.float32)}])
    path = write_gltf(tmp_path / "morph.gltf", primitives=[prim], nodes=[{"mesh": 0, "name": "m"}],
                      edit=_with_accessors({"TRANSLATION": TRANSLATION}, attach))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        scene = load_scene(path)
    assert any(EXT in str(w.message) and "drawn once" in str(w.message) for w in caught), \
        [str(w.message) for w in caught]
    assert [o.name for o in scene.objects] == ["m"] and scene.triangle_count == 2


def test_rendered_object_ids_are_distinct_per_instance(tmp_path, make_renderer):
    """Five instances of a quad in a row, facing the camera: the object_id AOV shows all five, and
    each pixel's id is the object of the triangle it shows."""
    from clrender import Camera

    def attach(doc, index):
        doc["nodes"][0]["extensions"] = {EXT: {"attributes": index}}
    row = np.c_[1.5 * np.arange(K), np.zeros((K, 2))].astype(np.float32)
    scene = load_scene(write_gltf(tmp_path / "row.gltf", nodes=[{"mesh": 0, "name": "q"}],
                                  edit=_with_accessors({"TRANSLATION": row}, attach)))
    assert [o.name for o in scene.objects] == [f"q#{k}" for k in range(K)]
    camera = Camera.look_at((3.5, 0.5, 6.0), (3.5, 0.5, 0.0), (0, 1, 0), 60.0, near=0.1, far=50)
    frame = make_renderer(96, 64).render(scene, camera)
    ids, tri = frame.object_id, frame.triangle_id
    assert set(np.unique(ids[ids >= 0]).tolist()) == set(range(K))
    np.testing.assert_array_equal(ids[tri >= 0], scene.triangle_object[tri[tri >= 0]])
    assert np.all(ids[tri < 0] == -1)


def test_an_animated_instanced_node_moves_every_instance(tmp_path):
    """Posed at t: NodeWorld(t) · Instance · p for each instance (the node's animation, the spec's order)."""
    moved = np.array(CHILD["translation"]) + [0.0, 0.0, 5.0]
    anim = {"channels": [{"sampler": 0, "target": {"node": 1, "path": "translation"}}],
            "samplers": [{"input": np.array([0.0, 1.0], np.float32),
                          "output": np.array([CHILD["translation"], moved], np.float32)}]}
    scene = load_scene(_write(tmp_path / "anim.gltf", animations=[anim]))
    scene.pose(1.0)
    world = _trs(PARENT["translation"], PARENT["rotation"], PARENT["scale"]) @ _trs(moved, CHILD["rotation"],
                                                                                      CHILD["scale"])
    for k in (0, K - 1):
        want = (world @ _trs(TRANSLATION[k], ROTATION[k], SCALE[k]) @ np.c_[QUAD_POSITIONS, np.ones(4)].T).T[:, :3]
        tris = np.flatnonzero(scene.triangle_mesh == 2 * k)
        np.testing.assert_allclose(scene.positions[np.unique(scene.triangles[tris])], want, atol=1e-4)
