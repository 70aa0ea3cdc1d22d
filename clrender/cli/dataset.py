"""`clrender dataset SCENE -o DIR --views N ...`: a synthetic NeRF / COLMAP dataset (clrender.dataset),
rendered through the batch machinery (clrender.batch: manifest, --resume, progress, Dask workers).

Every check that can fail (views, camera file, depth range, output folder, a --resume of another
job) runs before anything is written or rendered. The camera files are written before the first
view renders, and every view renders from the camera the reader parses from them.
"""
from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np

from clrender.outputs.aov_io import atomic_write
from clrender.batch.jobs import VERSION, FrameTask, Outputs, job_signature, scene_size
from clrender.cli.common import (
    PROG, CLIError, _note, allowed_folders, check_output_options, check_outputs_spare_inputs, input_files,
    render_options)
from clrender.cli.batch import _check_writable, run_job
from clrender.cli.parser import (
    _aov_list, _finite_float, _fov, _non_negative_int, _positive_float, _positive_int, add_batch_options,
    add_render_options)
from clrender.dataset.camera_file import file_camera, read_camera_file
from clrender.dataset.views import (
    DEFAULT_ELEVATION_DEG, DEFAULT_FOV_DEG, FORMATS, LAYOUTS, export_documents, layout_cameras, parse_documents)
from clrender.dataset.outputs import PNG16_MAX, view_files
from clrender.batch.manifest import MANIFEST_NAME, Manifest

FPS = 24.0                       # unused by a dataset (views have no motion) but part of a job's signature
DEFAULT_AOVS = ("depth", "object_id")


def _dataset_aovs(text: str) -> list[str]:
    """render's --aov list, or "none" (images only)."""
    return [] if text.strip().lower() == "none" else _aov_list(text)


def add_parser(sub) -> None:
    d = sub.add_parser("dataset", help="render a synthetic dataset (images, depth, masks, cameras) for NeRF/COLMAP",
                       description="Render N views around SCENE's bounds (or the cameras of a file) into DIR: "
                                   "images/, depth/, masks/ and the cameras as nerfstudio/instant-ngp "
                                   "transforms.json or a COLMAP text model (docs/datasets.md). Every view shows "
                                   "the scene at t = 0 (a camera file's: at its camera's time, if any).")
    d.add_argument("scenes", nargs=1, metavar="SCENE", help="scene file (.toml .gltf .glb .obj .ply .stl)")
    d.add_argument("-o", "--output", required=True, metavar="DIR", help="the export folder")
    d.add_argument("--views", type=_positive_int, metavar="N", help="number of views (with --cameras: the file's)")
    d.add_argument("--layout", choices=LAYOUTS,
                   help="orbit: a ring at --elevation; sphere: Fibonacci points over the upper hemisphere; "
                        "random: uniform directions from --seed (default orbit)")
    d.add_argument("--seed", type=_non_negative_int, metavar="S", help="with --layout random: the generator's seed (default 0)")
    d.add_argument("--elevation", type=_finite_float, metavar="DEG",
                   help=f"with --layout orbit: the ring's elevation in degrees (default {DEFAULT_ELEVATION_DEG:g})")
    d.add_argument("--fov", type=_fov, metavar="DEG",
                   help=f"vertical field of view of generated views, and of eye/target cameras without "
                        f"fov_y_deg (default {DEFAULT_FOV_DEG:g})")
    d.add_argument("--cameras", metavar="FILE.json|FILE.toml",
                   help="render these cameras (eye/target/up/fov_y_deg or OpenCV K/R/t each) instead of a layout")
    d.add_argument("--format", choices=FORMATS, default="nerf",
                   help="camera files: nerfstudio/instant-ngp transforms.json or COLMAP sparse/0/*.txt (default nerf)")
    d.add_argument("--aov", type=_dataset_aovs, default=list(DEFAULT_AOVS), metavar="LIST|none",
                   help="AOVs to write: depth -> depth/, object_id -> masks/, others -> aovs/ "
                        f"(default {','.join(DEFAULT_AOVS)})")
    d.add_argument("--depth-scale", type=_positive_float, default=1000.0, metavar="S",
                   help="depth PNG value per scene unit (default 1000: millimetres for a scene in metres); "
                        "views that can see past 65535/S are refused")
    d.add_argument("--exr", action="store_true", help="also write exr/NNNN.exr: colour and every float --aov")
    add_render_options(d)
    add_batch_options(d.add_argument_group("batches", "--resume and Dask workers, as `clrender render --frames`"))
    d.add_argument("-q", "--quiet", action="store_true", help="no progress or notes on stderr")


