"""The see-through extensions' device records and resources (clrender/render/scene_upload.py, issue 38;
docs/transmission.md): Material.flags/tx/door_alpha, MaterialTx rows, the diffuse-transmission fields of
MaterialExt, the slots' textures and decode tables, the Blinn-Phong records, the upload's
transmission resources (absent without a transmissive material), tri_volume_scale from the objects'
volume scales, and the screen door, which keeps the fraction 1 - transmission·(1 - metallic) of a
transmissive surface. Expectations are literals written from the extensions' READMEs and design.md.
"""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from test_screen_door import screen_door_mask
from transparency_cases import build_scene, quad

from clrender import Camera, Material, Scene
from clrender.abi import structs
from clrender.device.core import Device
from clrender.render import scene_upload as scene_gpu
from clrender.render.texture_pool import pool_layout
from clrender.scene.model import SceneObject, Texture, UVTransform

F32 = np.float32
BRDF = structs.MAT_METALLIC_ROUGHNESS | structs.MAT_GLTF_BRDF
SEE = structs.MAT_BLEND | structs.MAT_TRANSMISSION
UV_T = UVTransform(1, (0.5, 0.25), 0.3, (2.0, 3.0))


def texture(name, srgb, seed):
    rgba = np.random.default_rng(seed).integers(0, 256, (4, 4, 4), dtype=np.uint8)
    return Texture(name, rgba, srgb=srgb)


def materials():
    """glass (volume, dispersion, textures), thin (no volume: its volume values must not reach the
    device), leaf (diffuse transmission only), plain, alpha-BLEND glass, and two with a transmission
    factor that is no glTF-BRDF transmission (Blinn-Phong, unlit)."""
    mr = Material.from_metallic_roughness
    return [
        mr("glass", (0.9, 0.8, 0.7, 1.0), 0.2, 0.1, transmission=0.75, transmission_texture=0, transmission_uv=UV_T,
           thickness=0.4, thickness_texture=1, attenuation_distance=2.5, attenuation_color=(0.9, 0.5, 0.25),
           dispersion=0.6, ior=1.4, specular_factor=0.8, specular_color=(1.0, 0.9, 0.8)),
        mr("thin", (1.0, 1.0, 1.0, 1.0), 0.0, 0.0, transmission=0.5, thickness_texture=1, dispersion=0.6,
           attenuation_color=(0.5, 0.5, 0.5)),
        mr("leaf", (0.2, 0.6, 0.1, 1.0), 0.0, 0.5, diffuse_transmission=0.6, diffuse_transmission_color=(0.2, 0.8, 0.1),
           diffuse_transmission_texture=1, diffuse_transmission_color_texture=2,
           diffuse_transmission_color_uv=UVTransform(1)),
        mr("plain", (0.5, 0.5, 0.5, 1.0), 0.5, 0.5),
        mr("blend glass", (1.0, 1.0, 1.0, 0.5), 0.0, 0.2, alpha_mode="BLEND", transmission=1.0),
        Material("phong", transmission=0.8),
        mr("unlit", (1.0, 1.0, 1.0, 1.0), 0.0, 0.5, unlit=True, transmission=0.8),
    ]


def records_scene(objects=None):
    """One triangle per material (triangle i: material i), textures: transmission / thickness
    images linear (0, 1), the diffuse-transmission colour image sRGB (2)."""
    mats = materials()
    n = len(mats)
    pos = np.tile(np.array([[0, 0, -2], [1, 0, -2], [0, 1, -2]], np.float64), (n, 1))
    texs = [texture("t", False, 0), texture("d", False, 1), texture("c", True, 2)]
    kw = {}
    if objects is not None:
        kw = dict(mesh_names=[f"m{k}" for k in range(n)], triangle_mesh=np.arange(n), objects=objects,
                  mesh_object=np.arange(n))
    return Scene(pos, np.tile([0.0, 0.0, 1.0], (3 * n, 1)), np.zeros((3 * n, 2)), np.arange(3 * n).reshape(-1, 3),
                 np.arange(n), mats, textures=texs, extra_uvs=np.zeros((1, 3 * n, 2)), **kw)


