"""`clrender render`: one still per scene (the frames and cluster route: clrender/cli/batch.py; one
image per camera of a camera file: clrender/cli/camera_route.py), the camera and environment
flags, and the output plan checked before anything renders."""
from __future__ import annotations

import os
import sys
import time
from pathlib import Path
from typing import Optional, Sequence

import numpy as np

from clrender.batch.jobs import scene_size
from clrender.cli.common import (  # noqa: F401  (the environment names: clrender.cli.render.X before they moved)
    ENVIRONMENT_FLAGS, IMAGE_SUFFIXES, PROG, CLIError, OutputOverInput, _debug, _format_stats, _load, _note,
    _one_line, _scene_config, apply_environment, describe_environment, environment_option,
    batch_requested, check_output_options, check_outputs_spare_inputs, check_writable, input_files,
    is_folder_output, one_image_output, render_options)
from clrender.outputs.aov_io import aov_paths, write_outputs, write_video


def _previous_camera(camera, args):
    """--previous-eye/--previous-target: the camera of the previous frame (velocity, motion blur)."""
    from clrender.scene.camera import Camera
    if args.previous_eye is None and args.previous_target is None:
        return None
    eye = args.previous_eye if args.previous_eye is not None else camera.eye
    target = args.previous_target if args.previous_target is not None else camera.target
    try:
        if camera.is_orthographic:
            return Camera.orthographic(eye, target, camera.up, camera.xmag, camera.ymag, camera.near, camera.far)
        return Camera.look_at(eye, target, camera.up, camera.fov_y_deg, near=camera.near, far=camera.far)
    except ValueError as exc:
        raise CLIError(f"--previous-eye/--previous-target: {exc}") from None


def _camera(scene, args):
    """The scene's camera (or the framing default) with the command-line overrides applied."""
    from clrender.scene.camera import with_overrides
    try:
        return with_overrides(scene.default_camera(), scene.bounds(), args.camera_eye, args.camera_target,
                              args.fov, getattr(args, "ortho", None))
    except ValueError as exc:
        raise CLIError(str(exc)) from None


def _plan_outputs(scenes: list[str], out: str) -> list[Path]:
    """One image path per scene, checked before anything is rendered."""
    n = len(scenes)
    if "{" in out:
        paths = []
        for index, scene in enumerate(scenes, 1):
            try:
                text = out.format(name=Path(scene).stem, index=index)
            except (KeyError, IndexError, ValueError) as exc:
                raise CLIError(f"bad output pattern {out!r}: use {{name}} and {{index}} only ({exc})") from None
            p = Path(text)
            if p.suffix.lower() not in IMAGE_SUFFIXES:
                p = p.with_name(p.name + ".png")
            paths.append(p)
        if n > 1 and len({str(p) for p in paths}) == 1:
            raise CLIError(f"output pattern {out!r} gives the same file for every scene; use {{name}}")
        return paths
    if not is_folder_output(out):
        return one_image_output(out, n, f"{n} scenes but one output file {out!r}: give a directory or a pattern "
                                        f"containing {{name}}", "{name}")
    return [Path(out) / f"{Path(scene).stem}.png" for scene in scenes]


def _check_distinct(scenes: list[str], images: list[Path], aovs: Sequence[str], exr: bool,
                    video: Optional[str] = None, sheet: bool = False) -> None:
    """Refuse to write any file twice in one run, or over an input scene."""
    owner: dict[str, str] = {}
    inputs = {os.path.realpath(s): s for s in scenes}
    if video is not None:
        owner[os.path.realpath(video)] = "--video"
        if os.path.realpath(video) in inputs:
            raise CLIError(f"--video {video} would overwrite the input scene {video}")
    for scene, image in zip(scenes, images):
        for p in [image, *aov_paths(image, aovs, exr, sheet)]:
            key = os.path.realpath(p)
            if key in inputs:
                raise CLIError(f"output {p} would overwrite the input scene {inputs[key]}")
            if key in owner:
                raise CLIError(f"two outputs would be written to {p} (scenes {owner[key]} and {scene}); "
                               f"use a pattern with {{name}}/{{index}} or separate runs")
            owner[key] = scene


