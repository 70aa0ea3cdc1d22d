"""G-buffer layout: the kernel's pack functions against the NumPy codecs, the header's
defaults against the layout table, and struct layouts against their numpy dtypes."""
import re
from pathlib import Path

import numpy as np
import pyopencl.array as cla
import pytest

from clrender.abi import gbuffer as gb
from clrender.abi import structs
from clrender.device.core import Device, kernels_dir


@pytest.fixture
def cl_device(device):
    return Device.get(device)


def test_header_defaults_match_layout_table():
    text = (kernels_dir() / "gbuffer.h").read_text()
    defaults = {k: int(v) for k, v in re.findall(r"#define (GB_\w+) (\d+)", text)}
    assert defaults == gb.kernel_defines()


def test_layout_fields_do_not_overlap():
    """Every bit is one field's, but the glTF BRDF's material fields, which reuse exactly the bits
    of a Blinn-Phong field (a pixel's model comes from its triangle's material)."""
    used = {}
    bp = {(f.plane, f.shift, f.bits) for f in gb.LAYOUT if f.model == "blinn_phong"}
    for f in gb.LAYOUT:
        if f.model == "gltf":
            assert (f.plane, f.shift, f.bits) in bp, f"{f.name} does not alias a Blinn-Phong field"
            continue
        for bit in range(f.shift, f.shift + f.bits):
            assert (f.plane, bit) not in used, f"{f.name} overlaps {used[(f.plane, bit)]}"
            used[(f.plane, bit)] = f.name
    assert len(used) == 32 * len(gb.PLANES), "every bit of every plane is assigned"


def test_struct_layouts_match_device(cl_device):
    kernel = cl_device.kernel("testing/layout_probe.cl", "struct_layout")
    out = cla.zeros(cl_device.queue, 128, np.int32)
    kernel(cl_device.queue, (1,), None, out.data)
    got = out.get().tolist()
    expect = []
    for dtype, names in ((structs.prim_dtype, ["x", "tri", "y", "flags", "inv_w", "material", "bary1", "bary2", "area"]),
                         (structs.texslot_dtype, list(structs.texslot_dtype.names)),
                         (structs.material_dtype, list(structs.material_dtype.names)),
                         (structs.texinfo_dtype, list(structs.texinfo_dtype.names)),
                         (structs.texlevel_dtype, ["offset", "width", "height", "pad"]),
                         (structs.light_dtype, ["position", "radius", "color", "type", "direction", "cos_outer",
                                                "cos_inner", "shadow_size", "shadow", "falloff"]),
                         (structs.shadow_view_dtype, ["m", "x0", "y0", "size", "ortho", "texel", "far", "split",
                                                      "pad"]),
                         (structs.material_ext_dtype, list(structs.material_ext_dtype.names)),
                         (structs.material_tx_dtype, list(structs.material_tx_dtype.names))):
        expect.append(dtype.itemsize)
        expect.extend(dtype.fields[n][1] for n in names)
    expect.append(-12345)                   # the probe's end marker: no entry missed or extra
    assert got[: len(expect)] == expect


def _pack_on_device(cl_device, values):
    q = cl_device.queue
    kernel = cl_device.kernel("testing/layout_probe.cl", "pack_probe")
    n = len(values)
    inp = cla.to_device(q, np.ascontiguousarray(values, np.float32))
    enc = cla.to_device(q, gb.srgb_encode_table())
    out = cla.zeros(q, n * 4, np.uint32)
    out2 = cla.zeros(q, n, np.uint32)
    kernel(q, (n,), None, inp.data, enc.data, np.int32(n), out.data, out2.data)
    return out.get().reshape(n, 4), out2.get()


def _planes_with(field, words):
    planes = np.zeros((len(gb.PLANES), 1, len(words)), np.uint32)
    f = gb.FIELDS[field]
    planes[f.plane, 0] = np.asarray(words, np.uint32) << np.uint32(f.shift)
    return planes


