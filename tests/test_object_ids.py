"""Object and material ids (Frame.object_id, Frame.material_id, Scene.objects).

Truth: the NumPy rasterizer (tests/reference/raster.py) gives each pixel's triangle; the test
knows which instance and material each triangle belongs to from how it wrote the file (two glTF
nodes sharing one mesh: triangles [0, T) are the first node's, [T, 2T) the second's), so the
expected ids never go through the loader's tables.
"""
from __future__ import annotations

import json

import numpy as np
import pytest

from clrender import Camera
from clrender.loaders import load_scene
from reference.geometry import uv_sphere
from reference.raster import rasterize

W, H = 96, 72
CAMERA = Camera.look_at((0.0, 1.5, 5.0), (0.0, 0.2, 0.0), fov_y_deg=45, near=0.5, far=20)
EXTRAS = {"class": "ball", "instance": 7, "tags": ["a", "b"]}


def write_shared_mesh_gltf(path):
    """One sphere mesh (two primitives, two materials), drawn by nodes A and B under Root, plus a
    third node C with no mesh. Returns the triangles per primitive."""
    v, f, n = uv_sphere(12, 24, radius=0.8, center=(0, 0, 0))
    v, n, f = np.asarray(v, np.float32), np.asarray(n, np.float32), np.asarray(f, np.uint32)
    halves = [f[: len(f) // 2], f[len(f) // 2:]]
    blob = v.tobytes() + n.tobytes() + halves[0].tobytes() + halves[1].tobytes()
    off = [0, v.nbytes, 2 * v.nbytes, 2 * v.nbytes + halves[0].nbytes]
    views = [{"buffer": 0, "byteOffset": o, "byteLength": b} for o, b in
             zip(off, [v.nbytes, n.nbytes, halves[0].nbytes, halves[1].nbytes])]
    accessors = [{"bufferView": 0, "componentType": 5126, "count": len(v), "type": "VEC3",
                  "min": v.min(0).tolist(), "max": v.max(0).tolist()},
                 {"bufferView": 1, "componentType": 5126, "count": len(v), "type": "VEC3"},
                 {"bufferView": 2, "componentType": 5125, "count": halves[0].size, "type": "SCALAR"},
                 {"bufferView": 3, "componentType": 5125, "count": halves[1].size, "type": "SCALAR"}]
    doc = {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}],
           "nodes": [{"name": "Root", "children": [1, 2, 3]},
                     {"name": "A", "mesh": 0, "translation": [-1.0, 0, 0], "extras": EXTRAS},
                     {"name": "B", "mesh": 0, "translation": [1.0, 0, 0], "scale": [0.9, 1.1, 0.9]},
                     {"name": "C", "translation": [0, 3, 0]}],
           "meshes": [{"name": "ball", "primitives": [
               {"attributes": {"POSITION": 0, "NORMAL": 1}, "indices": 2, "material": 0},
               {"attributes": {"POSITION": 0, "NORMAL": 1}, "indices": 3, "material": 1}]}],
           "materials": [{"name": "red", "pbrMetallicRoughness": {"baseColorFactor": [0.8, 0.1, 0.1, 1]}},
                         {"name": "blue", "pbrMetallicRoughness": {"baseColorFactor": [0.1, 0.1, 0.8, 1]}}],
           "buffers": [{"uri": "ball.bin", "byteLength": len(blob)}], "bufferViews": views,
           "accessors": accessors}
    (path.parent / "ball.bin").write_bytes(blob)
    path.write_text(json.dumps(doc))
    return [len(h) for h in halves]


@pytest.fixture(scope="module")
def shared_mesh(tmp_path_factory):
    path = tmp_path_factory.mktemp("ids") / "two_nodes.gltf"
    counts = write_shared_mesh_gltf(path)
    scene = load_scene(path)
    t = sum(counts)
    tri = np.arange(2 * t)
    expect_object = tri // t                                     # node A's triangles, then node B's
    expect_material = ((tri % t) >= counts[0]).astype(np.int32)  # red half, then blue half (per node)
    return scene, expect_object, expect_material


def expected_ids(scene, table, camera=CAMERA, w=W, h=H):
    tri, _, _ = rasterize(scene, camera, w, h)
    out = np.full(tri.shape, -1, np.int64)
    out[tri >= 0] = table[tri[tri >= 0]]
    return out, tri


def test_two_nodes_sharing_a_mesh_are_two_objects(shared_mesh, make_renderer):
    scene, expect_object, expect_material = shared_mesh
    assert [(o.name, o.mesh, o.path) for o in scene.objects] == [("A", "ball", "Root/A"), ("B", "ball", "Root/B")]
    assert scene.objects[0].extras == EXTRAS and scene.objects[1].extras is None
    frame = make_renderer(W, H).render(scene, CAMERA)
    want, tri = expected_ids(scene, expect_object)
    assert np.array_equal(frame.triangle_id, tri), "the raster must match the reference first"
    assert frame.object_id.dtype == np.int32 and np.array_equal(frame.object_id, want)
    assert (want == 0).sum() > 300 and (want == 1).sum() > 300
    mat, _ = expected_ids(scene, expect_material)
    materials = [scene.materials.index(next(m for m in scene.materials if m.name == n)) for n in ("red", "blue")]
    want_mat = np.where(mat < 0, -1, np.asarray(materials)[np.maximum(mat, 0)])
    assert np.array_equal(frame.material_id, want_mat)
    assert set(np.unique(frame.material_id)) == {-1, *materials}


