"""The OBJ+MTL, PLY and STL loaders on files written by the tests."""
from __future__ import annotations

import numpy as np
import pytest

from clrender.loaders import load_scene
from clrender.scene.model import Material, SceneError
from helpers import assert_scene_error
from loader_cases import write_png


# -- OBJ / PLY / STL written by the tests --------------------------------------------------------------
OBJ = """\
mtllib m.mtl
v 0 0 0
v 2 0 0
v 2 1 0
v 0 1 0
v 0 0 -3
vt 0 0
vt 1 0
vt 1 1
vt 0 1
vt 0.25 0.75
vn 0 0 1
vn 0 1 0
usemtl shiny
f 1/1/1 2/2/1 3/3/1 4/4/1
usemtl plain
f 1/5/2 5/1/2 2/2/2
usemtl shiny
f 4/4/1 3/3/1 5/5/1
"""
MTL = """\
newmtl shiny
Kd 0.5 0.25 0.125
Ks 0.1 0.2 0.6
Ns 5000
map_Kd -clamp on tex.png
newmtl plain
Kd 1 0 0
"""


def test_obj_mtl(tmp_path):
    (tmp_path / "m.obj").write_text(OBJ)
    (tmp_path / "m.mtl").write_text(MTL)
    tex = np.random.default_rng(1).integers(0, 256, (4, 8, 4), dtype=np.uint8)
    write_png(tmp_path / "tex.png", tex)
    scene = load_scene(tmp_path / "m.obj")
    assert scene.triangle_count == 4                       # quad -> 2 triangles
    shiny, plain = scene.materials[0], scene.materials[1]
    assert (shiny.name, plain.name) == ("shiny", "plain")
    assert shiny.base_color == pytest.approx((0.5, 0.25, 0.125, 1.0))
    assert shiny.specular_intensity == pytest.approx(0.3)
    assert shiny.specular_power == 2048.0                   # Ns clamped
    assert shiny.double_sided and plain.double_sided
    assert plain.base_color_texture == -1 and plain.specular_power == Material().specular_power
    assert len(scene.textures) == 1 and scene.textures[0].wrap_s == "clamp"
    np.testing.assert_array_equal(scene.textures[0].rgba, tex)
    # material groups ordered by first use; faces within a group in file order
    assert scene.triangle_material.tolist() == [0, 0, 0, 1]
    assert scene.triangle_face.tolist() == [0, 1, 2, 0]
    # world positions, file normals, uv with v flipped to the glTF convention
    t = scene.triangles
    np.testing.assert_allclose(scene.positions[t[3]], [[0, 0, 0], [0, 0, -3], [2, 0, 0]])
    np.testing.assert_allclose(scene.normals[t[3]], [[0, 1, 0]] * 3)
    np.testing.assert_allclose(scene.uvs[t[3]], [[0.25, 0.25], [0, 1], [1, 1]])
    np.testing.assert_allclose(scene.positions[t[2]], [[0, 1, 0], [2, 1, 0], [0, 0, -3]])
    np.testing.assert_allclose(scene.uvs[t[2]], [[0, 0], [1, 0], [0.25, 0.25]])


def test_obj_without_normals_gets_area_weighted_normals(tmp_path):
    (tmp_path / "a.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1 4 2\n")
    scene = load_scene(tmp_path / "a.obj")
    assert scene.triangle_count == 2
    n = scene.normals[scene.triangles[:, 0]]                     # shared vertex 0
    expected = np.array([0, 0, 1]) * 0.5 + np.array([0, 1, 0]) * 0.5     # both faces have area 0.5
    assert n[0] == pytest.approx(expected / np.linalg.norm(expected))
    assert scene.materials[0].double_sided


