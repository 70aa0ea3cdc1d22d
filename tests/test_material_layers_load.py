"""The glTF surface extensions at the loader level (issue 37; docs/materials.md "Surface extensions").

KHR_materials_ior, _specular, _clearcoat, _sheen, _iridescence and _anisotropy into `Material`'s
fields: factors, textures (slot indices, texCoord, KHR_texture_transform, sRGB flags), `layers`
(degenerate values give no layer), the bad-input rule (one warning naming the material and the
value, the value clamped or the schema's default used, the load goes on) and extensionsRequired.
The expectations are literals written from the extensions' schemas and READMEs (KhronosGroup/glTF,
extensions/2.0/Khronos/KHR_materials_*), not computed by the loader's code. No rendering.
"""
from __future__ import annotations

import os
import sys
import warnings

import numpy as np
import pytest

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from gltf_files import QUAD_UVS, primitive, write_gltf  # noqa: E402

from clrender.loaders import load_scene  # noqa: E402
from clrender.scene import EXT_TEXTURE_SLOTS  # noqa: E402
from clrender.scene.model import Material, SceneError, UVTransform  # noqa: E402

SURFACE = ["KHR_materials_ior", "KHR_materials_specular", "KHR_materials_clearcoat", "KHR_materials_sheen",
           "KHR_materials_iridescence", "KHR_materials_anisotropy"]
ALL_LAYERS = frozenset({"specular", "clearcoat", "sheen", "iridescence", "anisotropy"})


def image(seed: int, h: int = 4, w: int = 8) -> np.ndarray:
    return np.random.default_rng(seed).integers(0, 256, (h, w, 4), dtype=np.uint8)