def test_material_records():
    scene = records_scene()
    textures, records = scene_gpu.device_materials(scene)
    layers = scene_gpu.layer_records(scene, records)
    tx = scene_gpu.tx_records(scene, records)
    blend = 4
    want_flags = [BRDF | SEE, BRDF | SEE, BRDF, BRDF, BRDF | SEE | structs.MAT_TX_ALPHA, 0, structs.MAT_METALLIC_ROUGHNESS | structs.MAT_UNLIT]
    assert records["flags"].tolist() == [f | structs.MAT_DOUBLE_SIDED for f in want_flags]   # Material's default
    assert records["tx"].tolist() == [0, 1, -1, -1, 2, -1, -1]
    # door_alpha = 1 - transmission (1 - metallic): 1 - 0.75·0.8, 1 - 0.5, 1 - 1
    np.testing.assert_array_equal(records["door_alpha"], F32([0.4, 0.5, 1, 1, 0.0, 1, 1]))
    assert records["base_color"][blend, 3] == F32(0.5)              # coverage stays the alpha
    assert len(tx) == 3
    g = tx[0]
    assert (g["transmission"], g["thickness"], g["attenuation_distance"], g["dispersion"]) == \
        (F32(0.75), F32(0.4), F32(2.5), F32(0.6))
    np.testing.assert_array_equal(g["attenuation_color"], F32([0.9, 0.5, 0.25]))
    assert (g["ior"], g["specular_factor"]) == (F32(1.4), F32(0.8))
    np.testing.assert_array_equal(g["specular_color"], F32([1.0, 0.9, 0.8]))
    assert g["slots"]["texture"].tolist() == [0, 1] and g["slots"]["texcoord"].tolist() == [1, 0]
    np.testing.assert_array_equal(g["slots"]["uv"][0], UV_T.matrix().reshape(-1).astype(F32))
    np.testing.assert_array_equal(g["slots"]["uv"][1], F32([1, 0, 0, 0, 1, 0]))
    t = tx[1]           # thin-walled: no thickness, no dispersion, no thickness texture read
    assert (t["transmission"], t["thickness"], t["dispersion"], t["ior"]) == (F32(0.5), 0, 0, F32(1.5))
    assert t["attenuation_distance"] == np.inf and t["slots"]["texture"].tolist() == [-1, -1]
    assert (tx[2]["transmission"], tx[2]["thickness"]) == (F32(1.0), 0)
    # MaterialExt: glass (ior 1.4: the specular layer) and the leaf
    assert records["ext"].tolist() == [0, -1, 1, -1, -1, -1, -1] and len(layers) == 2
    lf = layers[1]
    assert lf["layers"] == 32 and lf["diffuse_transmission"] == F32(0.6)
    np.testing.assert_array_equal(lf["diffuse_transmission_color"], F32([0.2, 0.8, 0.1]))
    assert lf["slots"]["texture"].tolist() == [-1] * 10 + [1, 2]
    assert lf["slots"]["texcoord"].tolist() == [0] * 11 + [1]
    assert layers[0]["diffuse_transmission"] == 0 and layers[0]["diffuse_transmission_color"].tolist() == [1, 1, 1]
    # the decode tables: transmission, thickness, diffuse transmission linear; its colour sRGB
    lut = pool_layout(textures)[0]["lut"]
    assert [int(lut[k]) for k in (0, 1, 2)] == [structs.LUT_LINEAR, structs.LUT_LINEAR, structs.LUT_SRGB]


def test_blinn_phong_records():
    """Transmission is a glTF-BRDF feature: the report's model draws the glass opaque and keeps the
    BLEND glass transparent by its alpha only."""
    scene = records_scene()
    _, records = scene_gpu.device_materials(scene)
    scene_gpu.layer_records(scene, records)
    scene_gpu.tx_records(scene, records)
    bp = scene_gpu.blinn_phong_records(records, scene.materials)
    mr = structs.MAT_METALLIC_ROUGHNESS
    want = [mr, mr, mr, mr, mr | structs.MAT_BLEND, 0, mr | structs.MAT_UNLIT]
    assert bp["flags"].tolist() == [f | structs.MAT_DOUBLE_SIDED for f in want]
    assert bp["tx"].tolist() == [-1] * 7 and bp["ext"].tolist() == [-1] * 7
    assert bp["door_alpha"].tolist() == [1.0] * 7
    assert records["tx"][0] == 0                                    # the glTF records are not changed


