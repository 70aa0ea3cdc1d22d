"""Command line: `clrender render | devices | info`, a thin loop over the library API.

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
                    --aov depth,normal,... --camera-eye x,y,z --camera-target x,y,z --fov DEG
                    --ortho HALF_HEIGHT --quiet]
    clrender devices [--json]
    clrender info SCENE [--json]
    clrender check [--device NAME|all] [--scene S] [--json report.json]

Errors are one line on stderr (`clrender: error: ...`) and a non-zero exit status; set
CLRENDER_DEBUG=1 to get the traceback instead.
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import math
import os
import sys
import time
import warnings
from pathlib import Path
from typing import Optional, Sequence

import numpy as np

from .aov_io import INT_AOVS  # noqa: F401  (re-exported)
from .aov_io import EXR_MISSING, aov_paths, check_video_path, exr_available, write_outputs, write_video
from .aov_io import preview  # noqa: F401  (re-exported: `clrender.cli.preview` predates aov_io)

PROG = "clrender"
ENV_DEBUG = "CLRENDER_DEBUG"
DEFAULT_SIZE = (1280, 720)
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg")
# AOVs the CLI writes: every Frame AOV but `image`, which is the main output.
def _aov_names():
    from .renderer import Frame
    return tuple(n for n in Frame.AOV_NAMES if n != "image")


AOVS = _aov_names()


class CLIError(Exception):
    """A user-facing error: printed as one line, exit status `code`."""

    def __init__(self, message: str, code: int = 1):
        super().__init__(message)
        self.code = code


class _Parser(argparse.ArgumentParser):
    """argparse that reports bad usage as a CLIError (one line) instead of usage + exit."""

    def error(self, message):
        raise CLIError(f"{message} (see `{self.prog} --help`)", code=2)


# ---------------------------------------------------------------------------------------------
# argument types
def _vec3(text: str) -> tuple[float, float, float]:
    parts = [p.strip() for p in text.replace(";", ",").split(",")]
    try:
        values = tuple(float(p) for p in parts)
    except ValueError:
        values = ()
    if len(values) != 3 or not all(math.isfinite(v) for v in values):
        raise argparse.ArgumentTypeError(f"expected three finite numbers x,y,z, got {text!r}")
    return values


def _positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}")
    return value


def _non_negative_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer >= 0, got {text!r}") from None
    if value < 0:
        raise argparse.ArgumentTypeError(f"expected an integer >= 0, got {text!r}")
    return value


def _fov(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not 0.0 < value < 180.0:
        raise argparse.ArgumentTypeError(f"expected degrees in (0, 180), got {text!r}")
    return value


def _half_height(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not (value > 0.0 and np.isfinite(value)):
        raise argparse.ArgumentTypeError(f"expected a positive half-height in world units, got {text!r}")
    return value


def _aov_list(text: str) -> list[str]:
    names = [n.strip().lower() for n in text.split(",") if n.strip()]
    if not names:
        raise argparse.ArgumentTypeError("expected a comma-separated list of AOV names")
    unknown = [n for n in names if n not in AOVS]
    if unknown:
        raise argparse.ArgumentTypeError(f"unknown AOV {unknown[0]!r} (available: {', '.join(AOVS)})")
    return list(dict.fromkeys(names))


def _join_vector_options(argv: list[str]) -> list[str]:
    """`--camera-eye -1,2,3` -> `--camera-eye=-1,2,3`: argparse would read `-1,2,3` as an option."""
    out, i = [], 0
    while i < len(argv):
        arg = argv[i]
        if arg in ("--camera-eye", "--camera-target") and i + 1 < len(argv) and argv[i + 1].startswith("-") \
                and argv[i + 1][1:2] in "0123456789.":
            out.append(f"{arg}={argv[i + 1]}")
            i += 2
            continue
        out.append(arg)
        i += 1
    return out


def build_parser() -> argparse.ArgumentParser:
    from .renderer import (LIGHT_BUFFER_PRECISION, LIGHT_BUFFER_SPECULAR, LIGHT_CULLING, PIPELINES,
                           TRANSPARENCY)

    parser = _Parser(prog=PROG, description="clrender: a tiled deferred renderer whose pixels are "
                                            "computed by OpenCL kernels.")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    sub.required = True

    r = sub.add_parser("render", help="render scene files to images (and AOVs)",
                       description="Render each SCENE with one renderer. OUT is an image file (.png/.jpg) "
                                   "for one scene, or a directory (OUT/<scene-name>.png) or a pattern "
                                   "containing {name} (and optionally {index}) for several. AOVs are "
                                   "written next to each image as <out-stem>.<aov>.npy (exact) and "
                                   "<out-stem>.<aov>.png (preview); --exr adds one multi-layer <out-stem>.exr "
                                   "(colour and every float AOV requested). Files are written to a temporary "
                                   "name and renamed into place when complete.")
    r.add_argument("scenes", nargs="+", metavar="SCENE", help="scene file (.toml .gltf .glb .obj .ply .stl)")
    r.add_argument("-o", "--output", required=True, metavar="OUT",
                   help="image file, directory, or pattern containing {name}")
    r.add_argument("--width", type=_positive_int, metavar="W",
                   help="image width (default: the scene's [render] width, else 1280)")
    r.add_argument("--height", type=_positive_int, metavar="H",
                   help="image height (default: the scene's [render] height, else 720)")
    r.add_argument("--device", metavar="NAME",
                   help="OpenCL device: a name substring or P:D (default: $CLRENDER_DEVICE, else a GPU, "
                        "else PoCL); see `clrender devices`")
    r.add_argument("--tile-size", type=int, metavar="N", help="raster tile size in pixels: 8, 16 or 32 (default 8)")
    r.add_argument("--light-tile-size", type=int, metavar="N", help="light-culling tile size: 8, 16 or 32 (default 32)")
    r.add_argument("--light-culling", choices=LIGHT_CULLING,
                   help="light lists per tile: culled against tile frusta, every light, each light's screen "
                        "quad, or tiled lists with per-pixel stencil bits (default tiled; "
                        "docs/light_accumulation.md)")
    r.add_argument("--pipeline", choices=PIPELINES,
                   help="renderer variant: deferred shading, Engel's light pre-pass, or Trebilco's light-indexed "
                        "deferred (default deferred; docs/variants.md)")
    r.add_argument("--msaa", type=int, metavar="N",
                   help="with --pipeline light_prepass: colour sub-samples per pixel, 1, 2, 4 or 8 (default 1)")
    r.add_argument("--light-buffer-specular", choices=LIGHT_BUFFER_SPECULAR,
                   help="with --pipeline light_prepass: specular RGB, or its luminance coloured by the diffuse "
                        "light (default rgb)")
    r.add_argument("--light-buffer-precision", choices=LIGHT_BUFFER_PRECISION,
                   help="with --pipeline light_prepass: light buffer of floats or halves (default float32)")
    r.add_argument("--tonemap", choices=("reinhard", "aces", "clamp"), help="tone-mapping operator (default reinhard)")
    r.add_argument("--exposure", type=float, metavar="X", help="exposure multiplier before tone mapping (default 1)")
    r.add_argument("--ssao", action="store_true", default=None, help="screen-space ambient occlusion (default off)")
    r.add_argument("--ssao-radius", type=float, metavar="R", help="with --ssao: its radius in world units (default 1)")
    r.add_argument("--ssao-strength", type=float, metavar="S", help="with --ssao: ao = 1 - S·occlusion (default 1)")
    r.add_argument("--transparency", choices=TRANSPARENCY,
                   help="how BLEND materials are drawn: per-pixel sorted fragment lists, depth peeling, or "
                        "a stipple pattern in the G-buffer (default abuffer)")
    r.add_argument("--peel-layers", type=_positive_int, metavar="N",
                   help="with --transparency depth_peeling: layers peeled per pixel, 1..64 (default 4)")
    r.add_argument("--max-fragments-per-pixel", type=_non_negative_int, metavar="K",
                   help="with the A-buffer: keep only the K nearest transparent fragments of a pixel "
                        "(default 0: all of them)")
    r.add_argument("--refraction", action="store_true", default=None,
                   help="distort what lies behind transparent surfaces by their materials' refraction "
                        "(default off)")
    r.add_argument("--edge-aa", action="store_true", default=None,
                   help="the report's edge-smoothing filter: blur along G-buffer edges (default off)")
    r.add_argument("--edge-depth-threshold", type=float, metavar="T",
                   help="with --edge-aa: relative view-depth jump that marks an edge (default 0.05)")
    r.add_argument("--edge-normal-threshold", type=float, metavar="DEG",
                   help="with --edge-aa: normal angle in degrees that marks an edge (default 30)")
    r.add_argument("--fxaa", action="store_true", default=None,
                   help="FXAA: luminance-edge anti-aliasing of the tone-mapped image (default off)")
    r.add_argument("--supersample", type=_positive_int, metavar="K",
                   help="render at K·W × K·H and filter down in linear HDR, K in 1..4 (default 1)")
    r.add_argument("--supersample-filter", choices=("box", "lanczos2", "mitchell"),
                   help="with --supersample: the resolve filter (default box)")
    r.add_argument("--bloom", action="store_true", default=None,
                   help="bloom: HDR colour above --bloom-threshold, blurred and added back (default off)")
    r.add_argument("--bloom-threshold", type=float, metavar="T", help="with --bloom: linear HDR threshold (default 1)")
    r.add_argument("--bloom-strength", type=float, metavar="S", help="with --bloom: strength (default 0.1)")
    r.add_argument("--bloom-radius", type=float, metavar="PX", help="with --bloom: radius in pixels (default 16)")
    r.add_argument("--motion-blur", action="store_true", default=None,
                   help="motion blur along the per-pixel velocity; give motion with --previous-eye/"
                        "--previous-target (default off)")
    r.add_argument("--shutter", type=float, metavar="F", help="with --motion-blur: exposure in frames (default 0.5)")
    r.add_argument("--motion-blur-samples", type=_positive_int, metavar="N",
                   help="with --motion-blur: samples along the velocity, 2..64 (default 8)")
    r.add_argument("--previous-eye", type=_vec3, metavar="X,Y,Z",
                   help="the camera's position at the previous frame (velocity, motion blur)")
    r.add_argument("--previous-target", type=_vec3, metavar="X,Y,Z",
                   help="the point the camera looked at in the previous frame")
    r.add_argument("--hatching", action="store_true", default=None,
                   help="the report's non-photorealistic hatching of the image (default off)")
    r.add_argument("--hatching-scale", type=float, metavar="S", help="with --hatching: stroke scale (default 1)")
    r.add_argument("--hatching-saturation", type=float, metavar="S",
                   help="with --hatching: colour kept, 0 (ink on white) .. 1 (default 0.3)")
    r.add_argument("--time", type=float, default=0.0, metavar="SECONDS",
                   help="animation time: places the scene's light particles (default 0)")
    r.add_argument("--aov", type=_aov_list, default=[], metavar="LIST",
                   help=f"comma-separated AOVs to write: {','.join(AOVS)}")
    r.add_argument("--camera-eye", type=_vec3, metavar="X,Y,Z", help="camera position (overrides the scene's)")
    r.add_argument("--camera-target", type=_vec3, metavar="X,Y,Z", help="point the camera looks at")
    r.add_argument("--fov", type=_fov, metavar="DEG",
                   help="vertical field of view in degrees (a perspective camera, also in place of an "
                        "orthographic one)")
    r.add_argument("--ortho", type=_half_height, metavar="HALF_HEIGHT",
                   help="an orthographic camera whose view box is 2·HALF_HEIGHT world units tall (its width "
                        "follows the image aspect)")
    r.add_argument("--bit-depth", type=int, choices=(8, 16), default=8, metavar="{8,16}",
                   help="bits per channel of the image (16: PNG only, from the tone-mapped float colour; default 8)")
    r.add_argument("--exr", action="store_true",
                   help="also write <out-stem>.exr: float32 layers color.RGB and every float --aov (needs OpenEXR)")
    r.add_argument("--video", metavar="FILE.mp4|FILE.gif",
                   help="also assemble the rendered images, in order, into a video (.mp4 H.264 via imageio-ffmpeg, or .gif)")
    r.add_argument("--fps", type=float, default=24.0, metavar="N", help="with --video: frames per second (default 24)")
    r.add_argument("-q", "--quiet", action="store_true", help="no progress or notes on stderr")
    r.set_defaults(func=cmd_render)

    d = sub.add_parser("devices", help="list OpenCL devices and whether clrender's kernels build on them",
                       description="List every OpenCL device with the limits clrender relies on, mark the "
                                   "default one, and try building clrender's kernels on each.")
    d.add_argument("--json", action="store_true", help="print JSON instead of a table")
    d.set_defaults(func=cmd_devices)

    c = sub.add_parser("check", help="render fixed cases on several devices and compare every AOV")
    c.add_argument("--device", default="all", metavar="NAME|all",
                   help="devices to compare (default all, simulators such as Oclgrind included)")
    c.add_argument("--scene", action="append", default=[], metavar="S", help="check this scene instead of the fixed cases")
    c.add_argument("--width", type=_positive_int, default=96, metavar="W")
    c.add_argument("--height", type=_positive_int, default=64, metavar="H")
    c.add_argument("--json", metavar="REPORT", help="also write the report as JSON")
    c.add_argument("-q", "--quiet", action="store_true", help="no progress on stderr")
    c.set_defaults(func=cmd_check)

    i = sub.add_parser("info", help="describe a scene file",
                       description="Triangles, vertices, meshes, materials, textures, bounds and camera "
                                   "of a scene file.")
    i.add_argument("scene", metavar="SCENE")
    i.add_argument("--json", action="store_true", help="print JSON instead of text")
    i.set_defaults(func=cmd_info)
    return parser


# ---------------------------------------------------------------------------------------------
# small helpers
def _note(args, message: str) -> None:
    if not getattr(args, "quiet", False):
        print(message, file=sys.stderr, flush=True)


def _load(path: str):
    from .loaders import load_scene
    return load_scene(path)


def _scene_size(scene, args) -> tuple[int, int]:
    """--width/--height, else the scene's [render] size, else 1280x720; one given keeps the aspect."""
    settings = scene.settings.get("render", {}) if isinstance(scene.settings, dict) else {}
    dw, dh = settings.get("width"), settings.get("height")
    if not (isinstance(dw, int) and isinstance(dh, int) and dw > 0 and dh > 0):
        dw = dw if isinstance(dw, int) and dw > 0 else DEFAULT_SIZE[0]
        dh = dh if isinstance(dh, int) and dh > 0 else DEFAULT_SIZE[1]
    w, h = args.width, args.height
    if w is None and h is None:
        return dw, dh
    if w is None:
        w = max(1, round(h * dw / dh))
    if h is None:
        h = max(1, round(w * dh / dw))
    return w, h


