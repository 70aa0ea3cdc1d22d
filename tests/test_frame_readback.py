"""Frames read their arrays from the device on first access (clrender/render/frame.py): the values are
those of a frame read at once, whatever is rendered after it, and only what is read is copied."""
from __future__ import annotations

import dataclasses
import pickle
from pathlib import Path

import numpy as np
import pytest

from clrender import load_scene
from clrender.render.frame import Frame, SnapshotPool
from clrender.abi.gbuffer import PLANES
from helpers import shared_file

REPO = Path(__file__).resolve().parents[1]
ARRAYS = Frame.AOV_NAMES + ("gbuffer",)


@pytest.fixture(scope="module")
def demo():
    return load_scene(str(REPO / "scenes" / "demo.toml"))


def moved(camera):
    return dataclasses.replace(camera, eye=np.asarray(camera.eye, np.float64) * 1.1 + 0.05)


def read_all(frame) -> dict:
    out = {name: np.array(getattr(frame, name)) for name in ARRAYS}
    if frame.ldr is not None:
        out["ldr"] = np.array(frame.ldr)
    return out


def assert_same(a: dict, b: dict, what: str):
    assert set(a) == set(b), what
    for name in a:
        assert a[name].dtype == b[name].dtype and a[name].shape == b[name].shape, (what, name)
        assert np.array_equal(a[name], b[name], equal_nan=True), (what, name)


CONFIGS = [dict(), dict(supersample=2, ssao=True), dict(edge_aa=True, color_aa="fxaa"),
           dict(pipeline="light_prepass", msaa=2)]


@pytest.mark.parametrize("opts", CONFIGS, ids=lambda o: ",".join(f"{k}={v}" for k, v in o.items()) or "default")
def test_unread_frame_survives_the_next_render(device, demo, opts):
    """Frame 1 is read only after frames 2 and 3 overwrote the pipeline's buffers; a fresh
    renderer's frame read at once is the reference (independent buffers, same kernels)."""
    import clrender
    camera = demo.default_camera()
    reference = read_all(clrender.Renderer(72, 40, device=device.id, **opts).render(demo, camera))
    r = clrender.Renderer(72, 40, device=device.id, **opts)
    first = r.render(demo, camera)
    _ = first.triangle_id                        # one plane read before, the rest after
    second = r.render(demo, moved(camera))
    third = r.render(demo, moved(moved(camera)))
    assert_same(read_all(first), reference, "frame read after two more renders")
    assert not np.array_equal(second.image, first.image)      # the views differ: a stale read would show
    assert not np.array_equal(third.gbuffer, second.gbuffer)


def test_transparent_frame_read_late(device):
    path = shared_file("khronos-AlphaBlendModeTest/AlphaBlendModeTest.gltf")
    import clrender
    scene = load_scene(str(path))
    camera = scene.default_camera()
    reference = read_all(clrender.Renderer(64, 48, device=device.id).render(scene, camera))
    assert reference["fragment_count"].max() > 0
    r = clrender.Renderer(64, 48, device=device.id)
    first = r.render(scene, camera)
    r.render(scene, moved(camera))
    assert_same(read_all(first), reference, "transparent frame read late")


def test_only_what_is_read_is_copied(make_renderer, demo):
    frame = make_renderer(72, 40).render(demo)
    rb = frame.readback
    depth_plane = f"gbuffer:{PLANES.index('depth')}"
    assert depth_plane in rb.sources and "color" in rb.sources
    frame.depth
    assert depth_plane not in rb.sources and depth_plane in rb.host
    assert "color" in rb.sources and f"gbuffer:{PLANES.index('albedo_spec')}" in rb.sources
    # constant AOVs are made on first use (no SSAO here)
    assert "ao" in rb.makers
    assert np.all(frame.ao == 1.0) and "ao" not in rb.makers
    # the whole G-buffer afterwards holds the plane read alone
    assert np.array_equal(frame.gbuffer[PLANES.index("depth")], rb.host[depth_plane])


def test_pool_budget_and_reuse(device, demo):
    """Over the budget, a retired frame is read to the host at once; in a render loop that reads
    only the image, the pool stops growing after two frames."""
    import clrender
    camera = demo.default_camera()
    r = clrender.Renderer(72, 40, device=device.id)
    reference = read_all(r.render(demo, camera))
    r.pipeline.snapshots = SnapshotPool(r.device.queue, budget=0)
    first = r.render(demo, camera)
    r.render(demo, moved(camera))
    assert not first.readback.sources and r.pipeline.snapshots.live == 0     # read to the host
    assert_same(read_all(first), reference, "frame read at retire")

    r.pipeline.snapshots = pool = SnapshotPool(r.device.queue, budget=1 << 30)
    held = []
    frame = None
    for k in range(6):
        frame = r.render(demo, camera if k % 2 else moved(camera))
        frame.image
        held.append(pool.held_bytes)
    assert held[2] > 0 and held[2:] == [held[2]] * 4, held
    assert frame.stats["frame_copy_bytes"] == held[-1]


def test_pickled_frame_carries_its_arrays(make_renderer, demo):
    frame = make_renderer(72, 40).render(demo)
    copy = pickle.loads(pickle.dumps(frame))
    assert copy.readback.queue is None and not copy.readback.sources
    assert_same(read_all(copy), read_all(frame), "pickle round trip")
    assert copy.stats == frame.stats and copy.width == 72 and copy.height == 40


def test_host_arrays_are_reused_only_when_nothing_references_them(make_renderer, demo):
    """Large reads land in host buffers reused across frames (clrender.render.frame.HostArrays: no fresh
    pages to fault in every frame), but never while any array made from one is alive: a view kept
    from frame A (derived, so its base is the buffer itself) keeps A's values after B is read."""
    from clrender.render.frame import HOST_ARRAYS, HostArrays
    r = make_renderer(800, 600)                           # colour: 5.8 MB, above HostArrays.MIN_BYTES
    cam = demo.camera
    a = r.render(demo, cam)
    kept = a.color.reshape(-1)[::3]                       # a derived view of A's colour
    expect = kept.copy()
    assert expect.max() > 0.0, "a black frame proves nothing"
    del a
    b = r.render(demo, moved(cam))
    assert not np.shares_memory(b.color, kept)
    np.testing.assert_array_equal(kept, expect)
    assert not np.array_equal(b.color.reshape(-1)[::3], expect), "B must differ from A for this test"
    del kept, b
    r.render(demo, cam).color                             # warm: one buffer of this size is free now
    count = len(HOST_ARRAYS.buffers)
    for k in range(4):
        c = r.render(demo, moved(cam) if k % 2 else cam)
        if k % 2 == 0:                                    # a reused buffer holds this frame's values
            np.testing.assert_array_equal(c.color.reshape(-1)[::3], expect)
        del c
    assert len(HOST_ARRAYS.buffers) == count, "a render loop reading its colour reuses the same buffers"
    small = HostArrays(budget=0)
    x = small.empty(2 << 20, np.float32)
    y = small.empty(2 << 20, np.float32)
    assert not np.shares_memory(x, y)
