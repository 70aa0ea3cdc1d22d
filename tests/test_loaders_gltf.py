"""The glTF loader (.gltf/.glb): shared Khronos samples and small files built by the tests.

glTF expectations are computed independently of the loader (tests/reference/gltf_reader.py): the
JSON is read with `json`, accessors with numpy, node matrices from TRS, so the checks compare
against the file's own data. Shared third-party scenes live in ../shared/scenes next to the
repository; tests that need them skip when they are absent.
"""
from __future__ import annotations

import json
import math
import struct
import time

import numpy as np
import pytest

from clrender.loaders import load_scene
from clrender.scene.model import Material, SceneError
from helpers import assert_scene_error, shared_file
from loader_cases import TRI_POS, write_gltf, write_png
from reference.gltf_reader import RawGltf, check_against_raw


# -- shared Khronos samples -------------------------------------------------------------------------
def test_box_textured_matches_accessors():
    path = shared_file("khronos-BoxTextured/BoxTextured.gltf")
    scene = load_scene(path)
    raw = RawGltf(path)
    check_against_raw(scene, raw)
    # the node matrix is a rotation about X: the file normals must have been rotated
    assert not np.allclose(scene.normals, raw.accessor(raw.j["meshes"][0]["primitives"][0]["attributes"]["NORMAL"]))
    assert len(scene.textures) == 1 and scene.textures[0].rgba.shape[2] == 4
    assert scene.materials[0].base_color_texture == 0
    assert scene.materials[0].double_sided is False
    assert scene.textures[0].wrap_s == scene.textures[0].wrap_t == "repeat"
    # metallicFactor 0, roughness absent -> 1: power clamps to 1
    assert scene.materials[0].specular_intensity == pytest.approx(0.04)
    assert scene.materials[0].specular_power == 1.0


def test_texture_coordinate_test_uv_orientation():
    path = shared_file("khronos-TextureCoordinateTest/TextureCoordinateTest.gltf")
    scene = load_scene(path)
    check_against_raw(scene, RawGltf(path))
    # glTF convention: uv (0, 0) is the top-left of the image. The quad in the top-left of the
    # test card samples the top-left of the image: its top-left corner has the smallest u and v.
    names = scene.mesh_names
    k = next(i for i, n in enumerate(names) if n.startswith("TopLeftObj"))
    sel = np.unique(scene.triangles[scene.triangle_mesh == k])
    p, uv = scene.positions[sel], scene.uvs[sel]
    corner = np.argmin(p[:, 0] - p[:, 1])             # min x, max y
    assert uv[corner] == pytest.approx([0.0, 0.0], abs=1e-6)
    assert uv[:, 0].max() == pytest.approx(0.4, abs=1e-6) and uv[:, 1].max() == pytest.approx(0.4, abs=1e-6)
    # the bottom-right quad samples the bottom-right of the image
    k = next(i for i, n in enumerate(names) if n.startswith("BottomRightObj"))
    uv = scene.uvs[np.unique(scene.triangles[scene.triangle_mesh == k])]
    assert uv.min(0) == pytest.approx([0.6, 0.6], abs=1e-6)
    # load order = the scene's root order (here [0, 2, 1, 4, 3]); trimesh's own graph order is the reverse
    raw = RawGltf(path).j
    assert [n.split("/")[0] for n in names] == [raw["nodes"][r]["name"] for r in raw["scenes"][0]["nodes"]]
    assert names[0].startswith("BackPlane") and names[1].startswith("BottomRightObj")


def test_khronos_cameras_perspective_used_orthographic_ignored():
    path = shared_file("khronos-Cameras/Cameras.gltf")
    cam = load_scene(path).camera
    assert cam is not None
    assert cam.eye == pytest.approx((0.5, 0.5, 3.0))
    assert np.subtract(cam.target, cam.eye) / np.linalg.norm(np.subtract(cam.target, cam.eye)) == \
        pytest.approx([0, 0, -1])
    assert cam.fov_y_deg == pytest.approx(math.degrees(0.7))
    assert (cam.near, cam.far) == pytest.approx((0.01, 100.0))


