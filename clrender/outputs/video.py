"""Video: frames (Frames, arrays or image files) assembled into .mp4 (H.264 through imageio-ffmpeg,
a pip wheel bundling an ffmpeg with libx264) or .gif (imageio through Pillow), written atomically."""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from clrender.outputs.atomic import _imwrite, atomic_write

VIDEO_SUFFIXES = (".mp4", ".gif")

FFMPEG_MISSING = "writing .mp4 needs ffmpeg: pip install imageio-ffmpeg (or clrender[outputs])"


def ffmpeg_available() -> bool:
    try:
        import imageio_ffmpeg
        return bool(imageio_ffmpeg.get_ffmpeg_exe())
    except Exception:          # not installed, or no binary for this platform
        return False


def check_video_path(path) -> None:
    """Raise ValueError/RuntimeError (one line) if `path` cannot be written as a video here."""
    suffix = Path(path).suffix.lower()
    if suffix not in VIDEO_SUFFIXES:
        raise ValueError(f"{path}: unsupported video type {suffix!r} (use {', '.join(VIDEO_SUFFIXES)})")
    if suffix == ".mp4" and not ffmpeg_available():
        raise RuntimeError(FFMPEG_MISSING)


def _video_frame(item) -> np.ndarray:
    """A frame as (H, W, 3) uint8: a Frame (its image), an array, or an image file path."""
    if hasattr(item, "image") and not isinstance(item, np.ndarray):
        a = item.image
    elif isinstance(item, (str, os.PathLike)):
        import imageio.v3 as iio
        a = iio.imread(item)
    else:
        a = np.asarray(item)
    if a.dtype == np.uint16:
        a = (a.astype(np.uint32) * 255 + 32767) // 65535
    if a.ndim == 2:
        a = np.repeat(a[..., None], 3, -1)
    if a.ndim != 3 or a.shape[2] not in (3, 4):
        raise ValueError(f"video frame of shape {a.shape}: expected (H, W, 3)")
    return np.ascontiguousarray(a[..., :3], np.uint8)


def write_video(path, frames_or_paths, fps: float = 24, quality_crf: int = 18) -> Path:
    """Assemble frames (Frames, (H, W, 3) arrays or image paths, in order) into `path`:
    .mp4 as H.264 (yuv420p, CRF `quality_crf`) through imageio-ffmpeg, .gif through imageio (Pillow).
    Every frame must have the same size; odd sizes are padded by one edge row/column for H.264."""
    path = Path(path)
    check_video_path(path)
    if not (np.isfinite(fps) and fps > 0):
        raise ValueError(f"fps must be positive, got {fps!r}")
    frames = [_video_frame(f) for f in frames_or_paths]
    if not frames:
        raise ValueError("write_video: no frames")
    shapes = {f.shape for f in frames}
    if len(shapes) != 1:
        raise ValueError(f"write_video: frames of different sizes {sorted(shapes)}")
    h, w, _ = frames[0].shape
    if path.suffix.lower() == ".gif":
        _imwrite(path, np.stack(frames), duration=1000.0 / fps, loop=0)
        return path
    import imageio_ffmpeg

    ph, pw = h + h % 2, w + w % 2                       # yuv420p needs even sizes

    def write(tmp):
        writer = imageio_ffmpeg.write_frames(str(tmp), (pw, ph), fps=fps, codec="libx264", pix_fmt_out="yuv420p",
                                             quality=None, macro_block_size=1, output_params=["-crf", str(quality_crf)],
                                             ffmpeg_log_level="error")
        writer.send(None)                              # start ffmpeg
        try:
            for f in frames:
                if (ph, pw) != (h, w):
                    f = np.pad(f, ((0, ph - h), (0, pw - w), (0, 0)), mode="edge")
                writer.send(np.ascontiguousarray(f))
        finally:
            writer.close()
    atomic_write(path, write)
    return path
