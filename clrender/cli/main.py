"""Command line: `clrender render | dataset | devices | check | info`, a thin loop over the library API
(the grammar: clrender/cli/parser.py; frames and clusters: clrender/cli/batch.py).

    clrender render SCENE [SCENE ...] -o OUT [--width W --height H --device NAME --tile-size N
                    --pipeline deferred|light_prepass|light_indexed --msaa N
                    --light-buffer-specular rgb|luminance --light-buffer-precision float32|float16
                    --light-culling tiled|brute_force|quads|stencil
                    --transparency abuffer|depth_peeling|screen_door --peel-layers N
                    --max-fragments-per-pixel K --refraction
                    --edge-aa --edge-depth-threshold T --edge-normal-threshold DEG --fxaa
                    --supersample K --supersample-filter box|lanczos2|mitchell
                    --bloom --bloom-threshold T --bloom-strength S --bloom-radius PX
                    --motion-blur --shutter F --motion-blur-samples N --previous-eye x,y,z --previous-target x,y,z
                    --hatching --hatching-scale S --hatching-saturation S
                    --environment PATH|studio|none --environment-intensity X --environment-rotation DEG
                    --aov depth,normal,... --camera-eye x,y,z --camera-target x,y,z --fov DEG
                    --ortho HALF_HEIGHT --bit-depth 8|16 --exr --video FILE --fps N --quiet
                    --frames A:B[:STEP]|N|all --time-range T0:T1 --resume --workers N
                    --scheduler ADDRESS --resources NAME=N]
    clrender dataset SCENE -o DIR --views N [--layout orbit|sphere|random --seed S --elevation DEG --fov DEG]
                     [--cameras FILE.json|.toml] [--format nerf|colmap] [--aov depth,object_id,...|none]
                     [--depth-scale S] [--exr] [--width W --height H --device NAME, render options]
                     [--resume] [--workers N | --scheduler ADDRESS]      (clrender/cli/dataset.py)
    clrender devices [--json] [--require NAME]
    clrender warmup [--device NAME] [--all] [-q]
    clrender cache info [--json] | clear
    clrender info SCENE [--json]
    clrender check [--device NAME|all] [--scene S] [--json report.json]

Errors are one line on stderr (`clrender: error: ...`) and a non-zero exit status; set
CLRENDER_DEBUG=1 to get the traceback instead.
"""
from __future__ import annotations

import dataclasses
import json
import os
import sys
import tempfile
import time
import warnings
from pathlib import Path
from typing import Iterable, Optional, Sequence

import numpy as np

from clrender.outputs.aov_io import INT_AOVS  # noqa: F401  (re-exported)
from clrender.outputs.aov_io import (
    EXR_MISSING, aov_paths, check_video_path, exr_available, write_outputs, write_video)
from clrender.outputs.aov_io import preview  # noqa: F401  (re-exported: `clrender.cli.preview` predates aov_io)
from clrender import progress
from clrender.batch.jobs import scene_config, scene_size

# The grammar (re-exported: tests and scripts use clrender.cli.build_parser, CLIError, AOVS).
from clrender.cli.parser import AOVS  # noqa: F401
from clrender.cli.parser import ENV_DEBUG, IMAGE_SUFFIXES, PROG, CLIError, _join_vector_options, build_parser


# ---------------------------------------------------------------------------------------------
# small helpers
def _note(args, message: str) -> None:
    if not getattr(args, "quiet", False):
        print(message, file=sys.stderr, flush=True)


def _load(path: str, args=None):
    """load_scene with the folders --allow-outside lets the scene's references reach."""
    from clrender.loaders import load_scene
    return load_scene(path, allow=allowed_folders(args))


def allowed_folders(args) -> tuple:
    """--allow-outside folders (each must exist: a typo must not silently allow nothing)."""
    folders = tuple(getattr(args, "allow_outside", None) or ())
    for folder in folders:
        if not Path(folder).is_dir():
            raise CLIError(f"--allow-outside {folder}: not a folder")
    return tuple(str(Path(folder).resolve()) for folder in folders)     # absolute: tasks travel to workers


def _scene_config(scene, options):
    try:
        return scene_config(scene, options)
    except ValueError as exc:
        raise CLIError(str(exc)) from None


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


