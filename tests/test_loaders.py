"""Scene loaders: glTF (.gltf/.glb), OBJ+MTL, PLY, STL and TOML scene files.

glTF expectations are computed here independently of the loader: the JSON is read with `json`,
accessors with numpy, node matrices from TRS, so the checks compare against the file's own data.
Shared third-party scenes live in ../shared/scenes next to the repository; tests that need them
skip when they are absent.
"""
from __future__ import annotations

import importlib.util
import json
import math
import os
import struct
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from clrender.scene.camera import Camera  # noqa: E402
from clrender.loaders import load_scene  # noqa: E402
from clrender.scene.model import Material, SceneError  # noqa: E402
from helpers import assert_scene_error, shared_file

REPO = Path(__file__).resolve().parents[1]
SCENES = REPO / "scenes"


def make_demo_module():
    spec = importlib.util.spec_from_file_location("make_demo", SCENES / "make_demo.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


# -- an independent glTF reader (json + numpy) -----------------------------------------------------
_CT = {5120: "<i1", 5121: "<u1", 5122: "<i2", 5123: "<u2", 5125: "<u4", 5126: "<f4"}
_NC = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT4": 16}


class RawGltf:
    def __init__(self, path: Path):
        self.path = path
        self.j = json.loads(path.read_text())
        self.buffers = [(path.parent / b["uri"]).read_bytes() for b in self.j["buffers"]]

    def accessor(self, i: int) -> np.ndarray:
        a = self.j["accessors"][i]
        v = self.j["bufferViews"][a["bufferView"]]
        dt = np.dtype(_CT[a["componentType"]])
        n = _NC[a["type"]]
        elem = dt.itemsize * n
        stride = v.get("byteStride", elem)
        base = v.get("byteOffset", 0) + a.get("byteOffset", 0)
        buf = self.buffers[v["buffer"]]
        rows = [np.frombuffer(buf, dt, n, base + k * stride) for k in range(a["count"])] if stride != elem \
            else [np.frombuffer(buf, dt, n * a["count"], base)]
        return np.concatenate(rows).reshape(a["count"], n)

    def local_matrix(self, node: dict) -> np.ndarray:
        if "matrix" in node:
            return np.array(node["matrix"], np.float64).reshape(4, 4).T
        t = np.eye(4)
        t[:3, 3] = node.get("translation", [0, 0, 0])
        q = np.array(node.get("rotation", [0, 0, 0, 1]), np.float64)
        x, y, z, w = q / np.linalg.norm(q)                 # file quaternions are unit to ~1e-7 only
        r = np.eye(4)
        r[:3, :3] = [[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]]
        s = np.diag([*node.get("scale", [1, 1, 1]), 1.0])
        return t @ r @ s

    def instances(self):
        """(node index, world matrix) of every node of the default scene, depth-first pre-order."""
        out = []

        def walk(n, parent):
            world = parent @ self.local_matrix(self.j["nodes"][n])
            out.append((n, world))
            for c in self.j["nodes"][n].get("children", []):
                walk(c, world)

        for root in self.j["scenes"][self.j.get("scene", 0)]["nodes"]:
            walk(root, np.eye(4))
        return out

    def expected(self):
        """Concatenated world positions, normals (or None per primitive), uvs, triangles in load order."""
        pos, nrm, uvs, tris, offset = [], [], [], [], 0
        for n, world in self.instances():
            node = self.j["nodes"][n]
            if "mesh" not in node:
                continue
            for prim in self.j["meshes"][node["mesh"]]["primitives"]:
                attrs = prim["attributes"]
                p = self.accessor(attrs["POSITION"]).astype(np.float64)
                pos.append(p @ world[:3, :3].T + world[:3, 3])
                if "NORMAL" in attrs:
                    q = self.accessor(attrs["NORMAL"]).astype(np.float64) @ np.linalg.inv(world[:3, :3])
                    nrm.append(q / np.linalg.norm(q, axis=1, keepdims=True))
                else:
                    nrm.append(None)
                uvs.append(self.accessor(attrs["TEXCOORD_0"]) if "TEXCOORD_0" in attrs else None)
                idx = self.accessor(prim["indices"]).reshape(-1, 3).astype(np.int64)
                if np.linalg.det(world[:3, :3]) < 0:
                    idx = idx[:, [0, 2, 1]]
                tris.append(idx + offset)
                offset += len(p)
        return pos, nrm, uvs, tris


def check_against_raw(scene, raw: RawGltf):
    pos, nrm, uvs, tris = raw.expected()
    assert scene.triangle_count == sum(len(t) for t in tris)
    np.testing.assert_allclose(scene.positions, np.concatenate(pos), rtol=1e-6, atol=1e-6)
    np.testing.assert_array_equal(scene.triangles, np.concatenate(tris))
    start = 0
    for p, n, uv in zip(pos, nrm, uvs):
        sl = slice(start, start + len(p))
        if n is not None:
            np.testing.assert_allclose(scene.normals[sl], n, rtol=0, atol=2e-7)
        if uv is not None:
            # exactly the file's TEXCOORD_0 (glTF convention, no flip)
            np.testing.assert_array_equal(scene.uvs[sl], uv)
        start += len(p)


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


# -- our own demo scene -------------------------------------------------------------------------------
def test_demo_files_are_in_sync_with_the_generator(tmp_path):
    demo = make_demo_module()
    doc, data = demo.build_demo()
    (tmp_path / "demo.gltf").write_text(json.dumps(doc))
    (tmp_path / "demo.bin").write_bytes(data)
    fresh, stored = RawGltf(tmp_path / "demo.gltf"), RawGltf(SCENES / "demo.gltf")

    def strip(j):  # min/max are floats from sin/cos: compared below with a tolerance
        j = json.loads(json.dumps(j))
        for a in j["accessors"]:
            a.pop("min", None), a.pop("max", None)
        return j
    assert strip(stored.j) == strip(fresh.j)
    for i, (a, b) in enumerate(zip(stored.j["accessors"], fresh.j["accessors"])):
        np.testing.assert_allclose(stored.accessor(i), fresh.accessor(i), rtol=0, atol=1e-6)
        np.testing.assert_allclose(a.get("min", 0), b.get("min", 0), atol=1e-6)
        np.testing.assert_allclose(a.get("max", 0), b.get("max", 0), atol=1e-6)
    assert (SCENES / "crate.obj").read_text() == demo.crate_obj()
    assert (SCENES / "crate.mtl").read_text() == demo.CRATE_MTL
    assert (SCENES / "demo.toml").read_text() == demo.DEMO_TOML
    total = sum(f.stat().st_size for f in SCENES.iterdir() if f.is_file())
    assert total < 1_000_000


def test_demo_gltf_round_trip():
    demo = make_demo_module()
    scene = load_scene(SCENES / "demo.gltf")
    check_against_raw(scene, RawGltf(SCENES / "demo.gltf"))
    counts = {name: len(f()[3]) // 3 for name, f in
              (("floor", demo.floor_mesh), ("box", demo.box_mesh), ("sphere", lambda: demo.sphere_mesh(0.8)),
               ("torus", demo.torus_mesh), ("card", demo.card_mesh))}
    expected = counts["floor"] + 4 * counts["box"] + counts["sphere"] + counts["torus"] + counts["card"]
    assert scene.triangle_count == expected
    assert scene.mesh_names == ["Floor/Floor", "BoxA/Box", "BoxTall/Box", "BoxBlue/BlueBox", "Sphere/Sphere",
                                "Torus/Torus", "LeafCard/LeafCard/0", "LeafCard/LeafCard/1"]
    mats = {m.name: m for m in scene.materials}
    assert [m.name for m in scene.materials] == ["FloorChecker", "RedPlastic", "BlueMetal", "GoldSingleSided",
                                                 "WhiteGloss", "LeafMask"]
    assert [n for n, m in mats.items() if not m.double_sided] == ["GoldSingleSided"]
    assert mats["LeafMask"].alpha_mode == "MASK" and mats["LeafMask"].alpha_cutoff == 0.5
    assert all(m.alpha_mode == "OPAQUE" for n, m in mats.items() if n != "LeafMask")
    assert mats["RedPlastic"].base_color == pytest.approx((0.8, 0.1, 0.08, 1.0))
    # a full metal: no diffuse (docs/materials.md), specular = the luminance of its base colour
    assert mats["BlueMetal"].metallic == 1.0
    assert mats["BlueMetal"].specular_intensity == pytest.approx(0.2126 * 0.2 + 0.7152 * 0.3 + 0.0722 * 0.9)
    checker = scene.textures[mats["FloorChecker"].base_color_texture]
    leaf = scene.textures[mats["LeafMask"].base_color_texture]
    np.testing.assert_array_equal(checker.rgba, demo.checker_texture())
    np.testing.assert_array_equal(leaf.rgba, demo.leaf_texture())
    assert (checker.wrap_s, leaf.wrap_s, leaf.wrap_t) == ("repeat", "clamp", "clamp")
    assert leaf.srgb and set(np.unique(leaf.rgba[..., 3])) == {0, 255}
    # each triangle knows where it came from
    k = scene.mesh_names.index("Torus/Torus")
    first = int(np.argmax(scene.triangle_mesh == k))
    assert scene.triangle_source(first) == ("Torus/Torus", 0)
    assert scene.triangle_source(first + 5) == ("Torus/Torus", 5)
    assert (scene.triangle_material[scene.triangle_mesh == k] == scene.materials.index(mats["GoldSingleSided"])).all()
    # the leaf card has no NORMAL in the file: area-weighted normals, +Z in its (unrotated) node
    k = scene.mesh_names.index("LeafCard/LeafCard/0")
    card = np.unique(scene.triangles[scene.triangle_mesh == k])
    np.testing.assert_allclose(scene.normals[card], np.tile([0, 0, 1], (len(card), 1)), atol=1e-6)
    # camera node looks from (0, 4, 10) at (0, 1, 0)
    cam = scene.camera
    assert cam.eye == pytest.approx((0, 4, 10), abs=1e-5)
    direction = np.subtract(cam.target, cam.eye)
    assert direction / np.linalg.norm(direction) == pytest.approx(np.array([0, -3, -10]) / math.sqrt(109), abs=1e-6)
    assert (cam.fov_y_deg, cam.near, cam.far) == pytest.approx((50.0, 0.1, 100.0))


def test_demo_glb_equals_gltf(tmp_path):
    demo = make_demo_module()
    doc = json.loads((SCENES / "demo.gltf").read_text())
    glb = tmp_path / "demo.glb"
    glb.write_bytes(demo.to_glb(doc, (SCENES / "demo.bin").read_bytes(), SCENES))
    a, b = load_scene(SCENES / "demo.gltf"), load_scene(glb)
    for field in ("positions", "normals", "uvs", "triangles", "triangle_material", "triangle_mesh", "triangle_face"):
        np.testing.assert_array_equal(getattr(a, field), getattr(b, field))
    assert a.materials == b.materials and a.mesh_names == b.mesh_names
    for ta, tb in zip(a.textures, b.textures):
        np.testing.assert_array_equal(ta.rgba, tb.rgba)


def test_demo_toml():
    demo = make_demo_module()
    scene = load_scene(SCENES / "demo.toml")
    gltf = load_scene(SCENES / "demo.gltf")
    crate = load_scene(SCENES / "crate.obj")
    assert scene.triangle_count == gltf.triangle_count + crate.triangle_count == gltf.triangle_count + 12
    assert scene.settings["render"] == {"width": 960, "height": 540}
    assert [light["type"] for light in scene.settings["lights"]] == ["point", "point", "point", "spot"]
    assert len(scene.lights) == 4 + 64
    assert scene.camera == Camera.look_at((0, 4, 10), (0, 1, 0), (0, 1, 0), 50, 0.1, 100)
    # crate transform: T(2.6, 0, 2.4) . Ry(30) . S(0.8)
    c, s = math.cos(math.radians(30)), math.sin(math.radians(30))
    m = np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]]) * 0.8
    nv = len(gltf.positions)
    np.testing.assert_allclose(scene.positions[nv:], crate.positions @ m.T + [2.6, 0, 2.4], atol=1e-6)
    np.testing.assert_allclose(scene.normals[nv:], crate.normals @ (m / 0.8).T, atol=1e-6)
    np.testing.assert_array_equal(scene.triangles[gltf.triangle_count:], crate.triangles + nv)
    # textures re-indexed after concatenation
    crate_mat = scene.materials[len(gltf.materials)]
    assert crate_mat.name == "crate" and crate_mat.base_color_texture == len(gltf.textures)
    np.testing.assert_array_equal(scene.textures[crate_mat.base_color_texture].rgba, demo.crate_texture())
    assert scene.mesh_names[-2:] == ["crate.obj:crate/crate", "crate.obj:crate/crate_top"]   # o group/material


