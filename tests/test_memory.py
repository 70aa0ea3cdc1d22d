"""Device-memory report and leaks.

`Frame.stats["device_bytes"]` is the sum of the device buffers clrender holds for the frame (passes,
pipeline constants, scene upload), broken down in `stats["device_bytes_by_owner"]`; it must agree
with `clrender.render.memory.estimate()` (used to refuse frames that cannot fit) and stay constant over
many renders, and the process's resident memory must not grow (on PoCL device memory is host
memory, so RSS covers the device buffers too).
"""
from __future__ import annotations

import gc
import os

import numpy as np
import pytest

import clrender
from clrender import Scene, Texture
from clrender.render import memory, scene_upload as scene_gpu, texture_pool
from clrender.abi import structs
from clrender.abi import gbuffer as layout
from reference.geometry import uv_sphere
from reference.raster import pixel_exact_camera

RSS_SLACK = 2 * 2**20     # bytes RSS may grow over 180 renders after warm-up (measured: < 0.3 MiB)
KNOWN_OWNERS = {"scene", "pipeline", "setup", "binning", "raster", "gbuffer", "light_cull", "shade", "tonemap",
                "particles"}


def rss_bytes() -> int:
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")


def sphere_scene(n_lat=16, textured=False) -> Scene:
    pos, faces, normals = uv_sphere(n_lat=n_lat, n_lon=2 * n_lat, radius=1.0, center=(0, 0, -4))
    scene = Scene.from_arrays(pos, faces, normals=normals)
    if textured:
        rgba = np.random.default_rng(0).integers(0, 256, (64, 32, 4), dtype=np.uint8)
        scene.textures = [Texture("noise", rgba)]
        scene.materials = [clrender.Material(base_color_texture=0)]
    return scene


def light_set(seed, n):
    rng = np.random.default_rng(seed)
    lights = np.zeros(n, structs.light_dtype)
    lights["position"] = rng.uniform((-2, -2, -6), (2, 2, -1), (n, 3))
    lights["radius"] = rng.uniform(0.5, 2.0, n)
    lights["color"] = rng.uniform(0.1, 1.0, (n, 3))
    lights["direction"] = (0, 0, -1)
    return lights


def test_device_bytes_reported_and_estimated(make_renderer):
    w, h = 96, 64
    scene = sphere_scene(textured=True)
    scene.lights = light_set(1, 50)
    frame = make_renderer(w, h).render(scene, camera=pixel_exact_camera())
    stats = frame.stats
    by_owner = stats["device_bytes_by_owner"]
    assert stats["device_bytes"] == sum(by_owner.values())
    pixels = w * h
    # the frame's own planes alone: G-buffer (5 × 4 B), visibility (8 B), color + count (16 B), image (4 B)
    assert stats["device_bytes"] >= 48 * pixels
    assert by_owner["gbuffer"] == 4 * len(layout.PLANES) * pixels and by_owner["raster"] == 8 * pixels
    assert by_owner["shade"] >= 16 * pixels and by_owner["tonemap"] == 4 * pixels
    tex_bytes = sum(level.nbytes for level in texture_pool.mip_chain(scene.textures[0]))
    assert by_owner["scene"] >= scene.positions.nbytes * 3 + tex_bytes + scene.lights.nbytes
    # The estimate that guards allocation covers every buffer of the passes it knows, within 2 %.
    known = sum(v for k, v in by_owner.items() if k in KNOWN_OWNERS)
    est = memory.estimate(w, h, make_renderer(w, h).config, scene)["total"]
    assert 0.98 * known <= est <= 1.02 * known + 4096, (
        f"memory.estimate() = {est} but the known passes hold {known} bytes ({by_owner}); "
        f"update clrender/render/memory.py when a pass's buffers change")
    # A larger frame holds proportionally more.
    big = make_renderer(2 * w, 2 * h).render(scene, camera=pixel_exact_camera()).stats
    assert big["device_bytes_by_owner"]["gbuffer"] == 4 * by_owner["gbuffer"]


@pytest.mark.parametrize("opts", [dict(pipeline="light_prepass"), dict(pipeline="light_indexed"),
                                  dict(pipeline="light_prepass", msaa=4, light_buffer_precision="float16"),
                                  dict(motion_blur=True, bloom=True, edge_aa=True, color_aa="fxaa")])
def test_variant_and_post_buffers_estimated(device, opts):
    """The estimate follows the renderer variants (docs/variants.md) and the post chain: within
    4 % of every buffer the frame holds (the partial maxima of motion blur are estimated for one
    pixel per work-item, an upper bound)."""
    w, h = 96, 64
    scene = sphere_scene(textured=True)
    scene.lights = light_set(1, 50)
    # a renderer of its own: a shared one may hold lists grown for another test's bigger scene
    r = clrender.Renderer(w, h, device=device.id, **opts)
    held = r.render(scene, camera=pixel_exact_camera()).stats["device_bytes"]
    est = memory.estimate(w, h, r.config, scene)["total"]
    assert 0.99 * held <= est <= 1.04 * held + 4096, (opts, est, held)