@pytest.mark.parametrize("body, word", [("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n", "index 4"),
                                        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n", "index 0"),
                                        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/1 2/2 3/1\n", "vt index 2")])
def test_obj_index_out_of_range(tmp_path, body, word):
    (tmp_path / "bad.obj").write_text(body)
    with pytest.raises(SceneError, match="bad.obj") as info:
        load_scene(tmp_path / "bad.obj")
    assert word in str(info.value) and "out of range" in str(info.value)


def test_obj_missing_texture_and_mtl(tmp_path):
    (tmp_path / "m.obj").write_text(OBJ)
    with pytest.raises(SceneError, match="m.mtl"):
        load_scene(tmp_path / "m.obj")
    (tmp_path / "m.mtl").write_text(MTL)
    with pytest.raises(SceneError, match="tex.png"):
        load_scene(tmp_path / "m.obj")


def test_obj_nan_refused_and_degenerate_kept(tmp_path):
    """A NaN vertex is an error naming its line (issue 34: it used to vanish from the render);
    degenerate triangles (collinear, repeated vertices) load and are counted by the raster."""
    (tmp_path / "n.obj").write_text("v 0 0 0\nv 1 0 0\nv nan 1 0\nv 2 0 0\nf 1 2 3\nf 1 2 4\nf 2 4 1\n")
    assert_scene_error(tmp_path / "n.obj", ["line 3: vertex 3 is (nan, 1, 0)", "finite"])
    (tmp_path / "d.obj").write_text("v 0 0 0\nv 1 0 0\nv 3 0 0\nv 2 0 0\nf 1 2 3\nf 1 2 4\nf 2 4 2\n")
    scene = load_scene(tmp_path / "d.obj")
    assert scene.triangle_count == 3


def test_empty_obj(tmp_path):
    (tmp_path / "e.obj").write_text("# nothing\n")
    scene = load_scene(tmp_path / "e.obj")
    assert scene.triangle_count == 0 and scene.positions.shape == (0, 3)


PLY = """\
ply
format ascii 1.0
comment TextureFile t.png
element vertex 4
property float x
property float y
property float z
property float nx
property float ny
property float nz
property float s
property float t
element face 2
property list uchar int vertex_indices
end_header
0 0 0 0 0 1 0 0
1 0 0 0 0.6 0.8 1 0
1 1 0 0 0 1 1 1
0 1 0 0 0 1 0 0.25
3 0 1 2
3 0 2 3
"""


def test_ply_ascii_with_normals_uvs_texture(tmp_path):
    write_png(tmp_path / "t.png", np.full((2, 2, 4), 128, np.uint8))
    (tmp_path / "q.ply").write_text(PLY)
    scene = load_scene(tmp_path / "q.ply")
    assert scene.triangle_count == 2 and len(scene.positions) == 4
    np.testing.assert_array_equal(scene.triangles, [[0, 1, 2], [0, 2, 3]])
    np.testing.assert_allclose(scene.normals[1], [0, 0.6, 0.8], atol=1e-7)   # file normal, not recomputed
    np.testing.assert_allclose(scene.uvs, [[0, 1], [1, 1], [1, 0], [0, 0.75]])
    assert scene.materials[0].double_sided and scene.materials[0].base_color_texture == 0
    (tmp_path / "t.png").unlink()
    with pytest.raises(SceneError, match="t.png"):
        load_scene(tmp_path / "q.ply")


def test_ply_binary_and_index_out_of_range(tmp_path):
    import trimesh
    mesh = trimesh.creation.icosphere(subdivisions=1)
    mesh.export(tmp_path / "s.ply")
    scene = load_scene(tmp_path / "s.ply")
    assert scene.triangle_count == len(mesh.faces)
    np.testing.assert_allclose(scene.positions, mesh.vertices, atol=1e-6)
    np.testing.assert_array_equal(scene.triangles, mesh.faces)
    # no normals in the file: area-weighted, pointing outwards on a sphere
    assert (np.einsum("ij,ij->i", scene.normals, scene.positions) > 0.9).all()
    bad = PLY.replace("comment TextureFile t.png\n", "").replace("3 0 2 3", "3 0 2 9")
    (tmp_path / "bad.ply").write_text(bad)
    with pytest.raises(SceneError, match=r"bad\.ply.*out of range"):
        load_scene(tmp_path / "bad.ply")


def test_stl(tmp_path):
    import trimesh
    box = trimesh.creation.box(extents=(1, 2, 3))
    box.export(tmp_path / "b.stl")
    scene = load_scene(tmp_path / "b.stl")
    assert scene.triangle_count == 12 and len(scene.positions) == 36
    tri = scene.positions[scene.triangles]
    np.testing.assert_allclose(tri, box.vertices[box.faces], atol=1e-6)
    # flat normals: every corner of a face carries that face's normal
    np.testing.assert_allclose(scene.normals[scene.triangles], np.repeat(box.face_normals[:, None], 3, 1), atol=1e-6)
    assert scene.materials[0].double_sided