def load_quietly(path):
    """Load, failing on any warning (an "extension ignored" warning included)."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        return load_scene(path)


def load_warned(path):
    """(scene, [warning messages])."""
    with warnings.catch_warnings(record=True) as record:
        warnings.simplefilter("always")
        scene = load_scene(path)
    return scene, [str(w.message) for w in record]


# -- every field ----------------------------------------------------------------------------------------
TT = {"KHR_texture_transform": {"offset": [0.25, -0.5], "rotation": 0.5, "scale": [2.0, 4.0]}}
LAYERED = {
    "name": "layered",
    "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}, "metallicFactor": 0.25, "roughnessFactor": 0.5},
    "extensions": {
        "KHR_materials_ior": {"ior": 1.45},
        "KHR_materials_specular": {"specularFactor": 0.7, "specularTexture": {"index": 0},
                                   "specularColorFactor": [1.5, 0.5, 0.25], "specularColorTexture": {"index": 0}},
        "KHR_materials_clearcoat": {"clearcoatFactor": 0.8, "clearcoatTexture": {"index": 1, "texCoord": 1},
                                    "clearcoatRoughnessFactor": 0.3,
                                    "clearcoatRoughnessTexture": {"index": 1, "extensions": TT},
                                    "clearcoatNormalTexture": {"index": 1, "scale": -0.5, "extensions": {
                                        "KHR_texture_transform": {"texCoord": 1}}}},
        "KHR_materials_sheen": {"sheenColorFactor": [0.2, 0.4, 0.6], "sheenColorTexture": {"index": 2},
                                "sheenRoughnessFactor": 0.5, "sheenRoughnessTexture": {"index": 2}},
        "KHR_materials_iridescence": {"iridescenceFactor": 0.9, "iridescenceTexture": {"index": 1},
                                      "iridescenceIor": 1.8, "iridescenceThicknessMinimum": 200,
                                      "iridescenceThicknessMaximum": 600,
                                      "iridescenceThicknessTexture": {"index": 0, "texCoord": 1}},
        "KHR_materials_anisotropy": {"anisotropyStrength": 0.6, "anisotropyRotation": 1.25,
                                     "anisotropyTexture": {"index": 1, "extensions": {
                                         "KHR_texture_transform": {"rotation": -0.75}}}},
    },
}


def test_every_extension_field(tmp_path):
    """Factors, texture indices, texCoord, transforms and colour spaces of every new slot: textures are
    shared per (image, wrap modes, sRGB) exactly as the core slots share them, so specular (linear) and
    specular colour (sRGB) of one image are two textures; the file loads without a warning."""
    imgs = [image(0), image(1)]
    textures = [{"source": 0}, {"source": 1}, {"source": 0, "sampler": 0}]
    path = write_gltf(tmp_path / "layered.gltf", [primitive(material=0, TEXCOORD_1=QUAD_UVS[::-1].copy())],
                      [LAYERED], images=imgs, textures=textures, samplers=[{"wrapS": 33071, "wrapT": 33071}],
                      extensionsUsed=SURFACE + ["KHR_texture_transform"], extensionsRequired=SURFACE)
    scene = load_quietly(path)
    m = scene.materials[0]
    # textures in order of first use: base colour img0 sRGB (0), specular img0 linear (1), clearcoat
    # img1 linear (2), sheen colour img0 clamp sRGB (3), sheen roughness img0 clamp linear (4)
    assert [(t.srgb, t.wrap_s) for t in scene.textures] == [(True, "repeat"), (False, "repeat"), (False, "repeat"),
                                                            (True, "clamp"), (False, "clamp")]
    for t, src in zip(scene.textures, (0, 0, 1, 0, 0)):
        np.testing.assert_array_equal(t.rgba, imgs[src])
    want = {"specular": 1, "specular_color": 0, "clearcoat": 2, "clearcoat_roughness": 2, "clearcoat_normal": 2,
            "sheen_color": 3, "sheen_roughness": 4, "iridescence": 2, "iridescence_thickness": 1, "anisotropy": 2,
            "diffuse_transmission": -1, "diffuse_transmission_color": -1}      # issue 38's slots: not given
    assert {s: getattr(m, f"{s}_texture") for s in EXT_TEXTURE_SLOTS} == want
    assert m.base_color_texture == 0
    uv = {s: getattr(m, f"{s}_uv") for s in EXT_TEXTURE_SLOTS}
    assert uv == {"specular": UVTransform(), "specular_color": UVTransform(), "clearcoat": UVTransform(1),
                  "clearcoat_roughness": UVTransform(0, (0.25, -0.5), 0.5, (2.0, 4.0)),
                  "clearcoat_normal": UVTransform(1), "sheen_color": UVTransform(), "sheen_roughness": UVTransform(),
                  "iridescence": UVTransform(), "iridescence_thickness": UVTransform(1),
                  "anisotropy": UVTransform(0, (0.0, 0.0), -0.75, (1.0, 1.0)),
                  "diffuse_transmission": UVTransform(), "diffuse_transmission_color": UVTransform()}
    assert (m.ior, m.specular_factor, m.specular_color) == (1.45, 0.7, (1.5, 0.5, 0.25))   # > 1 kept (spec)
    assert (m.clearcoat, m.clearcoat_roughness, m.clearcoat_normal_scale) == (0.8, 0.3, -0.5)
    assert (m.sheen_color, m.sheen_roughness) == ((0.2, 0.4, 0.6), 0.5)
    assert (m.iridescence, m.iridescence_ior, m.iridescence_thickness_min, m.iridescence_thickness_max) == \
        (0.9, 1.8, 200.0, 600.0)
    assert (m.anisotropy_strength, m.anisotropy_rotation) == (0.6, 1.25)
    assert m.layers == ALL_LAYERS
    assert set(m.layer_textures_used()) == set(EXT_TEXTURE_SLOTS[:10])    # issue 37's ten slots
    assert m.layer_textures_used()["clearcoat_roughness"] == (2, UVTransform(0, (0.25, -0.5), 0.5, (2.0, 4.0)))
    assert m.textures_used() == {"base_color": (0, UVTransform())}          # the base slots only
    # the base layer is read as before
    assert (m.metallic, m.roughness) == (0.25, 0.5)


@pytest.mark.parametrize("ext, layers", [
    ({}, set()),
    ({"KHR_materials_ior": {}, "KHR_materials_specular": {}, "KHR_materials_clearcoat": {},
      "KHR_materials_sheen": {}, "KHR_materials_iridescence": {}, "KHR_materials_anisotropy": {}}, set()),
    # the degenerate values of the issue: clearcoat 0 (its roughness alone does nothing), sheen colour 0,
    # specular 1 / white / IOR 1.5, iridescence 0, anisotropy 0: the base material itself
    ({"KHR_materials_ior": {"ior": 1.5},
      "KHR_materials_specular": {"specularFactor": 1, "specularColorFactor": [1, 1, 1]},
      "KHR_materials_clearcoat": {"clearcoatFactor": 0, "clearcoatRoughnessFactor": 0.5},
      "KHR_materials_sheen": {"sheenColorFactor": [0, 0, 0], "sheenRoughnessFactor": 1},
      "KHR_materials_iridescence": {"iridescenceFactor": 0, "iridescenceIor": 2},
      "KHR_materials_anisotropy": {"anisotropyStrength": 0, "anisotropyRotation": 1}}, set()),
    ({"KHR_materials_ior": {"ior": 1.0}}, {"specular"}),
    ({"KHR_materials_ior": {"ior": 0}}, {"specular"}),                       # the spec's special value
    ({"KHR_materials_specular": {"specularFactor": 0.5}}, {"specular"}),
    ({"KHR_materials_specular": {"specularColorFactor": [1, 1, 0.5]}}, {"specular"}),
    ({"KHR_materials_specular": {"specularColorTexture": {"index": 0}}}, {"specular"}),
    ({"KHR_materials_specular": {"specularTexture": {"index": 0}}}, {"specular"}),
    ({"KHR_materials_clearcoat": {"clearcoatFactor": 0.01}}, {"clearcoat"}),
    ({"KHR_materials_clearcoat": {"clearcoatTexture": {"index": 0}}}, set()),  # texture x factor 0
    ({"KHR_materials_sheen": {"sheenColorFactor": [0, 0, 0.1]}}, {"sheen"}),
    ({"KHR_materials_iridescence": {"iridescenceFactor": 0.5}}, {"iridescence"}),
    ({"KHR_materials_anisotropy": {"anisotropyStrength": 0.5}}, {"anisotropy"}),
    ({"KHR_materials_anisotropy": {"anisotropyRotation": 0.5}}, set()),
    ({"KHR_materials_unlit": {}, "KHR_materials_clearcoat": {"clearcoatFactor": 1}}, set()),   # unlit: none
])
def test_layers(tmp_path, ext, layers):
    path = write_gltf(tmp_path / "l.gltf", [primitive(material=0)], [{"name": "l", "extensions": ext}],
                      images=[image(4)], extensionsUsed=sorted(ext))
    m = load_quietly(path).materials[0]
    assert m.layers == frozenset(layers)


def test_extension_defaults(tmp_path):
    """An empty extension object gives its schema's defaults; no extension gives the same."""
    ext = {name: {} for name in SURFACE}
    path = write_gltf(tmp_path / "d.gltf", [primitive(material=0), primitive(material=1)],
                      [{"name": "empty", "extensions": ext}, {"name": "none"}], extensionsUsed=SURFACE)
    for m in load_quietly(path).materials:
        assert (m.ior, m.specular_factor, m.specular_color) == (1.5, 1.0, (1.0, 1.0, 1.0))
        assert (m.clearcoat, m.clearcoat_roughness, m.clearcoat_normal_scale) == (0.0, 0.0, 1.0)
        assert (m.sheen_color, m.sheen_roughness) == ((0.0, 0.0, 0.0), 0.0)
        assert (m.iridescence, m.iridescence_ior, m.iridescence_thickness_min, m.iridescence_thickness_max) == \
            (0.0, 1.3, 100.0, 400.0)
        assert (m.anisotropy_strength, m.anisotropy_rotation) == (0.0, 0.0)
        assert all(getattr(m, f"{s}_texture") == -1 and getattr(m, f"{s}_uv") == UVTransform()
                   for s in EXT_TEXTURE_SLOTS)
        assert m.layers == frozenset() and m.layer_textures_used() == {}