def test_resize_and_scene_changes_free_buffers(device):
    """Buffers for an old resolution, an old scene upload and old lights are released."""
    r = clrender.Renderer(64, 48, device=device.id)
    cam = pixel_exact_camera()
    scene = sphere_scene()
    scene.lights = light_set(2, 30)
    first = r.render(scene, cam).stats["device_bytes"]
    r.width, r.height = 160, 120
    bigger = r.render(scene, cam).stats["device_bytes"]
    assert bigger > first
    r.width, r.height = 64, 48
    assert r.render(scene, cam).stats["device_bytes"] == first
    gc.collect()
    uploads = len(scene_gpu._UPLOADS)
    for k in range(5):                                       # new arrays: re-upload, the old one is dropped
        scene.positions = scene.positions + np.float32(0.01 * k)
        scene.lights = light_set(3 + k, 30)
        assert r.render(scene, cam).stats["device_bytes"] == first
    assert len(scene_gpu._UPLOADS) == uploads
    other = sphere_scene(n_lat=10)
    r.render(other, cam)
    assert len(scene_gpu._UPLOADS) == uploads + 1
    del other
    gc.collect()
    assert len(scene_gpu._UPLOADS) == uploads, "a collected scene's upload must be released"


def test_200_renders_do_not_leak(device):
    """200 small renders alternating two scenes, two light sets and a throw-away scene: device bytes
    are the same for each (scene, lights) every time, and RSS grows by less than RSS_SLACK after a
    20-render warm-up."""
    r = clrender.Renderer(64, 48, device=device.id)
    cam = pixel_exact_camera()
    scenes = [sphere_scene(16, textured=True), sphere_scene(10)]
    lights = [light_set(4, 200), light_set(5, 20)]
    seen: dict = {}
    caches = None
    for i in range(200):
        if i % 10 == 9:
            scene = sphere_scene(12)                         # a new scene object, dropped after the frame
            scene.lights = lights[0]
            key = "fresh"
        else:
            s, l = i % 2, (i // 3) % 2
            scene = scenes[s]
            scene.lights = lights[l]                         # reassigned every frame: re-uploaded when changed
            key = (s, l)
        frame = r.render(scene, cam)
        assert (frame.triangle_id >= 0).any()
        seen.setdefault(key, set()).add(frame.stats["device_bytes"])
        del frame, scene
        if i == 19:
            gc.collect()
            caches = (len(scene_gpu._UPLOADS), len(scene_gpu._LIGHTS))
            rss0 = rss_bytes()
    gc.collect()
    grown = rss_bytes() - rss0
    assert all(len(v) == 1 for v in seen.values()), f"device bytes changed between renders: {seen}"
    assert (len(scene_gpu._UPLOADS), len(scene_gpu._LIGHTS)) == caches
    assert grown < RSS_SLACK, f"RSS grew by {grown / 2**20:.1f} MiB over 180 renders"


def glass_scene() -> Scene:
    """The sphere behind a transparent quad: the transparency passes allocate their buffers."""
    scene = sphere_scene()
    quad = np.array([[-1.5, -1.5, -2.5], [1.5, -1.5, -2.5], [1.5, 1.5, -2.5], [-1.5, 1.5, -2.5]], np.float32)
    scene = Scene.from_arrays(np.vstack([scene.positions, quad]),
                              np.vstack([scene.triangles, len(scene.positions) + np.array([[0, 1, 2], [0, 2, 3]])]))
    scene.materials = [clrender.Material(), clrender.Material("glass", (0.2, 0.5, 1.0, 1.0), opacity=0.5)]
    scene.triangle_material = np.r_[np.zeros(len(scene.triangles) - 2), 1, 1].astype(np.int32)
    return scene


def test_transparency_buffers_estimated_and_only_when_needed(make_renderer):
    """A scene with BLEND triangles adds the transparency passes' buffers, which the estimate
    covers within 2 %; a scene without any allocates none of them."""
    w, h = 96, 64
    r = make_renderer(w, h)
    opaque = r.render(sphere_scene(), camera=pixel_exact_camera()).stats["device_bytes_by_owner"]
    held = sum(opaque.get(k, 0) for k in ("fragments", "abuffer", "composite"))
    assert held <= 64, f"an opaque scene allocated {held} bytes of transparency buffers (only 4-byte counters expected)"
    frame = r.render(glass_scene(), camera=pixel_exact_camera())
    assert frame.fragment_count.max() == 1 and frame.stats["fragments"] > 0
    by_owner = frame.stats["device_bytes_by_owner"]
    assert by_owner["fragments"] >= 16 * w * h and by_owner["abuffer"] >= (28 + 16) * w * h
    assert by_owner["composite"] == 12 * w * h
    known = sum(v for k, v in by_owner.items() if k in KNOWN_OWNERS | {"fragments", "abuffer", "composite"})
    est = memory.estimate(w, h, r.config, glass_scene())["total"]
    assert 0.98 * known <= est <= 1.02 * known + 4096, (est, known, by_owner)