@pytest.mark.parametrize("opts", [dict(pipeline="light_prepass"), dict(pipeline="light_indexed"),
                                  dict(pipeline="light_prepass", msaa=4), dict(edge_aa=True, color_aa="fxaa")],
                         ids=["light-prepass", "light-indexed", "prepass-msaa4", "post-aa"])
def test_ids_are_the_same_in_every_pipeline(shared_mesh, make_renderer, opts):
    scene, expect_object, _ = shared_mesh
    want, _ = expected_ids(scene, expect_object)
    frame = make_renderer(W, H, **opts).render(scene, CAMERA)
    assert np.array_equal(frame.object_id, want)


def test_ids_survive_supersampling(shared_mesh, make_renderer):
    scene, expect_object, _ = shared_mesh
    k = 2
    frame = make_renderer(W, H, supersample=k).render(scene, CAMERA)
    fine, _ = expected_ids(scene, expect_object, w=k * W, h=k * H)
    blocks = fine.reshape(H, k, W, k).transpose(0, 2, 1, 3).reshape(H, W, k * k)
    uniform = (blocks == blocks[..., :1]).all(-1)
    got = frame.object_id
    assert uniform.mean() > 0.9
    assert np.array_equal(got[uniform], blocks[..., 0][uniform])
    assert all(got[y, x] in blocks[y, x] for y, x in zip(*np.nonzero(~uniform))), \
        "an edge pixel's id must be one of its samples' ids"


def _subset(scene, keep):
    """The scene's triangles `keep` only (for the reference raster), and their original ids."""
    from clrender import Scene
    sub = Scene(scene.positions, scene.normals, scene.uvs, scene.triangles[keep], scene.triangle_material[keep],
                list(scene.materials))
    return sub, np.flatnonzero(keep)


@pytest.mark.parametrize("method", ["abuffer", "depth_peeling", "screen_door"])
def test_ids_follow_the_nearest_surface_blend_included(shared_mesh, make_renderer, method):
    """The nearest-fragment rule: a BLEND fragment in front of the opaque surface names the pixel
    (the A-buffer's first fragment, peeling's layer 0); screen-door: what the G-buffer drew."""
    from dataclasses import replace
    scene, expect_object, expect_material = shared_mesh
    scene = load_scene(scene.source)
    blue = next(i for i, m in enumerate(scene.materials) if m.name == "blue")
    scene.materials[blue] = replace(scene.materials[blue], alpha_mode="BLEND", opacity=0.5, double_sided=True)
    blend = scene.triangle_material == blue
    frame = make_renderer(W, H, transparency=method).render(scene, CAMERA)
    if method == "screen_door":
        want = np.where(frame.triangle_id >= 0, expect_object[np.maximum(frame.triangle_id, 0)], -1)
        assert np.array_equal(frame.object_id, want) and blend[frame.triangle_id[frame.triangle_id >= 0]].any()
        return
    opaque_scene, opaque_ids = _subset(scene, ~blend)
    blend_scene, blend_ids = _subset(scene, blend)
    o_tri, o_depth, _ = rasterize(opaque_scene, CAMERA, W, H)
    b_tri, b_depth, _ = rasterize(blend_scene, CAMERA, W, H)
    assert np.array_equal(frame.triangle_id, np.where(o_tri >= 0, opaque_ids[np.maximum(o_tri, 0)], -1))
    in_front = (b_tri >= 0) & (b_depth < o_depth)
    assert in_front.sum() > 200 and (frame.fragment_count > 0).sum() == in_front.sum()
    tri = np.where(in_front, blend_ids[np.maximum(b_tri, 0)], np.where(o_tri >= 0, opaque_ids[np.maximum(o_tri, 0)], -1))
    want = np.where(tri >= 0, expect_object[np.maximum(tri, 0)], -1)
    assert np.array_equal(frame.object_id, want)
    assert np.array_equal(frame.material_id >= 0, want >= 0)
    assert (frame.material_id[in_front] == blue).all() and (frame.material_id[~in_front & (want >= 0)] != blue).all()