def test_khronos_alpha_blend_mode_materials():
    """AlphaBlendModeTest: the BLEND and MASK materials (mode, cutoff) reach the scene, each test
    mesh uses its material, and the RGBA labels texture keeps its alpha channel (the device samples
    texture alpha from it; the factor alpha is base_color[3], 1 here)."""
    import imageio.v3 as iio

    from clrender.abi import structs
    from clrender.render.scene_upload import material_records

    path = shared_file("khronos-AlphaBlendModeTest/AlphaBlendModeTest.gltf")
    scene = load_scene(path)
    raw = json.loads(path.read_text())
    mats = {m.name: m for m in scene.materials}
    assert set(mats) == {m["name"] for m in raw["materials"]}
    expect = {"MatBed": ("OPAQUE", 0.5), "MatOpaque": ("OPAQUE", 0.5), "MatBlend": ("BLEND", 0.5),
              "MatCutoff25": ("MASK", 0.25), "MatCutoff75": ("MASK", 0.75), "MatCutoffDefault": ("MASK", 0.5)}
    for name, (mode, cutoff) in expect.items():
        assert (mats[name].alpha_mode, mats[name].alpha_cutoff) == (mode, pytest.approx(cutoff)), name
        assert mats[name].opacity == 1.0 and mats[name].base_color[3] == 1.0, name
    # every mesh's triangles use the material the file gives it
    for mesh_index, mesh_name in enumerate(scene.mesh_names):
        node = mesh_name.split("/")[0]
        gltf_mesh = next(m for m in raw["meshes"] if m["name"] == mesh_name.split("/")[1])
        want = raw["materials"][gltf_mesh["primitives"][0]["material"]]["name"]
        used = {scene.materials[i].name for i in np.unique(scene.triangle_material[scene.triangle_mesh == mesh_index])}
        assert used == {want}, node
    assert {n.split("/")[0] for n in scene.mesh_names} >= {"TestBlend", "DecalBlend", "TestCutoff25"}
    # the labels texture, shared by the test materials, with its alpha channel as in the PNG
    tex = scene.textures[mats["MatBlend"].base_color_texture]
    png = iio.imread(path.parent / "AlphaBlendLabels.png")
    assert png.shape[2] == 4
    np.testing.assert_array_equal(tex.rgba, png)
    assert tex.rgba[..., 3].min() == 0 and tex.rgba[..., 3].max() == 255
    assert {mats[n].base_color_texture for n in expect if n != "MatBed"} == {mats["MatBlend"].base_color_texture}
    # what the device gets: the BLEND / MASK flags and the factor alpha
    records = material_records(scene)
    for i, m in enumerate(scene.materials):
        flags = int(records["flags"][i])
        assert bool(flags & structs.MAT_BLEND) == (m.alpha_mode == "BLEND"), m.name
        assert bool(flags & structs.MAT_MASK) == (m.alpha_mode == "MASK"), m.name
        assert records["base_color"][i, 3] == 1.0
    summary = scene.summary()
    assert (summary["transparent_materials"], summary["alpha_masked_materials"]) == (1, 3)


