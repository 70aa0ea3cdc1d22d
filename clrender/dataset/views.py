"""Synthetic datasets for NeRF / COLMAP tools: the views of `clrender dataset`, their files, and a reader.

    clrender dataset scene.gltf -o out/ --views 100 --layout sphere --format nerf
    views = clrender.dataset.load_dataset("out/")      # [DatasetView(camera=Camera, K, R, t, image, depth, ...)]

An export folder (docs/datasets.md has the conventions and a plain-NumPy loading example):

    images/NNNN.png           sRGB uint8, one per view (NNNN = view index)
    depth/NNNN.npy            float32 z-depth along the optical axis (Frame.depth), +inf on background
    depth/NNNN.png            uint16 round(z · depth_scale) (default 1000: mm for a scene in metres), 0 on background
    masks/NNNN.png            uint16 object_id + 1 (index into scene.objects), 0 on background
    aovs/NNNN.<aov>.npy/.png  every other --aov (normal, position, material_id, ...), as `clrender render` names them
    exr/NNNN.exr              with --exr: colour and every float AOV as layers
    transforms.json           --format nerf: nerfstudio / instant-ngp cameras (c2w, OpenGL axes)
    sparse/0/cameras.txt      --format colmap: COLMAP's text model (PINHOLE; world-to-camera poses)
    sparse/0/images.txt
    sparse/0/points3D.txt     (empty)
    dataset.json              clrender's record: scene, settings, and per view its files and near/far
    manifest.json             the batch manifest (--resume; clrender.batch.manifest)

Depth and masks are written for the AOVs `depth` and `object_id` (both by default). Pixel centres
lie at integer + 0.5 (COLMAP's, nerfstudio's and clrender's convention, clrender/scene/camera.py).

Exactness: the render camera of every view is made from the numbers the export stores, by the
reader's own parser (`parse_documents` on the file texts, before they are written), so re-rendering
a view with `load_dataset(folder)[i].camera` gives the written image bit for bit. JSON and the
COLMAP text hold floats as repr() (17 significant digits at most), which round-trips float64.
"""
from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Optional, Sequence

import numpy as np

from clrender.scene.camera import Camera
# Camera files moved to camera_file.py; their names stay importable from here.
from clrender.dataset.camera_file import (  # noqa: F401  (re-exported)
    CAMERA_KEYS, DEFAULT_FAR, DEFAULT_FOV_DEG, DEFAULT_NEAR, CameraFile, bounding_sphere, file_cameras, near_far,
    read_camera_file)

LAYOUTS = ("orbit", "sphere", "random")
FORMATS = ("nerf", "colmap")
DEFAULT_ELEVATION_DEG = 20.0
MARGIN = 1.1              # the bounding sphere fills 1/MARGIN of the narrower half field of view
# DEFAULT_NEAR, DEFAULT_FAR (camera_file): also a foreign export's cameras (no dataset.json)
META_NAME, NERF_NAME, COLMAP_DIR = "dataset.json", "transforms.json", "sparse/0"
COLMAP_FILES = ("cameras.txt", "images.txt", "points3D.txt")


# -- views ------------------------------------------------------------------------------------
def _up_for(direction: np.ndarray) -> tuple:
    # looking straight down or up: +Y is parallel to the view direction
    return (0.0, 0.0, -1.0) if abs(direction[1]) > 1.0 - 1e-9 else (0.0, 1.0, 0.0)


def layout_directions(layout: str, n: int, elevation_deg: float = DEFAULT_ELEVATION_DEG, seed: int = 0) -> np.ndarray:
    """(n, 3) unit vectors from the centre to the eyes: orbit (a ring at `elevation_deg`, azimuth 0
    on +Z), sphere (Fibonacci lattice over the upper hemisphere) or random (uniform on the whole
    sphere, numpy's default_rng(seed))."""
    if layout not in LAYOUTS:
        raise ValueError(f"unknown layout {layout!r} (use {', '.join(LAYOUTS)})")
    if not (isinstance(n, int) and n >= 1):
        raise ValueError(f"the number of views must be a positive integer, got {n!r}")
    i = np.arange(n, dtype=np.float64)
    if layout == "orbit":
        e, az = math.radians(elevation_deg), 2.0 * np.pi * i / n
        return np.stack([math.cos(e) * np.sin(az), np.full(n, math.sin(e)), math.cos(e) * np.cos(az)], 1)
    if layout == "sphere":
        y = 1.0 - (i + 0.5) / n                                  # equal areas of the hemisphere
        phi = i * np.pi * (3.0 - math.sqrt(5.0))                  # the golden angle
        r = np.sqrt(1.0 - y * y)
        return np.stack([r * np.cos(phi), y, r * np.sin(phi)], 1)
    v = np.random.default_rng(seed).standard_normal((n, 3))
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def layout_cameras(layout: str, n: int, bounds, width: int, height: int, fov_y_deg: float = DEFAULT_FOV_DEG,
                   elevation_deg: float = DEFAULT_ELEVATION_DEG, seed: int = 0) -> list[Camera]:
    """`n` cameras looking at the centre of `bounds` from `layout_directions`, each far enough for
    the bounding sphere to fit the narrower field of view with MARGIN, near/far around it."""
    centre, radius = bounding_sphere(bounds)
    tan_y = math.tan(math.radians(fov_y_deg) / 2)
    half = math.atan(min(tan_y, tan_y * width / height))
    distance = radius * MARGIN / math.sin(half)
    cameras = []
    for d in layout_directions(layout, n, elevation_deg, seed):
        eye = centre + d * distance
        near, far = near_far(eye, centre, radius)
        cameras.append(Camera.look_at(tuple(eye), tuple(centre), _up_for(d), fov_y_deg, near, far))
    return cameras


