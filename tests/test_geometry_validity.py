"""Invalid geometry and arguments (issue 34, item 7): non-finite or absurd vertex positions (NaN,
inf, |x| > 1e30) are a one-line error naming the file and the accessor / vertex (SceneError), or
the array for a Scene built in code; a glTF byteStride smaller than its element or off the spec's
rules is an error; Renderer sizes and RenderConfig integers must be real ints (no bool, str, float).
None of these load or render anything, so the module runs in well under a second."""
from __future__ import annotations

import struct

import numpy as np
import pytest

import clrender
from clrender import Scene, SceneError, load_scene
from clrender.render.renderer import RenderConfig
from gltf_files import QUAD_POSITIONS, primitive, write_gltf

BAD_VALUES = [np.nan, np.inf, -np.inf, 1e31, -3e38]
BAD_IDS = ["nan", "inf", "-inf", "1e31", "-3e38"]


def _positions(bad, vertex=2, axis=1):
    p = QUAD_POSITIONS.copy()
    p[vertex, axis] = bad
    return p


def _no_bounds(doc):
    """The POSITION accessor's min/max would carry the bad value too (and NaN is not JSON)."""
    for acc in doc["accessors"]:
        acc.pop("min", None)
        acc.pop("max", None)


# -- glTF ----------------------------------------------------------------------------------------
@pytest.mark.parametrize("bad", BAD_VALUES, ids=BAD_IDS)
def test_gltf_position_not_finite_or_absurd(tmp_path, bad):
    path = write_gltf(tmp_path / "bad.gltf", primitives=[primitive(positions=_positions(bad))], edit=_no_bounds)
    with pytest.raises(SceneError) as info:
        load_scene(path)
    msg = str(info.value)
    assert msg.startswith(str(path)) and "\n" not in msg, msg
    for words in ("accessors[0]", "mesh 0", "primitive 0", "POSITION", "vertex 2", "1e30"):
        assert words in msg, msg


def test_gltf_position_absurd_after_the_node_transform(tmp_path):
    """Finite accessor values a node's scale carries past 1e30: named with the node."""
    path = write_gltf(tmp_path / "scaled.gltf", nodes=[{"mesh": 0, "scale": [1e20, 1e20, 1e20]}],
                      primitives=[primitive(positions=QUAD_POSITIONS * 1e15)])
    with pytest.raises(SceneError) as info:
        load_scene(path)
    msg = str(info.value)
    assert msg.startswith(str(path)) and "node 0" in msg and "POSITION" in msg and "1e30" in msg, msg


@pytest.mark.parametrize("bad", [np.nan, 1e31], ids=["nan", "1e31"])
def test_gltf_morph_target_delta_not_finite_or_absurd(tmp_path, bad):
    delta = np.zeros((4, 3), np.float32)
    delta[1, 0] = bad
    path = write_gltf(tmp_path / "morph.gltf", primitives=[primitive(targets=[{"POSITION": delta}])],
                      edit=_no_bounds)
    with pytest.raises(SceneError) as info:
        load_scene(path)
    msg = str(info.value)
    assert msg.startswith(str(path)) and "morph target 0 POSITION" in msg and "vertex 1" in msg, msg


def _stride_doc(tmp_path, stride, name="stride.gltf"):
    def edit(doc):
        doc["bufferViews"][doc["accessors"][0]["bufferView"]]["byteStride"] = stride
    return write_gltf(tmp_path / name, primitives=[primitive(normals=None, uvs=None)], edit=edit)


def test_gltf_byte_stride_smaller_than_the_element(tmp_path):
    """byteStride 8 for a VEC3 float (12 bytes): elements would overlap; today it renders garbage."""
    path = _stride_doc(tmp_path, 8)
    with pytest.raises(SceneError) as info:
        load_scene(path)
    msg = str(info.value)
    assert msg.startswith(str(path)) and "accessors[0]" in msg and "byteStride 8" in msg and "12" in msg, msg


