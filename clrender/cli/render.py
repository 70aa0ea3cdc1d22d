"""`clrender render`: one still per scene (the frames and cluster route: clrender/cli/batch.py),
the camera and environment flags, and the output plan checked before anything renders."""
from __future__ import annotations

import os
import sys
import time
from pathlib import Path
from typing import Optional, Sequence

import numpy as np

from clrender.batch.jobs import scene_size
from clrender.cli.common import (
    IMAGE_SUFFIXES, PROG, CLIError, OutputOverInput, _debug, _load, _note, _one_line, _scene_config,
    batch_requested, check_output_options, check_outputs_spare_inputs, check_writable, input_files,
    render_options)
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


ENVIRONMENT_FLAGS = {"environment": "--environment", "environment_intensity": "--environment-intensity",
                     "environment_rotation": "--environment-rotation"}


def environment_option(args):
    """--environment, loaded once for every scene: None (not given: each scene's own), "none", or
    the Environment (with --environment-intensity/--environment-rotation)."""
    text = getattr(args, "environment", None)
    intensity = getattr(args, "environment_intensity", None)
    rotation = getattr(args, "environment_rotation", None)
    if text is None:
        return None
    if text.strip().lower() == "none":
        if intensity is not None or rotation is not None:
            raise CLIError("--environment-intensity/--environment-rotation: there is no environment with "
                           "--environment none")
        return "none"
    from clrender.scene.environment import load_environment
    try:
        return load_environment(text, 1.0 if intensity is None else intensity, 0.0 if rotation is None else rotation)
    except ValueError as exc:
        raise CLIError(f"--environment: {_one_line(exc)}") from None


def apply_environment(scene, args, environment) -> None:
    """Put environment_option's result on a loaded scene: "none" removes the scene's environment
    (a TOML table's, load_scene's default studio), an Environment replaces it; without
    --environment, --environment-intensity/--environment-rotation change the scene's own (a
    CLIError when it has none)."""
    if isinstance(environment, str):                 # "none"
        scene.set_environment(None)
        return
    if environment is not None:
        if isinstance(scene.settings, dict):
            scene.settings.pop("default_environment", None)
        scene.environment = environment
        return
    intensity = getattr(args, "environment_intensity", None)
    rotation = getattr(args, "environment_rotation", None)
    if intensity is None and rotation is None:
        return
    if scene.environment is None:
        flag = "--environment-intensity" if intensity is not None else "--environment-rotation"
        raise CLIError(f"{flag}: {scene.source} has no environment to change (give --environment PATH|studio)")
    scene.environment = scene.environment.with_params(intensity=intensity, rotation_deg=rotation)


def describe_environment(scene) -> str:
    """"environment: ..." for the per-scene line: none, the source, "studio (default: the file has no lights)"."""
    from clrender.scene.environment import describe
    settings = scene.settings if isinstance(scene.settings, dict) else {}
    return describe(getattr(scene, "environment", None), default=bool(settings.get("default_environment")))


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
    target = Path(out)
    is_dir = target.is_dir() or out.endswith(("/", os.sep)) or target.suffix == ""
    if not is_dir:
        if target.suffix.lower() not in IMAGE_SUFFIXES:
            raise CLIError(f"output {out!r}: unsupported image type {target.suffix!r} "
                           f"(use {', '.join(IMAGE_SUFFIXES)}, a directory, or a pattern with {{name}})")
        if n > 1:
            raise CLIError(f"{n} scenes but one output file {out!r}: give a directory or a pattern "
                           f"containing {{name}}")
        return [target]
    return [target / f"{Path(scene).stem}.png" for scene in scenes]


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


def _format_stats(stats: dict) -> str:
    from clrender.render.pipeline import pass_ms
    parts = [f"{name[:-3]} {ms:.2f}" for name, ms in pass_ms(stats).items()]
    text = "passes (ms): " + ", ".join(parts)
    if "total_ms" in stats:
        text += f"; total {stats['total_ms']:.2f}"
    if "wall_ms" in stats:
        host = ", ".join(f"{k[:-3]} {v:.1f}" for k, v in stats.get("host", {}).items())
        text += f"; render() {stats['wall_ms']:.1f} (host: {host})"
    extra = [f"{k} {stats[k]}" for k in ("prims", "tile_entries", "retries") if k in stats]
    if "device_bytes" in stats:
        extra.append(f"device {stats['device_bytes'] / 2**20:.1f} MiB")
    if extra:
        text += "; " + ", ".join(extra)
    return text

