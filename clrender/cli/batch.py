"""`clrender render ... --frames/--time-range/--resume/--workers/--scheduler`: the batch route of
the CLI, a thin layer over `clrender.batch`. Every check that can fail (ranges, output pattern,
output folder, ffmpeg, the scheduler's address) runs before the first frame renders."""
from __future__ import annotations

import logging
import os
import sys
from contextlib import contextmanager
from pathlib import Path

from clrender.batch import frames as _frames
from clrender.outputs.aov_io import write_video
from clrender.batch.jobs import CameraOverride, Outputs, plan_tasks, run_tasks
from clrender.cli.common import (
    PROG, CLIError, _note, _one_line, allowed_folders, check_output_options, check_outputs_spare_inputs,
    check_writable, input_files)

SCHEDULER_TIMEOUT_S = 10


def _frame_numbers(args, fps: float) -> range:
    if args.frames is not None and args.time_range is not None:
        raise CLIError("--frames and --time-range exclude each other")
    if args.time is not None and args.time != 0.0:
        raise CLIError("--time is for a single frame; with --frames/--time-range the time is frame/fps")
    if args.previous_eye is not None or args.previous_target is not None:
        raise CLIError("--previous-eye/--previous-target are for a single frame; an animation gives the "
                       "previous camera")
    try:
        if args.time_range is not None:
            return _frames.parse_time_range(args.time_range, fps)
        if args.frames is None:
            return range(0, 1)
        if args.frames.strip().lower() == "all":
            from clrender.loaders import load_scene
            durations = [getattr(load_scene(s, allow=allowed_folders(args), variant=args.variant).animation,
                                 "duration", None)
                         for s in args.scenes]
            return _frames.animation_frames(max((d for d in durations if d), default=None), fps)
        return _frames.parse_frames(args.frames)
    except ValueError as exc:
        raise CLIError(str(exc)) from None


def _check_writable(folders) -> None:
    """Create each output folder and write a probe file in it: an unwritable output fails now,
    not after the first frame has rendered (clrender.cli.common.check_writable)."""
    check_writable(folders)


