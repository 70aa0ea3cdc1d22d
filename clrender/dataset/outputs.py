"""The files of one view of a `clrender dataset` export (layout: clrender/dataset/views.py's docstring).

The view's image is ROOT/images/<stem>.png; everything else derives from that path, so a batch
task (`clrender.batch.FrameTask` with `Outputs(layout="dataset")`) names every file it writes
from its image alone:

    images/<stem>.png         sRGB uint8
    depth/<stem>.npy          float32 z-depth (Frame.depth), +inf on background        (aov depth)
    depth/<stem>.png          uint16 round(z · depth_scale), 0 on background            (aov depth)
    masks/<stem>.png          uint16 object_id + 1, 0 on background                     (aov object_id)
    aovs/<stem>.<aov>.npy/png every other AOV, clrender.outputs.aov_io.write_aovs's naming
    exr/<stem>.exr            with exr: colour and every float AOV (clrender.outputs.aov_io.write_exr)
"""
from __future__ import annotations

from pathlib import Path
from typing import Sequence

import numpy as np

# aov_io's atomic .npy and 16-bit PNG writers (private there: only whole outputs were public so far)
from clrender.outputs.aov_io import _save_npy, _write_png16, aov_paths, write_aovs, write_exr, write_image

PNG16_MAX = 65535
# AOVs with their own folder; the others go to aovs/ under write_aovs's names.
OWN_FOLDER = ("depth", "object_id")


def view_files(stem: str, aovs: Sequence[str], exr: bool) -> dict:
    """Relative paths (POSIX strings) of one view's files by role: image, depth, depth_png, mask,
    exr (None when not written) and aovs (every other AOV file)."""
    aovs = tuple(aovs)
    others = [a for a in aovs if a not in OWN_FOLDER]
    return {"image": f"images/{stem}.png",
            "depth": f"depth/{stem}.npy" if "depth" in aovs else None,
            "depth_png": f"depth/{stem}.png" if "depth" in aovs else None,
            "mask": f"masks/{stem}.png" if "object_id" in aovs else None,
            "exr": f"exr/{stem}.exr" if exr else None,
            "aovs": [p.as_posix() for p in aov_paths(Path("aovs") / f"{stem}.png", others, False)]}


def view_paths(image: Path, aovs: Sequence[str], exr: bool) -> list[Path]:
    """Every file of the view whose image is `image` (ROOT/images/<stem>.png), image first."""
    root = Path(image).parent.parent
    files = view_files(Path(image).stem, aovs, exr)
    rel = [files[k] for k in ("image", "depth", "depth_png", "mask", "exr") if files[k]] + files["aovs"]
    return [root / r for r in rel]


def depth_png(depth: np.ndarray, scale: float) -> np.ndarray:
    """uint16 round(depth · scale), 0 on background (non-finite depth). A foreground depth that
    would round to 0 is stored as 1 (0 means background); one beyond 65535 units is a ValueError,
    never clipped (the CLI refuses such views before rendering; this guards the library path)."""
    z = np.asarray(depth, np.float64) * float(scale)
    fg = np.isfinite(z)
    if fg.any() and z[fg].max() > PNG16_MAX + 0.5:
        raise ValueError(f"depth {z[fg].max() / scale:g} does not fit a 16-bit depth PNG at depth scale {scale:g} "
                         f"(max {PNG16_MAX / scale:g}); lower the depth scale")
    out = np.zeros(z.shape, np.uint16)
    out[fg] = np.maximum(np.rint(z[fg]), 1).astype(np.uint16)
    return out


def mask_png(object_id: np.ndarray) -> np.ndarray:
    """uint16 object_id + 1 (0: background, object_id -1)."""
    ids = np.asarray(object_id, np.int64)
    if ids.size and ids.max() + 1 > PNG16_MAX:
        raise ValueError(f"object id {int(ids.max())} does not fit a 16-bit mask PNG (max {PNG16_MAX - 1})")
    return (ids + 1).astype(np.uint16)


def write_view(frame, image: Path, aovs: Sequence[str], exr: bool, depth_scale: float) -> None:
    """Write `frame` as the view whose image is `image` (every file atomically, clrender.outputs.aov_io)."""
    image = Path(image)
    root, stem = image.parent.parent, image.stem
    write_image(frame, image, 8)
    if "depth" in aovs:
        depth = np.asarray(frame.depth, np.float32)
        png = depth_png(depth, depth_scale)          # first: a depth out of range writes no depth file
        _save_npy(root / "depth" / f"{stem}.npy", depth)
        _write_png16(root / "depth" / f"{stem}.png", png)
    if "object_id" in aovs:
        _write_png16(root / "masks" / f"{stem}.png", mask_png(frame.object_id))
    others = [a for a in aovs if a not in OWN_FOLDER]
    if others:
        write_aovs(frame, root / "aovs" / f"{stem}.png", others)
    if exr:
        write_exr(root / "exr" / f"{stem}.exr", frame, aovs)
