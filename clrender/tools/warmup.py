"""Build and first-launch clrender's kernels ahead of time (`clrender warmup`, Dask workers).

On PoCL a program is compiled at two moments: clBuildProgram (LLVM IR) and each kernel's first
launch (machine code, per local size). Both land in PoCL's kernel cache, so rendering small fixed
scenes once fills the cache with everything those renders use, at any later image size (launch
shapes do not depend on it). `warm_up()` renders what the default Renderer runs on typical scenes
(the portability check's cases: textures, transparency, shadowed spots and sun, particles);
`everything=True` adds every kernel file with its defaults and every Renderer variant
(the check's: light pre-pass with MSAA, light-indexed, light-accumulation modes, the post chain).
"""
from __future__ import annotations

import time

import numpy as np


def probe_scene():
    """One triangle lit by one point light: what the device probe renders."""
    from clrender.scene.camera import Camera
    from clrender.scene.model import Scene
    scene = Scene.from_arrays(np.array([[-1, -1, 0], [1, -1, 0], [0, 1, 0]], np.float32),
                              np.array([[0, 1, 2]], np.int32))
    scene.add_point_light((0, 0, 1), (1, 1, 1), 4.0)
    return scene, Camera.look_at((0, 0, 3), (0, 0, 0))


def render_probe_scene(info, width: int = 8, height: int = 8, **options):
    from clrender.render.renderer import Renderer
    scene, camera = probe_scene()
    return Renderer(width, height, device=info, **options).render(scene, camera)


def prepare_in_background(device, options: dict):
    """A Future of the DeviceInfo for `device`, chosen (and probed) on a thread that then builds and
    first-launches what a Renderer with `options` runs on a one-triangle scene, so that a render
    started after `.result()` finds its programs built. Errors surface at `.result()`; a failing
    warm-up itself is left to the real render to report."""
    from concurrent.futures import Future
    import threading
    future: Future = Future()

    def work():
        from clrender.device.probe import default_device_info
        try:
            info = default_device_info(device)
        except BaseException as exc:
            future.set_exception(exc)
            return
        try:
            render_probe_scene(info, **options)
        except Exception:
            pass               # the render that follows reports it, with its own scene and options
        future.set_result(info)

    threading.Thread(target=work, name="clrender-prepare", daemon=True).start()
    return future


def warm_up(device=None, everything: bool = False, width: int = 32, height: int = 24) -> dict:
    """Build and launch the default Renderer's kernels (every variant's with `everything`) on
    `device` (as Renderer takes it); returns {"device", "programs", "seconds"}."""
    from clrender.tools.check import LIGHT_VARIANTS, POST_OPTIONS, VARIANT_OPTIONS, default_cases
    from clrender.device.core import kernels_dir
    from clrender.device.probe import open_device
    from clrender.render.renderer import Renderer
    start = time.perf_counter()
    dev = open_device(device)
    before = len(dev.built)
    cases = default_cases(width, height)
    configs: list[dict] = [{}]
    if everything:
        configs += [dict(ssao=True), POST_OPTIONS, *VARIANT_OPTIONS.values(),
                    *(dict(light_culling=m) for m in LIGHT_VARIANTS),
                    dict(transparency="depth_peeling", refraction=True), dict(max_fragments_per_pixel=4),
                    dict(transparency="screen_door"), dict(shadow_filter="poisson"),
                    dict(pipeline="light_prepass"), dict(pipeline="light_prepass", msaa=2)]
    for options in configs:
        renderer = Renderer(width, height, device=dev.info, **options)
        for _, scene, camera in cases:
            renderer.render(scene, camera, time=0.5)
    if everything:
        from clrender.device.core import ProgramSpec
        dev.build(ProgramSpec.of(p.name) for p in sorted(kernels_dir().glob("*.cl")))
    return {"device": dev.name, "programs": len(dev.built) - before, "seconds": time.perf_counter() - start}
