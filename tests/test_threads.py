"""Renderers used from several threads (issue 34, item 3): one Renderer called by a thread pool
serialises its calls internally, several Renderers on one device render side by side, and a Frame
read late (lazily, clrender/render/frame.py) in one thread while another thread renders on the same
Renderer still gives its own image. Every threaded result is compared bit for bit with the same
job rendered alone on one thread."""
from __future__ import annotations

import sys
import threading
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest

import clrender
from clrender import Camera, Scene

W, H = 64, 48
READ = ("image", "color", "gbuffer", "light_count")


def _scene(seed: int) -> Scene:
    """A few random triangles in front of the origin, a handful of point lights."""
    rng = np.random.default_rng(seed)
    tris = rng.uniform(-1.5, 1.5, (24, 3, 3)) + rng.uniform(-0.3, 0.3, (24, 1, 3))
    scene = Scene.from_arrays(tris.reshape(-1, 3).astype(np.float32), np.arange(72).reshape(-1, 3))
    for _ in range(4):
        scene.add_point_light(rng.uniform(-2, 2, 3) + (0, 0, 2), rng.uniform(0.5, 3, 3), 6.0)
    return scene


def _camera(k: int) -> Camera:
    a = 0.4 * k
    return Camera.look_at((4 * np.sin(a), 0.5 * (k % 3), 4 * np.cos(a)), (0, 0, 0), (0, 1, 0), 50.0, 0.1, 50.0)


JOBS = [(s, c) for s in range(3) for c in range(4)]      # (scene, camera) pairs


@pytest.fixture(autouse=True)
def fast_thread_switches():
    """Switch threads every few microseconds (default 5 ms) so that interleavings a lock must
    prevent actually happen within the test's few hundred renders."""
    old = sys.getswitchinterval()
    sys.setswitchinterval(1e-5)
    yield
    sys.setswitchinterval(old)


@pytest.fixture(scope="module")
def scenes():
    return [_scene(s) for s in range(3)]


def _read(frame) -> dict:
    return {name: np.array(getattr(frame, name)) for name in READ}


def _assert_same(got: dict, want: dict, what: str) -> None:
    for name in READ:
        assert got[name].shape == want[name].shape and got[name].dtype == want[name].dtype, (what, name)
        diff = np.count_nonzero(got[name] != want[name])
        assert diff == 0, f"{what}: {name} differs from the single-threaded render on {diff} values"


def _references(renderer, scenes) -> dict:
    return {job: _read(renderer.render(scenes[job[0]], _camera(job[1]))) for job in JOBS}


def test_one_renderer_from_a_thread_pool(device, scenes):
    """8 threads hammer one Renderer with 48 jobs (different scenes and cameras)."""
    r = clrender.Renderer(W, H, device=device.id)
    want = _references(r, scenes)
    jobs = JOBS * 4
    start = threading.Barrier(8)

    def work(i):
        if i < 8:
            start.wait(timeout=60)            # the first eight start together
        s, c = jobs[i]
        return _read(r.render(scenes[s], _camera(c)))

    with ThreadPoolExecutor(8) as pool:
        results = list(pool.map(work, range(len(jobs))))
    for i, got in enumerate(results):
        _assert_same(got, want[jobs[i]], f"job {i} {jobs[i]}")


def test_several_renderers_on_one_device(device, scenes):
    """Four Renderers (two configurations) on one device, each driven by its own thread."""
    opts = [{}, {"tile_size": 16}, {}, {"tile_size": 16}]
    renderers = [clrender.Renderer(W, H, device=device.id, **o) for o in opts]
    want = [_references(r, scenes) for r in renderers[:2]]
    start = threading.Barrier(len(renderers))

    def work(k):
        start.wait(timeout=60)
        return [_read(renderers[k].render(scenes[s], _camera(c))) for s, c in JOBS]

    with ThreadPoolExecutor(len(renderers)) as pool:
        results = list(pool.map(work, range(len(renderers))))
    for k, frames in enumerate(results):
        for job, got in zip(JOBS, frames):
            _assert_same(got, want[k % 2][job], f"renderer {k} job {job}")


def test_lazy_frame_read_while_another_thread_renders(device, scenes, monkeypatch):
    """Frames rendered and left unread, then read by their own threads while other threads keep
    rendering on the same Renderer: each still holds its own pixels (the next render retires the
    previous frame's readback under the same lock a read takes). Host buffers are made slow to
    allocate (as large fresh ones are: page faults, clrender/render/frame.py HostArrays), which widens
    the moment between a read taking its source and enqueuing its copy."""
    import time

    from clrender.render import frame as frame_module
    r = clrender.Renderer(W, H, device=device.id)
    want = _references(r, scenes)
    empty = frame_module.HOST_ARRAYS.empty

    def slow_empty(count, dtype):
        time.sleep(0.002)
        return empty(count, dtype)

    monkeypatch.setattr(frame_module.HOST_ARRAYS, "empty", slow_empty)
    errors = []
    stop = threading.Event()

    def renderer_thread(k):
        i = 0
        while not stop.is_set():
            s, c = JOBS[(k + i) % len(JOBS)]
            r.render(scenes[s], _camera(c))          # never read: retired by the next render
            i += 1

    def reader_thread(k):
        try:
            for i in range(6):
                job = JOBS[(3 * k + i) % len(JOBS)]
                frame = r.render(scenes[job[0]], _camera(job[1]))
                _assert_same(_read(frame), want[job], f"reader {k} frame {i} {job}")
        except Exception as exc:           # reported below, on the test's thread
            errors.append(exc)

    busy = [threading.Thread(target=renderer_thread, args=(k,)) for k in range(2)]
    readers = [threading.Thread(target=reader_thread, args=(k,)) for k in range(3)]
    for t in busy + readers:
        t.start()
    for t in readers:
        t.join(timeout=120)
    stop.set()
    for t in busy:
        t.join(timeout=60)
    assert not errors, errors[0]
