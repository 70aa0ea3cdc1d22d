"""Scene loaders: our own demo scene in every format (glTF, GLB, TOML, OBJ: the files in scenes/
against their generator scenes/make_demo.py), and files that are missing or of no known format.

By format: glTF (.gltf/.glb) in test_loaders_gltf.py (geometry without trimesh:
test_loaders_geometry.py; lights: test_loaders_lights.py), OBJ+MTL, PLY and STL in
test_loaders_mesh.py, TOML scene files in test_loaders_toml.py. glTF expectations are computed
independently of the loader by tests/reference/gltf_reader.py.
"""
from __future__ import annotations

import json
import math

import numpy as np
import pytest

from clrender.scene.camera import Camera
from clrender.loaders import load_scene
from clrender.scene.model import SceneError
from loader_cases import SCENES, make_demo_module
from reference.gltf_reader import RawGltf, check_against_raw


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


def test_missing_file_and_unsupported_suffix(tmp_path):
    with pytest.raises(SceneError, match=r"nope\.gltf.*not found"):
        load_scene(tmp_path / "nope.gltf")
    (tmp_path / "x.fbx").write_text("")
    with pytest.raises(SceneError, match=r"x\.fbx.*unsupported"):
        load_scene(tmp_path / "x.fbx")
