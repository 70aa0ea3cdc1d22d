"""Batch rendering: the frames of a job, in this process or on a Dask cluster.

    from clrender.batch import render_frames
    result = render_frames("scene.gltf", range(0, 48), "out/frame_{frame:04d}.png", fps=24)
    result = render_frames("scene.gltf", range(0, 48), "out/", client=dask_client)

A job is a list of `FrameTask`s, one per (scene, frame): plain data that pickles, so the same
`render_task` runs here or on a Dask worker. Frame f shows the scene at t = f / fps, posed with
`Scene.pose(t, 1 / fps)` (glTF or TOML keyframe animation; the pose at t − 1/fps gives the
velocity AOV), light particles placed at t. A task with a `view` (`clrender dataset`,
clrender/cli_dataset.py) renders that camera instead, the scene posed at its time without motion,
and with `Outputs(layout="dataset")` writes the export's folders (clrender/dataset_outputs.py).

Each process (this one, or each Dask worker process) keeps its loaded scenes, keyed by path,
mtime and size, and one `Renderer` per (device, size, config): programs build and scenes load
once per process, not per frame. The device of a worker is, in order: the job's `device`, the
worker's $CLRENDER_DEVICE, the first GPU when the Dask worker has a `GPU` resource, else the
default device. So GPU workers (`dask worker ... --resources GPU=1`) and PoCL workers
(`CLRENDER_DEVICE=pocl dask worker ...`) can serve one cluster; `resources={"GPU": 1}` sends a
job to the GPU workers only.

Workers write their outputs themselves, to the shared output folder, with the atomic writes of
`clrender.aov_io`, and return their record; the client keeps the manifest
(`clrender.manifest`) and the progress bar. A task whose worker dies is re-run by Dask on
another worker (`distributed.scheduler.allowed-failures` times); a frame that fails with an
error is recorded as failed, with its message, and the other frames go on.
"""
from __future__ import annotations

import dataclasses
import hashlib
import os
import socket
import sys
import time as _time
import uuid
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterable, Optional, Sequence

from . import frames as _frames
from .aov_io import aov_paths, write_outputs
from .camera import Camera
from .manifest import MANIFEST_NAME, Manifest, manifest_folder

DEFAULT_SIZE = (1280, 720)
# The manifest is rewritten at most this often (and when the job ends, however it ends): a
# rewrite of 2400 frames' records takes ~0.1 s. A kill loses at most this much of the record; the
# frames it held are complete on disk and --resume renders them again.
MANIFEST_INTERVAL_S = 1.0
VERSION = "0.1.0"


@dataclass(frozen=True)
class Outputs:
    """What each frame writes beside its image (clrender.aov_io.write_outputs)."""
    aovs: tuple = ()
    bit_depth: int = 8
    exr: bool = False
    sheet: bool = False          # <stem>.sheet.png: the image and the AOV previews, labelled
    # "stem": <stem>.<aov>.npy/png beside the image; "dataset": the folders of a `clrender dataset`
    # export (images/, depth/, masks/, aovs/, exr/: clrender.dataset_outputs)
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

    def paths(self) -> list[Path]:
        if self.outputs.layout == "dataset":
            from .dataset_outputs import view_paths
            return view_paths(Path(self.image), self.outputs.aovs, self.outputs.exr)
        return [Path(self.image), *aov_paths(Path(self.image), self.outputs.aovs, self.outputs.exr, self.outputs.sheet)]


@dataclass(frozen=True)
class BatchResult:
    """What a job did: frames rendered now, skipped by --resume, failed (with their errors)."""
    rendered: tuple
    skipped: tuple
    failed: tuple                       # (scene, frame, error)
    manifest: Optional[Path]
    images: tuple                       # every finished frame's image, in job order
    wall_s: float

    @property
    def ok(self) -> bool:
        return not self.failed


