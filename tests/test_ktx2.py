"""KHR_texture_basisu / KTX2 textures (clrender.loaders.ktx2, docs/compression.md).

The fixtures (tests/data/ktx2/, written by tests/ktx2_files.py with Basis Universal's encoder) hold
`source_image()`, a seeded smooth RGBA field: the decoded pixels are compared with it, not with
another decoder. Tolerances (measured with opengl_basisu 0.1.0a2 / basis_universal v2_50 in
brackets): UASTC, near-lossless, PSNR >= 36 dB and no channel off by more than 16 codes [38.7 dB,
12]; ETC1S (BasisLZ), lossy, PSNR >= 28 dB [31.3 dB]. The same image upside down scores about
15 dB, so a wrong row order, channel order or codec fails. The headers are checked against the
KTX 2.0 specification and the extension's rules by reading their bytes, independently of the
decoder. A missing decoder is simulated by making `import opengl_basisu` fail.
"""
from __future__ import annotations

import base64
import io
import json
import os
import shutil
import struct
import sys
import warnings

import numpy as np
import pytest

from gltf_files import primitive, write_gltf
from ktx2_files import FILES, FIXTURES, H, W, source_image

import clrender
from clrender import SceneError
from clrender.loaders import budget as budget_mod
from clrender.loaders import ktx2
from clrender.loaders.common import decode_image

# The `test` extra installs the decoder; CI (CI=true) fails rather than skips without it.
if os.environ.get("CI", "").lower() in ("1", "true"):
    import opengl_basisu
else:
    opengl_basisu = pytest.importorskip("opengl_basisu", reason='pip install "clrender[compression]"')

INSTALL = 'pip install "clrender[compression]"'
BASISU = "KHR_texture_basisu"
# KTX 2.0 specification, section 3 (header) and the Khronos Data Format's colour models
ETC1S_MODEL, UASTC_MODEL, SRGB_TRANSFER = 163, 166, 2
SUPERCOMPRESSION = {"etc1s": 1, "uastc": 0, "uastc_zstd": 2}      # BasisLZ, none, Zstandard
UASTC_DB, UASTC_MAX, ETC1S_DB = 36.0, 16, 28.0


def psnr(a: np.ndarray, b: np.ndarray) -> float:
    mse = np.mean((a.astype(np.float64) - b.astype(np.float64)) ** 2)
    return float("inf") if mse == 0 else 10 * np.log10(255.0 ** 2 / mse)


def reference(name: str) -> np.ndarray:
    return source_image(FILES[name].get("opaque", False))


def header(data: bytes) -> dict:
    """The KTX2 header fields KHR_texture_basisu constrains, read from the bytes."""
    (vk_format, _, width, height, depth, layers, faces, levels, scheme,
     dfd_offset) = struct.unpack_from("<9I I", data, 12)
    model, primaries, transfer = data[dfd_offset + 12], data[dfd_offset + 13], data[dfd_offset + 14]
    return dict(identifier=data[:12], vk_format=vk_format, size=(width, height), depth=depth, layers=layers,
                faces=faces, levels=levels, scheme=scheme, model=model, primaries=primaries, transfer=transfer)


@pytest.mark.parametrize("name", sorted(FILES))
def test_fixtures_are_what_the_extension_allows(name):
    h = header((FIXTURES / name).read_bytes())
    codec = name.split(".")[0].replace("_rgb", "").replace("_mips", "")
    assert h["identifier"] == ktx2.IDENTIFIER and h["vk_format"] == 0          # VK_FORMAT_UNDEFINED
    assert h["size"] == (W, H) and h["size"][0] % 4 == 0 and h["size"][1] % 4 == 0
    assert (h["depth"], h["layers"], h["faces"]) == (0, 0, 1)                  # 2D
    assert h["levels"] == (6 if "mips" in name else 1)                         # 32 x 24: 6 levels
    assert h["scheme"] == SUPERCOMPRESSION[codec]
    assert h["model"] == (ETC1S_MODEL if codec == "etc1s" else UASTC_MODEL)
    assert (h["primaries"], h["transfer"]) == (1, SRGB_TRANSFER)             # BT.709, sRGB: colour data