@pytest.mark.slow
def test_sponza_counts_normals_and_speed():
    path = shared_file("sponza-crytek/Sponza.gltf")
    start = time.perf_counter()
    scene = load_scene(path)
    elapsed = time.perf_counter() - start
    assert scene.triangle_count == 262087
    assert len(scene.positions) == 184397
    assert len(scene.mesh_names) == 170
    assert sum(m.alpha_mode == "MASK" for m in scene.materials) == 3
    raw = RawGltf(path)
    # 35 glTF textures: 24 base-color images (sRGB) + 11 normal maps (linear), all loaded
    assert len(raw.j["textures"]) == 35
    base_color = {m["pbrMetallicRoughness"]["baseColorTexture"]["index"] for m in raw.j["materials"]}
    normal = {m["normalTexture"]["index"] for m in raw.j["materials"] if "normalTexture" in m}
    assert len(base_color) == 24 and len(normal) == 11 and len(scene.textures) == 35
    for indices, srgb in ((base_color, True), (normal, False)):
        images = [raw.j["images"][raw.j["textures"][i]["source"]] for i in indices]
        assert {t.name for t in scene.textures if t.srgb == srgb} == {img.get("name") or img["uri"] for img in images}
    assert all(t.rgba.dtype == np.uint8 and t.rgba.shape[2] == 4 for t in scene.textures)
    check_against_raw(scene, raw)
    assert scene.camera is not None and scene.camera.far == pytest.approx(50.0)
    assert elapsed < 10.0, f"Sponza took {elapsed:.1f} s to load"


# -- small glTF files built by the tests --------------------------------------------------------------------
def test_gltf_glb_minimal(tmp_path):
    a = load_scene(write_gltf(tmp_path / "a.gltf"))
    b = load_scene(write_gltf(tmp_path / "b.glb", glb=True))
    np.testing.assert_array_equal(a.positions, b.positions)
    np.testing.assert_array_equal(a.triangles, b.triangles)
    assert a.triangle_count == 2 and a.camera is None
    # no material: the glTF default (metallic 1, roughness 1, single-sided)
    m = a.materials[a.triangle_material[0]]
    assert (m.specular_intensity, m.specular_power, m.double_sided) == (1.0, 1.0, False)


def test_metallic_roughness_mapping(tmp_path):
    # the mapping itself
    m = Material.from_metallic_roughness("m", (1, 1, 1, 1), metallic=0.25, roughness=0.5)
    assert m.specular_intensity == pytest.approx(0.04 + (1.0 - 0.04) * 0.25)    # mix(0.04, luminance 1, m)
    assert (m.metallic, m.roughness) == (0.25, 0.5)
    assert m.specular_power == pytest.approx(2 / 0.25 ** 2 - 2)           # alpha = 0.25 -> 30
    # and what the loader passes it (defaults: metallic 1, roughness 1; doubleSided false)
    mats = [{"name": "a", "pbrMetallicRoughness": {"metallicFactor": 0.25, "roughnessFactor": 0.5,
                                                   "baseColorFactor": [0.5, 0.25, 1, 0.75]}},
            {"name": "b"},
            {"name": "c", "doubleSided": True, "alphaMode": "MASK",
             "pbrMetallicRoughness": {"metallicFactor": 0.0, "roughnessFactor": 0.1}},
            {"name": "d", "alphaMode": "BLEND", "alphaCutoff": 0.2,
             "pbrMetallicRoughness": {"roughnessFactor": 0.8}}]
    scene = load_scene(write_gltf(tmp_path / "m.gltf", materials=mats, prim_extra={"material": 2}))
    a, b, c, d = scene.materials
    lum = 0.2126 * 0.5 + 0.7152 * 0.25 + 0.0722 * 1.0                       # docs/materials.md
    assert (a.specular_intensity, a.specular_power) == pytest.approx((0.04 * 0.75 + lum * 0.25, 30.0))
    assert a.base_color == pytest.approx((0.5, 0.25, 1, 0.75))
    assert (b.specular_intensity, b.specular_power, b.double_sided, b.alpha_mode) == (1.0, 1.0, False, "OPAQUE")
    assert (c.specular_intensity, c.specular_power) == pytest.approx((0.04, 2048.0))   # 19998 clamped
    assert (c.double_sided, c.alpha_mode, c.alpha_cutoff) == (True, "MASK", 0.5)
    assert d.specular_power == pytest.approx(2 / 0.8 ** 4 - 2)
    assert (d.alpha_mode, d.alpha_cutoff) == ("BLEND", 0.2)
    assert (scene.triangle_material == 2).all()