# -- settings shared with the CLI -------------------------------------------------------------
def scene_size(scene, width: Optional[int], height: Optional[int]) -> tuple[int, int]:
    """width/height, else the scene's [render] size, else 1280x720; one given keeps the aspect."""
    settings = scene.settings.get("render", {}) if isinstance(scene.settings, dict) else {}
    dw, dh = settings.get("width"), settings.get("height")
    dw = dw if isinstance(dw, int) and dw > 0 else DEFAULT_SIZE[0]
    dh = dh if isinstance(dh, int) and dh > 0 else DEFAULT_SIZE[1]
    if width is None and height is None:
        return dw, dh
    if width is None:
        width = max(1, round(height * dw / dh))
    if height is None:
        height = max(1, round(width * dh / dw))
    return width, height


def scene_config(scene, options: dict):
    """The scene's [render] options (TOML) with `options` on top; ValueError names the table."""
    from .renderer import RenderConfig
    settings = scene.settings.get("render", {}) if isinstance(scene.settings, dict) else {}
    names = {f.name for f in dataclasses.fields(RenderConfig)}
    try:
        return RenderConfig.from_options(**{**{k: v for k, v in settings.items() if k in names}, **options})
    except ValueError as exc:
        raise ValueError(f"{scene.source}: [render]: {exc}") from None


# -- the worker side --------------------------------------------------------------------------
_SCENES: dict = {}                       # path -> ((mtime_ns, size), Scene)
_RENDERERS: dict = {}                    # (device id, w, h, config) -> Renderer


def _scene(path: str):
    from .loaders import load_scene
    st = os.stat(path)
    stamp = (st.st_mtime_ns, st.st_size)
    cached = _SCENES.get(path)
    if cached is None or cached[0] != stamp:
        _SCENES[path] = cached = (stamp, load_scene(path))
    return cached[1]


def _renderer(device_spec, width: int, height: int, config):
    from .device_probe import default_device_info
    from .renderer import Renderer
    info = default_device_info(device_spec)
    key = (info.id, width, height, config)
    renderer = _RENDERERS.get(key)
    if renderer is None:
        renderer = _RENDERERS[key] = Renderer(width, height, device=info, config=config)
    return renderer


def render_task(task: FrameTask) -> dict:
    """Render one frame and write its outputs; returns its manifest record (status ok). Raises
    on a bad frame (the caller records the error)."""
    from .camera import with_overrides
    start = _time.perf_counter()
    scene = _scene(task.scene)
    previous = scene.pose(task.time, None if task.view is not None else task.dt)    # a view: no motion (None)
    camera, o = task.view or scene.default_camera(), task.camera
    if task.view is None and o != CameraOverride():   # (scene.bounds() costs ~20 ms on Sponza: only when needed)
        bounds = scene.bounds()
        camera = with_overrides(camera, bounds, o.eye, o.target, o.fov, o.ortho)
        if previous is not None:
            previous = with_overrides(previous, bounds, o.eye, o.target, o.fov, o.ortho)
    width, height = scene_size(scene, task.width, task.height)
    from .device_probe import worker_device_spec
    renderer = _renderer(worker_device_spec(task.device), width, height, scene_config(scene, dict(task.options)))
    render_start = _time.perf_counter()
    frame = renderer.render(scene, camera, previous_camera=previous, time=task.time)
    render_ms = (_time.perf_counter() - render_start) * 1e3
    if task.outputs.layout == "dataset":
        from .dataset_outputs import write_view
        write_view(frame, Path(task.image), task.outputs.aovs, task.outputs.exr, task.outputs.depth_scale)
    else:
        write_outputs(frame, Path(task.image), task.outputs.aovs, bit_depth=task.outputs.bit_depth,
                      exr=task.outputs.exr, sheet=task.outputs.sheet)
    return {"status": "ok", "time": task.time, "outputs": [str(p) for p in task.paths()],
            "device": frame.stats.get("device"), "worker": f"{socket.gethostname()}:{os.getpid()}",
            "size": [width, height], "render_ms": render_ms,
            "wall_ms": (_time.perf_counter() - start) * 1e3, "stats": frame.stats}