@pytest.fixture
def cl_device(device):
    return Device.get(device)


def test_upload_without_transmission(cl_device):
    """No transmissive material (a diffuse-transmission leaf is opaque): no record, buffer or argument."""
    mats = materials()
    leaf = dataclasses.replace(mats[2], diffuse_transmission_texture=-1, diffuse_transmission_color_texture=-1)
    scene = build_scene([(quad(-1, 1, -1, 1, -3.0), None, leaf), (quad(-2, 2, -2, 2, -4.0), None, mats[3])])
    res = scene_gpu.upload(scene, cl_device)
    assert res.values["transmissive_materials"] == 0
    assert "transmission_args" not in res.values
    assert not {"material_tx", "tri_volume_scale"} & set(res.buffers)
    got = res.buffers["materials"].get()
    assert got["tx"].tolist() == [-1, -1] and got["door_alpha"].tolist() == [1.0, 1.0]


def test_upload_with_transmission(cl_device):
    objects = [SceneObject(f"o{k}", f"m{k}", f"o{k}", volume_scale=s) for k, s in
               enumerate((2.0, 0.5, 1.0, 3.0, 0.25, 1.0, 1.0))]
    scene = records_scene(objects)
    res = scene_gpu.upload(scene, cl_device)
    assert res.values["transmissive_materials"] == 3
    np.testing.assert_array_equal(res.buffers["tri_volume_scale"].get(), F32([2.0, 0.5, 1.0, 3.0, 0.25, 1.0, 1.0]))
    tx = res.buffers["material_tx"].get()
    assert tx["thickness"].tolist() == [F32(0.4), 0, 0]
    assert res.buffers["materials"].get()["tx"].tolist() == [0, 1, -1, -1, 2, -1, -1]
    args = res.values["transmission_args"]
    assert [a.int_ptr for a in args] == [res.buffers["material_tx"].data.int_ptr,
                                         res.buffers["tri_volume_scale"].data.int_ptr]
    # an object's scale changes between frames (same materials): written into the same buffer
    scene.objects = [dataclasses.replace(objects[0], volume_scale=4.0)] + objects[1:]
    again = scene_gpu.upload(scene, cl_device)
    assert again is res
    np.testing.assert_array_equal(again.buffers["tri_volume_scale"].get()[:2], F32([4.0, 0.5]))
    assert again.values["transmission_args"][1].int_ptr == args[1].int_ptr
    # multiscatter's copy of the records keeps tx and door_alpha
    ms = scene_gpu.multiscatter_buffers(scene, cl_device)["materials"].get()
    assert ms["tx"].tolist() == [0, 1, -1, -1, 2, -1, -1]
    np.testing.assert_array_equal(ms["door_alpha"], F32([0.4, 0.5, 1, 1, 0.0, 1, 1]))


def test_upload_thin_walled_only(cl_device):
    """Transmissive materials without a volume: tri_volume_scale is one unread 1.0."""
    scene = build_scene([(quad(-1, 1, -1, 1, -3.0), None, materials()[1])], textures=[texture("d", False, 1)] * 2)
    res = scene_gpu.upload(scene, cl_device)
    assert res.values["transmissive_materials"] == 1
    assert res.buffers["tri_volume_scale"].get().tolist() == [1.0]


# -- the screen door ------------------------------------------------------------------------------------
def door_scene(front: Material):
    """A wall (material 0) and a 48x32-pixel quad (material 1) at depth 4; 64x48, fov 90."""
    w, h = 64, 48
    cam = Camera.look_at((0, 0, 0), (0, 0, -1), fov_y_deg=90.0, near=0.1, far=50)

    def at(px, py, d):
        return ((px / w * 2 - 1) * (w / h) * d, (1 - py / h * 2) * d, -d)

    a, b, c, e = at(8, 40, 4), at(56, 40, 4), at(56, 8, 4), at(8, 8, 4)
    wall = Material.from_metallic_roughness("wall", (0.5, 0.5, 0.5, 1.0), 0.0, 0.5)
    scene = build_scene([(quad(-40, 40, -30, 30, -10.0), None, wall),
                         (np.array([[a, b, c], [a, c, e]], np.float64), None, front)])
    return scene, cam, w, h