@contextmanager
def dask_client(args):
    """None (this process), a LocalCluster of --workers processes, or the --scheduler's cluster."""
    if args.workers is None and args.scheduler is None:
        yield None
        return
    if args.workers is not None and args.scheduler is not None:
        raise CLIError("--workers (a local cluster) and --scheduler (an existing one) exclude each other")
    try:
        from distributed import Client, LocalCluster
    except ImportError:
        raise CLIError("--workers/--scheduler need Dask: pip install 'dask[distributed]' "
                       "(or clrender[batch])") from None
    if args.scheduler is not None:
        try:
            client = Client(args.scheduler, timeout=f"{SCHEDULER_TIMEOUT_S}s")
        except (OSError, TimeoutError, ValueError) as exc:
            raise CLIError(f"--scheduler {args.scheduler}: cannot reach the scheduler ({_one_line(exc)})") from None
        with client:
            yield client
        return
    # Each worker process runs PoCL's own thread pool: share the cores out instead of
    # oversubscribing them (a user's POCL_CPU_MAX_CU_NUM wins).
    threads = max(1, (os.cpu_count() or 1) // args.workers)
    env = {"POCL_CPU_MAX_CU_NUM": os.environ.get("POCL_CPU_MAX_CU_NUM", str(threads)),
           "PYTHONWARNINGS": "ignore"}
    with LocalCluster(n_workers=args.workers, threads_per_worker=1, processes=True, dashboard_address=None,
                      silence_logs=logging.ERROR, env=env) as cluster, Client(cluster) as client:
        yield client


def _resources(text):
    if text is None:
        return None
    out = {}
    for part in text.split(","):
        name, _, value = part.partition("=")
        try:
            out[name.strip()] = float(value)
        except ValueError:
            raise CLIError(f"--resources {text}: expected NAME=N[,NAME=N]") from None
        if not name.strip():
            raise CLIError(f"--resources {text}: expected NAME=N[,NAME=N]")
    return out


def run_job(args, tasks, manifest_path, fps: float, what: str):
    """Run planned tasks here, on --workers or on --scheduler (--resume, --resources), with the
    notes of the CLI; prints one error line per failed frame and returns the BatchResult."""
    resources = _resources(args.resources)
    if resources and args.scheduler is None:
        raise CLIError("--resources goes with --scheduler (the workers of a local cluster have none)")
    with dask_client(args) as client:
        where = "in this process" if client is None else (
            f"on {args.workers} local Dask workers" if args.workers else f"on the Dask cluster {args.scheduler}")
        _note(args, f"{PROG}: {what} {where}")
        try:
            result = run_tasks(tasks, manifest_path, fps, client=client, resume=args.resume, quiet=args.quiet,
                               resources=resources)
        except ValueError as exc:
            raise CLIError(str(exc)) from None
    rate = len(result.rendered) / result.wall_s if result.wall_s > 0 else 0.0
    _note(args, f"{PROG}: {len(result.rendered)} rendered, {len(result.skipped)} already complete, "
                f"{len(result.failed)} failed in {result.wall_s:.1f} s ({rate:.2f} frames/s); "
                f"manifest {result.manifest}")
    for scene, frame, error in result.failed:
        print(f"{PROG}: error: {scene} frame {frame}: {error}", file=sys.stderr, flush=True)
    return result


def cmd_render_frames(args, options: dict) -> int:
    fps = 24.0 if args.fps is None else args.fps
    if not (0 < fps < float("inf")):
        raise CLIError(f"--fps: expected a positive number, got {fps!r}")
    numbers = _frame_numbers(args, fps)
    camera = CameraOverride(args.camera_eye, args.camera_target, args.fov, args.ortho)
    if args.fov is not None and args.ortho is not None:
        raise CLIError("--fov (perspective) and --ortho (orthographic) exclude each other")
    try:
        tasks, manifest_path = plan_tasks(args.scenes, numbers, args.output, fps, width=args.width,
                                          height=args.height, outputs=Outputs(tuple(args.aov), args.bit_depth, args.exr,
                                                          args.aov_sheet),
                                          options=tuple(sorted(options.items())), camera=camera, device=args.device,
                                          allow=allowed_folders(args), variant=args.variant)
    except ValueError as exc:
        raise CLIError(str(exc)) from None
    check_output_options(args, [t.image for t in tasks.samples()])     # a lazy plan: first and last frames
    # Every file the scenes read (loaded here once: an in-process job renders from this cache) must
    # survive the job: no image, AOV, manifest or video may be written over one
    from clrender.batch.jobs import _scene
    scenes = []
    for s in args.scenes:
        try:
            scenes.append(_scene(s, allowed_folders(args), args.variant))
        except (ValueError, OSError) as exc:
            raise CLIError(_one_line(exc) if s in str(exc) else f"{s}: {_one_line(exc)}") from None
    extra = [manifest_path] + ([Path(args.video)] if args.video else [])
    inputs = input_files(scenes)        # a lazy plan: only the frames whose numbers the inputs' names hold
    check_outputs_spare_inputs([*tasks.output_paths(near=inputs), *extra], inputs)
    _check_writable([*tasks.folders(), manifest_path.parent])
    result = run_job(args, tasks, manifest_path, fps, f"{len(tasks)} frame(s) of {len(args.scenes)} scene(s)")
    if result.failed:
        print(f"{PROG}: error: {len(result.failed)} of {len(tasks)} frames failed"
              + (f"; {args.video} not written" if args.video else ""), file=sys.stderr, flush=True)
        return 1
    if args.video is not None:
        try:
            write_video(args.video, list(result.images), fps)
        except (ValueError, RuntimeError, OSError) as exc:
            raise CLIError(f"--video {args.video}: {_one_line(exc)}") from None
        _note(args, f"{PROG}: {len(result.images)} frame(s) -> {args.video} ({fps:g} fps)")
    return 0