# -- the client side --------------------------------------------------------------------------
def plan_tasks(scenes: Sequence[str], frame_numbers: Iterable[int], out: str, fps: float = 24.0, **task_fields
               ) -> tuple[list[FrameTask], Path]:
    """The tasks of scenes x frames writing to `out` (a pattern, folder or file), and the
    manifest path; ValueError for a bad pattern or two frames sharing a file."""
    if not (fps > 0 and fps < float("inf")):
        raise ValueError(f"fps must be a positive number, got {fps!r}")
    times = _frames.frame_times(list(frame_numbers), fps)
    if not times:
        raise ValueError("no frames to render")
    pattern = _frames.output_pattern(out, len(scenes) > 1)
    images = _frames.plan_images(pattern, scenes, times)
    tasks = [FrameTask(scene=str(s), frame=ft.frame, time=ft.time, dt=1.0 / fps, image=str(images[(s, ft.frame)]),
                       **task_fields) for s in scenes for ft in times]
    return tasks, manifest_folder(pattern) / MANIFEST_NAME


def job_signature(tasks: Sequence[FrameTask], fps: float) -> dict:
    """What must match for --resume to trust an earlier run's frames."""
    t = tasks[0]
    scenes = {}
    for s in dict.fromkeys(task.scene for task in tasks):
        st = os.stat(s)
        scenes[s] = {"bytes": st.st_size, "mtime_ns": st.st_mtime_ns}
    job = {"scenes": scenes, "fps": fps, "width": t.width, "height": t.height, "options": dict(t.options),
           "aovs": list(t.outputs.aovs), "bit_depth": t.outputs.bit_depth, "exr": t.outputs.exr,
           "camera": dataclasses.asdict(t.camera), "device": t.device}
    # Only when used, so the signature of a plain frames job (and --resume of older folders) is unchanged.
    if t.outputs.layout != "stem":
        job.update(layout=t.outputs.layout, depth_scale=t.outputs.depth_scale)
    if any(task.view is not None for task in tasks):     # repr of floats is exact: any changed number differs
        job["views"] = hashlib.sha256(repr([task.view for task in tasks]).encode()).hexdigest()
    return job


def _error_line(error: BaseException) -> str:
    """One line: the message of an expected error (bad scene, file, value), else its type too."""
    text = (str(error).strip().splitlines() or [""])[0]
    if isinstance(error, (ValueError, OSError)) and text:
        return text
    return f"{type(error).__name__}: {text}" if text else type(error).__name__


def _local_results(tasks):
    for task in tasks:
        try:
            yield task, render_task(task), None
        except Exception as exc:        # one bad frame must not lose the others
            yield task, None, exc


def _dask_results(tasks, client, resources, retries: int):
    from distributed import as_completed

    from .dask_plugin import WarmupPlugin
    # Every worker, and any that joins later, builds the kernels once before its first frame.
    if tasks:
        client.register_plugin(WarmupPlugin(tasks[0].device, dict(tasks[0].options)))
    futures = {}
    for task in tasks:
        key = f"clrender-frame-{uuid.uuid4().hex[:8]}-{Path(task.scene).stem}-{task.frame}"
        futures[client.submit(render_task, task, key=key, pure=False, retries=retries, resources=resources)] = task
    for future in as_completed(futures):
        task = futures[future]
        try:
            yield task, future.result(), None
        except Exception as exc:
            yield task, None, exc