def test_obj_groups_and_toml_entries_are_objects(tmp_path, make_renderer):
    obj = tmp_path / "two.obj"
    (tmp_path / "two.mtl").write_text("newmtl red\nKd 0.8 0.1 0.1\nnewmtl blue\nKd 0.1 0.1 0.8\n")
    # groups sharing a material, a group with two materials
    lines = ["mtllib two.mtl", "o left", "v -2 0 0", "v -1 0 0", "v -1.5 1 0", "usemtl red", "f 1 2 3", "o right",
             "v 1 0 0", "v 2 0 0", "v 1.5 1 0", "usemtl red", "f 4 5 6", "o top", "v 0 2 0", "v 1 2 0",
             "v 0.5 3 0", "usemtl red", "f 7 8 9", "usemtl blue", "f 7 9 8"]
    (tmp_path / "many.obj").write_text("\n".join(lines) + "\n")
    many = load_scene(tmp_path / "many.obj")
    assert [o.name for o in many.objects] == ["left", "right", "top"]
    top = many.triangle_object == 2
    assert top.sum() == 2 and len(set(many.triangle_material[top])) == 2
    assert np.array_equal(np.bincount(many.triangle_object), [1, 1, 2])
    obj.write_text("\n".join(lines[:13]) + "\n")
    scene = load_scene(obj)
    assert [o.name for o in scene.objects] == ["left", "right"] and np.array_equal(scene.triangle_object, [0, 1])
    (tmp_path / "flat.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 3 2\n")
    flat = load_scene(tmp_path / "flat.obj")
    assert [o.name for o in flat.objects] == ["flat"] and np.array_equal(flat.triangle_object, [0, 0])
    (tmp_path / "s.toml").write_text(
        '[[mesh]]\npath = "two.obj"\nname = "pair"\nextras = { class = "tri", n = 2 }\n'
        '[[mesh]]\npath = "two.obj"\ntransform = { translate = [0, 2, 0] }\n')
    toml = load_scene(tmp_path / "s.toml")
    assert [o.name for o in toml.objects] == ["pair", "two.obj"]
    assert toml.objects[0].extras == {"class": "tri", "n": 2} and toml.objects[1].extras is None
    assert np.array_equal(toml.triangle_object, [0, 0, 1, 1])
    cam = Camera.look_at((0, 1.5, 6), (0, 1.5, 0), fov_y_deg=50, near=0.5, far=20)
    frame = make_renderer(W, H).render(toml, cam)
    want, _ = expected_ids(toml, np.array([0, 0, 1, 1]), camera=cam)
    assert np.array_equal(frame.object_id, want) and set(np.unique(want)) == {-1, 0, 1}


def test_toml_extras_must_be_a_table(tmp_path):
    from clrender.errors import SceneError
    (tmp_path / "a.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    (tmp_path / "s.toml").write_text('[[mesh]]\npath = "a.obj"\nextras = 3\n')
    with pytest.raises(SceneError, match="extras must be a table"):
        load_scene(tmp_path / "s.toml")


def test_aov_files_hold_the_ids_and_positions(shared_mesh, tmp_path):
    from clrender.cli.app import main
    scene, expect_object, _ = shared_mesh
    out = tmp_path / "f.png"
    args = ["render", scene.source, "-o", str(out), "--width", str(W), "--height", str(H),
            "--aov", "object_id,material_id,position", "--aov-sheet"]
    assert main(args) == 0
    oid = np.load(tmp_path / "f.object_id.npy")
    assert oid.dtype == np.int32 and set(np.unique(oid)) == {-1, 0, 1}
    pos = np.load(tmp_path / "f.position.npy")
    assert pos.shape == (H, W, 3) and np.array_equal(np.isnan(pos).all(-1), oid < 0)
    assert np.array_equal(np.load(tmp_path / "f.material_id.npy") >= 0, oid >= 0)
    for name in ("object_id", "material_id", "position", "sheet"):
        assert (tmp_path / f"f.{name}.png").stat().st_size > 100


def test_position_is_an_exr_layer(shared_mesh, tmp_path):
    pytest.importorskip("OpenEXR")
    from clrender.outputs.aov_io import read_exr
    from clrender.cli.app import main
    scene, _, _ = shared_mesh
    out = tmp_path / "f.png"
    assert main(["render", scene.source, "-o", str(out), "--width", str(W), "--height", str(H),
                 "--aov", "position,object_id", "--exr"]) == 0
    layers = read_exr(tmp_path / "f.exr")
    pos = np.load(tmp_path / "f.position.npy")
    got = np.stack([layers[f"position.{c}"] for c in "XYZ"], -1)
    assert np.array_equal(np.isnan(got), np.isnan(pos)) and np.array_equal(got[~np.isnan(got)], pos[~np.isnan(pos)])
    assert not any(k.startswith("object_id") for k in layers), "integer AOVs stay out of the EXR"


def test_info_lists_the_objects(shared_mesh, capsys):
    from clrender.cli.app import main
    scene, _, _ = shared_mesh
    assert main(["info", scene.source]) == 0
    assert "objects    2 ('A', 'B'), 1 with extras" in capsys.readouterr().out
    assert main(["info", scene.source, "--json"]) == 0
    listed = json.loads(capsys.readouterr().out)["object_list"]
    assert listed == [{"name": "A", "mesh": "ball", "path": "Root/A", "extras": EXTRAS, "node": 1, "volume_scale": 1.0},
                      {"name": "B", "mesh": "ball", "path": "Root/B", "extras": None, "node": 2,
                       "volume_scale": pytest.approx((0.9 * 1.1 * 0.9) ** (1 / 3))}]     # |det(scale)|^(1/3)
