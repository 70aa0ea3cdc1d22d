"""The command line's grammar: `clrender render | devices | check | info` and their options'
types (`dataset`'s: clrender/cli/dataset.py, sharing add_render_options and add_batch_options;
clrender/cli/app.py's build_parser puts the subcommands together). The render flags come from
the option table (clrender/config.py). This module only describes and checks the arguments."""
from __future__ import annotations

import argparse
import math

from clrender.abi.aovs import WRITTEN as WRITTEN_AOVS

from clrender.cli.common import ENV_DEBUG, IMAGE_SUFFIXES, PROG, CLIError  # noqa: F401  (re-exported)
from clrender.config import OPTIONS

# AOVs the CLI writes: every AOV of the table but `image`, which is the main output.
AOVS = WRITTEN_AOVS


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


def _number(kind, accept, expected: str):
    """An argparse type: `kind`(text) (int or float) that `accept` takes, else "expected <expected>"."""
    def parse(text: str):
        try:
            value = kind(text)
        except ValueError:
            value = None
        if value is None or not accept(value):
            raise argparse.ArgumentTypeError(f"expected {expected}, got {text!r}")
        return value
    return parse


_positive_int = _number(int, lambda v: v >= 1, "a positive integer")
_non_negative_int = _number(int, lambda v: v >= 0, "an integer >= 0")
_fov = _number(float, lambda v: 0.0 < v < 180.0, "degrees in (0, 180)")
_half_height = _number(float, lambda v: 0.0 < v < math.inf, "a positive half-height in world units")
_positive_float = _number(float, lambda v: 0.0 < v < math.inf, "a positive number")
_non_negative_float = _number(float, lambda v: 0.0 <= v < math.inf, "a finite number >= 0")
_finite_float = _number(float, math.isfinite, "a finite number")


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


def add_allow_outside(p) -> None:
    p.add_argument("--allow-outside", action="append", default=[], metavar="PATH",
                   help="let the scene's references (textures, buffers, material libraries, meshes, "
                        "environments) read files in folder PATH too; by default a scene file reads only "
                        "files in its own folder (repeatable)")


def add_render_options(p) -> None:
    """The size, device and RenderConfig flags `render` and `dataset` share (cli.render_options reads them)."""
    add_allow_outside(p)
    p.add_argument("--width", type=_positive_int, metavar="W",
                   help="image width (default: the scene's [render] width, else 1280)")
    p.add_argument("--height", type=_positive_int, metavar="H",
                   help="image height (default: the scene's [render] height, else 720)")
    p.add_argument("--variant", metavar="NAME",
                   help="render the glTF material variant NAME (KHR_materials_variants; `clrender info SCENE` "
                        "lists them); default: each primitive's own material")
    p.add_argument("--device", metavar="NAME",
                   help="OpenCL device: P:D, an implementation (intel, pocl, oclgrind, nvidia, ...), pip or "
                        "system, or a name substring (default: $CLRENDER_DEVICE, else a GPU, else the best "
                        "usable CPU runtime); see `clrender devices`")
    for option in OPTIONS:                      # the RenderConfig options that have a flag
        if option.cli_flag is not None:
            p.add_argument(option.cli_flag, help=option.help_text(), **_flag_kind(option))


def _flag_kind(option) -> dict:
    """argparse's view of an option: a switch (left None when not given, so the scene's [render]
    value stands), a choice, or a number whose type names the smallest value it takes."""
    if option.cli_switch:
        return {"action": "store_true", "default": None}
    if option.type is str:
        return {"choices": option.choices}
    if option.type is float:
        kind = float
    elif option.choices is not None:            # tile sizes, msaa: RenderConfig names the choices
        kind = int
    else:
        kind = _positive_int if option.range[0] >= 1 else _non_negative_int
    return {"type": kind, "metavar": option.metavar}


def add_batch_options(g) -> None:
    """--resume, --workers, --scheduler, --resources (cli_batch.dask_client reads them)."""
    g.add_argument("--resume", action="store_true",
                   help="skip frames the output folder's manifest.json shows complete")
    g.add_argument("--workers", type=_positive_int, metavar="N",
                   help="render on a local Dask cluster of N worker processes")
    g.add_argument("--scheduler", metavar="ADDRESS", help="render on the Dask cluster at ADDRESS (tcp://host:8786)")
    g.add_argument("--resources", metavar="NAME=N[,...]",
                   help="with --scheduler: run only on workers with these Dask resources (e.g. GPU=1)")


def root_parser():
    """(the `clrender` parser, its subcommands' action): main.build_parser adds each command."""
    parser = _Parser(prog=PROG, description="clrender: a tiled deferred renderer whose pixels are "
                                            "computed by OpenCL kernels.")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    sub.required = True
    return parser, sub