@pytest.mark.parametrize("name", sorted(FILES))
def test_decodes_to_the_source_image_within_tolerance(name):
    rgba = decode_image(FIXTURES / name, name)
    ref = reference(name)
    assert rgba.shape == (H, W, 4) and rgba.dtype == np.uint8                  # level 0; other levels ignored
    db = psnr(rgba, ref)
    if name.startswith("uastc"):
        assert db >= UASTC_DB, f"{name}: {db:.1f} dB"
        assert np.abs(rgba.astype(int) - ref).max() <= UASTC_MAX
    else:
        assert db >= ETC1S_DB, f"{name}: {db:.1f} dB"
    if FILES[name].get("opaque"):
        assert (rgba[..., 3] == 255).all()
    assert psnr(rgba[::-1], ref) < 20 and psnr(rgba[..., [2, 1, 0, 3]], ref) < 25   # the bounds can fail


# -- glTF files ---------------------------------------------------------------------------------------------------
def _png(rgba: np.ndarray) -> str:
    from PIL import Image
    out = io.BytesIO()
    Image.fromarray(rgba).save(out, "PNG")
    return "data:image/png;base64," + base64.b64encode(out.getvalue()).decode()


FALLBACK = np.full((4, 4, 4), (10, 200, 30, 255), np.uint8)      # the PNG `source`: nothing like the KTX2