def test_gltf_blend_factor_and_texture_alpha(tmp_path):
    """glTF BLEND: the baseColorFactor alpha goes to base_color[3], the texture keeps its alpha
    channel (sampled on the device), and a TOML opacity multiplies the alpha the device gets."""
    from clrender.render.scene_upload import material_records

    rgba = np.zeros((2, 2, 4), np.uint8)
    rgba[..., :3] = 255
    rgba[..., 3] = [[0, 64], [128, 255]]
    write_png(tmp_path / "a.png", rgba)
    mats = [{"name": "glass", "alphaMode": "BLEND", "doubleSided": True,
             "pbrMetallicRoughness": {"baseColorFactor": [1, 0.5, 0.25, 0.4], "baseColorTexture": {"index": 0}}}]
    write_gltf(tmp_path / "g.gltf", uvs=np.zeros((4, 2), np.float32), materials=mats, prim_extra={"material": 0},
               edit=lambda doc: doc.update(images=[{"uri": "a.png"}], textures=[{"source": 0}]))
    scene = load_scene(tmp_path / "g.gltf")
    m = scene.materials[0]
    assert (m.alpha_mode, m.base_color, m.opacity) == ("BLEND", (1.0, 0.5, 0.25, 0.4), 1.0)
    np.testing.assert_array_equal(scene.textures[m.base_color_texture].rgba, rgba)
    assert material_records(scene)["base_color"][0, 3] == np.float32(0.4)
    (tmp_path / "s.toml").write_text('[[mesh]]\npath = "g.gltf"\nopacity = 0.5\n')
    toml = load_scene(tmp_path / "s.toml")
    assert toml.materials[0].base_color == m.base_color and toml.materials[0].opacity == 0.5
    assert material_records(toml)["base_color"][0, 3] == np.float32(0.4 * 0.5)


def test_gltf_texture_sharing_and_wrap_modes(tmp_path):
    write_png(tmp_path / "img.png", np.arange(2 * 3 * 4, dtype=np.uint8).reshape(2, 3, 4))

    def edit(doc):
        doc["images"] = [{"uri": "img.png"}]
        doc["samplers"] = [{"wrapS": 33648, "wrapT": 33071}]
        doc["textures"] = [{"source": 0, "sampler": 0}, {"source": 0, "sampler": 0}, {"source": 0}]
        doc["materials"] = [{"pbrMetallicRoughness": {"baseColorTexture": {"index": i}}} for i in range(3)]

    scene = load_scene(write_gltf(tmp_path / "t.gltf", uvs=np.zeros((4, 2), np.float32), edit=edit))
    # textures 0 and 1 are the same image + sampler: shared; texture 2 has the default sampler
    assert [m.base_color_texture for m in scene.materials[:3]] == [0, 0, 1]
    assert [(t.wrap_s, t.wrap_t) for t in scene.textures] == [("mirror", "clamp"), ("repeat", "repeat")]
    np.testing.assert_array_equal(scene.textures[0].rgba, np.arange(24, dtype=np.uint8).reshape(2, 3, 4))
    (tmp_path / "img.png").unlink()     # missing image: a warning naming it, the factors render
    with pytest.warns(UserWarning, match=r"t\.gltf.*img\.png"):
        scene = load_scene(tmp_path / "t.gltf")
    assert [m.base_color_texture for m in scene.materials[:3]] == [-1, -1, -1]


