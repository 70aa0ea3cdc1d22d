"""The see-through glTF extensions at the loader level (issue 38; docs/transmission.md).

KHR_materials_transmission, _volume, _dispersion and _diffuse_transmission into `Material`'s fields
(factors, textures with their slots, texCoord, KHR_texture_transform and sRGB flags), the derived
predicates (`transmissive`, `see_through`, `has_volume`, the "diffuse_transmission" layer), the
bad-input rule (one warning naming the file and the material, the schema's default or range used, the
load goes on), the dependencies (a volume needs transmission or diffuse transmission, a dispersion a
volume) and `SceneObject.volume_scale` (KHR_materials_volume: "thickness is given in the coordinate
space of the mesh; any transformations applied to the mesh's node will also be applied"). Expected
values are literals written from the extensions' READMEs and schemas (KhronosGroup/glTF,
extensions/2.0/Khronos/KHR_materials_*) and, for volume_scale, NumPy determinants of matrices built here
from the written TRS values. No rendering.
"""
from __future__ import annotations

import base64
import math
import os
import sys
import warnings

import numpy as np
import pytest

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from gltf_files import QUAD_UVS, primitive, write_gltf  # noqa: E402

from clrender.loaders import load_scene  # noqa: E402
from clrender.loaders.gltf.spec import SUPPORTED_EXTENSIONS  # noqa: E402
from clrender.passes.fragments import transparent_triangle_count  # noqa: E402
from clrender.scene.material import EXT_TEXTURE_SLOTS, LAYERS, TX_TEXTURE_SLOTS  # noqa: E402
from clrender.scene.model import Material, Scene, SceneError, SceneObject, Texture, UVTransform  # noqa: E402

SEE_THROUGH = ["KHR_materials_transmission", "KHR_materials_volume", "KHR_materials_dispersion",
               "KHR_materials_diffuse_transmission"]
INF = float("inf")


def image(seed: int, h: int = 4, w: int = 8) -> np.ndarray:
    return np.random.default_rng(seed).integers(0, 256, (h, w, 4), dtype=np.uint8)