def test_round_trips_through_kernel_pack_and_numpy_decode(cl_device):
    rng = np.random.default_rng(7)
    n = 4096
    normals = rng.normal(size=(n, 3))
    normals[:8] = [[0, 0, 1], [0, 0, -1], [1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0.6, 0, -0.8], [0, 0.6, -0.8]]
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    power = np.exp2(rng.uniform(0, 11, n))
    words, _ = _pack_on_device(cl_device, np.column_stack([normals, power]))

    # Normals: octahedral 2x12 keeps the sign of z; error well under 0.1 degree.
    dec = gb.decode(_planes_with("normal", words[:, 1]), "normal")[0]
    angle = np.degrees(np.arccos(np.clip((dec * normals).sum(1), -1, 1)))
    assert angle.max() < 0.1
    clear = np.abs(normals[:, 2]) > 1e-3
    assert np.all(np.sign(dec[clear, 2]) == np.sign(normals[clear, 2]))
    # The kernel and NumPy encoders agree bit for bit except where rounding ties differ.
    assert np.mean(gb.oct_encode(normals) == words[:, 1]) > 0.99

    # Specular power: log2 in 8 bits, <= 1.6% relative error.
    dec_p = gb.decode(_planes_with("specular_power", words[:, 2]), "specular_power")[0]
    assert np.max(np.abs(dec_p / power - 1)) < 0.016


def test_srgb_and_half_packing_match_numpy(cl_device):
    rng = np.random.default_rng(3)
    n = 4096
    rgb = rng.uniform(0, 1, (n, 3))
    rgb[:4] = [[0, 0, 0], [1, 1, 1], [0.5, 0.2, 0.0031308], [1e-6, 0.9999, 0.04]]
    vel = rng.normal(scale=30, size=(n, 2))
    words, report = _pack_on_device(cl_device, np.column_stack([rgb, np.ones(n)]))
    # sRGB8: the kernel's table encoder equals NumPy's exact rounding but at float32 ties.
    expect = gb.linear_to_srgb8(rgb.astype(np.float32))
    got = np.stack([(words[:, 0] >> (8 * c)) & 255 for c in range(3)], 1)
    assert np.abs(got.astype(int) - expect.astype(int)).max() <= 1
    assert np.mean(got == expect) > 0.999
    # Half floats for velocity, rounded to nearest even like numpy.
    vwords, _ = _pack_on_device(cl_device, np.column_stack([vel, np.zeros(n), np.ones(n)]))
    dec_v = gb.decode(_planes_with("velocity", vwords[:, 3]), "velocity")[0]
    np.testing.assert_array_equal(dec_v, vel.astype(np.float16).astype(np.float32))


def test_report_pack_float2_round_trip(cl_device):
    """The report's pack_float2/unpack_float2 (section II.3), kernel pack + NumPy unpack."""
    rng = np.random.default_rng(11)
    ab = rng.uniform(0, 1, (1000, 2))
    ab[0] = (0.5, 0.8)            # the report's own example
    _, words = _pack_on_device(cl_device, np.column_stack([ab, np.zeros(1000), np.ones(1000)]))
    a, b = gb.unpack_float2(words)
    assert np.max(np.abs(a - ab[:, 0])) <= 0.5 / 65535 + 1e-7
    assert np.max(np.abs(b - ab[:, 1])) <= 0.5 / 65535 + 1e-7
    np.testing.assert_array_equal(words, gb.pack_float2(ab[:, 0].astype(np.float32), ab[:, 1].astype(np.float32)))
    assert words[0] >> 16 == 0x8000 and words[0] & 0xFFFF == 0xCCCC   # 0.5 rounds up, 0.8 -> 0xCCCC


def test_layout_markdown_lists_every_field():
    md = gb.layout_markdown()
    for f in gb.LAYOUT:
        assert f"`{f.name}`" in md


def test_readme_layout_table_is_generated_from_the_layout():
    readme = (Path(__file__).resolve().parents[1] / "docs" / "gbuffer.md").read_text()
    start, end = readme.index("<!-- gbuffer-layout -->"), readme.index("<!-- /gbuffer-layout -->")
    assert readme[start:end].split("\n", 1)[1].strip() == gb.layout_markdown()