def test_gltf_node_transforms_mirror_and_nesting(tmp_path):
    normals = np.tile(np.array([0, 0, 1], np.float32), (4, 1))
    nodes = [{"children": [1, 2], "translation": [10, 0, 0]},
             {"mesh": 0, "scale": [-1, 2, 1]},                       # mirrored: winding reversed
             {"mesh": 0, "rotation": [0, math.sin(math.pi / 4), 0, math.cos(math.pi / 4)]}]   # 90 deg about Y
    scene = load_scene(write_gltf(tmp_path / "n.gltf", normals=normals, nodes=nodes))
    assert scene.triangle_count == 4 and len(scene.mesh_names) == 2
    np.testing.assert_allclose(scene.positions[:4], TRI_POS * [-1, 2, 1] + [10, 0, 0])
    np.testing.assert_allclose(scene.positions[4:], TRI_POS[:, [2, 1, 0]] * [1, 1, -1] + [10, 0, 0], atol=1e-6)
    np.testing.assert_allclose(scene.normals[4:], np.tile([1, 0, 0], (4, 1)), atol=1e-6)
    # geometric normal (from the winding) agrees with the shading normal on both instances
    p = scene.positions[scene.triangles].astype(np.float64)
    geo = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    assert (np.einsum("ij,ij->i", geo, scene.normals[scene.triangles[:, 0]]) > 0).all()
    assert scene.triangle_face.tolist() == [0, 1, 0, 1]


def test_gltf_camera_rules(tmp_path):
    def cams(kind):
        def edit(doc):
            doc["cameras"] = [{"type": "orthographic", "orthographic": {"xmag": 1, "ymag": 1, "znear": 0.1, "zfar": 9}},
                              {"type": "perspective", "perspective": {"yfov": 1.0, "znear": 0.5}}]
            doc["nodes"] = [{"mesh": 0}, {"camera": 0, "translation": [0, 0, 5]},
                            {"translation": [0, 0, 20], "children": [3]}, {"camera": 1, "translation": [1, 0, 0]}]
            doc["scenes"] = [{"nodes": {"ortho": [0, 1], "both": [0, 1, 2], "persp": [0, 2]}[kind]}]
        return edit
    # the first camera in traversal order, of either type
    for kind in ("ortho", "both"):
        ortho = load_scene(write_gltf(tmp_path / f"{kind}.gltf", edit=cams(kind))).camera
        assert ortho.is_orthographic and (ortho.xmag, ortho.ymag, ortho.near, ortho.far) == (1, 1, 0.1, 9)
        assert ortho.eye == pytest.approx((0, 0, 5)) and ortho.target == pytest.approx((0, 0, 4))
    cam = load_scene(write_gltf(tmp_path / "p.gltf", edit=cams("persp"))).camera
    assert cam.eye == pytest.approx((1, 0, 20)) and cam.target == pytest.approx((1, 0, 19))
    assert cam.fov_y_deg == pytest.approx(math.degrees(1.0)) and cam.near == 0.5
    assert cam.far == pytest.approx(1000 * 0.5)          # zfar absent: max(1000 * znear, 2 * scene reach)


def test_gltf_nan_refused_degenerate_kept_and_empty(tmp_path):
    pos = TRI_POS.copy()
    pos[3] = np.nan
    idx = np.array([0, 1, 2, 2, 1, 3, 0, 0, 1], np.uint16)
    assert_scene_error(write_gltf(tmp_path / "n.gltf", positions=pos, indices=idx),
                       ["POSITION (accessors[0])", "vertex 3 is (nan, nan, nan)"])
    scene = load_scene(write_gltf(tmp_path / "d.gltf", indices=idx))
    assert scene.triangle_count == 3
    np.testing.assert_array_equal(scene.triangles, idx.reshape(-1, 3))

    def no_meshes(doc):
        doc["nodes"] = [{}]
        doc.pop("meshes")
    empty = load_scene(write_gltf(tmp_path / "e.gltf", edit=no_meshes))
    assert empty.triangle_count == 0 and empty.positions.shape == (0, 3)


def _edit_accessor_count(doc):
    doc["accessors"][0]["count"] = 5                    # POSITION: 4 vertices in its view


def _edit_view_length(doc):
    doc["bufferViews"][0]["byteLength"] = 4096          # past the end of the buffer


