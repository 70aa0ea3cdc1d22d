"""The decoded texture pool (kernels/texel_decode.cl, clrender/render/texture_pool.py linear_texels,
kernels/texture_vec.h TEXELS_LINEAR): every texel as the float4 the RGBA8 path decodes per sample,
so the G-buffer and the image are the same bits with or without it; over its memory budget (or
at 0, the default: docs/benchmarks.md) the RGBA8 pool is sampled and no decoded program is built."""
import numpy as np
import pytest

import clrender
from clrender.abi.gbuffer import srgb_to_linear_lut
from clrender.device import capabilities
from clrender.device.core import Device
from clrender.render import memory, scene_upload, texture_pool
from clrender.tools import check

PIPELINES = ("deferred", "light_prepass", "light_indexed")


@pytest.fixture(scope="module")
def materials_case():
    cases = {name: (scene, camera) for name, scene, camera in check.default_cases(96, 64)}
    return cases["materials"]


def reference_decode(texels: np.ndarray, infos: np.ndarray, levels: np.ndarray) -> np.ndarray:
    """float32 (N, 4) from the RGBA8 words, written from texture_vec.h's per-sample decode: R, G, B
    through the sRGB table or as byte / 255 (a division in float32), A as byte · float32(1/255)."""
    out = np.zeros((texels.size, 4), np.float32)
    srgb = srgb_to_linear_lut()
    for info in infos:
        first = int(levels[int(info["first_level"])]["offset"])
        last = levels[int(info["first_level"]) + int(info["levels"]) - 1]
        end = int(last["offset"]) + int(last["width"]) * int(last["height"])
        words = texels[first:end]
        for c in range(3):
            byte = ((words >> (8 * c)) & 255).astype(np.int64)
            out[first:end, c] = srgb[byte] if int(info["lut"]) == 0 else byte.astype(np.float32) / np.float32(255)
        out[first:end, 3] = (words >> 24).astype(np.float32) * np.float32(1.0 / 255.0)
    return out


def test_decoded_pool_is_the_per_sample_decode(device, materials_case):
    scene, _ = materials_case
    dev = Device.get(device.id)
    res = scene_upload.upload(scene, dev)
    if capabilities.pixel_vector_width(dev.cl_device) == 1:         # GPUs, Oclgrind: the RGBA8 words
        assert not texture_pool.linear_texels(dev, res, 1024)
        return
    assert texture_pool.linear_texels(dev, res, 1024)
    infos, levels = res["tex_infos"].get(), res["tex_levels"].get()
    assert {int(i["lut"]) for i in infos} == {0, 256}, "the case should hold sRGB and linear textures"
    got = res.buffers["texels_linear"].get().reshape(-1, 4)
    want = reference_decode(res["texels"].get(), infos, levels)
    np.testing.assert_array_equal(got.view(np.uint32), want.view(np.uint32))
    assert np.all(got[:, :3].max(axis=0) > 0.0), "a black pool must fail"


@pytest.mark.parametrize("pipeline", PIPELINES)
def test_same_bits_with_and_without_the_decoded_pool(device, materials_case, pipeline):
    scene, camera = materials_case
    frames = {mb: clrender.Renderer(96, 64, device=device.id, pipeline=pipeline, decoded_textures_mb=mb)
              .render(scene, camera) for mb in (0, 64)}
    assert (frames[0].triangle_id >= 0).mean() > 0.3
    assert float(frames[0].albedo.max()) > 0.0
    np.testing.assert_array_equal(frames[64].gbuffer, frames[0].gbuffer)
    np.testing.assert_array_equal(frames[64].color, frames[0].color)


def test_over_budget_samples_the_rgba8_pool(device, materials_case, monkeypatch):
    scene, camera = materials_case
    reference = clrender.Renderer(96, 64, device=device.id, decoded_textures_mb=0).render(scene, camera)
    # the case's pool is small: texels 2^20 times their size put it over a 1024 MiB budget
    monkeypatch.setattr(texture_pool, "LINEAR_TEXEL_BYTES", 16 * 2**20)
    renderer = clrender.Renderer(96, 64, device=device.id, decoded_textures_mb=1024)
    frame = renderer.render(scene, camera)
    gbuffer_pass = next(p for p in renderer.pipeline.passes if p.name == "gbuffer")
    assert not gbuffer_pass.kernel.linear and set(gbuffer_pass.kernel.variants) == {False}
    np.testing.assert_array_equal(frame.gbuffer, reference.gbuffer)
    np.testing.assert_array_equal(frame.color, reference.color)


def test_budget_zero_builds_no_decoded_program(device, materials_case):
    scene, camera = materials_case
    renderer = clrender.Renderer(80, 48, device=device.id, decoded_textures_mb=0)
    renderer.render(scene, camera)
    for p in renderer.pipeline.passes:
        for value in vars(p).values():
            if hasattr(value, "variants"):
                assert set(value.variants) == {False}, p.name


def test_memory_estimate_counts_the_decoded_pool(materials_case):
    scene, _ = materials_case
    texels = sum(t.rgba.shape[0] * t.rgba.shape[1] for t in scene.textures) * 4 // 3 + 1
    on = memory.estimate(96, 64, clrender.RenderConfig(decoded_textures_mb=64), scene)["total"]
    off = memory.estimate(96, 64, clrender.RenderConfig(decoded_textures_mb=0), scene)["total"]
    assert on - off == 16 * texels


def test_decoded_once_per_upload(device, materials_case):
    """The decoded pool belongs to the scene's cached upload: later frames reuse it (a frame's
    Resources are a copy; a pool made there was decoded again every frame)."""
    scene, camera = materials_case
    renderer = clrender.Renderer(64, 48, device=device.id, decoded_textures_mb=64)
    renderer.render(scene, camera)
    upload = scene_upload.upload(scene, Device.get(device.id))
    first = upload.buffers.get("texels_linear")
    renderer.render(scene, camera)
    assert upload.buffers.get("texels_linear") is first
    assert (first is None) == (capabilities.pixel_vector_width(Device.get(device.id).cl_device) == 1)
