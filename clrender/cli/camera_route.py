"""`clrender render SCENE --camera FILE -o OUT`: one image per camera of a camera file (the shots
`clrender view` saves; clrender/dataset/camera_file.py), each with the scene posed at the camera's
"time" (else --time). Every check (the flags, the file, the output names, the folders) runs
before anything renders, and each image is Renderer(W, H, config).render(scene, camera, time=t)'s."""
from __future__ import annotations

import os
import string
import time
from pathlib import Path

from clrender.cli.common import (
    IMAGE_SUFFIXES, PROG, CLIError, _load, _note, _one_line, _scene_config, check_output_options,
    check_outputs_spare_inputs, check_writable, input_files, is_folder_output, one_image_output)
from clrender.outputs.aov_io import aov_paths, write_outputs, write_video

# flags the camera file replaces: (args attribute, flag, why)
_EXCLUDED = (
    ("camera_eye", "--camera-eye", "the file gives each camera's pose"),
    ("camera_target", "--camera-target", "the file gives each camera's pose"),
    ("fov", "--fov", "the file gives each camera's lens"),
    ("ortho", "--ortho", "the file gives each camera's lens"),
    ("frames", "--frames", "the file gives each camera's time"),
    ("time_range", "--time-range", "the file gives each camera's time"),
    ("previous_eye", "--previous-eye", "a camera of the file has no previous camera"),
    ("previous_target", "--previous-target", "a camera of the file has no previous camera"),
    ("resume", "--resume", "a camera file renders in this process"),
    ("workers", "--workers", "a camera file renders in this process"),
    ("scheduler", "--scheduler", "a camera file renders in this process"),
)


def _check_flags(args) -> None:
    for dest, flag, why in _EXCLUDED:
        if getattr(args, dest, None):
            raise CLIError(f"--camera and {flag} exclude each other ({why})")
    if len(args.scenes) != 1:
        raise CLIError(f"--camera renders one scene, got {len(args.scenes)} (run once per scene)")


def _safe_name(name) -> bool:
    return isinstance(name, str) and name not in (".", "..") and not any(c in name for c in "/\\\0")


def plan_camera_outputs(scene_path: str, cf, out: str) -> list[Path]:
    """One image per camera: OUT/<scene-stem>.NNNN.png for a folder (NNNN: the camera's index from
    0, 4 digits or more), a pattern with {camera} (index) and/or {name} (the camera's name), or
    one file for a one-camera file. CLIError before anything renders."""
    n, names = len(cf.entries), [e.get("name") for e in cf.entries]
    if "{" in out:
        try:
            fields = {f for _, f, _, _ in string.Formatter().parse(out) if f is not None}
        except ValueError as exc:
            raise CLIError(f"bad output pattern {out!r}: {exc}") from None
        if fields - {"camera", "name"}:
            raise CLIError(f"bad output pattern {out!r}: use {{camera}} and {{name}} only")
        if "name" in fields:
            for i, name in enumerate(names):
                if not _safe_name(name):
                    what = "has no name" if name is None else f"has the name {name!r}, not a file name"
                    raise CLIError(f"output pattern {out!r}: camera {i} of {cf.path} {what}")
        paths = []
        for i in range(n):
            try:
                p = Path(out.format(camera=i, name=names[i]))
            except (KeyError, IndexError, ValueError) as exc:
                raise CLIError(f"bad output pattern {out!r}: use {{camera}} and {{name}} only ({exc})") from None
            paths.append(p if p.suffix.lower() in IMAGE_SUFFIXES else p.with_name(p.name + ".png"))
        return paths
    if is_folder_output(out):
        digits = max(4, len(str(n - 1)))
        return [Path(out) / f"{Path(scene_path).stem}.{i:0{digits}d}.png" for i in range(n)]
    return one_image_output(out, n, f"{cf.path} has {n} cameras but one output file {out!r}: give a directory or "
                                    f"a pattern containing {{camera}} or {{name}}", "{camera}")


def _check_distinct(outputs_of: list[list[Path]], video) -> None:
    owner: dict = {} if video is None else {os.path.realpath(video): "--video"}
    for i, paths in enumerate(outputs_of):
        for p in paths:
            key = os.path.realpath(p)
            if key in owner:
                raise CLIError(f"two outputs would be written to {p} (camera {owner[key]} and camera {i}); "
                               f"use {{camera}} in the output pattern")
            owner[key] = i