def _edit_buffer_uri(doc):
    doc["buffers"][0]["uri"] = "missing.bin"


def _edit_mesh_ref(doc):
    doc["nodes"][0]["mesh"] = 3


@pytest.mark.parametrize("edit, words", [
    (_edit_accessor_count, ["accessor 0", "past the end"]),
    (_edit_view_length, ["bufferView 0", "past the end"]),
    (_edit_buffer_uri, ["missing.bin", "not found"]),
    (_edit_mesh_ref, ["meshes[3]", "does not exist"]),
])
def test_bad_gltf_structure(tmp_path, edit, words):
    path = write_gltf(tmp_path / "bad.gltf", edit=edit)
    assert_scene_error(path, words)


def test_bad_gltf_index_out_of_range(tmp_path):
    path = write_gltf(tmp_path / "idx.gltf", indices=np.array([0, 1, 2, 2, 1, 7], np.uint16))
    with pytest.raises(SceneError, match=r"idx\.gltf.*out of range"):
        load_scene(path)
    glb = write_gltf(tmp_path / "idx.glb", indices=np.array([0, 1, 2, 2, 1, 7], np.uint16), glb=True)
    with pytest.raises(SceneError, match=r"idx\.glb.*out of range"):
        load_scene(glb)


def test_bad_gltf_json_and_glb(tmp_path):
    broken = tmp_path / "broken.gltf"
    broken.write_text('{"asset": {"version": "2.0"}, "nodes": [')
    with pytest.raises(SceneError, match=r"broken\.gltf.*JSON"):
        load_scene(broken)
    notglb = tmp_path / "x.glb"
    notglb.write_bytes(b"not a glb file at all")
    with pytest.raises(SceneError, match=r"x\.glb"):
        load_scene(notglb)
    truncated = tmp_path / "t.glb"
    truncated.write_bytes(struct.pack("<3I", 0x46546C67, 2, 1000) + b"\0" * 20)
    with pytest.raises(SceneError, match=r"t\.glb"):
        load_scene(truncated)
    v1 = tmp_path / "v1.gltf"
    v1.write_text('{"asset": {"version": "1.0"}}')
    with pytest.raises(SceneError, match=r"v1\.gltf.*2\.0"):
        load_scene(v1)


def test_gltf_points_and_lines_skipped_without_breaking_the_hierarchy(tmp_path):
    def edit(doc):
        tri = doc["meshes"][0]["primitives"][0]
        lines = {"attributes": {"POSITION": tri["attributes"]["POSITION"]}, "mode": 1}
        points = {"attributes": {"POSITION": tri["attributes"]["POSITION"]}, "mode": 0}
        doc["meshes"] = [{"name": "mixed", "primitives": [tri, lines, dict(tri, material=0)]},
                         {"name": "dots", "primitives": [points]}]
        doc["materials"] = [{"name": "second"}]
        doc["nodes"] = [{"mesh": 1, "translation": [0, 5, 0], "children": [1]}, {"mesh": 0}]
    scene = load_scene(write_gltf(tmp_path / "m.gltf", edit=edit))
    assert scene.mesh_names == ["node1/mixed/0", "node1/mixed/2"]
    assert scene.triangle_count == 4 and scene.triangle_face.tolist() == [0, 1, 0, 1]
    assert [scene.materials[i].name for i in scene.triangle_material] == ["default"] * 2 + ["second"] * 2
    # the child of the points-only node keeps its parent's transform
    np.testing.assert_allclose(scene.positions, np.concatenate([TRI_POS, TRI_POS]) + [0, 5, 0])