def cmd_render(args) -> int:
    from clrender.render.renderer import Renderer

    options = render_options(args)
    if getattr(args, "camera", None) is not None:       # one image per camera of a camera file
        from clrender.cli.camera_route import cmd_render_cameras
        return cmd_render_cameras(args, options)
    if batch_requested(args):
        given = [flag for name, flag in ENVIRONMENT_FLAGS.items() if getattr(args, name, None) is not None]
        if given:
            raise CLIError(f"{given[0]}: not supported with --frames/--time-range/--resume/--workers/--scheduler "
                           f"yet (use a TOML [environment] table)")
        from clrender.cli.batch import cmd_render_frames
        return cmd_render_frames(args, options)
    scenes = list(args.scenes)
    images = _plan_outputs(scenes, args.output)
    bit_depth = getattr(args, "bit_depth", 8)
    exr = bool(getattr(args, "exr", False))
    video = getattr(args, "video", None)
    fps = 24.0 if getattr(args, "fps", None) is None else args.fps
    check_output_options(args, images)
    if video is not None:
        if not (np.isfinite(fps) and fps > 0):
            raise CLIError(f"--fps: expected a positive number, got {fps!r}")
    elif getattr(args, "fps", None) is not None:
        _note(args, f"{PROG}: note: --fps has no effect on a still without --video")
    _check_distinct(scenes, images, args.aov, exr, video, args.aov_sheet)
    environment = environment_option(args)
    outputs = [p for image in images for p in (image, *aov_paths(image, args.aov, exr, args.aov_sheet))]
    outputs += [Path(video)] if video is not None else []
    check_writable([p.parent for p in outputs], {p.parent: p for p in reversed(outputs)})
    env_file = getattr(args, "environment", None)
    extra = [(env_file, "--environment")] if env_file and Path(env_file).is_file() else []
    check_outputs_spare_inputs(outputs, input_files([], extra))
    if len(scenes) > 1 and any(os.path.lexists(p) for p in outputs):
        # An output of one scene may be a file a later scene reads: know every scene's files first
        # (only when an output exists already: a file not there yet cannot be anyone's input)
        for scene_path in scenes:
            try:
                check_outputs_spare_inputs(outputs, input_files([_load(scene_path, args)]))
            except (ValueError, OSError):        # the render loop reports it, in order
                pass
    written: list[Path] = []
    # The device (its probe, on a first run) and the kernels of the flags' configuration get ready
    # on another thread while the first scene loads: both are mostly waiting (a child process, the
    # OpenCL compiler), and loading is mostly Python.
    from clrender.tools.warmup import prepare_in_background
    ready = prepare_in_background(args.device, options)
    info = None

    renderers: dict = {}            # one per resolution (normally exactly one); kernels build once
    failures = 0
    n = len(scenes)
    for index, (scene_path, image) in enumerate(zip(scenes, images), 1):
        scene_start = time.monotonic()
        try:
            scene = _load(scene_path, args)
            check_outputs_spare_inputs(outputs, input_files([scene], extra))
            if scene.animation is not None:       # a still of an animated scene: posed at --time
                scene.pose(args.time)
            apply_environment(scene, args, environment)
            width, height = scene_size(scene, args.width, args.height)
            camera = _camera(scene, args)
            config = _scene_config(scene, options)
            if info is None:
                info = ready.result()          # raises what the device selection raised
            renderer = renderers.get((width, height, config))
            if renderer is None:
                renderer = renderers[(width, height, config)] = Renderer(width, height, device=info, config=config)
            start = time.perf_counter()
            frame = renderer.render(scene, camera, previous_camera=_previous_camera(camera, args), time=args.time)
            wall_ms = (time.perf_counter() - start) * 1e3
            write_outputs(frame, image, args.aov, bit_depth=bit_depth, exr=exr, sheet=args.aov_sheet)
            written.append(image)
        except (CLIError, ValueError, OSError) as exc:     # SceneError is a ValueError
            from clrender.interrupt import raise_if_interrupted
            raise_if_interrupted(scene_start)      # a failure a Ctrl-C caused ends the job
            if n == 1 or _debug() or isinstance(exc, OutputOverInput):     # the whole job's error
                raise
            failures += 1
            message = _one_line(exc)
            if scene_path not in message:
                message = f"{scene_path}: {message}"
            print(f"{PROG}: error: {message}", file=sys.stderr, flush=True)
            continue
        _note(args, f"[{index}/{n}] {scene_path} -> {image} ({wall_ms:.1f} ms, "
                    f"{scene.triangle_count} triangles, {width}x{height}; "
                    f"environment: {describe_environment(scene)})")
        _note(args, "    " + _format_stats(frame.stats))
    if video is not None and written:
        try:
            write_video(video, written, fps)
        except (ValueError, RuntimeError, OSError) as exc:
            raise CLIError(f"--video {video}: {_one_line(exc)}") from None
        _note(args, f"{PROG}: {len(written)} frame(s) -> {video} ({fps:g} fps)")
    if failures:
        print(f"{PROG}: error: {failures} of {n} scenes failed", file=sys.stderr, flush=True)
        return 1
    return 0
