"""Each pass declares its buffers next to allocate() (`RenderPass.buffer_bytes`), and
clrender.render.memory.estimate() is their sum (plus the scene upload and the pipeline's constant
tables): here the declarations are compared with what the passes really hold on the device after
a frame (Frame.stats["device_bytes_by_owner"]), for a few configurations."""
from __future__ import annotations

import pytest

import clrender
from clrender.render import memory, plan
from reference.raster import pixel_exact_camera
from test_memory import glass_scene, light_set

# What a pass may hold beyond its declaration: 4-byte counters and 1-element placeholder arguments.
SMALL = 256
CONFIGS = [dict(), dict(pipeline="light_prepass", msaa=4, light_buffer_precision="float16"),
           dict(motion_blur=True, bloom=True, edge_aa=True, color_aa="fxaa", ssao=True, supersample=2),
           dict(light_culling="quads", transparency="depth_peeling", hatching=True),
           dict(pipeline="light_indexed", light_culling="brute_force")]


@pytest.mark.parametrize("opts", CONFIGS, ids=lambda o: ",".join(f"{k}={v}" for k, v in o.items()) or "default")
def test_declared_buffers_are_what_the_passes_allocate(device, opts):
    w, h = 96, 64
    scene = glass_scene()                       # BLEND triangles: the transparency passes allocate too
    scene.lights = light_set(1, 12)             # fewer than a tile list's 16 first entries: nothing grows
    r = clrender.Renderer(w, h, device=device.id, **opts)
    stats = r.render(scene, camera=pixel_exact_camera()).stats
    assert stats["retries"] == 0, "a list grew past its declared initial capacity"
    held = stats["device_bytes_by_owner"]
    config, k = r.config, r.config.supersample
    assert [type(p) for p in r.pipeline.passes] == plan.pass_classes(config)
    declared_total = 0
    for p in r.pipeline.passes:
        size = (w, h) if plan.stage(type(p)) == "output" else (k * w, k * h)
        declared = sum(type(p).buffer_bytes(*size, config, scene).values())
        declared_total += declared
        extra = held.get(p.name, 0) - declared
        # the light lists' per-light culling spheres are counted with the scene's lights
        extra -= sum(s.nbytes for s in getattr(p, "spheres", ()))
        if p.name == "motion_blur":     # partial maxima declared for one pixel per work-item: an upper bound
            assert -16 * w * -(-h // 32) <= extra <= SMALL, (p.name, held[p.name], declared)
        else:
            assert 0 <= extra <= SMALL, (p.name, held.get(p.name, 0), declared)
    # the estimate that guards allocation is those declarations plus the scene and the constant tables
    est = memory.estimate(w, h, config, scene)
    base = memory.estimate(w, h, config)
    assert est["total"] > declared_total
    assert base["total"] == 4 * 64 + 8 * clrender.abi.gbuffer.SRGB_ENCODE_INTERVALS + sum(
        sum(cls.buffer_bytes(*((w, h) if plan.stage(cls) == "output" else (k * w, k * h)), config).values())
        for cls in plan.pass_classes(config) if plan.stage(cls) != "transparency")


def test_a_disabled_effect_has_no_pass(device):
    """runs(config) decides which passes exist: off effects build no program and hold no buffer."""
    config = clrender.RenderConfig(ssao=False, bloom=False, shadows=False, light_culling="brute_force")
    names = {cls.name for cls in plan.pass_classes(config)}
    assert not names & {"ssao", "ssao_blur", "bloom", "shadow", "light_cull", "light_quads", "encode", "resolve"}
    r = clrender.Renderer(32, 32, device=device.id, ssao=False, bloom=False, shadows=False,
                          light_culling="brute_force")
    assert {p.name for p in r.pipeline.passes} == names