def basisu_gltf(tmp_path, how="file", fallback=False, required=True, name="uastc.ktx2", source_ktx2=False):
    """A textured quad whose texture 0 reads `name` through KHR_texture_basisu (or, `source_ktx2`, through
    the core `source`), stored as a file beside the glTF, a data URI or a bufferView; `fallback` adds a
    PNG core `source`."""
    data = (FIXTURES / name).read_bytes()
    if how == "file":
        shutil.copy(FIXTURES / name, tmp_path / "albedo.ktx2")
        image = {"uri": "albedo.ktx2", "mimeType": "image/ktx2"}
    elif how == "data":
        image = {"uri": "data:image/ktx2;base64," + base64.b64encode(data).decode(), "mimeType": "image/ktx2"}
    else:
        image = {"bufferView": None, "mimeType": "image/ktx2"}
    tex = {"source": 0} if source_ktx2 else {"extensions": {BASISU: {"source": 0}}}
    if fallback:
        tex["source"] = 1

    def edit(doc):
        if how == "bufferView":
            buf = doc["buffers"][0]
            blob = bytearray(base64.b64decode(buf["uri"].split(",", 1)[1]))
            blob.extend(b"\0" * (-len(blob) % 4))
            doc["bufferViews"].append({"buffer": 0, "byteOffset": len(blob), "byteLength": len(data)})
            blob.extend(data)
            buf["uri"] = "data:application/octet-stream;base64," + base64.b64encode(bytes(blob)).decode()
            buf["byteLength"] = len(blob)
            image["bufferView"] = len(doc["bufferViews"]) - 1
        doc["images"] = [image, {"uri": _png(FALLBACK), "mimeType": "image/png"}]
        doc["textures"] = [tex]
        doc["extensionsUsed"] = [BASISU]
        if required:
            doc["extensionsRequired"] = [BASISU]
    return write_gltf(tmp_path / "basisu.gltf", primitives=[primitive(material=0)],
                      materials=[{"name": "albedo", "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}],
                      edit=edit)


def load_quiet(path):
    """load_scene and the warnings it gave."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        scene = clrender.load_scene(path)
    return scene, [str(w.message) for w in caught]


def no_decoder(monkeypatch):
    monkeypatch.setitem(sys.modules, "opengl_basisu", None)        # `import opengl_basisu` raises ImportError


@pytest.mark.parametrize("how", ["file", "data", "bufferView"])
def test_required_basisu_loads_with_the_decoder(tmp_path, how):
    scene, caught = load_quiet(basisu_gltf(tmp_path, how))
    assert caught == []                                        # nothing ignored, nothing to note
    (tex,) = scene.textures
    assert tex.srgb and scene.materials[0].base_color_texture == 0
    assert psnr(tex.rgba, reference("uastc.ktx2")) >= UASTC_DB


def test_ktx2_is_preferred_over_the_source_fallback(tmp_path):
    scene, caught = load_quiet(basisu_gltf(tmp_path, fallback=True, required=False, name="etc1s.ktx2"))
    assert caught == []
    assert psnr(scene.textures[0].rgba, reference("etc1s.ktx2")) >= ETC1S_DB


def test_missing_decoder_uses_the_fallback_with_one_note(tmp_path, monkeypatch):
    no_decoder(monkeypatch)
    assert not ktx2.available()
    scene, caught = load_quiet(basisu_gltf(tmp_path, fallback=True, required=False))
    np.testing.assert_array_equal(scene.textures[0].rgba, FALLBACK)
    assert len(caught) == 1 and BASISU in caught[0] and INSTALL in caught[0] and "fallback" in caught[0]
    assert "\n" not in caught[0]


def test_missing_decoder_without_fallback_is_a_one_line_error(tmp_path, monkeypatch):
    no_decoder(monkeypatch)
    with pytest.raises(SceneError, match=rf"texture 0 has only a {BASISU} image and no fallback") as info:
        load_quiet(basisu_gltf(tmp_path, required=False))
    assert INSTALL in str(info.value) and "\n" not in str(info.value)
    with pytest.raises(SceneError, match=rf"requires glTF extension {BASISU} \(extensionsRequired\), which needs "
                                         rf"the opengl_basisu package") as info:
        load_quiet(basisu_gltf(tmp_path, required=True))
    assert INSTALL in str(info.value) and "\n" not in str(info.value)


def test_ktx2_as_a_core_source_without_decoder_is_left_out_with_a_warning(tmp_path, monkeypatch):
    no_decoder(monkeypatch)
    scene, caught = load_quiet(basisu_gltf(tmp_path, required=False, source_ktx2=True))
    assert scene.textures == [] and scene.materials[0].base_color_texture == -1
    assert any("KTX2" in w and INSTALL in w for w in caught), caught


def test_corrupt_ktx2_is_left_out_and_the_load_goes_on(tmp_path):
    path = basisu_gltf(tmp_path, required=False)
    data = (tmp_path / "albedo.ktx2").read_bytes()
    (tmp_path / "albedo.ktx2").write_bytes(data[:len(data) // 2])           # truncated level data
    scene, caught = load_quiet(path)
    assert scene.textures == [] and scene.materials[0].base_color_texture == -1
    assert any("cannot decode KTX2 image" in w for w in caught), caught


def test_ktx2_outside_the_folder_is_refused(tmp_path):
    (tmp_path / "sub").mkdir()
    path = basisu_gltf(tmp_path / "sub")
    shutil.move(tmp_path / "sub" / "albedo.ktx2", tmp_path / "albedo.ktx2")
    doc = json.loads(path.read_text())
    doc["images"][0]["uri"] = "../albedo.ktx2"
    path.write_text(json.dumps(doc))
    with pytest.raises(SceneError, match=r"image 0 uri"):
        load_quiet(path)


def test_budget_is_checked_before_transcoding(monkeypatch):
    """32 x 24 RGBA (3 KiB kept, 3.75 KiB at the peak) over a 2 KiB budget: refused from the header,
    nothing transcoded."""
    calls = []
    real = opengl_basisu.Texture.transcode

    def spy(self, *args, **kwargs):
        calls.append(args)
        return real(self, *args, **kwargs)
    monkeypatch.setattr(opengl_basisu.Texture, "transcode", spy)
    assert decode_image(FIXTURES / "uastc.ktx2", "uastc").shape == (H, W, 4) and len(calls) == 1   # the spy works
    calls.clear()
    monkeypatch.setenv(budget_mod.ENV, "2K")
    with pytest.raises(budget_mod.BudgetError, match=r"^u: the embedded image \(32x24 pixels, KTX2 UASTC, decoded\) "
                                                     r"would take 3.75 KiB.*over the memory budget of 2 KiB"):
        decode_image((FIXTURES / "uastc.ktx2").read_bytes(), "u")
    assert calls == []


def test_renders_like_the_same_pixels_as_png(tmp_path, make_renderer):
    """The decoded KTX2 goes through the texture pool like any image: the albedo is bit-identical to a
    file whose PNG holds the decoded pixels."""
    scene, _ = load_quiet(basisu_gltf(tmp_path))
    (tmp_path / "png").mkdir()
    png = write_gltf(tmp_path / "png" / "png.gltf", primitives=[primitive(material=0)], images=[scene.textures[0].rgba],
                     materials=[{"name": "albedo", "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}])
    other, _ = load_quiet(png)
    cam = clrender.Camera.look_at(eye=(0.5, 0.5, 1.6), target=(0.5, 0.5, 0.0), fov_y_deg=45.0, near=0.1, far=10.0)
    a = make_renderer(48, 48).render(scene, cam)
    b = make_renderer(48, 48).render(other, cam)
    assert (a.triangle_id >= 0).mean() > 0.3
    np.testing.assert_array_equal(a.albedo, b.albedo)
