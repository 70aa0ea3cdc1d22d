"""Bad input files, material values and option names: each case is a one-line error naming the problem
(SceneError naming the file for file input) or a documented safe result (the rest of the bad and extreme
input, and what is covered elsewhere: test_bad_input.py).
"""
from __future__ import annotations

import base64
import json
import warnings

import numpy as np
import pytest

import clrender
from clrender import SceneError
from clrender.device.core import DeviceError
from helpers import assert_scene_error


# ------------------------------------------------------------------------------------------------
# Files
# ------------------------------------------------------------------------------------------------
def tiny_gltf(path, material=None, image_uri=None):
    """A one-triangle glTF with an embedded buffer; optional material and base color image file."""
    pos = np.array([[-1, -1, -3], [1, -1, -3], [0, 1, -3]], np.float32)
    uv = np.array([[0, 0], [1, 0], [0.5, 1]], np.float32)
    idx = np.array([0, 1, 2], np.uint16)
    blob = pos.tobytes() + uv.tobytes() + idx.tobytes()
    doc = {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
           "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "TEXCOORD_0": 1}, "indices": 2}]}],
           "buffers": [{"byteLength": len(blob),
                        "uri": "data:application/octet-stream;base64," + base64.b64encode(blob).decode()}],
           "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 36},
                           {"buffer": 0, "byteOffset": 36, "byteLength": 24},
                           {"buffer": 0, "byteOffset": 60, "byteLength": 6}],
           "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
                          "min": [-1, -1, -3], "max": [1, 1, -3]},
                         {"bufferView": 1, "componentType": 5126, "count": 3, "type": "VEC2"},
                         {"bufferView": 2, "componentType": 5123, "count": 3, "type": "SCALAR"}]}
    if material is not None or image_uri is not None:
        material = dict(material or {})
        if image_uri is not None:
            material.setdefault("pbrMetallicRoughness", {})["baseColorTexture"] = {"index": 0}
            doc.update(images=[{"uri": image_uri}], textures=[{"source": 0}])
        doc["materials"] = [material]
        doc["meshes"][0]["primitives"][0]["material"] = 0
    path.write_text(json.dumps(doc))
    return path


CORRUPT_PNG = b"\x89PNG\r\n\x1a\n" + b"\x00\x00\x00\x0dIHDR" + b"garbage" * 10


def test_corrupt_texture_files(tmp_path):
    (tmp_path / "bad.png").write_bytes(CORRUPT_PNG)
    (tmp_path / "empty.png").write_bytes(b"")
    # glTF: an unreadable or missing image is a one-line warning naming it; the material renders
    # with its factors (issue: "the render goes on")
    from clrender import load_scene
    for name in ("bad.png", "empty.png", "nothere.png"):
        with pytest.warns(UserWarning, match=name) as caught:
            scene = load_scene(tiny_gltf(tmp_path / f"t_{name}.gltf", image_uri=name))
        assert len([w for w in caught if name in str(w.message)]) == 1
        assert all(m.base_color_texture == -1 for m in scene.materials)
        assert "\n" not in str(caught[0].message)
    (tmp_path / "m.mtl").write_text("newmtl m\nKd 1 1 1\nmap_Kd bad.png\n")
    (tmp_path / "m.obj").write_text("mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl m\nf 1 2 3\n")
    assert_scene_error(tmp_path / "m.obj", ["decode"])


@pytest.mark.parametrize("body, words", [
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 x\n", ["'x'", "not an integer"]),
    ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n", ["index 9", "out of range"]),
    ("v 0 0 zero\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", ["zero"]),
    ("v 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", ["'v 0 0'"]),
])
def test_malformed_obj(tmp_path, body, words):
    (tmp_path / "bad.obj").write_text(body)
    assert_scene_error(tmp_path / "bad.obj", words)


def test_malformed_gltf_and_toml(tmp_path):
    (tmp_path / "trunc.gltf").write_text('{"asset": {"version": "2.0"}, "meshes": [{"primitives": [')
    assert_scene_error(tmp_path / "trunc.gltf", ["JSON"])
    (tmp_path / "bin.gltf").write_bytes(b"\xff\xfe\x00garbage")
    assert_scene_error(tmp_path / "bin.gltf", [])
    (tmp_path / "s.toml").write_text('[[mesh]]\npath = "x.obj"\n[[mesh]\n')
    assert_scene_error(tmp_path / "s.toml", ["TOML"])
    (tmp_path / "list.gltf").write_text("[1, 2, 3]")
    assert_scene_error(tmp_path / "list.gltf", [])


def test_unknown_material_keys_warn(tmp_path):
    """Misspelt material properties must not pass silently: unknown glTF material / PBR properties and
    unknown MTL statements are reported (the spec allows other files' extensions, so a warning)."""
    path = tiny_gltf(tmp_path / "m.gltf", material={"pbrMetalicRoughness": {"baseColorFactor": [1, 0, 0, 1]},
                                                    "name": "red"})
    with pytest.warns(UserWarning, match=r"m\.gltf.*pbrMetalicRoughness"):
        clrender.load_scene(path)
    path = tiny_gltf(tmp_path / "p.gltf", material={"pbrMetallicRoughness": {"baseColourFactor": [1, 0, 0, 1]}})
    with pytest.warns(UserWarning, match=r"p\.gltf.*baseColourFactor"):
        clrender.load_scene(path)
    (tmp_path / "m.mtl").write_text("newmtl m\nKd 1 0 0\nKdd 1 0 0\nillum 2\nKa 0 0 0\n")
    (tmp_path / "m.obj").write_text("mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl m\nf 1 2 3\n")
    with pytest.warns(UserWarning, match=r"m\.mtl.*line 3.*'Kdd'") as record:
        clrender.load_scene(tmp_path / "m.obj")
    assert not any("illum" in str(w.message) or "'Ka'" in str(w.message) for w in record)
    # Known keys only: no warning at all.
    good = tiny_gltf(tmp_path / "g.gltf", material={"pbrMetallicRoughness": {"baseColorFactor": [1, 0, 0, 1],
                                                                              "metallicFactor": 0.0},
                                                    "doubleSided": True, "extras": {"x": 1}})
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        clrender.load_scene(good)
    with pytest.raises(SceneError, match="alpha_mode|alphaMode"):
        clrender.load_scene(tiny_gltf(tmp_path / "a.gltf", material={"alphaMode": "SOMETIMES"}))