def _size(scene, cf, args) -> tuple[int, int]:
    """--width/--height, else the file's size, else the scene's."""
    from clrender.batch.jobs import scene_size
    if args.width is None and args.height is None and cf.width:
        return cf.width, cf.height
    return scene_size(scene, args.width, args.height)


def cmd_render_cameras(args, options: dict) -> int:
    from clrender.cli.common import _format_stats, apply_environment, describe_environment, environment_option
    from clrender.dataset.camera_file import file_camera, read_camera_file
    from clrender.render.renderer import Renderer

    _check_flags(args)
    scene_path = args.scenes[0]
    try:
        cf = read_camera_file(args.camera)
    except ValueError as exc:
        raise CLIError(f"--camera {exc}") from None
    images = plan_camera_outputs(scene_path, cf, args.output)
    bit_depth, exr, sheet = getattr(args, "bit_depth", 8), bool(getattr(args, "exr", False)), args.aov_sheet
    video = getattr(args, "video", None)
    fps = 24.0 if getattr(args, "fps", None) is None else args.fps
    check_output_options(args, images)
    if video is not None and not (0.0 < fps < float("inf")):
        raise CLIError(f"--fps: expected a positive number, got {fps!r}")
    if video is None and getattr(args, "fps", None) is not None:
        _note(args, f"{PROG}: note: --fps has no effect without --video")
    outputs_of = [[image, *aov_paths(image, args.aov, exr, sheet)] for image in images]
    _check_distinct(outputs_of, video)
    outputs = [p for paths in outputs_of for p in paths] + ([Path(video)] if video is not None else [])
    environment = environment_option(args)
    check_writable([p.parent for p in outputs], {p.parent: p for p in reversed(outputs)})
    env_file = getattr(args, "environment", None)
    extra = [(args.camera, f"--camera {args.camera}")]
    extra += [(env_file, "--environment")] if env_file and Path(env_file).is_file() else []
    check_outputs_spare_inputs(outputs, input_files([], extra))

    from clrender.tools.warmup import prepare_in_background
    ready = prepare_in_background(args.device, options)     # the device and kernels, while the scene loads
    scene = _load(scene_path, args)
    check_outputs_spare_inputs(outputs, input_files([scene], extra))
    apply_environment(scene, args, environment)
    width, height = _size(scene, cf, args)
    times = [float(e.get("time", args.time)) for e in cf.entries]
    bounds: dict = {}                  # near/far where a camera has none: around the scene posed at its time
    cameras = []
    for i, t in enumerate(times):
        if t not in bounds:
            if scene.animation is not None:
                scene.pose(t)
            bounds[t] = scene.bounds() if scene.animation is not None or not bounds else next(iter(bounds.values()))
        try:
            cameras.append(file_camera(cf, i, bounds[t], width, height))
        except ValueError as exc:
            raise CLIError(f"--camera {exc}") from None
    config = _scene_config(scene, options)
    renderer = Renderer(width, height, device=ready.result(), config=config)
    for i, (camera, t, image) in enumerate(zip(cameras, times, images)):
        if scene.animation is not None:
            scene.pose(t)
        start = time.perf_counter()
        try:
            frame = renderer.render(scene, camera, time=t)
            wall_ms = (time.perf_counter() - start) * 1e3
            write_outputs(frame, image, args.aov, bit_depth=bit_depth, exr=exr, sheet=sheet)
        except (ValueError, OSError) as exc:
            raise CLIError(f"{scene_path}: camera {i}: {_one_line(exc)}") from None
        label = f" ({cf.entries[i]['name']})" if "name" in cf.entries[i] else ""
        _note(args, f"[{i + 1}/{len(cameras)}] {scene_path} camera {i}{label} at t={t:g} -> {image} "
                    f"({wall_ms:.1f} ms, {width}x{height}; environment: {describe_environment(scene)})")
        _note(args, "    " + _format_stats(frame.stats))
    if video is not None:
        try:
            write_video(video, images, fps)
        except (ValueError, RuntimeError, OSError) as exc:
            raise CLIError(f"--video {video}: {_one_line(exc)}") from None
        _note(args, f"{PROG}: {len(images)} frame(s) -> {video} ({fps:g} fps)")
    return 0