def add_render_parser(sub) -> None:
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
    add_render_options(r)
    r.add_argument("--previous-eye", type=_vec3, metavar="X,Y,Z",
                   help="the camera's position at the previous frame (velocity, motion blur)")
    r.add_argument("--previous-target", type=_vec3, metavar="X,Y,Z",
                   help="the point the camera looked at in the previous frame")
    r.add_argument("--environment", metavar="PATH|studio|none",
                   help="HDR environment lighting the scene (image-based lighting): an .exr/.hdr/.pic "
                        "equirectangular image, the built-in neutral 'studio', or 'none' to remove the scene's "
                        "(default: the scene's own: a TOML [environment] table, or 'studio' for a glTF file "
                        "without lights)")
    r.add_argument("--environment-intensity", type=_non_negative_float, metavar="X",
                   help="scale the environment's radiance (default 1, or the scene's)")
    r.add_argument("--environment-rotation", type=_finite_float, metavar="DEG",
                   help="turn the environment about +Y by DEG degrees (default 0, or the scene's)")
    r.add_argument("--time", type=float, default=0.0, metavar="SECONDS",
                   help="time of a single frame: poses the scene's animation and places its light particles (default 0)")
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
    r.add_argument("--camera", metavar="FILE.json|FILE.toml",
                   help="one image per camera of this camera file (`clrender view`'s saved views; "
                        "docs/datasets.md), each at its camera's time, else --time: OUT is a directory "
                        "(OUT/<scene-name>.NNNN.png, NNNN the camera's index from 0), a pattern with {camera} "
                        "and/or {name} (the camera's name), or one image for a one-camera file; size: "
                        "--width/--height, else the file's, else the scene's. Excludes --camera-eye, "
                        "--camera-target, --fov, --ortho and --frames")
    r.add_argument("--bit-depth", type=int, choices=(8, 16), default=8, metavar="{8,16}",
                   help="bits per channel of the image (16: PNG only, from the tone-mapped float colour; default 8)")
    r.add_argument("--aov-sheet", action="store_true",
                   help="also write <out-stem>.sheet.png: the image and the previews of every --aov, labelled, "
                        "on one contact sheet")
    r.add_argument("--exr", action="store_true",
                   help="also write <out-stem>.exr: float32 layers color.RGB and every float --aov (needs OpenEXR)")
    r.add_argument("--video", metavar="FILE.mp4|FILE.gif",
                   help="also assemble the rendered images, in order, into a video (.mp4 H.264 via imageio-ffmpeg, or .gif)")
    r.add_argument("--fps", type=float, default=None, metavar="N",
                   help="frames per second: frame f shows time f/fps, and the video's rate (default 24)")
    b = r.add_argument_group("frames and batches", "Render an animation or a range of frames (frame f at time "
                             "f/fps; glTF animations and TOML keyframes), with a progress bar, a manifest.json "
                             "in the output folder, and optionally on a Dask cluster (docs/batch.md: Batch and cluster "
                             "rendering).")
    b.add_argument("--frames", metavar="A:B[:STEP]|N|all",
                   help="frames A..B-1 (every STEP-th), frame N, or all of the scene's animation")
    b.add_argument("--time-range", metavar="T0:T1", help="the frames whose times lie in [T0, T1) seconds")
    add_batch_options(b)
    r.add_argument("-q", "--quiet", action="store_true", help="no progress or notes on stderr")


def add_devices_parser(sub) -> None:
    d = sub.add_parser("devices", help="list OpenCL devices and whether clrender's kernels build on them",
                       description="List every OpenCL device with the limits clrender relies on, mark the "
                                   "default one, and try building clrender's kernels on each.")
    d.add_argument("--json", action="store_true", help="print JSON instead of a table")
    d.add_argument("--require", action="append", default=[], metavar="NAME",
                   help="fail unless a device matching NAME runs clrender's kernels (repeatable; CI)")
    d.add_argument("--no-probe", action="store_true",
                   help="list without building clrender's kernels on each device (KERNELS: not probed; "
                        "no default mark, which needs the probe)")


def add_check_parser(sub) -> None:
    c = sub.add_parser("check", help="render fixed cases on several devices and compare every AOV")
    c.add_argument("--device", default="all", metavar="NAME|all",
                   help="devices to compare (default all, simulators such as Oclgrind included)")
    c.add_argument("--scene", action="append", default=[], metavar="S", help="check this scene instead of the fixed cases")
    c.add_argument("--width", type=_positive_int, default=96, metavar="W")
    c.add_argument("--height", type=_positive_int, default=64, metavar="H")
    c.add_argument("--json", metavar="REPORT", help="also write the report as JSON")
    c.add_argument("--min-devices", type=_positive_int, default=1, metavar="N",
                   help="fail unless at least N devices were compared (CI: 2, so a missing "
                        "implementation cannot pass as agreement)")
    c.add_argument("-q", "--quiet", action="store_true", help="no progress on stderr")


def add_info_parser(sub) -> None:
    i = sub.add_parser("info", help="describe a scene file",
                       description="Triangles, vertices, meshes, materials, textures, bounds and camera "
                                   "of a scene file; for glTF also its skins, morph targets, animations and "
                                   "extensions.")
    i.add_argument("scene", metavar="SCENE")
    i.add_argument("--json", action="store_true", help="print JSON instead of text")
    add_allow_outside(i)