# -- conventions shared by the writer and the reader ------------------------------------------
def rotation_from_quaternion(q) -> np.ndarray:
    """COLMAP's qvec2rotmat: (qw, qx, qy, qz), normalized first."""
    w, x, y, z = np.asarray(q, np.float64) / np.linalg.norm(q)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def quaternion_from_rotation(R) -> np.ndarray:
    """Unit (qw, qx, qy, qz) with qw >= 0 (Shepperd's method: divide by the largest component)."""
    R = np.asarray(R, np.float64)
    tr = np.trace(R)
    k = int(np.argmax([tr, R[0, 0], R[1, 1], R[2, 2]]))
    if k == 0:
        s = 2.0 * math.sqrt(1.0 + tr)
        q = [0.25 * s, (R[2, 1] - R[1, 2]) / s, (R[0, 2] - R[2, 0]) / s, (R[1, 0] - R[0, 1]) / s]
    else:
        i, j, m = k - 1, k % 3, (k + 1) % 3
        s = 2.0 * math.sqrt(1.0 + R[i, i] - R[j, j] - R[m, m])
        q = [0.0] * 4
        q[0], q[1 + i] = (R[m, j] - R[j, m]) / s, 0.25 * s
        q[1 + j], q[1 + m] = (R[j, i] + R[i, j]) / s, (R[m, i] + R[i, m]) / s
    q = np.asarray(q) / np.linalg.norm(q)
    return -q if q[0] < 0 else q


def c2w_from_opencv(R, t) -> np.ndarray:
    """World-to-camera (OpenCV axes) -> camera-to-world 4×4 in OpenGL axes (x right, y up, z back)."""
    R, t = np.asarray(R, np.float64), np.asarray(t, np.float64)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = R[0], -R[1], -R[2], -R.T @ t
    return m


def opencv_from_c2w(c2w) -> tuple[np.ndarray, np.ndarray]:
    m = np.asarray(c2w, np.float64)
    if m.shape != (4, 4) or not np.isfinite(m).all() or np.abs(m[3] - [0, 0, 0, 1]).max() > 1e-9:
        raise ValueError(f"transform_matrix must be a finite 4x4 with last row 0 0 0 1, got {m.tolist()}")
    R = np.stack([m[:3, 0], -m[:3, 1], -m[:3, 2]])
    return R, -R @ m[:3, 3]


def intrinsic_matrix(fx, fy, cx, cy) -> np.ndarray:
    return np.array([[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]], np.float64)


# -- the reader ---------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class DatasetView:
    """One view of an export: the render `camera` and OpenCV's K, R, t (world -> camera, x right,
    y down, z forward), `c2w` (OpenGL axes), and its files (absolute Paths; None when absent)."""
    index: int
    camera: Camera
    K: np.ndarray
    R: np.ndarray
    t: np.ndarray
    c2w: np.ndarray
    width: int
    height: int
    image: Path
    depth: Optional[Path] = None          # float32 .npy
    depth_png: Optional[Path] = None      # uint16 PNG, round(z · depth_scale)
    mask: Optional[Path] = None           # uint16 PNG, object_id + 1
    exr: Optional[Path] = None
    depth_scale: Optional[float] = None


def _view(index, K, R, t, width, height, root: Path, files: dict, meta: dict) -> DatasetView:
    near, far = files.get("near", DEFAULT_NEAR), files.get("far", DEFAULT_FAR)
    camera = Camera.from_opencv(K, R, t, width, height, near, far)
    path = (lambda key: None if not files.get(key) else root / files[key])   # noqa: E731
    return DatasetView(index, camera, K, R, t, c2w_from_opencv(R, t), width, height, path("image"), path("depth"),
                       path("depth_png"), path("mask"), path("exr"), meta.get("depth_scale"))