def load_quietly(path):
    """Load, failing on any warning (an "extension ignored" warning included)."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        return load_scene(path)


def load_warned(path):
    with warnings.catch_warnings(record=True) as record:
        warnings.simplefilter("always")
        scene = load_scene(path)
    return scene, [str(w.message) for w in record]


# -- every field --------------------------------------------------------------------------------------------
GLASS = {
    "name": "glass",
    "pbrMetallicRoughness": {"baseColorFactor": [0.9, 1.0, 0.8, 1.0], "metallicFactor": 0.0, "roughnessFactor": 0.1},
    "extensions": {
        "KHR_materials_ior": {"ior": 1.45},
        "KHR_materials_transmission": {"transmissionFactor": 0.8, "transmissionTexture": {"index": 0, "texCoord": 1}},
        "KHR_materials_volume": {"thicknessFactor": 0.25, "attenuationDistance": 0.5,
                                 "attenuationColor": [0.9, 0.5, 0.25],
                                 "thicknessTexture": {"index": 1, "extensions": {"KHR_texture_transform": {
                                     "offset": [0.5, 0.25], "rotation": 0.75, "scale": [2.0, 3.0]}}}},
        "KHR_materials_dispersion": {"dispersion": 0.36},
        "KHR_materials_diffuse_transmission": {"diffuseTransmissionFactor": 0.3,
                                               "diffuseTransmissionTexture": {"index": 0},
                                               "diffuseTransmissionColorFactor": [1.0, 0.9, 0.85],
                                               "diffuseTransmissionColorTexture": {"index": 0, "texCoord": 1}},
    },
}


def test_every_field(tmp_path):
    """Factors, texture slots (texCoord, transform) and colour spaces: the diffuse transmission colour
    texture is sRGB (its README), the other three linear, so image 0 read as both is two textures; the
    alphaMode stays OPAQUE (transmission is not alpha: its README's "Blend Mode") and the file loads
    without a warning."""
    imgs = [image(0), image(1)]
    used = SEE_THROUGH + ["KHR_materials_ior", "KHR_texture_transform"]
    path = write_gltf(tmp_path / "glass.gltf", [primitive(material=0, TEXCOORD_1=QUAD_UVS[::-1].copy())], [GLASS],
                      images=imgs, extensionsUsed=used, extensionsRequired=SEE_THROUGH)
    scene = load_quietly(path)
    m = scene.materials[0]
    # first use, in slot order: diffuse transmission img0 linear (0), its colour img0 sRGB (1),
    # transmission img0 linear (0 again), thickness img1 linear (2)
    assert [t.srgb for t in scene.textures] == [False, True, False]
    for t, src in zip(scene.textures, (0, 0, 1)):
        np.testing.assert_array_equal(t.rgba, imgs[src])
    assert (m.diffuse_transmission_texture, m.diffuse_transmission_color_texture) == (0, 1)
    assert (m.transmission_texture, m.thickness_texture) == (0, 2)
    assert (m.transmission_uv, m.thickness_uv) == (UVTransform(1), UVTransform(0, (0.5, 0.25), 0.75, (2.0, 3.0)))
    assert (m.diffuse_transmission_uv, m.diffuse_transmission_color_uv) == (UVTransform(), UVTransform(1))
    assert (m.transmission, m.thickness, m.attenuation_distance, m.attenuation_color) == \
        (0.8, 0.25, 0.5, (0.9, 0.5, 0.25))
    assert (m.dispersion, m.ior) == (0.36, 1.45)
    assert (m.diffuse_transmission, m.diffuse_transmission_color) == (0.3, (1.0, 0.9, 0.85))
    assert m.alpha_mode == "OPAQUE"
    assert m.transmissive and m.see_through and m.has_volume
    assert m.layers == {"specular", "diffuse_transmission"}          # ior 1.45 is a specular layer (issue 37)
    assert m.tx_textures_used() == {"transmission": (0, UVTransform(1)),
                                    "thickness": (2, UVTransform(0, (0.5, 0.25), 0.75, (2.0, 3.0)))}
    layer = m.layer_textures_used()
    assert layer == {"diffuse_transmission": (0, UVTransform()), "diffuse_transmission_color": (1, UVTransform(1))}
    # the transparent-fragment path counts its triangles; the stats line counts it as transparent
    assert transparent_triangle_count(scene) == 2
    assert scene.summary()["transparent_materials"] == 1


def test_defaults_when_absent(tmp_path):
    """Without the extensions every field is the schemas' default and nothing is see-through."""
    path = write_gltf(tmp_path / "plain.gltf", [primitive(material=0)], [{"name": "plain"}])
    m = load_quietly(path).materials[0]
    want = {"transmission": 0.0, "transmission_texture": -1, "thickness": 0.0, "thickness_texture": -1,
            "attenuation_distance": INF, "attenuation_color": (1.0, 1.0, 1.0), "dispersion": 0.0,
            "diffuse_transmission": 0.0, "diffuse_transmission_texture": -1,
            "diffuse_transmission_color": (1.0, 1.0, 1.0), "diffuse_transmission_color_texture": -1}
    assert {k: getattr(m, k) for k in want} == want
    assert {k: getattr(Material(), k) for k in want} == want
    assert not (m.transmissive or m.see_through or m.has_volume)
    assert m.layers == frozenset() and m.tx_textures_used() == {} and m.layer_textures_used() == {}
    assert all(getattr(m, f"{s}_uv") == UVTransform() for s in TX_TEXTURE_SLOTS + EXT_TEXTURE_SLOTS)


def test_extension_tables():
    assert set(SEE_THROUGH) <= SUPPORTED_EXTENSIONS
    assert TX_TEXTURE_SLOTS == ("transmission", "thickness")            # MaterialTx's slots, in order
    assert EXT_TEXTURE_SLOTS[-2:] == ("diffuse_transmission", "diffuse_transmission_color")   # XSLOT 10, 11
    assert len(EXT_TEXTURE_SLOTS) == 12 and LAYERS[-1] == "diffuse_transmission"


def test_required_see_through_extensions_load(tmp_path):
    """Listed in extensionsRequired and extensionsUsed, on a material or not: no refusal, no warning."""
    path = write_gltf(tmp_path / "r.gltf", extensionsUsed=SEE_THROUGH, extensionsRequired=SEE_THROUGH)
    assert load_quietly(path).triangle_count == 2


# -- bad input: one warning naming the file and the material, the default (or the range), the load goes on ----
def tx(**kw):
    return {"KHR_materials_transmission": {"transmissionFactor": 1.0, **kw}}


def vol(**kw):
    return {**tx(), "KHR_materials_volume": kw}


VOLUME_DEFAULTS = {"thickness": 0.0, "attenuation_distance": INF, "attenuation_color": (1.0, 1.0, 1.0)}
BAD = [  # (extensions, {field: value loaded}, [substrings of each expected warning, in order])
    (vol(thicknessFactor=-1), {"thickness": 0.0},
     ["KHR_materials_volume.thicknessFactor -1 is out of its range >= 0.0: clamped to 0.0"]),
    (vol(thicknessFactor="thick"), {"thickness": 0.0},
     ["KHR_materials_volume.thicknessFactor must be a finite number, got 'thick': the default 0.0 is used"]),
    (vol(thicknessFactor=None, attenuationDistance=2), {"thickness": 0.0, "attenuation_distance": 2.0},
     ["thicknessFactor must be a finite number, got None: the default 0.0 is used"]),
    (vol(thicknessFactor=1, attenuationDistance=0), {"thickness": 1.0, "attenuation_distance": INF},
     ["KHR_materials_volume.attenuationDistance 0 is out of its range > 0.0: the default inf is used"]),
    (vol(thicknessFactor=1, attenuationDistance=-2.5), {"attenuation_distance": INF},
     ["attenuationDistance -2.5 is out of its range > 0.0: the default inf is used"]),
    (vol(attenuationDistance=[1]), {"attenuation_distance": INF},
     ["attenuationDistance must be a finite number, got [1]: the default inf is used"]),
    (vol(attenuationColor=[2, 0.5, -1]), {"attenuation_color": (1.0, 0.5, 0.0)},
     ["attenuationColor [2, 0.5, -1] is out of its range [0.0, 1.0]: clamped to [1.0, 0.5, 0.0]"]),
    (vol(attenuationColor=[1, 1]), {"attenuation_color": (1.0, 1.0, 1.0)},
     ["attenuationColor must be 3 finite numbers, got [1, 1]: the default [1.0, 1.0, 1.0] is used"]),
    (tx(transmissionFactor=1.5), {"transmission": 1.0},
     ["KHR_materials_transmission.transmissionFactor 1.5 is out of its range [0.0, 1.0]: clamped to 1.0"]),
    (tx(transmissionFactor=True), {"transmission": 0.0},
     ["transmissionFactor must be a finite number, got True: the default 0.0 is used"]),
    (tx(thickness=1), {"transmission": 1.0},
     ["KHR_materials_transmission: unknown properties ignored: 'thickness'"]),
    (tx(transmissionTexture={"index": 7}), {"transmission_texture": -1},
     ["KHR_materials_transmission.transmissionTexture.index 7 is not a texture of the file (there are 0): "
      "no texture is used"]),
    # IOR < 1 other than the README's special value 0: clamped to 1 (issue 37's rule, kept); 0 is kept
    ({**tx(), "KHR_materials_ior": {"ior": 0.5}}, {"ior": 1.0},
     ["KHR_materials_ior.ior 0.5 is out of its range >= 1.0 or exactly 0: clamped to 1.0"]),
    ({**tx(), "KHR_materials_ior": {"ior": 0}}, {"ior": 0.0}, []),
    # a volume needs transmission (or diffuse transmission): without, it is ignored, texture included
    ({"KHR_materials_volume": {"thicknessFactor": 2, "attenuationDistance": 1, "thicknessTexture": {"index": 7}}},
     VOLUME_DEFAULTS | {"thickness_texture": -1},
     ["KHR_materials_volume without KHR_materials_transmission or KHR_materials_diffuse_transmission "
      "(a volume needs light through its surface): the extension is ignored, the material is thin-walled"]),
    ({"KHR_materials_transmission": 3, "KHR_materials_volume": {"thicknessFactor": 2}}, VOLUME_DEFAULTS,
     ["KHR_materials_transmission must be an object, got 3: the extension is ignored",
      "KHR_materials_volume without KHR_materials_transmission"]),
    # a dispersion needs a volume: without (or with an ignored one), it is ignored
    ({**tx(), "KHR_materials_dispersion": {"dispersion": 0.5}}, {"dispersion": 0.0},
     ["KHR_materials_dispersion without KHR_materials_volume (dispersion applies to a volume): the extension is "
      "ignored, no dispersion"]),
    ({"KHR_materials_volume": {"thicknessFactor": 1}, "KHR_materials_dispersion": {"dispersion": 0.5}},
     VOLUME_DEFAULTS | {"dispersion": 0.0},
     ["KHR_materials_volume without", "KHR_materials_dispersion without KHR_materials_volume"]),
    ({**vol(thicknessFactor=1), "KHR_materials_dispersion": {"dispersion": -1}}, {"dispersion": 0.0},
     ["KHR_materials_dispersion.dispersion -1 is out of its range >= 0.0: clamped to 0.0"]),
    ({"KHR_materials_diffuse_transmission": {"diffuseTransmissionFactor": 2,
                                             "diffuseTransmissionColorFactor": [1.5, 0.5, 0]}},
     {"diffuse_transmission": 1.0, "diffuse_transmission_color": (1.0, 0.5, 0.0)},
     ["diffuseTransmissionFactor 2 is out of its range [0.0, 1.0]: clamped to 1.0",
      "diffuseTransmissionColorFactor [1.5, 0.5, 0] is out of its range [0.0, 1.0]: clamped to [1.0, 0.5, 0.0]"]),
]


@pytest.mark.parametrize("ext, want, expected", BAD, ids=[f"bad{i}" for i in range(len(BAD))])
def test_bad_input_warns_once_and_loads(tmp_path, ext, want, expected):
    path = write_gltf(tmp_path / "bad.gltf", [primitive(material=0)], [{"name": "bad", "extensions": ext}],
                      extensionsUsed=sorted(ext))
    scene, messages = load_warned(path)
    assert len(messages) == len(expected), messages
    for msg, part in zip(messages, expected):
        assert "\n" not in msg and msg.startswith(f"{path}: material 0 ('bad'): "), msg
        assert part in msg, (part, msg)
    m = scene.materials[0]
    assert {k: getattr(m, k) for k in want} == want
    assert scene.triangle_count == 2


def test_volume_with_diffuse_transmission_only(tmp_path):
    """Diffuse transmission is a transmitting extension too (the volume README's "Dependencies", the
    diffuse transmission README's "KHR_materials_volume"): the volume loads without a warning, but the
    material is not transmissive, so it has no see-through volume."""
    ext = {"KHR_materials_diffuse_transmission": {"diffuseTransmissionFactor": 0.5},
           "KHR_materials_volume": {"thicknessFactor": 1.5, "attenuationDistance": 2}}
    path = write_gltf(tmp_path / "dt.gltf", [primitive(material=0)], [{"extensions": ext}], extensionsUsed=sorted(ext))
    m = load_quietly(path).materials[0]
    assert (m.thickness, m.attenuation_distance, m.diffuse_transmission) == (1.5, 2.0, 0.5)
    assert not (m.transmissive or m.has_volume or m.see_through)
    assert m.layers == {"diffuse_transmission"}


def test_texture_reading_a_missing_texcoord_fails(tmp_path):
    """The new slots are held to the core rule: a texture reading a TEXCOORD set the primitive lacks is
    an error naming the primitive, the material and the slot (as the glTF validator's)."""
    mat = {"name": "t", "extensions": tx(transmissionTexture={"index": 0, "texCoord": 1})}
    path = write_gltf(tmp_path / "uv.gltf", [primitive(material=0)], [mat], images=[image(2)])
    with pytest.raises(SceneError) as info:
        load_scene(path)
    assert "KHR_materials_transmission.transmissionTexture from TEXCOORD_1" in str(info.value)


def test_failed_image_renumbers_the_new_slots(tmp_path):
    """An image that cannot be read drops its textures with one warning; the other slots' indices move
    down (the transmission and volume slots included)."""
    ext = {**tx(transmissionTexture={"index": 1}),
           "KHR_materials_volume": {"thicknessFactor": 1, "thicknessTexture": {"index": 0}},
           "KHR_materials_diffuse_transmission": {"diffuseTransmissionTexture": {"index": 1},
                                                  "diffuseTransmissionColorTexture": {"index": 0}}}
    path = write_gltf(tmp_path / "img.gltf", [primitive(material=0)], [{"name": "m", "extensions": ext}],
                      images=[image(3), image(4)])
    os.remove(tmp_path / "img_image1.png")
    scene, messages = load_warned(path)
    assert len(messages) == 1 and "img_image1.png" in messages[0], messages
    m = scene.materials[0]
    # made in slot order: dt img1 (0, lost), dt colour img0 sRGB (1 -> 0), transmission img1 (0, lost),
    # thickness img0 linear (2 -> 1)
    assert (m.diffuse_transmission_texture, m.diffuse_transmission_color_texture) == (-1, 0)
    assert (m.transmission_texture, m.thickness_texture) == (-1, 1)
    assert [t.srgb for t in scene.textures] == [True, False]


# -- the Material record (programmatic use) ---------------------------------------------------------------
def gltf(**kw) -> Material:
    return Material.from_metallic_roughness("m", (1, 1, 1, 1), 0.0, 0.5, **kw)


def test_predicates():
    assert not gltf(transmission=0.0).transmissive                       # transmission 0: the opaque material
    assert not gltf(transmission=0.0, transmission_texture=0).transmissive   # a texture only multiplies
    assert gltf(transmission=1e-6).transmissive
    assert not Material(transmission=1.0).transmissive                   # Blinn-Phong: no glTF BRDF
    assert not gltf(transmission=1.0, unlit=True).transmissive           # the README's exclusion
    assert Material(alpha_mode="BLEND").see_through and Material(opacity=0.5).see_through
    assert gltf(transmission=0.5).see_through and not gltf().see_through
    assert not gltf(transmission=0.5).has_volume                         # thickness 0: thin-walled
    assert gltf(transmission=0.5, thickness=0.1).has_volume
    assert not gltf(transmission=0.0, thickness=0.1).has_volume
    assert gltf(diffuse_transmission=0.25).layers == {"diffuse_transmission"}
    assert gltf(diffuse_transmission=0.0, diffuse_transmission_texture=0).layers == frozenset()
    assert Material(diffuse_transmission=1.0).layers == frozenset()
    assert gltf(diffuse_transmission=1.0, unlit=True).layers == frozenset()
    assert gltf(attenuation_distance=INF).attenuation_distance == INF
    assert gltf(transmission_texture=3, thickness_texture=4, thickness_uv=UVTransform(1)).tx_textures_used() == \
        {"transmission": (3, UVTransform()), "thickness": (4, UVTransform(1))}


@pytest.mark.parametrize("kw, field", [
    ({"transmission": 1.5}, "transmission"), ({"transmission": -0.1}, "transmission"),
    ({"transmission": math.nan}, "transmission"), ({"thickness": -1.0}, "thickness"),
    ({"thickness": INF}, "thickness"), ({"thickness": "1"}, "thickness"),
    ({"attenuation_distance": 0.0}, "attenuation_distance"), ({"attenuation_distance": -1}, "attenuation_distance"),
    ({"attenuation_distance": math.nan}, "attenuation_distance"),
    ({"attenuation_distance": "far"}, "attenuation_distance"), ({"attenuation_distance": True}, "attenuation_distance"),
    ({"attenuation_color": (1.5, 0, 0)}, "attenuation_color"), ({"attenuation_color": (1, 1)}, "attenuation_color"),
    ({"dispersion": -1.0}, "dispersion"), ({"dispersion": INF}, "dispersion"),
    ({"diffuse_transmission": 2.0}, "diffuse_transmission"),
    ({"diffuse_transmission_color": (-0.1, 0, 0)}, "diffuse_transmission_color"),
    ({"transmission_texture": -2}, "transmission_texture"), ({"thickness_texture": 1.0}, "thickness_texture"),
    ({"diffuse_transmission_color_texture": -3}, "diffuse_transmission_color_texture"),
    ({"thickness_uv": (0, 0)}, "thickness_uv"),
])
def test_material_validation(kw, field):
    with pytest.raises(SceneError) as info:
        gltf(**kw)
    msg = str(info.value)
    assert "\n" not in msg and msg.startswith("material 'm': ") and field in msg, msg


def test_scene_checks_tx_textures():
    """Scene validation covers the transmission slots: a missing texture, an absent uv set."""
    tri = dict(vertices=[[0, 0, 0], [1, 0, 0], [0, 1, 0]], faces=[[0, 1, 2]])
    with pytest.raises(SceneError, match=r"references missing texture 2 \(thickness\)"):
        Scene.from_arrays(**tri, material=gltf(transmission=1.0, thickness_texture=2))
    scene = Scene.from_arrays(**tri)
    scene.materials = [gltf(transmission=1.0, transmission_texture=0, transmission_uv=UVTransform(1))]
    scene.textures = [Texture("t", image(5))]
    with pytest.raises(SceneError, match="reads transmission from TEXCOORD_1"):
        scene.validate()


# -- volume_scale: the node's scale for thickness ---------------------------------------------------------------
def _trs(t=(0, 0, 0), q=(0, 0, 0, 1), s=(1, 1, 1)) -> np.ndarray:
    """T·R·S (glTF node order), float64, R from the unit quaternion (x, y, z, w) by its textbook formula."""
    x, y, z, w = np.asarray(q, np.float64) / np.linalg.norm(q)
    r = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                  [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                  [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
    m = np.eye(4)
    m[:3, :3] = r @ np.diag(np.asarray(s, np.float64))
    m[:3, 3] = t
    return m


def test_volume_scale_of_nodes(tmp_path):
    """|det|^(1/3) of each drawn node's world 3x3: a uniform scale 2 gives 2, (1, 2, 4) gives 2, a mirror
    (-2, 1, 1) gives 2^(1/3); a parent's scale composes; an unscaled node gives 1."""
    q = [0.0, math.sin(0.4), 0.0, math.cos(0.4)]
    nodes = [{"name": "uniform", "mesh": 0, "scale": [2, 2, 2]},
             {"name": "stretched", "mesh": 0, "scale": [1, 2, 4], "rotation": q},
             {"name": "mirror", "mesh": 0, "scale": [-2, 1, 1]},
             {"name": "parent", "scale": [0.5, 0.5, 0.5], "translation": [3, 0, 0], "children": [4]},
             {"name": "child", "mesh": 0, "rotation": q, "scale": [3, 3, 3]},
             {"name": "plain", "mesh": 0, "translation": [5, 5, 5]},
             {"name": "matrix", "mesh": 0, "matrix": (_trs((1, 2, 3), q, (1, 1, 8))).T.reshape(-1).tolist()}]
    path = write_gltf(tmp_path / "nodes.gltf", nodes=nodes)
    scene = load_quietly(path)
    got = {o.name: o.volume_scale for o in scene.objects}
    world = {"uniform": _trs(s=(2, 2, 2)), "stretched": _trs(q=q, s=(1, 2, 4)), "mirror": _trs(s=(-2, 1, 1)),
             "child": _trs(t=(3, 0, 0), s=(0.5, 0.5, 0.5)) @ _trs(q=q, s=(3, 3, 3)), "plain": _trs(t=(5, 5, 5)),
             "matrix": _trs((1, 2, 3), q, (1, 1, 8))}
    want = {k: abs(np.linalg.det(m[:3, :3])) ** (1 / 3) for k, m in world.items()}
    assert set(got) == set(want)
    for k in want:
        assert got[k] == pytest.approx(want[k], rel=1e-12), k
    # the literal values the issue names
    assert got["uniform"] == pytest.approx(2.0) and got["stretched"] == pytest.approx(2.0)
    assert got["child"] == pytest.approx(1.5) and got["plain"] == 1.0 and got["matrix"] == pytest.approx(2.0)
    assert got["mirror"] == pytest.approx(2 ** (1 / 3))


def test_volume_scale_of_instances(tmp_path):
    """EXT_mesh_gpu_instancing: node world · instance T·R·S per instance object."""
    scales = np.array([[1, 1, 1], [1, 2, 4], [0.5, 0.5, 0.5]], np.float32)
    rotations = np.array([[0, 0, 0, 1], [0, 0, math.sin(0.3), math.cos(0.3)], [math.sin(1), 0, 0, math.cos(1)]],
                         np.float32)

    def edit(doc):
        buf = doc["buffers"][0]
        blob = bytearray(base64.b64decode(buf["uri"].split(",", 1)[1]))
        attrs = {}
        for name, a in (("SCALE", scales), ("ROTATION", rotations)):
            blob.extend(b"\0" * (-len(blob) % 4))
            doc["bufferViews"].append({"buffer": 0, "byteOffset": len(blob), "byteLength": a.nbytes})
            blob.extend(a.tobytes())
            doc["accessors"].append({"bufferView": len(doc["bufferViews"]) - 1, "componentType": 5126,
                                     "count": len(a), "type": f"VEC{a.shape[1]}"})
            attrs[name] = len(doc["accessors"]) - 1
        buf["uri"] = "data:application/octet-stream;base64," + base64.b64encode(bytes(blob)).decode()
        buf["byteLength"] = len(blob)
        doc["nodes"][0]["extensions"] = {"EXT_mesh_gpu_instancing": {"attributes": attrs}}
        doc["extensionsUsed"] = ["EXT_mesh_gpu_instancing"]

    path = write_gltf(tmp_path / "inst.gltf", nodes=[{"name": "grove", "mesh": 0, "scale": [2, 2, 2]}], edit=edit)
    scene = load_quietly(path)
    assert [o.name for o in scene.objects] == ["grove#0", "grove#1", "grove#2"]
    want = [abs(np.linalg.det((_trs(s=(2, 2, 2)) @ _trs(q=q, s=s))[:3, :3])) ** (1 / 3)
            for q, s in zip(rotations.astype(np.float64), scales.astype(np.float64))]
    np.testing.assert_allclose([o.volume_scale for o in scene.objects], want, rtol=1e-6)
    np.testing.assert_allclose(want, [2.0, 4.0, 1.0], rtol=1e-6)


def test_volume_scale_of_a_flattening_node(tmp_path):
    """A node that flattens its mesh (scale 0 on an axis: det 0) has no length scale: 1 (documented)."""
    path = write_gltf(tmp_path / "flat.gltf", nodes=[{"name": "flat", "mesh": 0, "scale": [1, 1, 0]}])
    assert load_quietly(path).objects[0].volume_scale == 1.0


@pytest.mark.parametrize("bad", [0, -1.0, math.nan, INF, "2", True, None])
def test_scene_object_volume_scale_validation(bad):
    assert SceneObject("a", "m", "a").volume_scale == 1.0
    assert SceneObject("a", "m", "a", volume_scale=np.float32(2.5)).volume_scale == 2.5
    with pytest.raises(SceneError) as info:
        SceneObject("a", "m", "a", volume_scale=bad)
    assert str(info.value).startswith("object 'a': volume_scale must be a finite number > 0")