def _scene_config(scene, path, options):
    """The scene's [render] options (TOML) with the command line's on top."""
    import dataclasses

    from .renderer import RenderConfig
    settings = scene.settings.get("render", {}) if isinstance(scene.settings, dict) else {}
    names = {f.name for f in dataclasses.fields(RenderConfig)}
    try:
        return RenderConfig.from_options(**{**{k: v for k, v in settings.items() if k in names}, **options})
    except ValueError as exc:
        raise CLIError(f"{path}: [render]: {exc}") from None


def _previous_camera(camera, args):
    """--previous-eye/--previous-target: the camera of the previous frame (velocity, motion blur)."""
    from .camera import Camera
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
    from .camera import Camera

    cam = scene.default_camera()
    ortho = getattr(args, "ortho", None)
    if args.fov is not None and ortho is not None:
        raise CLIError("--fov (perspective) and --ortho (orthographic) exclude each other")
    if args.camera_eye is None and args.camera_target is None and args.fov is None and ortho is None:
        return cam
    eye = args.camera_eye if args.camera_eye is not None else cam.eye
    target = args.camera_target if args.camera_target is not None else cam.target
    fov = args.fov if args.fov is not None else cam.fov_y_deg
    if ortho is None and args.fov is None and cam.is_orthographic:
        ortho = cam.ymag                          # the scene's orthographic camera, moved
    far = cam.far
    if args.camera_eye is not None or args.camera_target is not None:
        # Keep the whole scene inside the far plane from the new viewpoint.
        lo, hi = scene.bounds().astype(np.float64)
        reach = float(np.linalg.norm(np.subtract((lo + hi) / 2, eye)) + np.linalg.norm(hi - lo) / 2)
        far = max(far, reach * 1.5)
    up = np.asarray(cam.up, np.float64)
    forward = np.subtract(target, eye)
    if np.linalg.norm(forward) == 0.0:
        raise CLIError(f"camera eye and target are the same point {tuple(eye)}")
    if np.linalg.norm(np.cross(forward, up)) < 1e-6 * np.linalg.norm(forward):
        up = np.array([0.0, 0.0, -1.0])          # looking straight up or down
    try:
        if ortho is not None:
            xmag = cam.xmag * ortho / cam.ymag if cam.is_orthographic else ortho
            return Camera.orthographic(eye, target, tuple(up), xmag, ortho, near=min(cam.near, far * 0.5), far=far)
        return Camera.look_at(eye, target, tuple(up), fov, near=min(cam.near, far * 0.5), far=far)
    except ValueError as exc:
        raise CLIError(str(exc)) from None


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
                    video: Optional[str] = None) -> None:
    """Refuse to write any file twice in one run, or over an input scene."""
    owner: dict[str, str] = {}
    inputs = {os.path.realpath(s): s for s in scenes}
    if video is not None:
        owner[os.path.realpath(video)] = "--video"
        if os.path.realpath(video) in inputs:
            raise CLIError(f"--video {video} would overwrite the input scene {video}")
    for scene, image in zip(scenes, images):
        for p in [image, *aov_paths(image, aovs, exr)]:
            key = os.path.realpath(p)
            if key in inputs:
                raise CLIError(f"output {p} would overwrite the input scene {inputs[key]}")
            if key in owner:
                raise CLIError(f"two outputs would be written to {p} (scenes {owner[key]} and {scene}); "
                               f"use a pattern with {{name}}/{{index}} or separate runs")
            owner[key] = scene