def _parse_nerf(doc: dict, root: Path, meta: dict, by_image: dict) -> list[DatasetView]:
    views = []
    for i, f in enumerate(doc.get("frames") or []):
        g = {**doc, **f}                          # a frame's intrinsics override the top level's
        if any(float(g.get(k, 0.0)) != 0.0 for k in ("k1", "k2", "k3", "k4", "p1", "p2")):
            raise ValueError(f"{NERF_NAME}: frame {i}: lens distortion is not supported (k1..p2 must be 0)")
        w, h = int(g["w"]), int(g["h"])
        fx = g["fl_x"] if "fl_x" in g else 0.5 * w / math.tan(0.5 * g["camera_angle_x"])
        fy = g.get("fl_y", fx)
        K = intrinsic_matrix(fx, fy, g.get("cx", w / 2), g.get("cy", h / 2))
        R, t = opencv_from_c2w(f["transform_matrix"])
        files = by_image.get(f["file_path"], {"image": f["file_path"], "depth_png": f.get("depth_file_path"),
                                               "mask": f.get("mask_path")})
        views.append(_view(files.get("index", i), K, R, t, w, h, root, files, meta))
    return views


def _colmap_lines(text: str) -> list[str]:
    return [ln.strip() for ln in text.splitlines() if ln.strip() and not ln.lstrip().startswith("#")]


def _parse_colmap(cameras_txt: str, images_txt: str, root: Path, meta: dict, by_image: dict) -> list[DatasetView]:
    cams = {}
    for ln in _colmap_lines(cameras_txt):
        cid, model, w, h, *p = ln.split()
        p = [float(v) for v in p]
        if model == "SIMPLE_PINHOLE":
            p = [p[0], p[0], p[1], p[2]]
        elif model != "PINHOLE":
            raise ValueError(f"cameras.txt: camera {cid}: model {model} is not supported (PINHOLE, SIMPLE_PINHOLE)")
        cams[int(cid)] = (intrinsic_matrix(*p), int(w), int(h))
    views = []
    for i, parts in enumerate(_image_lines(images_txt)):
        if len(parts) < 10:
            raise ValueError(f"images.txt: image line {i}: expected IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME")
        iid, cid, name = int(parts[0]), int(parts[8]), " ".join(parts[9:])
        K, w, h = cams[cid]
        R = rotation_from_quaternion([float(v) for v in parts[1:5]])
        t = np.array([float(v) for v in parts[5:8]])
        files = by_image.get(f"images/{name}", {"image": f"images/{name}"})
        views.append(_view(files.get("index", iid - 1), K, R, t, w, h, root, files, meta))
    return views


def _image_lines(text: str):
    """The pose lines of images.txt, as COLMAP reads them: after each one, the next line (even an
    empty one) is its 2D points."""
    lines = iter(text.splitlines())
    for ln in lines:
        ln = ln.strip()
        if not ln or ln.startswith("#"):
            continue
        yield ln.split()
        next(lines, None)


def parse_documents(docs: dict, root) -> list[DatasetView]:
    """The views of an export from its files' texts ({relative path: text}): dataset.json when
    present (format, near/far, file names), and transforms.json or sparse/0/*.txt."""
    root = Path(root)
    meta = json.loads(docs[META_NAME]) if META_NAME in docs else {}
    by_image = {v["image"]: v for v in meta.get("views", [])}
    fmt = meta.get("format") or ("nerf" if NERF_NAME in docs else "colmap")
    if fmt == "nerf":
        views = _parse_nerf(json.loads(docs[NERF_NAME]), root, meta, by_image)
    else:
        views = _parse_colmap(docs[f"{COLMAP_DIR}/cameras.txt"], docs[f"{COLMAP_DIR}/images.txt"], root, meta,
                              by_image)
    return sorted(views, key=lambda v: v.index)


def load_dataset(folder) -> list[DatasetView]:
    """Read an export (clrender's, or a nerfstudio/instant-ngp transforms.json, or a COLMAP text
    model in sparse/0/ with PINHOLE cameras) into views ordered by index. Without clrender's
    dataset.json, near/far are DEFAULT_NEAR/DEFAULT_FAR. ValueError for what it cannot read."""
    folder = Path(folder)
    names = [META_NAME, NERF_NAME] + [f"{COLMAP_DIR}/{n}" for n in COLMAP_FILES]
    docs = {n: (folder / n).read_text() for n in names if (folder / n).is_file()}
    if NERF_NAME not in docs and f"{COLMAP_DIR}/images.txt" not in docs:
        raise ValueError(f"{folder}: no {NERF_NAME} or {COLMAP_DIR}/images.txt: not a dataset export")
    try:
        return parse_documents(docs, folder)
    except (KeyError, IndexError, TypeError) as exc:
        raise ValueError(f"{folder}: malformed dataset files ({type(exc).__name__}: {exc})") from None