def _layout_settings(args) -> dict:
    """The layout and its settings (each only with the layout that uses it), checked."""
    layout = args.layout or "orbit"
    for flag, value, owner in (("--seed", args.seed, "random"), ("--elevation", args.elevation, "orbit")):
        if value is not None and layout != owner:
            raise CLIError(f"{flag} goes with --layout {owner} (the {layout} layout does not use it)")
    elevation = DEFAULT_ELEVATION_DEG if args.elevation is None else args.elevation
    if not -90.0 < elevation < 90.0:
        raise CLIError(f"--elevation: expected degrees in (-90, 90), got {elevation:g}")
    return {"layout": layout, "elevation_deg": elevation, "seed": 0 if args.seed is None else args.seed}


# What one view costs before the first renders (measured: 5-7 KB): its camera, the camera files'
# text, the view parsed back from them, its task and output paths. A dataset's camera files list
# every view and are written before rendering, so its views are planned up front, not lazily: their
# number is checked against the memory budget (clrender.loaders.budget) before any is made.
DATASET_VIEW_BYTES = 8 << 10


def _check_view_budget(views: int) -> None:
    from clrender.loaders import budget
    try:
        budget.Budget().check(views * DATASET_VIEW_BYTES, "--views", f"{views} views (their cameras, camera files "
                                                                       f"and tasks, planned before rendering)")
    except ValueError as exc:           # BudgetError, or a bad CLRENDER_MAX_MEMORY
        raise CLIError(str(exc)) from None


def _cameras(args, scene, bounds):
    """(source cameras, per view its time and name, the scene's bounds at each, width, height, what
    the dataset.json records of them): a layout's (all at t = 0) or a file's (each at its "time",
    else 0)."""
    fov = args.fov or DEFAULT_FOV_DEG
    if args.cameras is None:
        if args.views is None:
            raise CLIError("give --views N (or --cameras FILE)")
        _check_view_budget(args.views)
        settings = _layout_settings(args)
        width, height = scene_size(scene, args.width, args.height)
        cameras = layout_cameras(settings["layout"], args.views, bounds, width, height, fov,
                                 settings["elevation_deg"], settings["seed"])
        return (cameras, [{"time": 0.0}] * len(cameras), [bounds] * len(cameras), width, height,
                {**settings, "fov_y_deg": fov})
    given = [f for f, v in (("--layout", args.layout), ("--seed", args.seed), ("--elevation", args.elevation))
             if v is not None]
    if given:
        raise CLIError(f"{given[0]} places generated views; --cameras gives them (use one or the other)")
    try:
        cf = read_camera_file(args.cameras)
        if args.views is not None and args.views != len(cf.entries):
            raise CLIError(f"--views {args.views}: {args.cameras} has {len(cf.entries)} cameras")
        _check_view_budget(len(cf.entries))
        if args.width is None and args.height is None and cf.width:
            width, height = cf.width, cf.height              # the size the file's K are given for
        else:
            width, height = scene_size(scene, args.width, args.height)
        times = [float(e.get("time", 0.0)) for e in cf.entries]
        at = {0.0: bounds}                   # near/far where absent: around the scene posed at the view's time
        for t in times:
            if t not in at:
                if scene.animation is not None:
                    scene.pose(t)
                at[t] = scene.bounds() if scene.animation is not None else bounds
        if len(at) > 1 and scene.animation is not None:
            scene.pose(0.0)
        cameras = [file_camera(cf, i, at[t], width, height, fov) for i, t in enumerate(times)]
        for i, camera in enumerate(cameras):
            if camera.is_orthographic:      # transforms.json and COLMAP hold pinhole cameras
                raise CLIError(f"--cameras {cf.path}: camera {i}: ortho: a {args.format} dataset holds pinhole "
                               f"cameras only (give fov_y_deg, or render it with `clrender render --camera`)")
        labels = [{"time": t, **({"name": e["name"]} if "name" in e else {})} for t, e in zip(times, cf.entries)]
        return cameras, labels, [at[t] for t in times], width, height, {"cameras": args.cameras}
    except ValueError as exc:
        raise CLIError(f"--cameras {exc}") from None