# ---------------------------------------------------------------------------------------------
# outputs
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


def _output_key(path, parents: dict) -> str:
    """An output's real folder + its name: what os.replace overwrites (a symlink there is replaced
    itself, and a scene reading through it loses it just the same)."""
    path = Path(path)
    parent = parents.get(path.parent)
    if parent is None:
        parent = parents[path.parent] = os.path.realpath(path.parent)
    return os.path.join(parent, path.name)


def input_files(scenes: Sequence, extra: Sequence = ()) -> dict:
    """{real path: scene} of every file the loaded `scenes` read (Scene.source_files: the scene
    file, its buffers, textures, MTL, TOML meshes, environment) and of `extra` ((path, what) pairs:
    --environment, --cameras)."""
    inputs: dict = {}
    for scene in scenes:
        for f in [scene.source, *getattr(scene, "source_files", ())]:
            for key in {os.path.realpath(f), _output_key(f, {})}:
                inputs.setdefault(key, scene.source)
    for path, what in extra:
        if path:
            for key in {os.path.realpath(path), _output_key(path, {})}:
                inputs.setdefault(key, what)
    return inputs


class OutputOverInput(CLIError):
    """An output path is a file the job reads."""


def check_outputs_spare_inputs(outputs: Iterable, inputs: dict) -> None:
    """CLIError, before anything renders, when an output would be written over a file the job
    reads: `clrender render scenes/crate.obj -o scenes/` would replace crate.png, the OBJ's texture."""
    if not inputs:
        return
    parents: dict = {}
    for output in outputs:
        key = _output_key(output, parents)
        if key in inputs:
            owner = inputs[key]
            what = "the input scene" if os.path.realpath(owner) == key else f"which {owner} reads"
            raise OutputOverInput(f"output {output} would overwrite {key}, {what}; choose another "
                                  f"output folder or name")


def check_writable(folders, outputs_of: Optional[dict] = None) -> None:
    """Create each output folder and write a probe file in it: an unwritable output fails before
    anything renders, naming the output (`outputs_of`: folder -> one output in it) or folder."""
    for folder in sorted(set(map(Path, folders))):
        what = f"output {outputs_of[folder]}" if outputs_of and folder in outputs_of else f"output folder {folder}"
        try:
            folder.mkdir(parents=True, exist_ok=True)
            fd, probe = tempfile.mkstemp(prefix=".clrender-probe-", dir=folder)
            os.close(fd)
            os.unlink(probe)
        except OSError as exc:
            reason = exc.strerror or str(exc)
            if isinstance(exc, (FileExistsError, NotADirectoryError)):
                reason = f"{folder} is not a folder" if folder.exists() else "a parent is not a folder"
            raise CLIError(f"{what} is not writable: {reason}") from None


# ---------------------------------------------------------------------------------------------
# commands
def check_scene_files(scenes) -> None:
    for s in scenes:
        p = Path(s)
        if not p.exists():
            raise CLIError(f"{s}: file not found")
        if not p.is_file():
            raise CLIError(f"{s}: not a file")


def batch_requested(args) -> bool:
    """Frames, resume or a cluster: the batch route (clrender.cli.batch)."""
    return any(getattr(args, k, None) for k in ("frames", "time_range", "resume", "workers", "scheduler"))