def test_still_unimplemented_extension_warns(tmp_path):
    """Only extensions clrender does not implement keep the "ignored" warning."""
    ext = {"KHR_materials_clearcoat": {"clearcoatFactor": 1}, "KHR_materials_volume_scatter": {}}
    path = write_gltf(tmp_path / "w.gltf", [primitive(material=0)], [{"extensions": ext}],
                      extensionsUsed=sorted(ext))
    _, messages = load_warned(path)
    assert len(messages) == 1 and "extension KHR_materials_volume_scatter" in messages[0], messages
    assert "ignored" in messages[0] and "clearcoat" not in messages[0]


# -- bad input: one warning, the value clamped or the default, the load goes on ---------------------------
def cc(**kw):
    return {"KHR_materials_clearcoat": kw}


BAD = [  # (extensions, {field: value loaded}, [substrings of each expected warning])
    (cc(clearcoatFactor=-0.5), {"clearcoat": 0.0},
     ["KHR_materials_clearcoat.clearcoatFactor -0.5 is out of its range [0.0, 1.0]: clamped to 0.0"]),
    (cc(clearcoatFactor=1.5), {"clearcoat": 1.0},
     ["clearcoatFactor 1.5 is out of its range [0.0, 1.0]: clamped to 1.0"]),
    (cc(clearcoatFactor=1, clearcoatRoughnessFactor=2), {"clearcoat_roughness": 1.0},
     ["clearcoatRoughnessFactor 2 is out of its range [0.0, 1.0]: clamped to 1.0"]),
    ({"KHR_materials_specular": {"specularFactor": -1}}, {"specular_factor": 0.0},
     ["KHR_materials_specular.specularFactor -1 is out of its range [0.0, 1.0]: clamped to 0.0"]),
    ({"KHR_materials_specular": {"specularColorFactor": [-1, 0.5, 3]}}, {"specular_color": (0.0, 0.5, 3.0)},
     ["specularColorFactor [-1, 0.5, 3] is out of its range >= 0.0: clamped to [0.0, 0.5, 3.0]"]),
    ({"KHR_materials_sheen": {"sheenColorFactor": [1.5, -0.25, 0.5]}}, {"sheen_color": (1.0, 0.0, 0.5)},
     ["KHR_materials_sheen.sheenColorFactor [1.5, -0.25, 0.5] is out of its range [0.0, 1.0]: "
      "clamped to [1.0, 0.0, 0.5]"]),
    ({"KHR_materials_sheen": {"sheenRoughnessFactor": 1.5}}, {"sheen_roughness": 1.0},
     ["sheenRoughnessFactor 1.5 is out of its range [0.0, 1.0]: clamped to 1.0"]),
    ({"KHR_materials_ior": {"ior": 0.5}}, {"ior": 1.0},
     ["KHR_materials_ior.ior 0.5 is out of its range >= 1.0 or exactly 0: clamped to 1.0"]),
    ({"KHR_materials_ior": {"ior": -2}}, {"ior": 1.0}, ["KHR_materials_ior.ior -2 is out of its range"]),
    ({"KHR_materials_iridescence": {"iridescenceFactor": 7}}, {"iridescence": 1.0},
     ["KHR_materials_iridescence.iridescenceFactor 7 is out of its range [0.0, 1.0]: clamped to 1.0"]),
    ({"KHR_materials_iridescence": {"iridescenceIor": 0.9}}, {"iridescence_ior": 1.0},
     ["iridescenceIor 0.9 is out of its range >= 1.0: clamped to 1.0"]),
    ({"KHR_materials_iridescence": {"iridescenceThicknessMinimum": -10}}, {"iridescence_thickness_min": 0.0},
     ["iridescenceThicknessMinimum -10 is out of its range >= 0.0: clamped to 0.0"]),
    ({"KHR_materials_iridescence": {"iridescenceThicknessMinimum": 500, "iridescenceThicknessMaximum": 300}},
     {"iridescence_thickness_min": 300.0, "iridescence_thickness_max": 300.0},
     ["iridescenceThicknessMinimum (500.0) is larger than iridescenceThicknessMaximum (300.0): "
      "the minimum is clamped to 300.0"]),
    ({"KHR_materials_iridescence": {"iridescenceThicknessMaximum": 50}},          # min keeps its default 100
     {"iridescence_thickness_min": 50.0, "iridescence_thickness_max": 50.0},
     ["iridescenceThicknessMinimum (100.0) is larger than iridescenceThicknessMaximum (50.0)"]),
    ({"KHR_materials_anisotropy": {"anisotropyStrength": -0.1}}, {"anisotropy_strength": 0.0},
     ["KHR_materials_anisotropy.anisotropyStrength -0.1 is out of its range [0.0, 1.0]: clamped to 0.0"]),
    # wrong JSON types: the schema's default
    (cc(clearcoatFactor="0.5"), {"clearcoat": 0.0},
     ["KHR_materials_clearcoat.clearcoatFactor must be a finite number, got '0.5': the default 0.0 is used"]),
    (cc(clearcoatFactor=float("nan")), {"clearcoat": 0.0},        # json writes NaN, Python's json reads it
     ["clearcoatFactor must be a finite number, got nan: the default 0.0 is used"]),
    ({"KHR_materials_ior": {"ior": True}}, {"ior": 1.5},
     ["KHR_materials_ior.ior must be a finite number, got True: the default 1.5 is used"]),
    ({"KHR_materials_anisotropy": {"anisotropyStrength": 1, "anisotropyRotation": None}},
     {"anisotropy_rotation": 0.0, "anisotropy_strength": 1.0},
     ["anisotropyRotation must be a finite number, got None"]),
    ({"KHR_materials_specular": {"specularColorFactor": [1, 1]}}, {"specular_color": (1.0, 1.0, 1.0)},
     ["specularColorFactor must be 3 finite numbers, got [1, 1]: the default [1.0, 1.0, 1.0] is used"]),
    ({"KHR_materials_sheen": {"sheenColorFactor": "red"}}, {"sheen_color": (0.0, 0.0, 0.0)},
     ["sheenColorFactor must be 3 finite numbers, got 'red'"]),
    ({"KHR_materials_clearcoat": 5}, {"clearcoat": 0.0},
     ["KHR_materials_clearcoat must be an object, got 5: the extension is ignored"]),
    (cc(clearcoatFactr=0.5), {"clearcoat": 0.0},
     ["KHR_materials_clearcoat: unknown properties ignored: 'clearcoatFactr'"]),
    # textures: a missing or ill-typed index drops the texture; ill-typed fields get their defaults
    (cc(clearcoatFactor=1, clearcoatTexture={"index": 9}), {"clearcoat_texture": -1, "clearcoat": 1.0},
     ["KHR_materials_clearcoat.clearcoatTexture.index 9 is not a texture of the file (there are 1): "
      "no texture is used"]),
    (cc(clearcoatFactor=1, clearcoatTexture={"index": "0"}), {"clearcoat_texture": -1},
     ["clearcoatTexture.index '0' is not a texture of the file"]),
    (cc(clearcoatFactor=1, clearcoatTexture={}), {"clearcoat_texture": -1},
     ["clearcoatTexture.index None is not a texture of the file"]),
    (cc(clearcoatFactor=1, clearcoatTexture=3), {"clearcoat_texture": -1},
     ["KHR_materials_clearcoat.clearcoatTexture must be an object, got 3: no texture is used"]),
    (cc(clearcoatFactor=1, clearcoatTexture={"index": 0, "texCoord": -1}),
     {"clearcoat_texture": 0, "clearcoat_uv": UVTransform()},
     ["KHR_materials_clearcoat.clearcoatTexture.texCoord must be an integer >= 0, got -1: 0 is used"]),
    ({"KHR_materials_sheen": {"sheenColorFactor": [1, 1, 1], "sheenRoughnessTexture": {
        "index": 0, "extensions": {"KHR_texture_transform": {"offset": [1], "rotation": "x", "scale": [3, 3]}}}}},
     {"sheen_roughness_texture": 0, "sheen_roughness_uv": UVTransform(0, (0.0, 0.0), 0.0, (3.0, 3.0))},
     ["KHR_materials_sheen.sheenRoughnessTexture.KHR_texture_transform.offset must be 2 finite numbers, got [1]: "
      "[0.0, 0.0] is used",
      "sheenRoughnessTexture.KHR_texture_transform.rotation must be a finite number, got 'x': 0.0 is used"]),
    (cc(clearcoatFactor=1, clearcoatNormalTexture={"index": 0, "scale": "big"}),
     {"clearcoat_normal_texture": 0, "clearcoat_normal_scale": 1.0},
     ["KHR_materials_clearcoat.clearcoatNormalTexture.scale must be a finite number, got 'big': 1.0 is used"]),
]