def test_gltf_normals_use_the_inverse_transpose(tmp_path):
    pos = np.array([[0, 0, 0], [0, 1, 0], [1, 0, -1]], np.float32)           # plane x + z = 0
    normals = np.tile(np.array([1, 0, 1], np.float32) / np.float32(math.sqrt(2)), (3, 1))
    nodes = [{"mesh": 0, "scale": [2, 1, 1]}]
    scene = load_scene(write_gltf(tmp_path / "s.gltf", positions=pos, indices=np.array([0, 1, 2], np.uint16),
                                  normals=normals, nodes=nodes))
    expected = np.array([1, 0, 2]) / math.sqrt(5)       # S^-T n, renormalized (S n would give (2, 0, 1))
    np.testing.assert_allclose(scene.normals, np.tile(expected, (3, 1)), atol=1e-6)
    p = scene.positions.astype(np.float64)
    geo = np.cross(p[1] - p[0], p[2] - p[0])
    assert np.cross(geo, expected) == pytest.approx([0, 0, 0], abs=1e-6)


def test_gltf_uvs_are_the_file_data_bit_for_bit(tmp_path):
    # v values below 0.5 with low mantissa bits do not survive trimesh's float32 flip (1 - v) and back
    uvs = np.array([[0.1, 0.1], [0.3, 0.123456], [1e-3, 7.9e-8], [2.5, -0.75]], np.float32)
    scene = load_scene(write_gltf(tmp_path / "uv.gltf", uvs=uvs))
    np.testing.assert_array_equal(scene.uvs, uvs)
    glb = load_scene(write_gltf(tmp_path / "uv.glb", uvs=uvs, glb=True))
    np.testing.assert_array_equal(glb.uvs, uvs)


def test_gltf_sparse_and_normalized_accessors(tmp_path):
    # POSITION with a sparse override of vertex 3, NORMAL as normalized int8, TEXCOORD_0 as normalized uint16
    def edit(doc):
        blob_path = tmp_path / "sp.bin"
        blob = bytearray(blob_path.read_bytes())
        extra = len(blob)
        blob += np.array([3], np.uint16).tobytes() + b"\0\0" + np.array([5, 6, 7], np.float32).tobytes()
        blob += np.array([[0, 0, 127, 0]] * 4, np.int8).tobytes()
        blob += np.array([[0, 65535], [65535, 0], [32768, 32768], [0, 0]], np.uint16).tobytes()
        blob_path.write_bytes(bytes(blob))
        doc["buffers"][0]["byteLength"] = len(blob)
        views = doc["bufferViews"]
        views += [{"buffer": 0, "byteOffset": extra, "byteLength": 2},
                  {"buffer": 0, "byteOffset": extra + 4, "byteLength": 12},
                  {"buffer": 0, "byteOffset": extra + 16, "byteLength": 16, "byteStride": 4},
                  {"buffer": 0, "byteOffset": extra + 32, "byteLength": 16}]
        n = len(views)
        doc["accessors"][0]["sparse"] = {"count": 1, "indices": {"bufferView": n - 4, "componentType": 5123},
                                         "values": {"bufferView": n - 3}}
        doc["accessors"] += [{"bufferView": n - 2, "componentType": 5120, "normalized": True, "count": 4, "type": "VEC3"},
                             {"bufferView": n - 1, "componentType": 5123, "normalized": True, "count": 4, "type": "VEC2"}]
        attrs = doc["meshes"][0]["primitives"][0]["attributes"]
        attrs["NORMAL"], attrs["TEXCOORD_0"] = len(doc["accessors"]) - 2, len(doc["accessors"]) - 1

    path = tmp_path / "sp.gltf"
    write_gltf(path)
    doc = json.loads(path.read_text())
    edit(doc)
    path.write_text(json.dumps(doc))
    scene = load_scene(path)
    np.testing.assert_allclose(scene.positions, np.concatenate([TRI_POS[:3], [[5, 6, 7]]]))
    np.testing.assert_allclose(scene.normals, np.tile([0, 0, 1], (4, 1)))
    np.testing.assert_allclose(scene.uvs, [[0, 1], [1, 0], [32768 / 65535] * 2, [0, 0]])
