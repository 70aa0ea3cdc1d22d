"""Batch rendering: the frames of a job, in this process or on a Dask cluster.

    from clrender.batch import render_frames
    result = render_frames("scene.gltf", range(0, 48), "out/frame_{frame:04d}.png", fps=24)
    result = render_frames("scene.gltf", range(0, 48), "out/", client=dask_client)

A job is a list of `FrameTask`s, one per (scene, frame): plain data that pickles, so the same
`render_task` runs here or on a Dask worker. Frame f shows the scene at t = f / fps, posed with
`Scene.pose(t, 1 / fps)` (glTF or TOML keyframe animation; the pose at t − 1/fps gives the
velocity AOV), light particles placed at t. A task with a `view` (`clrender dataset`,
clrender/cli/dataset.py) renders that camera instead, the scene posed at its time without motion,
and with `Outputs(layout="dataset")` writes the export's folders (clrender/dataset/outputs.py).

The task and its rendering, with each process's caches of scenes and renderers (the worker
side): clrender/batch/tasks.py.

Workers write their outputs themselves, to the shared output folder, with the atomic writes of
`clrender.outputs.aov_io`, and return their record; the client keeps the manifest
(`clrender.batch.manifest`) and the progress bar. A task whose worker dies is re-run by Dask on
another worker (`distributed.scheduler.allowed-failures` times); a frame that fails with an
error is recorded as failed, with its message, and the other frames go on.
"""
from __future__ import annotations

import dataclasses
import hashlib
import itertools
import os
import sys
import time as _time
import uuid
from dataclasses import dataclass, field
from pathlib import Path
from collections.abc import Sequence
from typing import Iterable, Iterator, Optional

from clrender.batch import frames as _frames
from clrender.batch.manifest import MANIFEST_NAME, Manifest, manifest_folder
# render_task is looked up here when a job runs (tests replace clrender.batch.jobs.render_task); the
# other names are re-exported: clrender.batch.jobs.X (and clrender.batch.X) predate tasks.py.
from clrender.batch.tasks import (DEFAULT_SIZE, CameraOverride, FrameTask, Outputs, _scene,  # noqa: F401
                                  render_task, scene_config, scene_size)

# The manifest is rewritten at most this often (and when the job ends, however it ends): a
# rewrite of 2400 frames' records takes ~0.1 s. A kill loses at most this much of the record; the
# frames it held are complete on disk and --resume renders them again.
MANIFEST_INTERVAL_S = 1.0
VERSION = "0.1.0"
DASK_IN_FLIGHT = 1024            # frames submitted to a Dask cluster ahead of the finished ones


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