def render_options(args) -> dict:
    """The RenderConfig options given on the command line, each checked (CLIError naming its flag)."""
    from clrender.render.renderer import RenderConfig
    check_scene_files(args.scenes)
    allowed_folders(args)                          # --allow-outside: before anything renders
    options = {name: value for name, value in (
        ("tile_size", args.tile_size), ("light_tile_size", args.light_tile_size),
        ("light_culling", args.light_culling), ("pipeline", args.pipeline), ("shading", args.shading),
        ("msaa", args.msaa),
        ("light_buffer_specular", args.light_buffer_specular),
        ("light_buffer_precision", args.light_buffer_precision), ("reuse_visibility", args.reuse_visibility),
        ("tonemap", args.tonemap), ("exposure", args.exposure),
        ("ssao", args.ssao), ("ssao_radius", args.ssao_radius), ("ssao_strength", args.ssao_strength),
        ("transparency", args.transparency), ("peel_layers", args.peel_layers),
        ("max_fragments_per_pixel", args.max_fragments_per_pixel), ("refraction", args.refraction),
        ("edge_aa", args.edge_aa), ("edge_depth_threshold", args.edge_depth_threshold),
        ("edge_normal_threshold_deg", args.edge_normal_threshold),
        ("color_aa", "fxaa" if args.fxaa else None), ("supersample", args.supersample),
        ("supersample_filter", args.supersample_filter), ("bloom", args.bloom),
        ("bloom_threshold", args.bloom_threshold), ("bloom_strength", args.bloom_strength),
        ("bloom_radius", args.bloom_radius), ("motion_blur", args.motion_blur), ("shutter", args.shutter),
        ("motion_blur_samples", args.motion_blur_samples), ("hatching", args.hatching),
        ("hatching_scale", args.hatching_scale), ("hatching_saturation", args.hatching_saturation))
        if value is not None}
    flags = {"edge_normal_threshold_deg": "--edge-normal-threshold", "color_aa": "--fxaa"}
    pipeline = {"pipeline": options["pipeline"]} if "pipeline" in options else {}
    for name, value in options.items():          # name the offending flag (with the pipeline it goes with)
        try:
            RenderConfig.from_options(**{**pipeline, name: value})
        except ValueError as exc:
            raise CLIError(f"{flags.get(name, '--' + name.replace('_', '-'))}: {exc}") from None
    RenderConfig.from_options(**options)
    return options


def check_output_options(args, images) -> None:
    """--bit-depth 16 (PNG only), --exr (OpenEXR installed) and --video (a known type, ffmpeg
    for .mp4) against the planned images, before anything renders."""
    if getattr(args, "bit_depth", 8) == 16:
        for image in images:
            if Path(image).suffix.lower() != ".png":
                raise CLIError(f"--bit-depth 16: {image} is not a .png (16-bit images are PNG only)")
    if getattr(args, "exr", False) and not exr_available():
        raise CLIError(f"--exr: {EXR_MISSING}")
    if getattr(args, "video", None) is not None:
        try:
            check_video_path(args.video)
        except (ValueError, RuntimeError) as exc:
            raise CLIError(f"--video: {exc}") from None


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


def cmd_devices(args) -> int:
    from clrender.device import icd
    from clrender.device.core import DeviceError, list_devices, no_device_error
    from clrender.device.probe import default_device_info
    from clrender.device.report import device_record, devices_table

    if args.no_probe and args.require:
        raise CLIError("--require needs the probe (whether a device runs clrender's kernels): drop --no-probe")
    if icd.note:                                # logged at import, before CLRENDER_LOG took effect
        icd.log.debug(icd.note)
    for line in icd.icd_problems():             # the loader skips these silently: say so, keep going
        print(f"{PROG}: {line}", file=sys.stderr)
    devices = list_devices()
    if not devices:
        raise CLIError(str(no_device_error()))
    try:                                        # the default is the first device whose probe passes
        default_id = None if args.no_probe else default_device_info().id
    except DeviceError:
        default_id = None
    records = [device_record(d, default_id, _one_line, probe=not args.no_probe) for d in devices]
    if args.json:
        print(json.dumps(records, indent=2))
    else:
        print(devices_table(records))
        if default_id is not None:
            print("* default device (override with --device NAME or $CLRENDER_DEVICE)")
    for name in args.require:                   # CI: a missing implementation is a failure, not a skip
        usable = [d.label for d, r in zip(devices, records) if d.matches(name) and r["kernels"] == "ok"]
        if not usable:
            raise CLIError(f"--require {name!r}: no OpenCL device matching it runs clrender's kernels")
    return 0


def cmd_check(args) -> int:
    from clrender.tools.check import run_check
    for s in args.scene:
        if not Path(s).is_file():
            raise CLIError(f"{s}: file not found")
    report = run_check(args.device, args.scene, args.width, args.height,
                       progress=None if args.quiet else (lambda m: print(f"rendering {m}", file=sys.stderr)))
    print(report.table())
    if len(report.devices) > 1:
        print("\nlargest difference per AOV over every case (=: bit-identical everywhere, !: past the tolerance)")
        print(report.summary())
    if args.json:
        Path(args.json).write_text(json.dumps(report.to_dict(), indent=2))
    if len(report.devices) < args.min_devices:
        raise CLIError(f"{len(report.devices)} device(s) compared ({', '.join(report.devices)}), "
                       f"--min-devices {args.min_devices} wanted")
    if len(report.devices) < 2:
        _note(args, f"{PROG}: note: only one device ({report.devices[0]}): nothing to compare")
    return 0 if report.ok else 1


