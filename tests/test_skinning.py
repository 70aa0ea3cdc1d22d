"""One subject (skins and morph targets posed on the device against one NumPy reference) in one file: 536 lines.

Skins and morph targets posed on the device (kernels/pose.cl, clrender/passes/pose.py) against the
independent NumPy reference (tests/reference/skinning_reference.py) on generated files (random joint
hierarchies, 1-8 influences over two weight sets, mirrored joints, morph + skin, sparse morph
accessors, node.weights, STEP / CUBICSPLINE / LINEAR channels) and on the Khronos RiggedSimple and
SimpleMorph samples; renders of a posed mesh against the same mesh posed in NumPy as static
geometry; velocity against the analytic reprojection of the two poses; bad input."""
from __future__ import annotations

import base64
import json
import warnings

import numpy as np
import pytest

from gltf_files import write_gltf
from helpers import pixel_far_points, shared_file
from reference.skinning_reference import GltfReference

from clrender import Camera, Renderer, Scene, load_scene
from clrender.errors import SceneError

W, H = 96, 64
pytestmark = pytest.mark.filterwarnings("ignore:.*skin weights that do not sum to 1")


def quat(axis, angle) -> np.ndarray:
    axis = np.asarray(axis, np.float64) / np.linalg.norm(axis)
    return np.concatenate([axis * np.sin(angle / 2), [np.cos(angle / 2)]])


