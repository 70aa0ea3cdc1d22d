"""A batch job's frame task and its rendering: `FrameTask` (plain data that pickles) and
`render_task`, which renders one frame and writes its outputs wherever it runs, in this process or
on a Dask worker (the client side that plans and runs jobs: clrender/batch/jobs.py).

Each process (this one, or each Dask worker process) keeps its loaded scenes, keyed by path,
mtime and size, and one `Renderer` per (device, size, config): programs build and scenes load
once per process, not per frame. The device of a worker is, in order: the job's `device`, the
worker's $CLRENDER_DEVICE, the first GPU when the Dask worker has a `GPU` resource, else the
default device. So GPU workers (`dask worker ... --resources GPU=1`) and PoCL workers
(`CLRENDER_DEVICE=pocl dask worker ...`) can serve one cluster; `resources={"GPU": 1}` sends a
job to the GPU workers only.
"""
from __future__ import annotations

import os
import socket
import time as _time
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

from clrender.config import DEFAULT_SIZE, scene_config, scene_size  # noqa: F401  (jobs and the CLI import them here)
from clrender.outputs.aov_io import aov_paths, write_outputs
from clrender.scene.camera import Camera



@dataclass(frozen=True)
class Outputs:
    """What each frame writes beside its image (clrender.outputs.aov_io.write_outputs)."""
    aovs: tuple = ()
    bit_depth: int = 8
    exr: bool = False
    sheet: bool = False          # <stem>.sheet.png: the image and the AOV previews, labelled
    # "stem": <stem>.<aov>.npy/png beside the image; "dataset": the folders of a `clrender dataset`
    # export (images/, depth/, masks/, aovs/, exr/: clrender.dataset.outputs)
    layout: str = "stem"
    depth_scale: float = 1000.0  # dataset layout: depth PNG units per scene unit (mm for metres)


@dataclass(frozen=True)
class CameraOverride:
    """--camera-eye/--camera-target/--fov/--ortho, applied to the (posed) scene camera."""
    eye: Optional[tuple] = None
    target: Optional[tuple] = None
    fov: Optional[float] = None
    ortho: Optional[float] = None


@dataclass(frozen=True)
class FrameTask:
    scene: str
    frame: int
    time: float
    dt: float
    image: str
    outputs: Outputs = Outputs()
    width: Optional[int] = None
    height: Optional[int] = None
    options: tuple = ()                 # RenderConfig options as sorted (name, value) pairs
    camera: CameraOverride = CameraOverride()
    device: Optional[str] = None
    view: Optional[Camera] = None       # replaces the scene camera (a dataset view): scene posed at `time`,
                                        # no motion (no previous camera, no previous pose)
    allow: tuple = ()                   # folders outside the scene's own its references may read (absolute)
    variant: Optional[str] = None       # the glTF material variant to render (Scene.set_variant); None: none

    def paths(self) -> list[Path]:
        if self.outputs.layout == "dataset":
            from clrender.dataset.outputs import view_paths
            return view_paths(Path(self.image), self.outputs.aovs, self.outputs.exr)
        return [Path(self.image), *aov_paths(Path(self.image), self.outputs.aovs, self.outputs.exr, self.outputs.sheet)]


# -- the worker side --------------------------------------------------------------------------
_SCENES: dict = {}                       # (path, allowed folders, variant) -> ((mtime_ns, size), Scene)
_RENDERERS: dict = {}                    # (device id, w, h, config) -> Renderer


def _scene(path: str, allow: tuple = (), variant: Optional[str] = None):
    from clrender.loaders import load_scene
    key = (path, tuple(allow), variant)  # a scene refused without a folder must not be served from one allowed with it
    cached = _SCENES.get(key)
    # Reloaded when the scene file or any file it read (MTL, textures, buffers, TOML meshes) changed
    if cached is None or cached[0] != _stamps([path, *cached[1].source_files]):
        scene = load_scene(path, allow=list(allow), variant=variant)
        _SCENES[key] = cached = (_stamps([path, *scene.source_files]), scene)
    return cached[1]


def _stamps(files) -> tuple:
    out = []
    for f in files:
        try:
            st = os.stat(f)
            out.append((st.st_mtime_ns, st.st_size))
        except OSError:
            out.append(None)
    return tuple(out)


def _renderer(device_spec, width: int, height: int, config):
    from clrender.device.probe import default_device_info
    from clrender.render.renderer import Renderer
    info = default_device_info(device_spec)
    key = (info.id, width, height, config)
    renderer = _RENDERERS.get(key)
    if renderer is None:
        renderer = _RENDERERS[key] = Renderer(width, height, device=info, config=config)
    return renderer


def _spare_inputs(task: FrameTask, scene) -> None:
    """ValueError when one of the task's outputs is a file its scene reads (the CLI checks the whole
    job before it starts; this guards every frame, wherever and however it was planned)."""
    files = {str(f) for f in getattr(scene, "source_files", ())} | {os.path.realpath(task.scene)}
    for p in task.paths():
        key = os.path.join(os.path.realpath(p.parent), p.name)
        if key in files:
            raise ValueError(f"output {p} would overwrite {key}, which {task.scene} reads")


def render_task(task: FrameTask) -> dict:
    """Render one frame and write its outputs; returns its manifest record (status ok). Raises
    on a bad frame (the caller records the error)."""
    from clrender.scene.camera import with_overrides
    start = _time.perf_counter()
    scene = _scene(task.scene, task.allow, task.variant)
    previous = scene.pose(task.time, None if task.view is not None else task.dt)    # a view: no motion (None)
    camera, o = task.view or scene.default_camera(), task.camera
    if task.view is None and o != CameraOverride():   # (scene.bounds() costs ~20 ms on Sponza: only when needed)
        bounds = scene.bounds()
        camera = with_overrides(camera, bounds, o.eye, o.target, o.fov, o.ortho)
        if previous is not None:
            previous = with_overrides(previous, bounds, o.eye, o.target, o.fov, o.ortho)
    width, height = scene_size(scene, task.width, task.height)
    _spare_inputs(task, scene)
    from clrender.device.probe import worker_device_spec
    renderer = _renderer(worker_device_spec(task.device), width, height, scene_config(scene, dict(task.options)))
    render_start = _time.perf_counter()
    frame = renderer.render(scene, camera, previous_camera=previous, time=task.time)
    render_ms = (_time.perf_counter() - render_start) * 1e3
    if task.outputs.layout == "dataset":
        from clrender.dataset.outputs import write_view
        write_view(frame, Path(task.image), task.outputs.aovs, task.outputs.exr, task.outputs.depth_scale)
    else:
        write_outputs(frame, Path(task.image), task.outputs.aovs, bit_depth=task.outputs.bit_depth,
                      exr=task.outputs.exr, sheet=task.outputs.sheet)
    return {"status": "ok", "time": task.time, "outputs": [str(p) for p in task.paths()],
            "device": frame.stats.get("device"), "worker": f"{socket.gethostname()}:{os.getpid()}",
            "size": [width, height], "render_ms": render_ms,
            "wall_ms": (_time.perf_counter() - start) * 1e3, "stats": frame.stats}