@pytest.mark.parametrize("ext, want, words", BAD, ids=[str(i) for i in range(len(BAD))])
def test_bad_values_warn_and_clamp(tmp_path, ext, want, words):
    path = write_gltf(tmp_path / "bad.gltf", [primitive(material=0)], [{"name": "bad", "extensions": ext}],
                      images=[image(5)], extensionsUsed=sorted(ext))
    scene, messages = load_warned(path)
    assert len(messages) == len(words), messages
    for msg, word in zip(messages, words):
        assert "\n" not in msg and msg.startswith(f"{path}: material 0 ('bad'): "), msg
        assert word in msg, (word, msg)
    m = scene.materials[0]
    assert {k: getattr(m, k) for k in want} == want


def test_ior_zero_is_not_clamped(tmp_path):
    path = write_gltf(tmp_path / "z.gltf", [primitive(material=0)], [{"extensions": {"KHR_materials_ior": {"ior": 0}}}],
                      extensionsUsed=["KHR_materials_ior"])
    assert load_quietly(path).materials[0].ior == 0.0


def test_layer_texture_missing_uv_set_fails(tmp_path):
    """A well-formed layer texture reading a TEXCOORD set the primitive lacks: the core slots' error."""
    mat = {"name": "m", "extensions": cc(clearcoatFactor=1, clearcoatRoughnessTexture={"index": 0, "texCoord": 1})}
    path = write_gltf(tmp_path / "uv.gltf", [primitive(material=0)], [mat], images=[image(6)],
                      extensionsUsed=["KHR_materials_clearcoat"])
    with pytest.raises(SceneError) as info:
        load_scene(path)
    msg = str(info.value)
    assert msg.startswith(str(path)) and "material 0 ('m')" in msg and "TEXCOORD_1" in msg
    assert "KHR_materials_clearcoat.clearcoatRoughnessTexture" in msg and "does not have" in msg