def trs(t, q, s) -> np.ndarray:
    x, y, z, w = q
    r = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                  [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                  [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
    m = np.eye(4)
    m[:3, :3] = r * np.asarray(s)
    m[:3, 3] = t
    return m


def grid(n: int = 6):
    """An n x n vertex grid in z = 0, [-1, 1]^2; triangles counter-clockwise from +Z."""
    xs = np.linspace(-1, 1, n)
    x, y = np.meshgrid(xs, xs)
    pos = np.stack([x.ravel(), y.ravel(), np.zeros(n * n)], 1)
    tris = []
    for r in range(n - 1):
        for c in range(n - 1):
            a = r * n + c
            tris += [(a, a + 1, a + n + 1), (a, a + n + 1, a + n)]
    return pos.astype(np.float32), np.array(tris, np.uint16)


def sparse_target(doc, prim_target_accessor: int, indices: np.ndarray, values: np.ndarray) -> None:
    """Turn accessor `prim_target_accessor` into a sparse one (no bufferView: zeros + these values)."""
    values = np.ascontiguousarray(values, np.float32)
    blob = indices.astype(np.uint16).tobytes() + b"\0" * (-(2 * len(indices)) % 4) + values.tobytes()
    doc["buffers"].append({"byteLength": len(blob),
                           "uri": "data:application/octet-stream;base64," + base64.b64encode(blob).decode()})
    b = len(doc["buffers"]) - 1
    doc["bufferViews"] += [{"buffer": b, "byteOffset": 0, "byteLength": 2 * len(indices)},
                           {"buffer": b, "byteOffset": len(blob) - values.nbytes, "byteLength": values.nbytes}]
    acc = doc["accessors"][prim_target_accessor]
    acc.pop("bufferView", None)
    acc["sparse"] = {"count": len(indices), "indices": {"bufferView": len(doc["bufferViews"]) - 2, "componentType": 5123},
                     "values": {"bufferView": len(doc["bufferViews"]) - 1}}


def rigged_file(tmp_path, seed: int, influences: int = 4, morph: bool = True, skin: bool = True,
                mirrored: bool = False, weights_interpolation: str = "CUBICSPLINE", node_weights: bool = False,
                unorm: bool = False):
    """A random joint tree (3-6 joints under an armature node) skinning a grid with `influences`
    per vertex over JOINTS_0/1 (raw weights that do not sum to 1), optional morph targets
    (POSITION/NORMAL/TANGENT, one POSITION sparse), animations of every kind. Returns (path, mesh node)."""
    rng = np.random.default_rng(seed)
    pos, tris = grid()
    v = len(pos)
    normals = rng.normal(size=(v, 3)) + [0, 0, 3]
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    tang = np.cross(normals, rng.normal(size=(v, 3)))
    tang /= np.linalg.norm(tang, axis=1, keepdims=True)
    tangents = np.concatenate([tang, rng.choice([-1.0, 1.0], (v, 1))], 1)
    n_joints = int(rng.integers(3, 7))
    nodes = [{"name": "armature", "translation": rng.normal(size=3).tolist(), "rotation": quat(rng.normal(size=3), 0.7).tolist(),
              "children": []}]
    parents = [0]
    rest_world = []
    for j in range(n_joints):
        parent = 0 if j == 0 else int(rng.integers(1, j + 1))
        scale = rng.uniform(0.6, 1.5, 3)
        if mirrored and j == 1:
            scale[0] = -scale[0]
        node = {"name": f"joint{j}", "translation": rng.normal(scale=0.5, size=3).tolist(),
                "rotation": quat(rng.normal(size=3), rng.uniform(-1, 1)).tolist(), "scale": scale.tolist()}
        nodes.append(node)
        nodes[parent].setdefault("children", []).append(j + 1)
        parents.append(parent)
    for j in range(n_joints + 1):          # rest world matrices
        n = nodes[j]
        local = trs(n.get("translation", [0, 0, 0]), n.get("rotation", [0, 0, 0, 1]), n.get("scale", [1, 1, 1]))
        rest_world.append(local if j == 0 else rest_world[parents[j]] @ local)
    ibm = np.array([np.linalg.inv(rest_world[j + 1]) @ trs(rng.normal(scale=0.1, size=3), quat([0, 0, 1], 0.1), [1, 1, 1])
                    for j in range(n_joints)])
    if mirrored:        # a mirrored skin: every joint matrix has a negative determinant (normals: M^-T)
        ibm = ibm @ np.diag([-1.0, 1.0, 1.0, 1.0])
    mesh_node = len(nodes)
    nodes.append({"name": "body", "mesh": 0, "translation": [5.0, -3.0, 2.0], "scale": [3.0, 1.0, 1.0]})   # ignored
    if skin:
        nodes[mesh_node]["skin"] = 0
    attrs = {"TANGENT": tangents.astype(np.float32)}
    if skin:
        j8 = np.zeros((v, 8), np.uint8 if n_joints < 256 else np.uint16)
        w8 = np.zeros((v, 8))
        for i in range(v):
            k = int(rng.integers(1, influences + 1)) if influences > 1 else 1
            slots = rng.choice(8 if influences > 4 else 4, size=k, replace=False)
            j8[i, slots] = rng.integers(0, n_joints, size=k)
            w8[i, slots] = rng.uniform(0.05, 1.0, size=k)
        w8 *= rng.uniform(0.3, 1.3, (v, 1))             # sums off 1: renormalized
        if unorm:
            w8 = w8 / w8.sum(1, keepdims=True)
            wq = np.round(w8 * 65535).astype(np.uint16)
            attrs.update(JOINTS_0=j8[:, :4], WEIGHTS_0=wq[:, :4], JOINTS_1=j8[:, 4:], WEIGHTS_1=wq[:, 4:])
        else:
            attrs.update(JOINTS_0=j8[:, :4], WEIGHTS_0=w8[:, :4].astype(np.float32),
                         JOINTS_1=j8[:, 4:], WEIGHTS_1=w8[:, 4:].astype(np.float32))
    targets = None
    n_targets = 3
    if morph:
        targets = [{"POSITION": rng.normal(scale=0.2, size=(v, 3)).astype(np.float32),
                    "NORMAL": rng.normal(scale=0.2, size=(v, 3)).astype(np.float32),
                    "TANGENT": rng.normal(scale=0.2, size=(v, 3)).astype(np.float32)} for _ in range(n_targets)]
    prim = {"attributes": {"POSITION": pos, "NORMAL": normals.astype(np.float32), **attrs}, "indices": tris,
            "material": 0}
    if targets:
        prim["targets"] = targets
    animations = [{"channels": [], "samplers": []}]
    a = animations[0]

    def channel(node, path, times, values, interpolation="LINEAR"):
        a["samplers"].append({"input": np.float32(times), "output": np.float32(values).reshape(len(values), -1)
                              if path != "weights" else np.float32(values).reshape(-1),
                              "interpolation": interpolation})
        a["channels"].append({"sampler": len(a["samplers"]) - 1, "target": {"node": node, "path": path}})

    channel(1, "rotation", [0, 1, 2], [quat([0, 1, 0], 0), quat([1, 1, 0], 1.2), quat([0, 0, 1], -2.5)])
    channel(2, "translation", [0.25, 1, 1.75], rng.normal(scale=0.4, size=(3, 3)), "STEP")
    channel(3, "scale", [0, 2], rng.uniform(0.7, 1.3, (6, 3)), "CUBICSPLINE")
    if skin and n_joints > 3:
        channel(4, "translation", [0.5, 1.5], rng.normal(scale=0.3, size=(6, 3)), "CUBICSPLINE")
    if morph:
        keys = 4
        per = 3 if weights_interpolation == "CUBICSPLINE" else 1
        channel(mesh_node, "weights", [0, 0.6, 1.3, 2.0], rng.uniform(-0.5, 1.2, (keys * per, n_targets)),
                weights_interpolation)
    if not skin:
        channel(mesh_node, "translation", [0, 2], [[5, -3, 2], [4, -2, 3]])
        channel(mesh_node, "rotation", [0, 2], [quat([0, 0, 1], 0.3), quat([1, 0, 0], 1.3)])
    meshes = [[prim]]
    top = {}
    if skin:
        top["skins"] = [{"joints": list(range(1, n_joints + 1)), "inverseBindMatrices": ibm, "skeleton": 1}]
    mesh_weights = rng.uniform(0, 1, n_targets).tolist()
    if node_weights and morph:
        nodes[mesh_node]["weights"] = rng.uniform(0, 1, n_targets).tolist()

    def edit(doc):
        if morph:
            doc["meshes"][0]["weights"] = mesh_weights
            acc = doc["meshes"][0]["primitives"][0]["targets"][1]["POSITION"]
            idx = np.array([0, 7, 20, v - 1])
            sparse_target(doc, acc, idx, rng.normal(scale=0.3, size=(len(idx), 3)))

    if morph and not node_weights and weights_interpolation == "none":
        a["channels"] = [c for c in a["channels"] if c["target"]["path"] != "weights"]
    path = write_gltf(tmp_path / f"rig{seed}.gltf", meshes=meshes, nodes=nodes, animations=animations, edit=edit,
                      materials=[{"doubleSided": True}], **top)
    return path, mesh_node


def posed_close(scene, ref, node, t, renderer, atol_p=3e-5, atol_n=3e-5):
    scene.pose(t)
    got = renderer.posed_vertices(scene)
    d = scene.deformation.deformers[0]
    sl = slice(d.first, d.first + d.count)
    p, n, tg = ref.pose(node, 0, t)
    scale = max(1.0, float(np.abs(p).max()))
    np.testing.assert_allclose(got["positions"][sl], p, atol=atol_p * scale, rtol=0)
    lo, hi = scene.deformation.bounds()              # conservative: the sun's shadow fit relies on it
    assert (p >= lo - 1e-9 * scale).all() and (p <= hi + 1e-9 * scale).all()
    if n is not None:               # without NORMAL: bind-space generated normals, posed (no reference)
        np.testing.assert_allclose(got["normals"][sl], n, atol=atol_n, rtol=0)
    if tg is not None:
        np.testing.assert_allclose(got["tangents"][sl], tg, atol=atol_n, rtol=0)
    return got


@pytest.fixture(scope="module")
def renderer(device):
    return Renderer(W, H, device=device)


TIMES = (-0.5, 0.0, 0.3, 0.61, 1.0, 1.37, 1.9, 3.0)      # outside the keys too: clamped


@pytest.mark.parametrize("case", [
    dict(seed=1, influences=1),
    dict(seed=2, influences=4),
    dict(seed=3, influences=8),
    dict(seed=4, influences=8, mirrored=True),
    dict(seed=5, influences=4, weights_interpolation="STEP", node_weights=True),
    dict(seed=6, influences=6, weights_interpolation="LINEAR", unorm=True),
    dict(seed=7, skin=False),                                 # morph only: the node's animated transform
    dict(seed=8, morph=False, influences=8),                  # skin only
], ids=lambda c: "-".join(f"{k}={v}" for k, v in c.items()))
def test_generated_rigs_match_numpy_reference(tmp_path, renderer, case):
    path, node = rigged_file(tmp_path, **case)
    with warnings.catch_warnings(record=True) as record:
        warnings.simplefilter("always")
        scene = load_scene(path)
    messages = [str(w.message) for w in record]
    if case.get("skin", True) and not case.get("unorm"):
        assert sum("do not sum to 1" in m for m in messages) == 1, messages       # once per file
    assert scene.deformation is not None and len(scene.deformation.deformers) == 1
    ref = GltfReference(path)
    rest = ref.pose(node, 0, None)                   # the load pose (host float64, stored float32)
    d = scene.deformation.deformers[0]
    np.testing.assert_allclose(scene.positions[d.first:d.first + d.count], rest[0], atol=1e-5 * max(1, np.abs(rest[0]).max()))
    for t in TIMES:
        posed_close(scene, ref, node, t, renderer)


def test_rigged_simple_across_its_animation(renderer):
    path = shared_file("khronos-RiggedSimple/RiggedSimple.gltf")
    scene, ref = load_scene(path), GltfReference(path)
    node = next(i for i, n in enumerate(ref.j["nodes"]) if "skin" in n)
    duration = scene.animation.duration
    moved = []
    for t in np.linspace(-0.1, duration + 0.1, 9):
        got = posed_close(scene, ref, node, float(t), renderer)
        moved.append(got["positions"].copy())
    assert np.abs(moved[4] - moved[0]).max() > 0.5            # it does bend


def test_simple_morph_across_its_animation(renderer):
    path = shared_file("khronos-SimpleMorph/SimpleMorph.gltf")
    scene, ref = load_scene(path), GltfReference(path)
    node = next(i for i, n in enumerate(ref.j["nodes"]) if "mesh" in n)
    seen = []
    for t in np.linspace(-0.1, scene.animation.duration + 0.1, 11):
        seen.append(posed_close(scene, ref, node, float(t), renderer)["positions"].copy())
    assert np.ptp(np.array(seen), axis=0).max() > 0.5          # the weights animate


def render_static(positions, triangles, camera, device):
    s = Scene.from_arrays(positions, triangles)
    return Renderer(W, H, device=device).render(s, camera)


def test_posed_depth_equals_numpy_posed_static_mesh(tmp_path, renderer, device):
    path, node = rigged_file(tmp_path, seed=11, influences=4)
    scene, ref = load_scene(path), GltfReference(path)
    cam = Camera.look_at((0.5, 1.0, 9.0), (0.0, 0.0, 0.0), fov_y_deg=45, near=0.1, far=60)
    for t in (0.4, 1.3):
        scene.pose(t)
        lo, hi = ref.pose(node, 0, t)[0].min(0), ref.pose(node, 0, t)[0].max(0)
        c = (lo + hi) / 2
        cam = Camera.look_at(c + np.array([0.2, 0.3, 1.0]) * 1.1 * np.linalg.norm(hi - lo), c, fov_y_deg=45, near=0.1, far=100)
        f = renderer.render(scene, cam)
        p = ref.pose(node, 0, t)[0].astype(np.float32)
        g = render_static(p, scene.triangles, cam, device)
        hit = f.triangle_id >= 0
        assert hit.mean() > 0.1
        same = hit & (g.triangle_id >= 0)
        assert (hit != (g.triangle_id >= 0)).mean() < 0.005             # edge pixels at most
        np.testing.assert_allclose(f.depth[same], g.depth[same], rtol=2e-5)
        assert (f.triangle_id[same] == g.triangle_id[same]).mean() > 0.995


def pixel_rays(camera):
    eye = np.asarray(camera.eye, np.float64)
    d = pixel_far_points(camera, W, H) - eye
    return eye, d / np.linalg.norm(d, axis=-1, keepdims=True)


def test_velocity_is_the_analytic_reprojection_of_the_two_poses(tmp_path, renderer):
    path, node = rigged_file(tmp_path, seed=12, influences=4)
    scene, ref = load_scene(path), GltfReference(path)
    t, dt = 0.8, 1 / 24
    cur = ref.pose(node, 0, t)[0]
    prev = ref.pose(node, 0, t - dt)[0]
    lo, hi = cur.min(0), cur.max(0)
    c = (lo + hi) / 2
    cam = Camera.look_at(c + np.array([0.2, 0.3, 1.0]) * 1.1 * np.linalg.norm(hi - lo), c, fov_y_deg=45, near=0.1, far=100)
    previous_camera = scene.pose(t, dt)
    f = renderer.render(scene, cam, previous_camera=cam if previous_camera is None else cam)
    got = renderer.posed_vertices(scene)
    d = scene.deformation.deformers[0]
    np.testing.assert_allclose(got["previous_positions"][d.first:d.first + d.count], prev, atol=3e-5 * np.abs(prev).max())
    eye, rays = pixel_rays(cam)
    tri = f.triangle_id
    ys, xs = np.nonzero(tri >= 0)
    assert len(ys) > 300
    tris = scene.triangles[tri[ys, xs]] - d.first
    a, b, cc = cur[tris[:, 0]], cur[tris[:, 1]], cur[tris[:, 2]]
    r = rays[ys, xs]
    e1, e2 = b - a, cc - a                    # Moller-Trumbore: barycentrics of the pixel centre's ray
    pv = np.cross(r, e2)
    det = np.einsum("ij,ij->i", e1, pv)
    tv = eye - a
    u = np.einsum("ij,ij->i", tv, pv) / det
    qv = np.cross(tv, e1)
    v = np.einsum("ij,ij->i", r, qv) / det
    x_prev = (1 - u - v)[:, None] * prev[tris[:, 0]] + u[:, None] * prev[tris[:, 1]] + v[:, None] * prev[tris[:, 2]]
    clip = np.concatenate([x_prev, np.ones((len(x_prev), 1))], 1) @ cam.view_projection(W, H).T
    ndc = clip[:, :2] / clip[:, 3:]
    prev_px = np.stack([(ndc[:, 0] + 1) / 2 * W, (1 - ndc[:, 1]) / 2 * H], 1)
    expect = np.stack([xs + 0.5, ys + 0.5], 1) - prev_px
    err = np.abs(f.velocity[ys, xs] - expect)
    assert np.abs(expect).max() > 1.0                        # it moves
    assert err.max() < 0.05, err.max()


def test_pose_uploads_only_joints_and_weights_and_skips_unchanged_frames(tmp_path, renderer):
    path, node = rigged_file(tmp_path, seed=13, influences=4)
    scene = load_scene(path)
    renderer.render(scene)
    pose = renderer.pipeline.pose_pass
    scene.pose(0.5, 1 / 24)
    f1 = renderer.render(scene)
    assert pose.ran and f1.stats["pose_ms"] > 0
    d = scene.deformation
    assert pose.bytes_per_frame == 2 * 4 * (12 * d.palette_size + int(d.weight_offsets[-1]))
    f2 = renderer.render(scene)                     # same pose: no kernel, same bits
    assert not pose.ran and "pose_ms" not in f2.stats
    assert np.array_equal(f1.depth, f2.depth) and np.array_equal(f1.color, f2.color)
    scene.pose(0.5, 1 / 24)                         # the same pose again: bit-identical frame
    f3 = renderer.render(scene)
    assert pose.ran and np.array_equal(f1.color, f3.color) and np.array_equal(f1.velocity, f3.velocity)


def test_set_transform_on_a_deformed_mesh_is_an_error(tmp_path):
    path, node = rigged_file(tmp_path, seed=14)
    scene = load_scene(path)
    with pytest.raises(SceneError, match="pose it with scene.pose"):
        scene.set_transform(0, np.eye(4))


# -- bad input -----------------------------------------------------------------------------------------------
def edited(tmp_path, change, **case):
    path, node = rigged_file(tmp_path, seed=21, **case)
    doc = json.loads(path.read_text())
    change(doc)
    path.write_text(json.dumps(doc))
    return path


def set_accessor(doc, index, array):
    blob = np.ascontiguousarray(array).tobytes()
    doc["buffers"].append({"byteLength": len(blob),
                           "uri": "data:application/octet-stream;base64," + base64.b64encode(blob).decode()})
    doc["bufferViews"].append({"buffer": len(doc["buffers"]) - 1, "byteLength": len(blob)})
    doc["accessors"][index].update(bufferView=len(doc["bufferViews"]) - 1, byteOffset=0)
    doc["accessors"][index].pop("sparse", None)


def attr(doc, name):
    return doc["meshes"][0]["primitives"][0]["attributes"][name]


def weights_of(doc, fill):
    a = attr(doc, "WEIGHTS_0")
    w = np.full((doc["accessors"][a]["count"], 4), 0.25, np.float32)
    fill(w)
    set_accessor(doc, a, w)


@pytest.mark.parametrize("change, words", [
    (lambda d: set_accessor(d, attr(d, "JOINTS_0"), np.full((36, 4), 200, np.uint8)),
     ["mesh 0", "JOINTS_0", "accessor", "joint 200", "lists"]),
    (lambda d: weights_of(d, lambda w: w.__setitem__((3, 1), -0.5)), ["mesh 0", "WEIGHTS", "negative"]),
    (lambda d: weights_of(d, lambda w: w.__setitem__((3, 1), np.nan)), ["mesh 0", "WEIGHTS", "finite"]),
    (lambda d: (weights_of(d, lambda w: w.__setitem__(5, 0.0)),
                set_accessor(d, attr(d, "WEIGHTS_1"), np.zeros((36, 4), np.float32))),
     ["mesh 0", "vertex 5", "summing to 0"]),
    (lambda d: d["skins"][0]["joints"].__setitem__(slice(None), d["skins"][0]["joints"][:1]),
     ["mesh 0", "JOINTS_", "lists 1 joints"]),
    (lambda d: d["accessors"][d["meshes"][0]["primitives"][0]["targets"][0]["NORMAL"]].update(count=35),
     ["mesh 0", "morph target 0 NORMAL", "36 vertices"]),
    (lambda d: d["meshes"][0].update(weights=[1.0]), ["mesh 0", "mesh.weights", "3 finite numbers"]),
    (lambda d: d["meshes"][0]["primitives"][0]["attributes"].pop("WEIGHTS_1"), ["mesh 0", "pairs"]),
    (lambda d: d["skins"][0].update(joints=[99]), ["skin 0", "joint 99"]),
], ids=["joint-out-of-range", "negative-weight", "nan-weight", "zero-sum", "more-joints-than-skin",
        "morph-count", "default-weights-length", "unpaired-sets", "joint-not-a-node"])
def test_bad_skin_and_morph_input_is_one_line_scene_error(tmp_path, change, words):
    path = edited(tmp_path, change, influences=8)
    with pytest.raises(SceneError) as info:
        load_scene(path)
    message = str(info.value)
    assert "\n" not in message and str(path) in message, message
    for w in words:
        assert w in message, (w, message)


@pytest.mark.parametrize("rigid_motion", [False, True])
def test_a_frame_sequence_keeps_the_previous_positions(tmp_path, device, rigid_motion):
    """Frames at t, t + dt, ... with dt: the previous positions are the last frame's, copied on the
    device (no second posing, half the upload) and bit-identical to posing them; also when another
    mesh moves by set_transform (the upload's own previous positions)."""
    path, node = rigged_file(tmp_path, seed=15, influences=4)
    scene = load_scene(path)
    if rigid_motion:                      # a second, rigid mesh moved with set_transform
        extra = Scene.from_arrays([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]])
        scene.positions = np.concatenate([scene.positions, extra.positions])
        scene.normals = np.concatenate([scene.normals, extra.normals])
        scene.uvs = np.concatenate([scene.uvs, extra.uvs])
        if scene.tangents is not None:
            scene.tangents = np.concatenate([scene.tangents, np.float32([[0, 0, 0, 1]] * 3)])
        n0 = len(scene.positions) - 3
        scene.triangles = np.concatenate([scene.triangles, [[n0, n0 + 1, n0 + 2]]]).astype(np.int32)
        scene.triangle_material = np.concatenate([scene.triangle_material, [0]]).astype(np.int32)
        scene.triangle_mesh = np.concatenate([scene.triangle_mesh, [len(scene.mesh_names)]]).astype(np.int32)
        scene.triangle_face = np.concatenate([scene.triangle_face, [0]]).astype(np.int32)
        scene.mesh_names.append("rigid")
    r = Renderer(W, H, device=device)
    dt = 1 / 24

    def pose(k):
        scene.pose(0.2 + k * dt, dt)
        if rigid_motion:
            m, prev = np.eye(4), np.eye(4)
            m[0, 3], prev[0, 3] = 0.1 * k, 0.1 * (k - 1)
            scene.set_transform("rigid", m, previous=prev)

    frames = []
    for k in range(3):
        pose(k)
        frames.append(r.posed_vertices(scene))
        assert r.pipeline.pose_pass.kept_previous == (k > 0)
        assert r.pipeline.pose_pass.bytes_per_frame == (1 if k else 2) * 4 * (
            12 * scene.deformation.palette_size + int(scene.deformation.weight_offsets[-1]))
    for k, got in enumerate(frames):          # each frame posed from scratch (another pipeline)
        pose(k)
        fresh = Renderer(W, H, device=device).posed_vertices(scene)
        for name in ("positions", "previous_positions", "normals"):
            np.testing.assert_array_equal(got[name], fresh[name], err_msg=f"{name} frame {k}")
        if rigid_motion:
            np.testing.assert_allclose(got["previous_positions"][-3:, 0] - got["positions"][-3:, 0], -0.1, atol=1e-6)


def test_a_toml_scene_including_a_skinned_gltf_warns_and_draws_its_load_pose(tmp_path):
    import shutil
    from pathlib import Path
    worm = Path(__file__).resolve().parents[1] / "scenes" / "worm.gltf"
    shutil.copy(worm, tmp_path / "worm.gltf")
    (tmp_path / "s.toml").write_text('[[mesh]]\npath = "worm.gltf"\n')
    with pytest.warns(UserWarning, match="'worm.gltf'.*not carried into a TOML scene"):
        scene = load_scene(tmp_path / "s.toml")
    alone = load_scene(tmp_path / "worm.gltf")
    np.testing.assert_array_equal(scene.positions, alone.positions)     # the load pose
    assert scene.deformation is None


@pytest.mark.parametrize("kind", ["draco", "meshopt", "quantize"])
def test_compressed_skinned_files_pose_like_the_original(device, kind):
    """scenes/worm.gltf through gltf-transform's draco / meshopt / quantize (tests/data/compressed):
    skin attributes, the morph target and the animation decode and pose like the original: the
    worm's pixels, their depth and velocity agree (triangle ids differ: the encoders reorder)."""
    from pathlib import Path
    here = Path(__file__).resolve().parent
    original = load_scene(here.parent / "scenes" / "worm.gltf")
    packed = load_scene(here / "data" / "compressed" / f"worm_{kind}.glb")
    assert packed.deformation is not None and packed.animation is not None
    assert packed.animation.duration == pytest.approx(original.animation.duration)
    r = Renderer(160, 90, device=device)
    for t in (0.3, 1.1):
        frames = []
        for scene in (original, packed):
            previous = scene.pose(t, 1 / 24)
            f = r.render(scene, previous_camera=previous)
            worm = (f.triangle_id >= 0) & (scene.triangle_material[np.maximum(f.triangle_id, 0)] == 0)
            frames.append((f, worm))
        (a, wa), (b, wb) = frames
        assert wa.mean() > 0.05
        assert (wa != wb).mean() < 0.002                       # a few silhouette pixels (quantization)
        inner = wa & wb
        for k in range(2):                                     # away from the silhouette: 1 px erosion
            inner[1:-1, 1:-1] &= inner[:-2, 1:-1] & inner[2:, 1:-1] & inner[1:-1, :-2] & inner[1:-1, 2:]
        np.testing.assert_allclose(b.depth[inner], a.depth[inner], rtol=2e-3)
        assert np.abs(b.velocity[inner] - a.velocity[inner]).max() < 0.05


def test_batch_frames_of_a_skinned_file_equal_direct_renders(tmp_path, device):
    """clrender.batch.jobs.render_frames on scenes/worm.gltf (skin, morph, animated weights): each
    written frame (image and velocity AOV) equals pose(f / fps, 1 / fps) + render() of the same
    file, in any order (frames 5, 2, 3: a sequence and a jump)."""
    import imageio.v3 as iio
    from pathlib import Path
    from clrender.batch.jobs import render_frames
    worm = Path(__file__).resolve().parents[1] / "scenes" / "worm.gltf"
    fps = 24.0
    result = render_frames(worm, [5, 2, 3], tmp_path / "out", width=64, height=36, aovs=("velocity",),
                           device=device.id, fps=fps)
    assert not result.failed
    scene = load_scene(worm)
    r = Renderer(64, 36, device=device)
    for f in (2, 3, 5):
        previous = scene.pose(f / fps, 1 / fps)
        frame = r.render(scene, previous_camera=previous)
        image = iio.imread(tmp_path / "out" / f"worm_{f:04d}.png")[..., :3]
        np.testing.assert_array_equal(image, frame.image)
        velocity = np.load(tmp_path / "out" / f"worm_{f:04d}.velocity.npy")
        np.testing.assert_array_equal(velocity, frame.velocity)
        assert np.abs(frame.velocity).max() > 0.1


def test_mirrored_morph_mesh_without_normals_matches_the_static_mesh(tmp_path, device):
    """A morph-only quad without NORMAL under a mirroring node (scale -1 in x), weights 0: the same
    winding flip and the same (generated) normals as the quad without targets, on the host and as
    the device poses it."""
    from gltf_files import QUAD_POSITIONS, primitive
    node = [{"mesh": 0, "scale": [-1.0, 1.0, 1.0], "translation": [0.5, 0.0, 0.0]}]
    static = load_scene(write_gltf(tmp_path / "s.gltf", [primitive(normals=None)], nodes=node))
    morph = load_scene(write_gltf(tmp_path / "m.gltf", [primitive(normals=None, targets=[
        {"POSITION": np.full_like(QUAD_POSITIONS, 0.5)}])], nodes=node))
    assert morph.deformation is not None and static.deformation is None
    np.testing.assert_array_equal(morph.triangles, static.triangles)
    np.testing.assert_allclose(morph.positions, static.positions, atol=1e-7)
    np.testing.assert_allclose(morph.normals, static.normals, atol=1e-7)
    posed = Renderer(W, H, device=device).posed_vertices(morph)
    np.testing.assert_allclose(posed["normals"], static.normals, atol=1e-6)
    np.testing.assert_allclose(posed["positions"], static.positions, atol=1e-6)