def test_demo_crate_obj():
    demo = make_demo_module()
    scene = load_scene(SCENES / "crate.obj")
    assert scene.triangle_count == 12
    assert [m.name for m in scene.materials] == ["crate", "crate_top"]
    # the textured sides come first (file order), the top last
    assert scene.triangle_material.tolist() == [0] * 10 + [1] * 2
    top = np.unique(scene.triangles[scene.triangle_material == 1])
    np.testing.assert_allclose(scene.normals[top], np.tile([0, 1, 0], (len(top), 1)))
    np.testing.assert_array_equal(scene.textures[0].rgba, demo.crate_texture())


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


def write_png(path: Path, rgba: np.ndarray):
    from PIL import Image
    Image.fromarray(rgba, "RGBA").save(path)


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


# -- small glTF files built by the tests --------------------------------------------------------------------
TRI_POS = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]], np.float32)
TRI_IDX = np.array([0, 1, 2, 2, 1, 3], np.uint16)


def write_gltf(path: Path, positions=TRI_POS, indices=TRI_IDX, normals=None, uvs=None, materials=None,
               nodes=None, prim_extra=None, edit=None, glb=False) -> Path:
    """A one-mesh glTF; `edit(doc)` may break it afterwards."""
    blob, views, accessors = bytearray(), [], []

    def add(array, kind, target):
        array = np.ascontiguousarray(array)
        blob.extend(b"\0" * (-len(blob) % 4))
        views.append({"buffer": 0, "byteOffset": len(blob), "byteLength": array.nbytes, "target": target})
        blob.extend(array.tobytes())
        ct = {np.float32: 5126, np.uint16: 5123, np.uint32: 5125}[array.dtype.type]
        accessors.append({"bufferView": len(views) - 1, "componentType": ct, "count": len(array), "type": kind})
        return len(accessors) - 1

    attrs = {"POSITION": add(positions, "VEC3", 34962)}
    if normals is not None:
        attrs["NORMAL"] = add(normals, "VEC3", 34962)
    if uvs is not None:
        attrs["TEXCOORD_0"] = add(uvs, "VEC2", 34962)
    prim = {"attributes": attrs, "indices": add(indices, "SCALAR", 34963), **(prim_extra or {})}
    doc = {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}],
           "nodes": nodes or [{"mesh": 0}], "meshes": [{"name": "tri", "primitives": [prim]}],
           "accessors": accessors, "bufferViews": views,
           "buffers": [{"uri": path.stem + ".bin", "byteLength": len(blob)}]}
    if materials is not None:
        doc["materials"] = materials
    if edit:
        edit(doc)
    if glb:
        demo = make_demo_module()
        for b in doc["buffers"]:
            b.pop("uri", None)
        path.write_bytes(demo.to_glb(doc, bytes(blob), path.parent))
    else:
        (path.parent / (path.stem + ".bin")).write_bytes(bytes(blob))
        path.write_text(json.dumps(doc))
    return path


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