def cmd_info(args) -> int:
    path = Path(args.scene)
    if not path.exists():
        raise CLIError(f"{args.scene}: file not found")
    scene = _load(args.scene, args)
    summary = scene.summary()
    summary["settings"] = scene.settings
    # Frame.object_id's index; a shallow dict: asdict would deep-copy `extras` recursively
    summary["object_list"] = [{f.name: getattr(o, f.name) for f in dataclasses.fields(o)} for o in scene.objects]
    from clrender.loaders.gltf.info import empty_details, format_details, gltf_details, is_gltf
    gltf = is_gltf(path)
    from clrender.loaders.context import loading
    with loading(allowed_folders(args)):         # gltf_details reads the buffers again, as confined
        summary.update(gltf_details(path) if gltf else empty_details())   # always present: [] unless glTF
    if args.json:
        print(json.dumps(summary, indent=2, default=_json_default))
        return 0
    s = summary
    fmt = lambda v: ", ".join(f"{x:g}" for x in v)  # noqa: E731
    lines = [
        ("source", s["source"]),
        ("triangles", s["triangles"]),
        ("vertices", s["vertices"]),
        ("meshes", s["meshes"]),
        ("objects", _objects_line(s["object_list"])),
        ("materials", f"{s['materials']} ({s['alpha_masked_materials']} alpha-masked, "
                      f"{s['transparent_materials']} transparent, {s['single_sided_materials']} single-sided)"),
        ("textures", s["textures"] if not s["texture_sizes"] else
         f"{s['textures']} ({', '.join(f'{w}x{h}' for w, h in s['texture_sizes'])})"),
        ("bounds", f"min ({fmt(s['bounds_min'])})  max ({fmt(s['bounds_max'])})"),
        ("camera", "none (a default camera frames the bounds)" if s["camera"] is None else
         f"eye ({fmt(s['camera']['eye'])})  target ({fmt(s['camera']['target'])})  " + (
             f"orthographic xmag {s['camera']['xmag']:g} ymag {s['camera']['ymag']:g}"
             if s["camera"].get("projection") == "orthographic" else f"fov {s['camera']['fov_y_deg']:g} deg")),
    ]
    render = scene.settings.get("render") if isinstance(scene.settings, dict) else None
    if render:
        lines.append(("render", ", ".join(f"{k} {v}" for k, v in render.items())))
    if isinstance(scene.settings, dict) and scene.settings.get("lights"):
        lines.append(("lights", len(scene.settings["lights"])))
    width = max(len(k) for k, _ in lines)
    for k, v in lines:
        print(f"{k.ljust(width)}  {v}")
    if gltf:
        print("\n".join(format_details(summary)))
    return 0


def _objects_line(objects: list) -> str:
    """The object count (Frame.object_id), the first names and how many carry extras."""
    names = ", ".join(repr(o["name"]) for o in objects[:4]) + (", ..." if len(objects) > 4 else "")
    extras = sum(o["extras"] is not None for o in objects)
    return f"{len(objects)} ({names})" + (f", {extras} with extras" if extras else "") if objects else "0"


def _json_default(obj):
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, np.generic):
        return obj.item()
    if dataclasses.is_dataclass(obj):
        return dataclasses.asdict(obj)
    return str(obj)


# ---------------------------------------------------------------------------------------------
def _debug() -> bool:
    """CLRENDER_DEBUG=1 or CLRENDER_LOG=debug: tracebacks instead of one-line errors."""
    return (os.environ.get(ENV_DEBUG, "").strip() not in ("", "0")
            or os.environ.get("CLRENDER_LOG", "").strip().lower() == "debug")