def _check_depth_range(views, view_bounds, scale: float) -> None:
    """Refuse a view that could see a depth the 16-bit PNG cannot hold: the farthest corner of the
    bounds (the scene's at the view's time) along its optical axis, or its far plane if nearer
    (nothing renders beyond far)."""
    for v, bounds in zip(views, view_bounds):
        lo, hi = np.asarray(bounds, np.float64)
        corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
        reach = min(float((corners @ v.R[2] + v.t[2]).max()), v.camera.far)
        if reach * scale > PNG16_MAX:
            fit = 10.0 ** math.floor(math.log10(PNG16_MAX / reach))
            raise CLIError(f"--depth-scale {scale:g}: view {v.index} can see depths up to {reach:.6g} scene units, "
                           f"past the 16-bit depth PNG's {PNG16_MAX / scale:g} (65535 / depth scale); "
                           f"use --depth-scale {fit:g} or less")


def cmd_dataset(args) -> int:
    from clrender.batch.jobs import _scene

    options = render_options(args)                  # checks the scene file and every render flag
    check_output_options(args, [])                  # --exr needs OpenEXR
    scene_path = args.scenes[0]
    root = Path(args.output)
    if root.exists() and not root.is_dir():
        raise CLIError(f"output {root} is not a folder")
    allow = allowed_folders(args)
    scene = _scene(scene_path, allow, args.variant)   # the batch's cache: an in-process job loads it once
    if scene.animation is not None:
        scene.pose(0.0)
    bounds = scene.bounds()
    cameras, labels, view_bounds, width, height, source = _cameras(args, scene, bounds)
    times = [label["time"] for label in labels]
    aovs = tuple(args.aov)
    if "object_id" in aovs and len(scene.objects) >= PNG16_MAX:
        raise CLIError(f"{scene_path}: {len(scene.objects)} objects do not fit 16-bit masks "
                       f"(drop object_id from --aov)")
    digits = max(4, len(str(len(cameras) - 1)))
    files = [view_files(f"{i:0{digits}d}", aovs, args.exr) for i in range(len(cameras))]
    timed = any(t != 0.0 for t in times)           # dataset.json: each view's time instead of one, and names
    files = [{**f, **{k: v for k, v in label.items() if timed or k != "time"}} for f, label in zip(files, labels)]
    meta = {"clrender": VERSION, "scene": scene_path, **source, **({} if timed else {"time": 0.0}),
            "aovs": list(aovs), "exr": args.exr,
            "depth_scale": args.depth_scale, **({"variant": args.variant} if args.variant is not None else {})}
    docs = export_documents(args.format, cameras, width, height, files, meta)
    views = parse_documents(docs, root)            # the reader's cameras, from the very texts written below
    if "depth" in aovs:
        _check_depth_range(views, view_bounds, args.depth_scale)
    inputs = input_files([scene], [(args.cameras, f"--cameras {args.cameras}")])   # and what the scene reads
    outputs = Outputs(aovs, exr=args.exr, layout="dataset", depth_scale=args.depth_scale)
    tasks = [FrameTask(scene=scene_path, frame=v.index, time=times[v.index], dt=1.0 / FPS, image=str(v.image),
                       outputs=outputs, width=width, height=height, options=tuple(sorted(options.items())),
                       device=args.device, view=v.camera, allow=allow, variant=args.variant) for v in views]
    manifest_path = root / MANIFEST_NAME
    check_outputs_spare_inputs([*(root / rel for rel in docs), *(p for t in tasks for p in t.paths()), manifest_path],
                               inputs)
    _check_writable({Path(p).parent for t in tasks for p in t.paths()} | {(root / rel).parent for rel in docs})
    if args.resume:                                  # before the camera files are rewritten
        try:
            manifest = Manifest.open(manifest_path, job_signature(tasks, FPS), VERSION, resume=True)
        except ValueError as exc:
            raise CLIError(str(exc)) from None
        for t in tasks:                              # the signature has the cameras, not their times
            record = manifest.get(t.scene, t.frame) or {}
            if record.get("status") == "ok" and record.get("time") != t.time:
                raise CLIError(f"--resume: {manifest_path}: view {t.frame} was rendered at time {record.get('time')}, "
                               f"not {t.time:g}; render into another folder or drop --resume")
    for rel, text in docs.items():
        atomic_write(root / rel, lambda tmp, text=text: Path(tmp).write_text(text))
    result = run_job(args, tasks, manifest_path, FPS, f"{len(tasks)} view(s) of {scene_path} ({width}x{height}, "
                                                      f"{args.format})")
    if result.failed:
        print(f"{PROG}: error: {len(result.failed)} of {len(tasks)} views failed", file=sys.stderr, flush=True)
        return 1
    _note(args, f"{PROG}: dataset in {root} ({len(tasks)} views)")
    return 0