def test_failed_image_renumbers_layer_slots(tmp_path):
    """An image that cannot be read: its textures are left out (one warning) and the layer slots of the
    others are renumbered like the core slots."""
    mat = {"name": "m", "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}},
           "extensions": {"KHR_materials_sheen": {"sheenColorFactor": [1, 1, 1], "sheenColorTexture": {"index": 0},
                                                  "sheenRoughnessTexture": {"index": 1}}}}
    path = write_gltf(tmp_path / "f.gltf", [primitive(material=0)], [mat], images=[image(7), image(8)],
                      extensionsUsed=["KHR_materials_sheen"])
    (tmp_path / "f_image0.png").unlink()
    scene, messages = load_warned(path)
    assert len(messages) == 1 and "f_image0.png" in messages[0] and "sheenColorTexture" in messages[0], messages
    m = scene.materials[0]
    assert (m.base_color_texture, m.sheen_color_texture, m.sheen_roughness_texture) == (-1, -1, 0)
    assert len(scene.textures) == 1 and not scene.textures[0].srgb
    np.testing.assert_array_equal(scene.textures[0].rgba, image(8))


# -- extensionsRequired --------------------------------------------------------------------------------------
def test_required_surface_extensions_load(tmp_path):
    path = write_gltf(tmp_path / "r.gltf", extensionsUsed=SURFACE, extensionsRequired=SURFACE)
    assert load_quietly(path).triangle_count == 2