def _quiet_unraisable() -> None:
    """Errors Python can only print as "Exception ignored in ..." (a writer's clean-up in __del__
    after a full disk: 3-11 tracebacks) say nothing the error line has not: hidden unless debugging."""
    if not _debug():
        sys.unraisablehook = lambda unraisable: None


def _one_line(exc: BaseException) -> str:
    text = str(exc).strip()
    if isinstance(exc, OSError) and exc.strerror:
        text = f"{exc.filename}: {exc.strerror}" if exc.filename else exc.strerror
    lines = [ln.strip() for ln in text.splitlines() if ln.strip()]
    if not lines:
        return type(exc).__name__
    first = lines[0].rstrip(":")
    if len(lines) > 1:
        first += f" (set {ENV_DEBUG}=1 for details)"
    return first


def _quiet_compiler_logs() -> None:
    """OpenCL compilers' harmless notes (PoCL's AVX ABI remarks on pyopencl's own kernels) would
    bury the CLI's output on first builds; CLRENDER_DEBUG=1 shows them."""
    if _debug():
        return
    try:
        from pyopencl import CompilerWarning
    except ImportError:                          # reported properly by the command that needs it
        return
    warnings.simplefilter("ignore", CompilerWarning)


def _one_line_warnings(quiet: bool) -> None:
    """Library warnings (a device left out, a loader note) as one `clrender: note:` line each;
    none with --quiet."""
    if quiet and not _debug():
        warnings.simplefilter("ignore", UserWarning)
        return

    def show(message, category, filename, lineno, file=None, line=None):
        print(f"{PROG}: note: {message}", file=sys.stderr, flush=True)
    warnings.showwarning = show


def _log_level() -> None:
    """CLRENDER_LOG=info|debug: the library's log (builds, probes, caches) on stderr."""
    level = os.environ.get("CLRENDER_LOG", "").strip().upper()
    if level:
        import logging
        handler = logging.StreamHandler(sys.stderr)
        handler.setFormatter(logging.Formatter(f"{PROG}: %(message)s"))
        logger = logging.getLogger("clrender")
        if not logger.handlers:
            logger.addHandler(handler)
        logger.setLevel(getattr(logging, level, logging.INFO))


def main(argv: Optional[Sequence[str]] = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    from clrender import interrupt
    interrupt.install()                          # a failure a Ctrl-C caused ends as the interrupt
    _quiet_compiler_logs()
    _quiet_unraisable()
    _log_level()
    try:
        args = build_parser().parse_args(_join_vector_options(argv))
        _one_line_warnings(getattr(args, "quiet", False))
        progress.show_bars(not getattr(args, "quiet", False))    # first-run builds: a bar, not silence
        from clrender.cli import dataset as cli_dataset, setup as cli_setup
        commands = {"render": cmd_render, "devices": cmd_devices, "check": cmd_check, "info": cmd_info,
                    "warmup": cli_setup.run_warmup, "cache": cli_setup.run_cache, "dataset": cli_dataset.cmd_dataset}
        return int(commands[args.command](args) or 0)
    except SystemExit as exc:                    # --help / --version
        return exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
    except KeyboardInterrupt:
        print(f"{PROG}: interrupted", file=sys.stderr)
        return 130
    except CLIError as exc:
        if _debug():
            raise
        print(f"{PROG}: error: {_one_line(exc)}", file=sys.stderr)
        return exc.code
    except Exception as exc:                     # SceneError, DeviceError, ValueError, OSError, cl.Error
        if _debug():
            raise
        from clrender.scene.model import SceneError
        known = isinstance(exc, (SceneError, ValueError, OSError)) or type(exc).__name__ == "DeviceError"
        message = _one_line(exc) if known else f"{type(exc).__name__}: {_one_line(exc)}"
        print(f"{PROG}: error: {message}", file=sys.stderr)
        return 1
    finally:
        progress.show_bars(False)


def run() -> None:
    """The `clrender` program (console script and `python -m clrender`): main(), then exit. Nothing
    is left to do once main() returns (outputs renamed into place, clusters closed), and the OpenCL
    driver's teardown of every program and context cost 0.25-0.3 s of a 1.6 s warm demo run: the
    process exits without it, once its streams and logs are flushed."""
    code = main()
    import logging
    logging.shutdown()
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)


if __name__ == "__main__":
    run()
