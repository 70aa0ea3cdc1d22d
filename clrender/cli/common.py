"""What the command modules share (clrender/cli/render.py, camera_route.py, batch.py, dataset.py, info.py, ...):
the program name, one-line errors and notes, the checks every command runs before anything
renders (scene files, --allow-outside, render flags, outputs that would overwrite inputs), the
environment flags and the per-scene stats line.
The bottom of clrender/cli/: it imports no other command module."""
from __future__ import annotations

import os
import sys
import tempfile
from pathlib import Path
from typing import Iterable, Optional, Sequence

from clrender.batch.jobs import scene_config
from clrender.config import OPTIONS, RenderConfig
from clrender.errors import CLIError, OutputOverInput  # noqa: F401  (re-exported)
from clrender.outputs.aov_io import EXR_MISSING, check_video_path, exr_available

PROG = "clrender"
ENV_DEBUG = "CLRENDER_DEBUG"
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg")


def _note(args, message: str) -> None:
    if not getattr(args, "quiet", False):
        print(message, file=sys.stderr, flush=True)


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


def is_folder_output(out: str) -> bool:
    """An output that names a folder: an existing one, a trailing slash, or no suffix."""
    target = Path(out)
    return target.is_dir() or out.endswith(("/", os.sep)) or target.suffix == ""


def one_image_output(out: str, n: int, many: str, pattern: str) -> list[Path]:
    """[the image file `out`] for one output (`many`: the error when n > 1 items would share it;
    `pattern`: the placeholder a pattern would use instead)."""
    target = Path(out)
    if target.suffix.lower() not in IMAGE_SUFFIXES:
        raise CLIError(f"output {out!r}: unsupported image type {target.suffix!r} "
                       f"(use {', '.join(IMAGE_SUFFIXES)}, a directory, or a pattern with {pattern})")
    if n > 1:
        raise CLIError(many)
    return [target]


def _debug() -> bool:
    """CLRENDER_DEBUG=1 or CLRENDER_LOG=debug: tracebacks instead of one-line errors."""
    return (os.environ.get(ENV_DEBUG, "").strip() not in ("", "0")
            or os.environ.get("CLRENDER_LOG", "").strip().lower() == "debug")


def _load(path: str, args=None):
    """load_scene with the folders --allow-outside lets the scene's references reach, in the
    material variant --variant names (if any)."""
    from clrender.loaders import load_scene
    return load_scene(path, allow=allowed_folders(args), variant=getattr(args, "variant", None))


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
    check_scene_files(args.scenes)
    allowed_folders(args)                          # --allow-outside: before anything renders
    options, flags = {}, {}
    for option in OPTIONS:
        value = getattr(args, option.cli_dest) if option.cli_flag is not None else None
        if value is not None:                      # a switch is None unless given
            options[option.name] = option.flag_value if option.flag_value is not None else value
            flags[option.name] = option.cli_flag
    pipeline = {"pipeline": options["pipeline"]} if "pipeline" in options else {}
    for name, value in options.items():          # name the offending flag (with the pipeline it goes with)
        try:
            RenderConfig.from_options(**{**pipeline, name: value})
        except ValueError as exc:
            raise CLIError(f"{flags[name]}: {exc}") from None
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


# -- the environment flags and the per-scene lines (render, its camera-file route) ----------------
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