def test_missing_file_and_unsupported_suffix(tmp_path):
    with pytest.raises(SceneError, match=r"nope\.gltf.*not found"):
        load_scene(tmp_path / "nope.gltf")
    (tmp_path / "x.fbx").write_text("")
    with pytest.raises(SceneError, match=r"x\.fbx.*unsupported"):
        load_scene(tmp_path / "x.fbx")


# -- TOML ---------------------------------------------------------------------------------------------------
def test_toml_transforms_camera_and_settings(tmp_path):
    write_gltf(tmp_path / "t.gltf")
    (tmp_path / "s.toml").write_text("""
[[mesh]]
path = "t.gltf"
[[mesh]]
path = "t.gltf"
name = "moved"
transform = { translate = [1, 2, 3], rotate_deg = [0, 0, 90], scale = 2.0 }
[[mesh]]
path = "t.gltf"
transform = { scale = [-1, 1, 1] }
[camera]
eye = [0, 0, 5]
target = [0, 0, 0]
fov_y_deg = 40
[render]
width = 320
height = 200
[[light]]
type = "spot"
position = [0, 5, 0]
direction = [0, -1, 0]
outer_cone_deg = 30
""")
    scene = load_scene(tmp_path / "s.toml")
    assert scene.triangle_count == 6
    np.testing.assert_allclose(scene.positions[:4], TRI_POS)
    # Rz(90) . S(2): (x, y, z) -> (-2y, 2x, 2z), then + (1, 2, 3)
    expected = np.stack([-2 * TRI_POS[:, 1], 2 * TRI_POS[:, 0], 2 * TRI_POS[:, 2]], 1) + [1, 2, 3]
    np.testing.assert_allclose(scene.positions[4:8], expected, atol=1e-6)
    np.testing.assert_allclose(scene.positions[8:], TRI_POS * [-1, 1, 1])
    np.testing.assert_array_equal(scene.triangles[4:], TRI_IDX.reshape(-1, 3)[:, [0, 2, 1]] + 8)  # mirrored
    assert scene.mesh_names == ["t.gltf:node0/tri", "moved:node0/tri", "t.gltf:node0/tri"]
    assert scene.triangle_mesh.tolist() == [0, 0, 1, 1, 2, 2]
    assert scene.camera == Camera.look_at((0, 0, 5), (0, 0, 0), (0, 1, 0), 40.0, 0.1, 100.0)
    assert scene.settings["render"] == {"width": 320, "height": 200}
    assert scene.settings["lights"] == [{"type": "spot", "position": [0.0, 5.0, 0.0],
                                         "direction": [0.0, -1.0, 0.0], "outer_cone_deg": 30.0}]