# -- the writer -----------------------------------------------------------------------------------
def _num(x) -> str:
    return repr(float(x))


def _nerf_document(stored, width: int, height: int, files: Sequence[dict], depth_scale: float) -> dict:
    def intrinsics(K):
        return {"fl_x": float(K[0, 0]), "fl_y": float(K[1, 1]), "cx": float(K[0, 2]), "cy": float(K[1, 2])}
    top = intrinsics(stored[0][0])
    doc = {"camera_model": "OPENCV", **top, "w": width, "h": height, "k1": 0.0, "k2": 0.0, "p1": 0.0, "p2": 0.0}
    if any(f.get("depth_png") for f in files):
        doc["depth_unit_scale_factor"] = 1.0 / depth_scale      # nerfstudio: depth PNG value -> scene units
    frames = []
    for (K, R, t), f in zip(stored, files):
        frame = {"file_path": f["image"], "transform_matrix": c2w_from_opencv(R, t).tolist()}
        if f.get("depth_png"):
            frame["depth_file_path"] = f["depth_png"]
        if f.get("mask"):
            frame["mask_path"] = f["mask"]
        if intrinsics(K) != top:                   # per-frame intrinsics (a camera file's own K)
            frame.update(intrinsics(K))
        frames.append(frame)
    doc["frames"] = frames
    return doc


def _colmap_documents(stored, width: int, height: int, files: Sequence[dict]) -> dict:
    cam_ids: dict = {}
    for K, _, _ in stored:
        cam_ids.setdefault((K[0, 0], K[1, 1], K[0, 2], K[1, 2]), len(cam_ids) + 1)
    cameras = ["# Camera list with one line of data per camera:", "#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]",
               f"# Number of cameras: {len(cam_ids)}"]
    cameras += [f"{cid} PINHOLE {width} {height} {' '.join(map(_num, k))}" for k, cid in cam_ids.items()]
    images = ["# Image list with two lines of data per image:",
              "#   IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME", "#   POINTS2D[] as (X, Y, POINT3D_ID)",
              f"# Number of images: {len(stored)}, mean observations per image: 0"]
    for i, ((K, R, t), f) in enumerate(zip(stored, files)):
        q = quaternion_from_rotation(R)
        # t from the rotation the reader will rebuild from q, so the eye stays where it was
        tq = -rotation_from_quaternion(q) @ (-R.T @ t)
        cid = cam_ids[(K[0, 0], K[1, 1], K[0, 2], K[1, 2])]
        images += [f"{i + 1} {' '.join(map(_num, [*q, *tq]))} {cid} {Path(f['image']).name}", ""]
    points = ["# 3D point list with one line of data per point:",
              "#   POINT3D_ID, X, Y, Z, R, G, B, ERROR, TRACK[] as (IMAGE_ID, POINT2D_IDX)",
              "# Number of points: 0, mean track length: 0"]
    texts = {"cameras.txt": cameras, "images.txt": images, "points3D.txt": points}
    return {f"{COLMAP_DIR}/{name}": "\n".join(lines) + "\n" for name, lines in texts.items()}


def export_documents(fmt: str, cameras: Sequence[Camera], width: int, height: int, files: Sequence[dict],
                     meta: dict) -> dict:
    """{relative path: text} of an export's camera files: dataset.json (`meta` plus per view its
    files and near/far) and transforms.json (nerf) or sparse/0/*.txt (colmap)."""
    if fmt not in FORMATS:
        raise ValueError(f"unknown format {fmt!r} (use {', '.join(FORMATS)})")
    stored = [c.to_opencv(width, height) for c in cameras]
    views = [{"index": i, **{k: v for k, v in f.items() if v or k == "time"}, "near": c.near, "far": c.far}
             for i, (c, f) in enumerate(zip(cameras, files))]
    docs = {META_NAME: json.dumps({**meta, "format": fmt, "width": width, "height": height, "views": views},
                                  indent=1) + "\n"}
    if fmt == "nerf":
        docs[NERF_NAME] = json.dumps(_nerf_document(stored, width, height, files, meta.get("depth_scale", 1000.0)),
                                     indent=1) + "\n"
    else:
        docs.update(_colmap_documents(stored, width, height, files))
    return docs