# ---------------------------------------------------------------------------------------------
# commands
def cmd_render(args) -> int:
    from .device import default_device_info
    from .renderer import RenderConfig, Renderer

    scenes = list(args.scenes)
    for s in scenes:
        p = Path(s)
        if not p.exists():
            raise CLIError(f"{s}: file not found")
        if not p.is_file():
            raise CLIError(f"{s}: not a file")
    options = {name: value for name, value in (
        ("tile_size", args.tile_size), ("light_tile_size", args.light_tile_size),
        ("light_culling", args.light_culling), ("pipeline", args.pipeline), ("msaa", args.msaa),
        ("light_buffer_specular", args.light_buffer_specular),
        ("light_buffer_precision", args.light_buffer_precision), ("tonemap", args.tonemap), ("exposure", args.exposure),
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
    images = _plan_outputs(scenes, args.output)
    bit_depth = getattr(args, "bit_depth", 8)
    exr = bool(getattr(args, "exr", False))
    video = getattr(args, "video", None)
    fps = getattr(args, "fps", 24.0)
    if bit_depth == 16:
        for image in images:
            if image.suffix.lower() != ".png":
                raise CLIError(f"--bit-depth 16: {image} is not a .png (16-bit images are PNG only)")
    if exr and not exr_available():
        raise CLIError(f"--exr: {EXR_MISSING}")
    if video is not None:
        if not (np.isfinite(fps) and fps > 0):
            raise CLIError(f"--fps: expected a positive number, got {fps!r}")
        try:
            check_video_path(video)
        except (ValueError, RuntimeError) as exc:
            raise CLIError(f"--video: {exc}") from None
    elif getattr(args, "fps", 24.0) != 24.0:
        _note(args, f"{PROG}: note: --fps has no effect without --video")
    _check_distinct(scenes, images, args.aov, exr, video)
    written: list[Path] = []
    info = default_device_info(args.device)

    renderers: dict = {}            # one per resolution (normally exactly one); kernels build once
    failures = 0
    n = len(scenes)
    for index, (scene_path, image) in enumerate(zip(scenes, images), 1):
        try:
            scene = _load(scene_path)
            width, height = _scene_size(scene, args)
            camera = _camera(scene, args)
            config = _scene_config(scene, scene_path, options)
            renderer = renderers.get((width, height, config))
            if renderer is None:
                renderer = renderers[(width, height, config)] = Renderer(width, height, device=info, config=config)
            start = time.perf_counter()
            frame = renderer.render(scene, camera, previous_camera=_previous_camera(camera, args), time=args.time)
            wall_ms = (time.perf_counter() - start) * 1e3
            write_outputs(frame, image, args.aov, bit_depth=bit_depth, exr=exr)
            written.append(image)
        except (CLIError, ValueError, OSError) as exc:     # SceneError is a ValueError
            if n == 1 or _debug():
                raise
            failures += 1
            message = _one_line(exc)
            if scene_path not in message:
                message = f"{scene_path}: {message}"
            print(f"{PROG}: error: {message}", file=sys.stderr, flush=True)
            continue
        _note(args, f"[{index}/{n}] {scene_path} -> {image} ({wall_ms:.1f} ms, "
                    f"{scene.triangle_count} triangles, {width}x{height})")
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
    passes = [(k[:-3], v) for k, v in stats.items() if k.endswith("_ms") and k != "total_ms"]
    parts = [f"{name} {ms:.2f}" for name, ms in passes]
    text = "passes (ms): " + ", ".join(parts)
    if "total_ms" in stats:
        text += f"; total {stats['total_ms']:.2f}"
    extra = [f"{k} {stats[k]}" for k in ("prims", "tile_entries", "retries") if k in stats]
    if "device_bytes" in stats:
        extra.append(f"device {stats['device_bytes'] / 2**20:.1f} MiB")
    if extra:
        text += "; " + ", ".join(extra)
    return text


def cmd_devices(args) -> int:
    from .device import DeviceError, default_device_info, list_devices
    from .device_report import device_record, devices_table

    devices = list_devices()
    if not devices:
        raise CLIError("no OpenCL device found: install one, e.g. `pip install pocl-binary-distribution`")
    try:
        default_id = default_device_info().id
    except DeviceError:
        default_id = None
    records = [device_record(d, default_id, _one_line) for d in devices]
    if args.json:
        print(json.dumps(records, indent=2))
        return 0
    print(devices_table(records))
    if default_id is not None:
        print("* default device (override with --device NAME or $CLRENDER_DEVICE)")
    return 0


def cmd_check(args) -> int:
    from .check import run_check
    for s in args.scene:
        if not Path(s).is_file():
            raise CLIError(f"{s}: file not found")
    report = run_check(args.device, args.scene, args.width, args.height,
                       progress=None if args.quiet else (lambda m: print(f"rendering {m}", file=sys.stderr)))
    print(report.table())
    if len(report.devices) < 2:
        _note(args, f"{PROG}: note: only one device ({report.devices[0]}): nothing to compare")
    if args.json:
        Path(args.json).write_text(json.dumps(report.to_dict(), indent=2))
    return 0 if report.ok else 1


def cmd_info(args) -> int:
    path = Path(args.scene)
    if not path.exists():
        raise CLIError(f"{args.scene}: file not found")
    scene = _load(args.scene)
    summary = scene.summary()
    summary["settings"] = scene.settings
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
    return 0


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
    return os.environ.get(ENV_DEBUG, "").strip() not in ("", "0")


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


def main(argv: Optional[Sequence[str]] = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    _quiet_compiler_logs()
    try:
        args = build_parser().parse_args(_join_vector_options(argv))
        _one_line_warnings(getattr(args, "quiet", False))
        return int(args.func(args) or 0)
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
        from .scene import SceneError
        known = isinstance(exc, (SceneError, ValueError, OSError)) or type(exc).__name__ == "DeviceError"
        message = _one_line(exc) if known else f"{type(exc).__name__}: {_one_line(exc)}"
        print(f"{PROG}: error: {message}", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