@pytest.mark.parametrize("text, words", [
    ('[[mesh]]\npath = "t.gltf"\ncolour = 1\n', ["colour"]),
    ('[[mesh]]\npath = "t.gltf"\ntransform = { rotate = [0, 1, 0] }\n', ["rotate"]),
    ('[camera]\neye = [0, 0, 1]\ntarget = [0, 0, 0]\nfov = 40\n', ["fov"]),
    ('[render]\nwidht = 10\n', ["widht"]),
    ('[[light]]\ntype = "point"\npower = 3\n', ["power"]),
    ('[lights]\n', ["lights"]),
    ('[[light]]\ntype = "area"\n', ["type"]),
    ('[render]\nwidth = -3\n', ["width"]),
    ('[[mesh]]\npath = "missing/nothere.obj"\n', ["nothere.obj", "not found"]),
    ('[[mesh]]\npath = "bad.gltf"\n', ["bad.gltf", "JSON"]),
    ('[[mesh]\npath = "t.gltf"\n', ["TOML"]),
])
def test_toml_errors(tmp_path, text, words):
    write_gltf(tmp_path / "t.gltf")
    (tmp_path / "bad.gltf").write_text("{")
    path = tmp_path / "s.toml"
    path.write_text(text)
    assert_scene_error(path, words)