@pytest.mark.parametrize("kw, words", [
    ({"opacity": float("nan")}, ["opacity", "nan"]),
    ({"opacity": 1.5}, ["opacity", "1.5"]),
    ({"opacity": -0.1}, ["opacity", "-0.1"]),
    ({"opacity": float("inf")}, ["opacity", "inf"]),
    ({"opacity": "0.5"}, ["opacity", "'0.5'"]),
    ({"refraction": -1.0}, ["refraction", "-1"]),
    ({"refraction": float("nan")}, ["refraction", "nan"]),
    ({"alpha_mode": "MASK", "opacity": 0.5}, ["MASK", "opacity"]),
])
def test_bad_material_transparency_values(kw, words):
    """Opacity outside [0, 1] or NaN, a negative refraction, or MASK with opacity < 1: a SceneError
    naming the material and the field (docs/transparency.md)."""
    with pytest.raises(SceneError) as info:
        clrender.Material(name="glass_pane", **kw)
    msg = str(info.value)
    assert "glass_pane" in msg, msg
    for w in words:
        assert w in msg, msg


def test_material_opacity_makes_opaque_blend():
    """The documented safe results next to the errors above: opacity < 1 turns OPAQUE into BLEND,
    opacity 1 changes nothing, and the bounds 0 and 1 are accepted."""
    assert clrender.Material(name="m", opacity=0.5).alpha_mode == "BLEND"
    assert clrender.Material(name="m", opacity=0.0).alpha_mode == "BLEND"
    assert clrender.Material(name="m", opacity=1.0).alpha_mode == "OPAQUE"
    assert clrender.Material(name="m", alpha_mode="MASK", opacity=1.0).alpha_mode == "MASK"
    assert clrender.Material(name="m", refraction=0.0).refraction == 0.0


@pytest.mark.parametrize("value, words", [
    ("1.5", ["mesh[0].opacity", "1.5"]),
    ("-0.1", ["mesh[0].opacity", "-0.1"]),
    ("nan", ["mesh[0].opacity", "nan"]),
    ('"half"', ["mesh[0].opacity", "'half'"]),
])
def test_toml_bad_mesh_opacity(tmp_path, value, words):
    (tmp_path / "t.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    path = tmp_path / "s.toml"
    path.write_text(f'[[mesh]]\npath = "t.obj"\nopacity = {value}\n')
    assert_scene_error(path, words)


@pytest.mark.parametrize("line, words", [
    ("opacity = 1.5", ["'leaf'", "opacity", "1.5"]),
    ("opacity = nan", ["'leaf'", "opacity", "nan"]),
    ('opacity = "0.5"', ["'leaf'", "opacity", "'0.5'"]),
    ("refraction = -1", ["'leaf'", "refraction", "-1"]),
    ('alpha_mode = "GLASS"', ["'leaf'", "alpha_mode", "GLASS"]),
    ("alpha_cutoff = 2", ["'leaf'", "alpha_cutoff", "2"]),
])
def test_toml_bad_material_override_values(tmp_path, line, words):
    """[[material]] values are checked before any mesh file is read: the message names the file and
    the material the table is for."""
    path = tmp_path / "s.toml"
    path.write_text(f'[[mesh]]\npath = "never_read.obj"\n[[material]]\nname = "leaf"\n{line}\n')
    msg = assert_scene_error(path, words)
    assert "not found" not in msg, msg


def test_toml_mask_material_with_mesh_opacity(tmp_path):
    """A mesh opacity < 1 over a MASK material is the Material rule's error, naming the file and the
    material (a [[material]] table making it BLEND is the way out)."""
    (tmp_path / "m.mtl").write_text("newmtl leaf\nKd 0 1 0\n")
    (tmp_path / "m.obj").write_text("mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl leaf\nf 1 2 3\n")
    path = tmp_path / "s.toml"
    head = '[[mesh]]\npath = "m.obj"\nopacity = 0.5\n[[material]]\nname = "leaf"\n'
    path.write_text(head + 'alpha_mode = "MASK"\n')
    assert_scene_error(path, ["'leaf'", "MASK", "opacity"])
    path.write_text(head + 'alpha_mode = "BLEND"\n')
    m = clrender.load_scene(path).materials[0]
    assert (m.name, m.alpha_mode, m.opacity) == ("leaf", "BLEND", 0.5)


def test_unknown_option_names_are_errors(device):
    with pytest.raises(ValueError, match=r"tile_sise.*known.*'tile_size'"):
        clrender.Renderer(16, 16, device=device.id, tile_sise=8)
    with pytest.raises(ValueError, match="unknown render option"):
        clrender.RenderConfig.from_options(exposure=1.0, gamma=2.2)
    with pytest.raises(TypeError):
        clrender.RenderConfig(tone_map="aces")


def test_unknown_device_lists_the_available_ones(device):
    with pytest.raises(DeviceError) as info:
        clrender.Renderer(16, 16, device="no-such-device-xyz")
    msg = str(info.value)
    assert "no-such-device-xyz" in msg and "installed:" in msg and device.id in msg, msg
    assert "\n" not in msg