@pytest.mark.parametrize("name", ["KHR_materials_volume_scatter", "KHR_animation_pointer"])
def test_required_unimplemented_extension_fails(tmp_path, name):
    required = ["KHR_materials_clearcoat", name]
    path = write_gltf(tmp_path / "r.gltf", extensionsUsed=required, extensionsRequired=required)
    with pytest.raises(SceneError) as info:
        load_scene(path)
    msg = str(info.value)
    assert "\n" not in msg and msg.startswith(str(path))
    assert f"requires unsupported glTF extension(s) {name} (extensionsRequired" in msg
    assert "KHR_materials_clearcoat" not in msg.split("(")[0]          # the implemented one is not blamed


# -- the Material record (programmatic use) ---------------------------------------------------------------
def test_material_record_defaults_and_slots():
    m = Material.from_metallic_roughness("m", (1, 1, 1, 1), 0.0, 0.5)
    assert EXT_TEXTURE_SLOTS == ("specular", "specular_color", "clearcoat", "clearcoat_roughness", "clearcoat_normal",
                                 "sheen_color", "sheen_roughness", "iridescence", "iridescence_thickness",
                                 "anisotropy", "diffuse_transmission", "diffuse_transmission_color")
    assert m.layers == frozenset() and m.layer_textures_used() == {}
    t = Material.from_metallic_roughness("t", (1, 1, 1, 1), 0.0, 0.5, anisotropy_texture=3,
                                         anisotropy_uv=UVTransform(1), ior=1.5)
    assert t.layer_textures_used() == {"anisotropy": (3, UVTransform(1))} and t.layers == frozenset()
    assert t.textures_used() == {}
    # the Blinn-Phong model has no layers whatever its extension values
    assert Material(clearcoat=1.0, sheen_color=(1, 1, 1), ior=2.0).layers == frozenset()
    everything = Material.from_metallic_roughness(
        "e", (1, 1, 1, 1), 0.0, 0.5, clearcoat=0.5, sheen_color=(0, 0, 0.5), specular_color=(2.0, 1.0, 1.0),
        iridescence=0.25, anisotropy_strength=1.0)
    assert everything.layers == ALL_LAYERS and everything.specular_color == (2.0, 1.0, 1.0)