def test_toml_camera_defaults_to_the_first_mesh_camera(tmp_path):
    def edit(doc):
        doc["cameras"] = [{"type": "perspective", "perspective": {"yfov": 0.8, "znear": 0.1, "zfar": 50}}]
        doc["nodes"] = [{"mesh": 0}, {"camera": 0, "translation": [0, 0, 4]}]
        doc["scenes"] = [{"nodes": [0, 1]}]
    write_gltf(tmp_path / "c.gltf", edit=edit)
    (tmp_path / "s.toml").write_text('[[mesh]]\npath = "c.gltf"\ntransform = { translate = [5, 0, 0] }\n')
    cam = load_scene(tmp_path / "s.toml").camera
    assert cam.eye == pytest.approx((5, 0, 4)) and cam.target == pytest.approx((5, 0, 3))
    assert cam.far == pytest.approx(50)


TRANSPARENT_OBJ = """\
mtllib t.mtl
v 0 0 0
v 1 0 0
v 0 1 0
vt 0 0
usemtl glass_curtain
f 1/1 2/1 3/1
usemtl red_curtain
f 1/1 3/1 2/1
usemtl wood
f 2/1 3/1 1/1
"""
TRANSPARENT_MTL = """\
newmtl glass_curtain
Kd 0.5 0.5 1
newmtl red_curtain
Kd 1 0 0
d 0.75
newmtl wood
Kd 0.5 0.25 0
map_Kd wood.png
"""