@pytest.mark.parametrize("stride", [2, 13, 256], ids=["2", "13", "256"])
def test_gltf_byte_stride_off_the_spec(tmp_path, stride):
    """The spec's schema: byteStride is a multiple of 4 in [4, 252]."""
    path = _stride_doc(tmp_path, stride)
    with pytest.raises(SceneError) as info:
        load_scene(path)
    msg = str(info.value)
    assert msg.startswith(str(path)) and "bufferViews[0].byteStride" in msg and "252" in msg, msg


def test_gltf_valid_strides_still_load(tmp_path):
    """Tightly packed (12) and padded (16) VEC3 floats: the same positions."""
    scene = load_scene(_stride_doc(tmp_path, 12))
    np.testing.assert_array_equal(scene.positions, QUAD_POSITIONS)

    def padded(doc):                           # rewrite POSITION with 4 bytes of padding per vertex
        import base64
        uri = doc["buffers"][0]["uri"]
        blob = bytearray(base64.b64decode(uri.split(",", 1)[1]))
        rows = np.zeros((4, 4), np.float32)
        rows[:, :3] = QUAD_POSITIONS
        offset = len(blob)
        blob += rows.tobytes()
        doc["buffers"][0] = {"byteLength": len(blob),
                             "uri": "data:application/octet-stream;base64," + base64.b64encode(bytes(blob)).decode()}
        doc["bufferViews"].append({"buffer": 0, "byteOffset": offset, "byteLength": 64, "byteStride": 16})
        doc["accessors"][0]["bufferView"] = len(doc["bufferViews"]) - 1
    scene = load_scene(write_gltf(tmp_path / "padded.gltf", primitives=[primitive(normals=None, uvs=None)],
                                  edit=padded))
    np.testing.assert_array_equal(scene.positions, QUAD_POSITIONS)


# -- OBJ / PLY / STL -----------------------------------------------------------------------------
@pytest.mark.parametrize("bad", ["nan", "inf", "-1e31", "3e38"])
def test_obj_vertex_not_finite_or_absurd(tmp_path, bad):
    path = tmp_path / "bad.obj"
    path.write_text(f"# a quad\nv 0 0 0\nv 1 0 0\nv 1 {bad} 0\nv 0 1 0\nf 1 2 3\nf 1 3 4\n")
    with pytest.raises(SceneError) as info:
        load_scene(path)
    msg = str(info.value)
    assert msg.startswith(str(path)) and "\n" not in msg, msg
    assert "line 4" in msg and "vertex 3" in msg and "1e30" in msg, msg


def _ply(path, vertices):
    header = ("ply\nformat binary_little_endian 1.0\n"
              f"element vertex {len(vertices)}\nproperty float x\nproperty float y\nproperty float z\n"
              "element face 2\nproperty list uchar int vertex_indices\nend_header\n")
    body = np.asarray(vertices, "<f4").tobytes()
    for f in ((0, 1, 2), (0, 2, 3)):
        body += struct.pack("<B3i", 3, *f)
    path.write_bytes(header.encode() + body)
    return path


@pytest.mark.parametrize("bad", [np.nan, np.inf, 1e31], ids=["nan", "inf", "1e31"])
def test_ply_vertex_not_finite_or_absurd(tmp_path, bad):
    path = _ply(tmp_path / "bad.ply", _positions(bad, vertex=3))
    with pytest.raises(SceneError) as info:
        load_scene(path)
    msg = str(info.value)
    assert msg.startswith(str(path)) and "vertex 3" in msg and "1e30" in msg, msg


