"""TOML scene files: meshes with transforms, camera, render settings and lights; transparency
keys and [[material]] overrides; the errors of every table."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from clrender.scene.camera import Camera
from clrender.loaders import load_scene
from helpers import assert_scene_error
from loader_cases import TRI_IDX, TRI_POS, write_gltf, write_png


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