@pytest.mark.parametrize("kw, words", [
    ({"ior": 0.5}, ["ior", ">= 1 or exactly 0", "0.5"]),
    ({"ior": float("nan")}, ["ior", "nan"]),
    ({"specular_factor": 1.5}, ["specular_factor", "1.5"]),
    ({"specular_color": (-0.1, 1, 1)}, ["specular_color", "-0.1"]),
    ({"specular_color": (1, 1)}, ["specular_color", "3 finite numbers"]),
    ({"clearcoat": -0.25}, ["clearcoat", "-0.25"]),
    ({"clearcoat_roughness": 2}, ["clearcoat_roughness", "2"]),
    ({"clearcoat_normal_scale": float("inf")}, ["clearcoat_normal_scale", "inf"]),
    ({"sheen_color": (0.5, 1.5, 0)}, ["sheen_color", "1.5"]),
    ({"sheen_roughness": "0.5"}, ["sheen_roughness", "'0.5'"]),
    ({"iridescence": 3}, ["iridescence", "3"]),
    ({"iridescence_ior": 0.5}, ["iridescence_ior", "0.5"]),
    ({"iridescence_thickness_min": -1}, ["iridescence_thickness_min", "-1"]),
    ({"iridescence_thickness_min": 500.0}, ["iridescence_thickness_max (400.0)", "iridescence_thickness_min (500.0)"]),
    ({"anisotropy_strength": True}, ["anisotropy_strength", "True"]),
    ({"anisotropy_rotation": float("nan")}, ["anisotropy_rotation", "nan"]),
    ({"sheen_color_texture": -2}, ["sheen_color_texture", "-2"]),
    ({"clearcoat_normal_texture": 1.0}, ["clearcoat_normal_texture", "1.0"]),
    ({"iridescence_thickness_uv": (0, 1)}, ["iridescence_thickness_uv", "UVTransform"]),
])
def test_material_record_rejects_bad_values(kw, words):
    with pytest.raises(SceneError) as info:
        Material.from_metallic_roughness("rec", (1, 1, 1, 1), 0.0, 0.5, **kw)
    msg = str(info.value)
    assert msg.startswith("material 'rec': ")
    for word in words:
        assert word in msg, (word, msg)