@pytest.mark.parametrize("transmission, metallic, kept", [(0.75, 0.0, 0.25), (0.5, 0.5, 0.75), (1.0, 0.0, 0.0)])
def test_screen_door_keeps_what_is_not_let_through(make_renderer, device, transmission, metallic, kept):
    """The screen door keeps round(16·(1 - transmission (1 - metallic))) pixels of every 4x4 block: the
    documented dither of a BLEND surface of that alpha, pixel for pixel."""
    mr = Material.from_metallic_roughness
    glass, cam, w, h = door_scene(mr("glass", (1.0, 0.2, 0.2, 1.0), metallic, 0.3, transmission=transmission))
    blend, _, _, _ = door_scene(mr("blend", (1.0, 0.2, 0.2, kept), metallic, 0.3, alpha_mode="BLEND"))
    renderer = make_renderer(w, h, transparency="screen_door")
    ids = renderer.render(glass, cam).triangle_id
    np.testing.assert_array_equal(ids, renderer.render(blend, cam).triangle_id)
    on_quad = np.isin(ids, (2, 3))
    blocks = on_quad[8:40, 8:56].reshape(8, 4, 12, 4).sum(axis=(1, 3))
    assert blocks.min() == blocks.max() == round(16 * kept), np.unique(blocks)
    assert not on_quad[:8].any() and not on_quad[40:].any()
    np.testing.assert_array_equal(on_quad[8:40, 8:56], screen_door_mask(kept, 1, h, w)[8:40, 8:56])
    assert (ids[8:40, 8:56][~on_quad[8:40, 8:56]] >= 0).all(), "the wall shows where the glass lets it through"


def test_loaded_slots_decode_tables(tmp_path):
    """From a glTF file: the new slots' textures reach the records with their colour space's decode
    table: transmission (R), thickness (G) and diffuse transmission (A) linear, the diffuse
    transmission colour sRGB (the extensions' READMEs), all from one image."""
    from gltf_files import primitive, write_gltf
    from clrender.loaders import load_scene

    ext = {"KHR_materials_transmission": {"transmissionFactor": 0.5, "transmissionTexture": {"index": 0}},
           "KHR_materials_volume": {"thicknessFactor": 1.0, "thicknessTexture": {"index": 0}},
           "KHR_materials_diffuse_transmission": {"diffuseTransmissionFactor": 0.5,
                                                  "diffuseTransmissionTexture": {"index": 0},
                                                  "diffuseTransmissionColorTexture": {"index": 0}}}
    mat = {"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}, "extensions": ext}
    path = write_gltf(tmp_path / "tx.gltf", [primitive(material=0)], [mat],
                      images=[np.random.default_rng(3).integers(0, 256, (4, 4, 4), dtype=np.uint8)],
                      extensionsUsed=list(ext))
    scene = load_scene(path)
    textures, records = scene_gpu.device_materials(scene)
    layers = scene_gpu.layer_records(scene, records)
    tx = scene_gpu.tx_records(scene, records)
    lut = pool_layout(textures)[0]["lut"]
    slot = {"base": records[0]["slots"]["texture"][0], "transmission": tx[0]["slots"]["texture"][0],
            "thickness": tx[0]["slots"]["texture"][1], "diffuse_transmission": layers[0]["slots"]["texture"][10],
            "diffuse_transmission_color": layers[0]["slots"]["texture"][11]}
    assert min(slot.values()) >= 0
    assert {k: int(lut[t]) for k, t in slot.items()} == {
        "base": structs.LUT_SRGB, "transmission": structs.LUT_LINEAR, "thickness": structs.LUT_LINEAR,
        "diffuse_transmission": structs.LUT_LINEAR, "diffuse_transmission_color": structs.LUT_SRGB}