# -- the client side --------------------------------------------------------------------------
class TaskPlan(Sequence):
    """The tasks of scenes x frames, made when asked for: a job of a hundred million frames costs
    nothing until its frames render (`--frames 0:100000000` starts with frame 0 at once, memory
    flat). Scene-major order (every frame of the first scene, then the next scene's), like the list
    it replaces; indexing and iterating give `FrameTask`s."""

    def __init__(self, scenes: Sequence[str], frames: Sequence[int], fps: float, pattern: str, fields: dict):
        self.scenes = [str(s) for s in scenes]
        self.frames = frames                    # a range (or a list the caller gave)
        self.fps, self.pattern, self.fields = fps, pattern, fields

    def __len__(self) -> int:
        return len(self.scenes) * len(self.frames)

    def task(self, scene: str, frame: int) -> FrameTask:
        time = frame / self.fps
        image = _frames.image_path(self.pattern, scene, _frames.FrameTime(int(frame), time))
        return FrameTask(scene=scene, frame=int(frame), time=time, dt=1.0 / self.fps, image=str(image), **self.fields)

    def __getitem__(self, index):
        if isinstance(index, slice):
            return [self[i] for i in range(len(self))[index]]
        n = len(self.frames)
        index = range(len(self))[index]         # negative indices; IndexError past the end
        return self.task(self.scenes[index // n], self.frames[index % n])

    def __iter__(self):
        for scene in self.scenes:
            for frame in self.frames:
                yield self.task(scene, frame)

    def find(self, scene: str, frame: int) -> Optional[FrameTask]:
        """The task of (scene, frame), or None when the job has no such frame."""
        return self.task(scene, frame) if scene in self.scenes and frame in self.frames else None

    @property
    def lazy(self) -> bool:
        """Whether the job is too large to make every task before it starts (frames.EAGER_CHECK_LIMIT)."""
        return len(self) > _frames.EAGER_CHECK_LIMIT

    def samples(self) -> list:
        """All tasks of a small job; the first and last of each scene of a lazy one (whose pattern
        has no field in its folders and a plain {frame}: they write the same folders and types)."""
        if not self.lazy:
            return list(self)
        return [self.task(s, f) for s in self.scenes for f in dict.fromkeys((self.frames[0], self.frames[-1]))]

    def folders(self) -> set:
        """Every folder the job writes into (the samples' folders: see `samples`)."""
        return {p.parent for t in self.samples() for p in t.paths()}

    def output_paths(self, near=()) -> Iterator[Path]:
        """Every output of a small job. Of a lazy one, the outputs of the tasks whose frame number is
        written in one of the paths `near` (frames.frame_candidates): the only ones that can be one
        of those files, since a lazy job's file names hold their frame number."""
        if not self.lazy:
            yield from (p for t in self for p in t.paths())
            return
        for scene in self.scenes:
            for frame in sorted({f for p in near for f in _frames.frame_candidates(p)}):
                if frame in self.frames:
                    yield from self.task(scene, frame).paths()


def plan_tasks(scenes: Sequence[str], frame_numbers: Iterable[int], out: str, fps: float = 24.0, **task_fields
               ) -> tuple[TaskPlan, Path]:
    """The tasks of scenes x frames writing to `out` (a pattern, folder or file), as a lazy
    `TaskPlan`, and the manifest path; ValueError for a bad pattern or two frames sharing a file
    (frames.check_images)."""
    if not (fps > 0 and fps < float("inf")):
        raise ValueError(f"fps must be a positive number, got {fps!r}")
    frames = frame_numbers if isinstance(frame_numbers, range) else [int(f) for f in frame_numbers]
    if not len(frames):
        raise ValueError("no frames to render")
    pattern = _frames.output_pattern(out, len(scenes) > 1)
    _frames.check_images(pattern, [str(s) for s in scenes], frames, fps)
    return TaskPlan(scenes, frames, fps, pattern, task_fields), manifest_folder(pattern) / MANIFEST_NAME


def job_signature(tasks: Sequence[FrameTask], fps: float) -> dict:
    """What must match for --resume to trust an earlier run's frames."""
    t = tasks[0]
    scenes = {}
    names = tasks.scenes if isinstance(tasks, TaskPlan) else (task.scene for task in tasks)
    for s in dict.fromkeys(names):
        st = os.stat(s)
        scenes[s] = {"bytes": st.st_size, "mtime_ns": st.st_mtime_ns}
    job = {"scenes": scenes, "fps": fps, "width": t.width, "height": t.height, "options": dict(t.options),
           "aovs": list(t.outputs.aovs), "bit_depth": t.outputs.bit_depth, "exr": t.outputs.exr,
           "camera": dataclasses.asdict(t.camera), "device": t.device}
    # Only when used, so the signature of a plain frames job (and --resume of older folders) is unchanged.
    if t.outputs.layout != "stem":
        job.update(layout=t.outputs.layout, depth_scale=t.outputs.depth_scale)
    if t.variant is not None:           # only when used, as above
        job["variant"] = t.variant
    if not isinstance(tasks, TaskPlan) and any(task.view is not None for task in tasks):
        # repr of floats is exact: any changed number differs (a TaskPlan has no views)
        job["views"] = hashlib.sha256(repr([task.view for task in tasks]).encode()).hexdigest()
    return job


def _error_line(error: BaseException) -> str:
    """One line: the message of an expected error (bad scene, file, value), else its type too."""
    text = (str(error).strip().splitlines() or [""])[0]
    if isinstance(error, (ValueError, OSError)) and text:
        return text
    return f"{type(error).__name__}: {text}" if text else type(error).__name__


def _local_results(tasks):
    from clrender.interrupt import raise_if_interrupted
    for task in tasks:
        start = _time.monotonic()
        try:
            yield task, render_task(task), None
        except Exception as exc:        # one bad frame must not lose the others
            raise_if_interrupted(start)   # ... but a failure a Ctrl-C caused ends the job
            yield task, None, exc


def _dask_results(tasks, client, resources, retries: int):
    from distributed import as_completed

    from clrender.batch.dask_plugin import WarmupPlugin
    pending = iter(tasks)                   # `tasks` may be a generator (run_tasks' todo)
    first = next(pending, None)
    if first is None:
        return
    # Every worker, and any that joins later, builds the kernels once before its first frame.
    client.register_plugin(WarmupPlugin(first.device, dict(first.options)))
    # At most DASK_IN_FLIGHT frames are submitted ahead: a job of millions of frames neither plans
    # nor submits them all up front; each finished frame lets the next one in.
    pending = itertools.chain([first], pending)
    futures: dict = {}
    completed = as_completed()

    def submit_next() -> None:
        task = next(pending, None)
        if task is not None:
            key = f"clrender-frame-{uuid.uuid4().hex[:8]}-{Path(task.scene).stem}-{task.frame}"
            future = client.submit(render_task, task, key=key, pure=False, retries=retries, resources=resources)
            futures[future] = task
            completed.add(future)

    for _ in range(DASK_IN_FLIGHT):
        submit_next()
    for future in completed:
        task = futures.pop(future)
        submit_next()
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


def _complete(tasks, manifest) -> tuple:
    """(scene, frame) of the tasks the manifest shows complete, in job order. Of a TaskPlan only the
    frames the manifest lists are looked at: the manifest is as large as the frames done, the job
    may be far larger."""
    if not isinstance(tasks, TaskPlan):
        return tuple((t.scene, t.frame) for t in tasks if manifest.is_done(t.scene, t.frame, t.paths()))
    position = ((lambda f: tasks.frames.index(f)) if isinstance(tasks.frames, range)
                else {f: i for i, f in enumerate(tasks.frames)}.__getitem__)
    done = []
    for scene, frame in list(manifest.records):
        task = tasks.find(scene, frame)
        if task is not None and manifest.is_done(scene, frame, task.paths()):
            done.append((tasks.scenes.index(scene), position(frame), scene, frame))
    return tuple((scene, frame) for *_, scene, frame in sorted(done))


class _FinishedImages(Sequence):
    """The images of a job's tasks that did not fail, in job order, made as they are read."""

    def __init__(self, tasks, failed: set):
        self.tasks, self.failed = tasks, failed

    def __iter__(self):
        return (Path(t.image) for t in self.tasks if (t.scene, t.frame) not in self.failed)

    def __len__(self) -> int:
        return len(self.tasks) - len(self.failed)

    def __getitem__(self, index):
        if isinstance(index, slice):
            return list(self)[index]
        index = range(len(self))[index]
        return next(p for i, p in enumerate(self) if i == index)


def _remove_leftovers(tasks, manifest_path) -> None:
    """--resume: remove the temporary files a killed run left beside the job's outputs (each folder
    once; frames found complete are not rewritten, so their folders would otherwise keep them)."""
    from clrender.outputs.aov_io import remove_stale_temps
    folders = {Path(manifest_path).parent}
    if isinstance(tasks, TaskPlan):         # its folders without making every task
        folders.update(tasks.folders())
    else:
        for task in tasks:
            folders.update(p.parent for p in task.paths())
    for folder in folders:
        remove_stale_temps(folder, force=True)


def run_tasks(tasks: Sequence[FrameTask], manifest_path, fps: float = 24.0, client=None, resume: bool = False,
              quiet: bool = True, resources: Optional[dict] = None, retries: int = 0) -> BatchResult:
    """Render `tasks` (skipping, with `resume`, those the manifest shows complete), in this
    process or on `client`'s Dask cluster, keeping the manifest and a progress bar."""
    start = _time.perf_counter()
    manifest = Manifest.open(manifest_path, job_signature(tasks, fps), VERSION, resume)
    if resume:
        _remove_leftovers(tasks, manifest.path)
    run = uuid.uuid4().hex[:12]
    skipped = _complete(tasks, manifest) if resume else ()
    skip = set(skipped)
    todo = (t for t in tasks if (t.scene, t.frame) not in skip)     # lazily: a TaskPlan's tasks as they render
    progress = _Progress(len(tasks) - len(skipped), quiet)
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
    images = _FinishedImages(tasks, {(s, f) for s, f, _ in failed})
    if not isinstance(tasks, TaskPlan):
        images = tuple(images)
    return BatchResult(tuple(rendered), skipped, tuple(failed), manifest.path, images,
                       _time.perf_counter() - start)


def render_frames(scene_path, frames: Iterable[int], out, client=None, *, fps: float = 24.0,
                  width: Optional[int] = None, height: Optional[int] = None, aovs: Sequence[str] = (),
                  bit_depth: int = 8, exr: bool = False, device: Optional[str] = None, resume: bool = False,
                  quiet: bool = True, resources: Optional[dict] = None, allow: Sequence = (),
                  variant: Optional[str] = None, **options) -> BatchResult:
    """Render frames `frames` (numbers; frame f at t = f / fps) of one scene file into `out` (a
    pattern with {name}/{frame}/{time}, or a folder: out/<name>_<frame:04d>.png), on `client`
    (a dask.distributed Client) or in this process. `options` are RenderConfig options; `allow`:
    folders outside the scene file's own that its references may read (load_scene's `allow`);
    `variant`: the glTF material variant to render (load_scene's `variant`)."""
    if not Path(scene_path).is_file():
        raise FileNotFoundError(f"{scene_path}: file not found")
    tasks, manifest_path = plan_tasks([str(scene_path)], frames, str(out), fps, width=width, height=height,
                                      outputs=Outputs(tuple(aovs), bit_depth, exr),
                                      options=tuple(sorted(options.items())), device=device,
                                      allow=tuple(str(Path(p).resolve()) for p in
                                                  ([allow] if isinstance(allow, (str, os.PathLike)) else allow)),
                                      variant=variant)
    return run_tasks(tasks, manifest_path, fps, client=client, resume=resume, quiet=quiet, resources=resources)