def test_stl_vertex_not_finite(tmp_path):
    tris = np.array([[[0, 0, 0], [1, 0, 0], [1, 1, 0]], [[0, 0, 0], [1, 1, 0], [0, np.nan, 0]]], "<f4")
    body = b"\0" * 80 + struct.pack("<I", len(tris))
    for t in tris:
        body += np.zeros(3, "<f4").tobytes() + t.tobytes() + b"\0\0"
    path = tmp_path / "bad.stl"
    path.write_bytes(body)
    with pytest.raises(SceneError) as info:
        load_scene(path)
    msg = str(info.value)
    assert msg.startswith(str(path)) and "facet 1" in msg and "1e30" in msg, msg


# -- Scenes built in code ------------------------------------------------------------------------
@pytest.mark.parametrize("bad", BAD_VALUES, ids=BAD_IDS)
def test_scene_from_arrays_rejects_bad_positions(bad):
    """from_arrays names its argument (vertices), the dataclass its field (positions)."""
    with pytest.raises(ValueError) as info:
        Scene.from_arrays(_positions(bad), [[0, 1, 2], [0, 2, 3]])
    msg = str(info.value)
    assert msg.startswith("<arrays>: vertices[2] is (1, ") and "1e30" in msg, msg
    with pytest.raises(ValueError) as info:
        Scene(_positions(bad), np.zeros((4, 3)), np.zeros((4, 2)), [[0, 1, 2]], [0])
    assert str(info.value).startswith("<arrays>: positions[2] is (1, "), str(info.value)


def test_scene_positions_replaced_after_construction(make_renderer):
    """Arrays edited after construction are checked when the scene is uploaded."""
    scene = Scene.from_arrays(QUAD_POSITIONS, [[0, 1, 2], [0, 2, 3]])
    scene.positions = _positions(np.nan)
    with pytest.raises(SceneError, match=r"positions\[2\]"):
        make_renderer(16, 16).render(scene, clrender.Camera.look_at((0.5, 0.5, 3), (0.5, 0.5, 0)))


def test_set_transform_overflowing_positions():
    scene = Scene.from_arrays(QUAD_POSITIONS * 1e10, [[0, 1, 2], [0, 2, 3]])
    huge = np.eye(4)
    huge[0, 3] = 1e31                           # finite, but far beyond the coordinates' bound
    with pytest.raises(SceneError) as info:
        scene.set_transform(0, huge)
    msg = str(info.value)
    assert "mesh 'mesh'" in msg and "1e30" in msg, msg
    np.testing.assert_array_equal(scene.positions, QUAD_POSITIONS * np.float32(1e10))   # left as it was


# -- arguments -----------------------------------------------------------------------------------
@pytest.mark.parametrize("value, typename", [(True, "bool"), ("160", "str"), (160.0, "float"), (None, "NoneType")])
@pytest.mark.parametrize("name", ["width", "height"])
def test_renderer_size_must_be_an_int(name, value, typename):
    kwargs = {"width": 160, "height": 120, name: value}
    with pytest.raises(ValueError) as info:
        clrender.Renderer(**kwargs)
    msg = str(info.value)
    assert msg.startswith(f"{name} must be an integer") and typename in msg, msg


def test_renderer_size_range_names_the_parameter():
    with pytest.raises(ValueError, match=r"^height must be an integer in \[1, 16384\], got 0$"):
        clrender.Renderer(160, 0)


@pytest.mark.parametrize("option, value", [("tile_size", 8.0), ("tile_size", True), ("light_tile_size", 32.0),
                                           ("shadow_tile_size", 16.0), ("exposure", True), ("msaa", True),
                                           ("peel_layers", True), ("supersample", True), ("sun_cascades", 2.0)])
def test_render_config_integers_refuse_bool_and_float(option, value):
    opts = {option: value}
    if option == "msaa":
        opts["pipeline"] = "light_prepass"
    with pytest.raises(ValueError, match=rf"^{option} must be"):
        RenderConfig(**opts)


def test_numpy_integers_are_fine():
    cfg = RenderConfig(tile_size=np.int64(16), supersample=np.int32(2))
    assert cfg.tile_size == 16 and cfg.supersample == 2