def test_toml_opacity_refraction_and_material_overrides(tmp_path):
    """[[mesh]] opacity multiplies every material of the mesh (< 1 -> BLEND) and refraction sets it;
    [[material]] tables match loaded names exactly or by glob, a later table's key winning, and set
    opacity / refraction (a table's refraction wins over the mesh's) / alpha_mode / alpha_cutoff."""
    write_png(tmp_path / "wood.png", np.full((2, 2, 4), 200, np.uint8))
    (tmp_path / "t.obj").write_text(TRANSPARENT_OBJ)
    (tmp_path / "t.mtl").write_text(TRANSPARENT_MTL)
    write_gltf(tmp_path / "g.gltf", uvs=np.zeros((4, 2), np.float32), edit=lambda doc: doc.update(
        images=[{"uri": "wood.png"}], textures=[{"source": 0}],
        materials=[{"name": "pane", "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}]),
        prim_extra={"material": 0})
    plain = load_scene(tmp_path / "t.obj")
    glass, red, wood = plain.materials
    (tmp_path / "s.toml").write_text("""
[[mesh]]
path = "g.gltf"
[[mesh]]
path = "t.obj"
name = "a"
opacity = 0.5
refraction = 0.1
[[mesh]]
path = "t.obj"
name = "b"
[[material]]
name = "*curtain*"
opacity = 0.8
[[material]]
name = "red_curtain"
refraction = 0.02
alpha_mode = "BLEND"
[[material]]
name = "wood"
alpha_cutoff = 0.25
""")
    scene = load_scene(tmp_path / "s.toml")
    assert [m.name for m in scene.materials] == ["pane"] + ["glass_curtain", "red_curtain", "wood"] * 2
    pane, a_glass, a_red, a_wood, b_glass, b_red, b_wood = scene.materials
    # untouched: the glTF's material, texture 0
    assert (pane.alpha_mode, pane.opacity, pane.refraction, pane.base_color_texture) == ("OPAQUE", 1.0, 0.0, 0)
    # mesh "a": opacity x 0.5 on top of the tables' values, refraction 0.1 unless a table sets it
    assert (a_glass.alpha_mode, a_glass.opacity, a_glass.refraction) == ("BLEND", pytest.approx(0.4), 0.1)
    assert (a_red.alpha_mode, a_red.opacity, a_red.refraction) == ("BLEND", pytest.approx(0.4), 0.02)
    assert (a_wood.alpha_mode, a_wood.opacity, a_wood.refraction, a_wood.alpha_cutoff) == ("BLEND", 0.5, 0.1, 0.25)
    # mesh "b": the tables only
    assert (b_glass.alpha_mode, b_glass.opacity, b_glass.refraction) == ("BLEND", pytest.approx(0.8), 0.0)
    assert (b_red.alpha_mode, b_red.opacity, b_red.refraction) == ("BLEND", pytest.approx(0.8), 0.02)
    assert b_wood == replace(wood, alpha_cutoff=0.25, base_color_texture=2) and b_wood.alpha_mode == "OPAQUE"
    # everything else as loaded: colours (the MTL's d in base_color[3]), textures re-indexed after
    for ours, loaded in ((a_glass, glass), (a_red, red), (b_glass, glass), (b_red, red)):
        assert ours.base_color == loaded.base_color and ours.specular_power == loaded.specular_power
    assert red.base_color[3] == pytest.approx(0.75)
    assert (wood.base_color_texture, a_wood.base_color_texture, b_wood.base_color_texture) == (0, 1, 2)
    assert len(scene.textures) == 3
    np.testing.assert_array_equal(scene.triangle_material, [0, 0, 1, 2, 3, 4, 5, 6])
    summary = scene.summary()
    assert (summary["transparent_materials"], summary["alpha_masked_materials"]) == (5, 0)


def test_toml_material_alpha_mode_override(tmp_path):
    """alpha_mode OPAQUE/MASK from a [[material]] table; OPAQUE with opacity < 1 still becomes BLEND."""
    (tmp_path / "t.obj").write_text(TRANSPARENT_OBJ)
    (tmp_path / "t.mtl").write_text(TRANSPARENT_MTL.replace("map_Kd wood.png\n", ""))
    (tmp_path / "s.toml").write_text("""
[[mesh]]
path = "t.obj"
[[material]]
name = "glass_curtain"
alpha_mode = "MASK"
alpha_cutoff = 0.4
[[material]]
name = "red_?urtain"
alpha_mode = "OPAQUE"
opacity = 0.3
""")
    glass, red, wood = load_scene(tmp_path / "s.toml").materials
    assert (glass.alpha_mode, glass.alpha_cutoff, glass.opacity) == ("MASK", 0.4, 1.0)
    assert (red.alpha_mode, red.opacity) == ("BLEND", 0.3)
    assert (wood.alpha_mode, wood.opacity) == ("OPAQUE", 1.0)


@pytest.mark.parametrize("pattern", ["curtain", "*CURTAIN*", "a:wood", "glass_curtain "])
def test_toml_material_override_matching_nothing(tmp_path, pattern):
    """An override that matches no loaded material (names are exact and case-sensitive, and not
    prefixed by the mesh's name) is an error naming the file and the pattern, listing the names."""
    (tmp_path / "t.obj").write_text(TRANSPARENT_OBJ)
    (tmp_path / "t.mtl").write_text(TRANSPARENT_MTL.replace("map_Kd wood.png\n", ""))
    path = tmp_path / "s.toml"
    path.write_text(f'[[mesh]]\npath = "t.obj"\nname = "a"\n[[material]]\nname = "wood"\nopacity = 0.5\n'
                    f'[[material]]\nname = "{pattern}"\nopacity = 0.5\n')
    msg = assert_scene_error(path, ["material[1]", repr(pattern), "matches no material", "'glass_curtain'"])
    assert "material[0]" not in msg


@pytest.mark.parametrize("text, words", [
    ('[[material]]\nopacity = 0.5\n', ["material[0]", "name"]),
    ('[[material]]\nname = "x"\n', ["material[0]", "'x'", "changes nothing"]),
    ('[[material]]\nname = "x"\ncolor = [1, 0, 0]\n', ["material[0]", "color"]),
    ('[material]\nname = "x"\n', ["[[material]]"]),
    ('[[mesh]]\npath = "t.gltf"\nalpha_mode = "BLEND"\n', ["mesh[0]", "alpha_mode"]),
    ('[[mesh]]\npath = "t.gltf"\nrefraction = -0.5\n', ["mesh[0].refraction", "-0.5"]),
    ('[[mesh]]\npath = "t.gltf"\nopacity = 2\n', ["mesh[0].opacity", "2"]),
])
def test_toml_transparency_key_errors(tmp_path, text, words):
    write_gltf(tmp_path / "t.gltf")
    path = tmp_path / "s.toml"
    path.write_text(text)
    assert_scene_error(path, words)


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