@dataclass
class _Progress:
    total: int
    quiet: bool
    bar: object = field(default=None)

    def __post_init__(self):
        if not self.quiet:
            from tqdm import tqdm
            self.bar = tqdm(total=self.total, unit="frame", file=sys.stderr, dynamic_ncols=True,
                            bar_format="{l_bar}{bar}| {n_fmt}/{total_fmt} [{elapsed}<{remaining}, "
                                       "{rate_fmt}{postfix}]")

    def step(self, ms: Optional[float]) -> None:
        if self.bar is not None:
            if ms is not None:
                self.bar.set_postfix_str(f"{ms:.0f} ms/frame", refresh=False)
            self.bar.update(1)

    def write(self, message: str) -> None:
        if self.bar is not None:
            self.bar.write(message, file=sys.stderr)
        elif not self.quiet:
            print(message, file=sys.stderr, flush=True)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


def run_tasks(tasks: Sequence[FrameTask], manifest_path, fps: float = 24.0, client=None, resume: bool = False,
              quiet: bool = True, resources: Optional[dict] = None, retries: int = 0) -> BatchResult:
    """Render `tasks` (skipping, with `resume`, those the manifest shows complete), in this
    process or on `client`'s Dask cluster, keeping the manifest and a progress bar."""
    start = _time.perf_counter()
    manifest = Manifest.open(manifest_path, job_signature(tasks, fps), VERSION, resume)
    run = uuid.uuid4().hex[:12]
    todo = [t for t in tasks if not (resume and manifest.is_done(t.scene, t.frame, t.paths()))]
    queued = {(t.scene, t.frame) for t in todo}
    skipped = tuple((t.scene, t.frame) for t in tasks if (t.scene, t.frame) not in queued)
    progress = _Progress(len(todo), quiet)
    for scene, frame in skipped:
        manifest.mark_skipped(scene, frame, run)
    if skipped:
        progress.write(f"clrender: --resume: {len(skipped)} of {len(tasks)} frames already complete")
    rendered, failed, saved = [], [], -float("inf")
    results = _local_results(todo) if client is None else _dask_results(todo, client, resources, retries)
    try:
        for task, record, error in results:
            if error is None:
                manifest.record(task.scene, task.frame, dict(record, run=run))
                rendered.append((task.scene, task.frame))
            else:
                message = _error_line(error)
                manifest.record(task.scene, task.frame, {"status": "failed", "time": task.time, "run": run,
                                                         "error": message})
                failed.append((task.scene, task.frame, message))
                progress.write(f"clrender: error: {task.scene} frame {task.frame}: {message}")
            if _time.monotonic() - saved >= MANIFEST_INTERVAL_S:
                manifest.save()
                saved = _time.monotonic()
            progress.step(None if record is None else record["wall_ms"])
    finally:
        manifest.save()
        progress.close()
    done = {(t.scene, t.frame) for t in tasks} - {(s, f) for s, f, _ in failed}
    images = tuple(Path(t.image) for t in tasks if (t.scene, t.frame) in done)
    return BatchResult(tuple(rendered), skipped, tuple(failed), manifest.path, images,
                       _time.perf_counter() - start)


def render_frames(scene_path, frames: Iterable[int], out, client=None, *, fps: float = 24.0,
                  width: Optional[int] = None, height: Optional[int] = None, aovs: Sequence[str] = (),
                  bit_depth: int = 8, exr: bool = False, device: Optional[str] = None, resume: bool = False,
                  quiet: bool = True, resources: Optional[dict] = None, **options) -> BatchResult:
    """Render frames `frames` (numbers; frame f at t = f / fps) of one scene file into `out` (a
    pattern with {name}/{frame}/{time}, or a folder: out/<name>_<frame:04d>.png), on `client`
    (a dask.distributed Client) or in this process. `options` are RenderConfig options."""
    if not Path(scene_path).is_file():
        raise FileNotFoundError(f"{scene_path}: file not found")
    tasks, manifest_path = plan_tasks([str(scene_path)], frames, str(out), fps, width=width, height=height,
                                      outputs=Outputs(tuple(aovs), bit_depth, exr),
                                      options=tuple(sorted(options.items())), device=device)
    return run_tasks(tasks, manifest_path, fps, client=client, resume=resume, quiet=quiet, resources=resources)
