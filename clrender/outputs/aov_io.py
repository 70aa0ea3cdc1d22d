"""AOV previews and output files: how a rendered `Frame` and its AOVs land on disk.

`preview(name, data, background)` turns one AOV array into a viewable uint8 image (depth as
gray, normals as RGB, triangle ids as stable hash colors, velocity as a color wheel, ...);
`write_outputs(frame, image, aovs, bit_depth=8, exr=False)` writes the image (8- or 16-bit) plus,
per AOV, <stem>.<aov>.npy (exact) and <stem>.<aov>.png (preview), and with `exr` one multi-layer
<stem>.exr holding the colour and every requested float AOV. `write_video(path, frames, fps)`
assembles frames into .mp4 (H.264) or .gif.

Every file is written through `atomic_write`: to a temporary name in the destination folder,
renamed into place (os.replace) only once complete, and removed on failure, so a killed or
failed job never leaves a truncated file under a final name.

Libraries (optional extra `clrender[outputs]`):
- EXR: the maintained `OpenEXR` binding (Academy Software Foundation, PyPI `OpenEXR` >= 3.2).
  It installs from PyPI as a self-contained manylinux/macOS/Windows wheel (~2 MB, NumPy only),
  writes any number of named float32 channels, so one file holds every AOV as a layer
  (color.R/G/B, depth.Z, normal.X/Y/Z, velocity.X/Y, ao, ...), and reads them back bit-exact.
  imageio's EXR support goes through FreeImage, whose shared library imageio downloads at run
  time (not from PyPI; nothing here may reach the network), and writes one RGB(A) layer per file.
- Video: imageio-ffmpeg (a pip wheel bundling an ffmpeg with libx264) for .mp4; Pillow through
  imageio for .gif.
- 16-bit PNG: Pillow cannot write 16-bit RGB, so `_write_png16` encodes it with zlib (PNG is
  simple: one IHDR, zlib-deflated filter-0 rows, IEND).
NumPy only at import; imageio, OpenEXR and imageio-ffmpeg are imported when something is written.
"""
from __future__ import annotations

import errno
import os
import re
import secrets
import struct
import time
import zlib
from pathlib import Path
from typing import Callable, Sequence

import numpy as np

INT_AOVS = ("triangle_id", "object_id", "material_id", "fragment_count", "edges",
            "shading_model")                                               # integer AOVs: not in the EXR
BIT_DEPTHS = (8, 16)
VIDEO_SUFFIXES = (".mp4", ".gif")
# EXR channel names per AOV (an AOV with one channel is named by itself: "ao", "light_count").
EXR_CHANNELS = {"color": "RGB", "albedo": "RGB", "emissive": "RGB", "normal": "XYZ", "position": "XYZ", "velocity": "XY",
                "depth": "Z", "linear_depth": "Z"}


# -- atomic writes --------------------------------------------------------------------------
def _umask() -> int:
    if "umask" not in _UMASK:
        _UMASK["umask"] = os.umask(0o022)
        os.umask(_UMASK["umask"])
    return _UMASK["umask"]


_UMASK: dict = {}


def temp_prefix(path) -> str:
    """The start of `atomic_write`'s temporary names for `path`: `.<stem>.<pid>.`; the rest is
    mkstemp's 8 random characters and `.tmp<suffix>`. The pid tells a leftover of a killed job
    (removed by `remove_stale_temps`) from a write in progress in another live process."""
    path = Path(path)
    return f".{path.stem}.{os.getpid()}."


# A leftover temporary file: .<stem>.[<pid>.]<8 mkstemp characters>.tmp<suffix> (without the pid:
# written before clrender named its temporaries by process).
_TEMP_NAME = re.compile(r"^\..+?\.(?:(\d+)\.)?[a-z0-9_]{8}\.tmp(?:\.[A-Za-z0-9]+)?$")
STALE_TEMP_S = 3600.0        # a leftover without a pid, or of a pid alive again, is stale after an hour
_SCANNED: set = set()        # folders this process has cleaned already


def _alive(pid: int) -> bool:
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:           # EPERM: someone else's live process
        return True
    return True


def remove_stale_temps(folder, force: bool = False) -> list[Path]:
    """Remove the temporary files that killed writers left in `folder` (a SIGKILL or power loss
    mid-write: `atomic_write` removes its own on any error it sees): those whose writing process is
    gone, or untouched for STALE_TEMP_S. Each folder is scanned once per process (`force`: again).
    Returns what was removed."""
    folder = Path(folder)
    key = os.path.abspath(folder)
    if key in _SCANNED and not force:
        return []
    _SCANNED.add(key)
    removed = []
    try:
        entries = list(os.scandir(folder))
    except OSError:
        return removed
    now = time.time()
    for entry in entries:
        m = _TEMP_NAME.match(entry.name)
        if m is None:
            continue
        try:
            if not entry.is_file(follow_symlinks=False):
                continue
            age = now - entry.stat(follow_symlinks=False).st_mtime
            pid = m.group(1)
            if (pid is not None and not _alive(int(pid))) or age > STALE_TEMP_S:
                os.unlink(entry.path)
                removed.append(Path(entry.path))
        except OSError:
            continue
    return removed


class OutputError(OSError):
    """Writing an output file failed: the message names the output (never its temporary file)."""


def _output_error(path: Path, exc: BaseException) -> OutputError:
    """One line naming the output `path` for a failed write: the OS's reason (a full disk, a
    read-only or missing folder), or a writer's own words (numpy: "19200 requested and 14304
    written") with the free space when the disk is full."""
    errno_ = getattr(exc, "errno", None)
    reason = getattr(exc, "strerror", None) or (str(exc).strip().splitlines() or [type(exc).__name__])[0]
    if errno_ is None:
        try:
            st = os.statvfs(path.parent)
            if st.f_bavail * st.f_frsize < 1 << 20:
                errno_, reason = 28, f"{os.strerror(28)} ({reason})"
        except OSError:
            pass
    return OutputError(errno_ or 5, f"cannot write {path}: {reason}")


def _create_temp(path: Path, names: list) -> str:
    """Create an empty temporary file for `path` (mkstemp's rule: O_EXCL, mode 0600), its name
    appended to `names` before the file exists: a Ctrl-C the moment after it is created still
    leaves the caller a name to remove (mkstemp returns it only afterwards)."""
    chars = "abcdefghijklmnopqrstuvwxyz0123456789_"
    for _ in range(100):
        name = temp_prefix(path) + "".join(secrets.choice(chars) for _ in range(8)) + f".tmp{path.suffix}"
        tmp = str(path.parent / name)
        names.append(tmp)
        try:
            os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600))
            return tmp
        except FileExistsError:
            names.pop()                  # someone else's: never the caller's to remove
            continue
    raise FileExistsError(errno.EEXIST, "no free temporary name", str(path))


def atomic_write(path, writer: Callable[[str], object]) -> Path:
    """Call `writer(tmp)` to write a temporary file in `path`'s folder (same suffix, so writers
    that go by the extension still work), then rename it to `path` with os.replace. On any
    failure (the writer's or the rename's) the temporary file is removed and the error raised
    (an OSError as `OutputError`, naming `path`); `path` is then untouched: absent, or its previous
    complete content. The first write into a folder removes the leftovers of killed writers there."""
    path = Path(path)
    names: list = []
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        remove_stale_temps(path.parent)
        tmp = _create_temp(path, names)
        writer(tmp)
        os.chmod(tmp, 0o666 & ~_umask())     # mkstemp makes 0600; give the usual permissions of a new file
        os.replace(tmp, path)
    except BaseException as exc:
        if names:
            try:
                os.unlink(names[-1])
            except OSError:
                pass
        if isinstance(exc, OSError) and not isinstance(exc, OutputError):
            raise _output_error(path, exc) from exc
        raise
    return path


# zlib level of 8-bit PNGs: 3 encodes a 640x360 frame in 14 ms against 45 ms at Pillow's default 6,
# for files 12 % larger (a batch job's frames were spending longer in PNG encoding than rendering).
PNG_COMPRESS_LEVEL = 3


def _imwrite(path, array, **kwargs) -> None:
    import imageio.v3 as iio
    path = Path(path)
    if path.suffix.lower() == ".png":
        kwargs.setdefault("compress_level", PNG_COMPRESS_LEVEL)
    # Encoded in memory, then written here: a writer that fails on a full disk while holding the
    # file retries its close in __del__ and prints tracebacks ("Exception ignored in ...")
    data = iio.imwrite("<bytes>", array, extension=path.suffix, **kwargs)
    atomic_write(path, lambda tmp: _write_bytes(tmp, data))


def _write_bytes(tmp, data: bytes) -> None:
    with open(tmp, "wb") as f:
        f.write(data)


def _save_npy(path, array) -> None:
    def write(tmp):
        with open(tmp, "wb") as f:          # a file object: np.save would append .npy to a name
            np.save(f, array)
    atomic_write(path, write)


# -- the display image: 8 and 16 bits ---------------------------------------------------------
def tonemap(color: np.ndarray, operator: str = "reinhard", exposure: float = 1.0) -> np.ndarray:
    """kernels/tonemap.cl's `tonemap(c · exposure)` in float32: linear HDR -> linear [0, 1]."""
    c = np.maximum(np.asarray(color, np.float32) * np.float32(exposure), np.float32(0.0))
    if operator == "reinhard":
        return c / (np.float32(1.0) + c)
    if operator == "aces":
        num = c * (np.float32(2.51) * c + np.float32(0.03))
        den = c * (np.float32(2.43) * c + np.float32(0.59)) + np.float32(0.14)
        return np.clip(num / den, 0.0, 1.0).astype(np.float32)
    if operator == "clamp":
        return np.clip(c, 0.0, 1.0).astype(np.float32)
    raise ValueError(f"unknown tone-mapping operator {operator!r}")


def display_linear(frame) -> np.ndarray:
    """(H, W, 3) float32 in [0, 1]: the tone-mapped linear colour `frame.image` was sRGB-encoded
    from. With LDR post effects it is the device's final LDR planes (`frame.ldr`); otherwise
    tonemap.cl's operator applied here to `frame.color` (the HDR colour after bloom, motion blur
    and the supersample resolve, which is exactly what the tone-mapping kernel read)."""
    ldr = getattr(frame, "ldr", None)
    if ldr is not None:
        return np.clip(np.asarray(ldr, np.float32), 0.0, 1.0)
    return tonemap(frame.color, getattr(frame, "tonemap", "reinhard"), getattr(frame, "exposure", 1.0))


def linear_to_srgb16(x: np.ndarray) -> np.ndarray:
    """Linear [0, 1] -> 16-bit sRGB codes (the exact curve, rounded; the 8-bit image rounds the same
    curve to 255 levels, so round(v16 / 257) is within one code of it)."""
    x = np.clip(np.nan_to_num(np.asarray(x, np.float64), nan=0.0), 0.0, 1.0)
    s = np.where(x <= 0.0031308, x * 12.92, 1.055 * x ** (1 / 2.4) - 0.055)
    return np.floor(s * 65535.0 + 0.5).astype(np.uint16)


def image16(frame) -> np.ndarray:
    """(H, W, 3) uint16 sRGB: the display image at 16 bits, from the float colour (not `frame.image`)."""
    return linear_to_srgb16(display_linear(frame))


def _write_png16(path, rgb16: np.ndarray) -> None:
    """A 16-bit RGB (or grey) PNG: IHDR, one zlib stream of filter-0 big-endian rows, IEND."""
    a = np.ascontiguousarray(rgb16, np.uint16)
    if a.ndim == 2:
        a = a[..., None]
    h, w, c = a.shape
    colour_type = {1: 0, 3: 2, 4: 6}[c]
    rows = np.zeros((h, 1 + w * c * 2), np.uint8)
    rows[:, 1:] = a.astype(">u2").reshape(h, w * c).view(np.uint8)

    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)

    data = (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 16, colour_type, 0, 0, 0))
            + chunk(b"IDAT", zlib.compress(rows.tobytes(), 6)) + chunk(b"IEND", b""))

    def write(tmp):
        with open(tmp, "wb") as f:
            f.write(data)
    atomic_write(path, write)


def write_image(frame, path, bit_depth: int = 8) -> Path:
    """Write the display image of `frame` to `path`: 8 bits (`frame.image`, any imageio format) or
    16 bits (PNG only; `image16(frame)`)."""
    path = Path(path)
    if bit_depth not in BIT_DEPTHS:
        raise ValueError(f"bit_depth must be 8 or 16, got {bit_depth!r}")
    if bit_depth == 16:
        if path.suffix.lower() != ".png":
            raise ValueError(f"{path}: 16-bit images are written as PNG only (got {path.suffix!r})")
        _write_png16(path, image16(frame))
    else:
        _imwrite(path, frame.image)
    return path


# -- multi-layer OpenEXR ----------------------------------------------------------------------
_EXR_STATE: dict = {"available": None}


def exr_available() -> bool:
    """Whether the OpenEXR binding is installed (`pip install OpenEXR` or clrender[outputs])."""
    if _EXR_STATE["available"] is None:
        try:
            import OpenEXR  # noqa: F401
            _EXR_STATE["available"] = True
        except ImportError:
            _EXR_STATE["available"] = False
    return _EXR_STATE["available"]


EXR_MISSING = "OpenEXR output needs the OpenEXR package: pip install OpenEXR (or clrender[outputs])"


def exr_channels(name: str, data: np.ndarray) -> dict:
    """The float32 EXR channels of AOV `name`: {"color.R": (H, W), ...}; one-channel AOVs are
    named by themselves ("ao"); `shadow` (H, W, K) gives shadow.0 .. shadow.K-1."""
    a = np.asarray(data)
    if a.ndim == 2:
        suffix = EXR_CHANNELS.get(name)
        key = f"{name}.{suffix}" if suffix else name
        return {key: np.ascontiguousarray(a, np.float32)}
    letters = EXR_CHANNELS.get(name)
    if letters is None or len(letters) != a.shape[2]:
        letters = [str(i) for i in range(a.shape[2])]
    return {f"{name}.{c}": np.ascontiguousarray(a[..., i], np.float32) for i, c in enumerate(letters)}


def exr_layers(frame, aovs: Sequence[str]) -> list[str]:
    """The AOVs the multi-layer EXR holds: colour first, then every requested float AOV."""
    return list(dict.fromkeys(["color", *[a for a in aovs if a not in INT_AOVS and a != "image"]]))


def write_exr(path, frame, aovs: Sequence[str] = ()) -> Path:
    """One multi-layer OpenEXR file (float32, ZIP compression) with `exr_layers(frame, aovs)`."""
    if not exr_available():
        raise RuntimeError(EXR_MISSING)
    import OpenEXR

    channels: dict = {}
    for aov in exr_layers(frame, aovs):
        channels.update(exr_channels(aov, frame.aov(aov)))
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    # OpenEXR.File replaces the dict's arrays by Channel objects: give it a copy.
    atomic_write(path, lambda tmp: OpenEXR.File(header, dict(channels)).write(str(tmp)))
    return Path(path)


def read_exr(path) -> dict:
    """{channel name: (H, W) array} of an EXR file, each channel as stored."""
    import OpenEXR
    with OpenEXR.File(str(path), separate_channels=True) as f:
        return {name: np.array(ch.pixels) for name, ch in f.channels().items()}


def exr_path(image) -> Path:
    return Path(image).with_suffix(".exr")


def sheet_path(image) -> Path:
    return Path(image).with_suffix(".sheet.png")


def aov_paths(image: Path, aovs: Sequence[str], exr: bool, sheet: bool = False) -> list[Path]:
    """Every file `write_outputs` writes for `aovs` next to `image` (not `image` itself)."""
    stem = Path(image).with_suffix("")
    paths = []
    for aov in aovs:
        paths += [Path(f"{stem}.{aov}.npy"), Path(f"{stem}.{aov}.png")]
    if exr:
        paths.append(exr_path(image))
    if sheet:
        paths.append(sheet_path(image))
    return paths


# -- previews -------------------------------------------------------------------------------
def _u8(x: np.ndarray) -> np.ndarray:
    return np.floor(np.clip(np.nan_to_num(x, nan=0.0), 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8)


def _preview_depth(depth: np.ndarray, background: np.ndarray) -> np.ndarray:
    """Near white -> far dark gray, background black."""
    fg = ~background & np.isfinite(depth)
    out = np.zeros(depth.shape, np.float64)
    if fg.any():
        lo, hi = float(depth[fg].min()), float(depth[fg].max())
        t = (depth[fg] - lo) / (hi - lo) if hi > lo else np.zeros(int(fg.sum()))
        out[fg] = 1.0 - 0.85 * t
    return _u8(out)


def _hash_u32(x: np.ndarray) -> np.ndarray:
    """A fixed integer hash (lowbias32), so a triangle keeps its color across runs and scenes."""
    h = x.astype(np.uint32)
    with np.errstate(over="ignore"):
        h ^= h >> np.uint32(16)
        h *= np.uint32(0x7FEB352D)
        h ^= h >> np.uint32(15)
        h *= np.uint32(0x846CA68B)
        h ^= h >> np.uint32(16)
    return h


def _preview_ids(ids: np.ndarray) -> np.ndarray:
    h = _hash_u32(ids)
    rgb = np.stack([(h >> np.uint32(s)) & np.uint32(255) for s in (0, 8, 16)], -1)
    rgb = (48 + rgb * 207 // 255).astype(np.uint8)      # never black: black is the background
    rgb[ids < 0] = 0
    return rgb


def _preview_position(p: np.ndarray, background: np.ndarray) -> np.ndarray:
    fg = ~background & np.isfinite(p).all(-1)
    if not fg.any():
        return np.zeros(p.shape, np.uint8)
    lo, hi = p[fg].min(0), p[fg].max(0)
    out = _u8((np.nan_to_num(p) - lo) / np.maximum(hi - lo, 1e-30))
    out[~fg] = 0
    return out


def _preview_velocity(vel: np.ndarray) -> np.ndarray:
    """Color wheel: hue = direction, brightness = speed relative to the fastest pixel."""
    v = np.nan_to_num(vel.astype(np.float64), nan=0.0, posinf=0.0, neginf=0.0)
    mag = np.hypot(v[..., 0], v[..., 1])
    peak = float(mag.max()) if mag.size else 0.0
    value = mag / peak if peak > 0 else np.zeros_like(mag)
    hue = (np.arctan2(-v[..., 1], v[..., 0]) / (2 * np.pi)) % 1.0
    k = (np.array([5.0, 3.0, 1.0]) + hue[..., None] * 6.0) % 6.0
    rgb = value[..., None] * (1.0 - np.clip(np.minimum(k, 4.0 - k), 0.0, 1.0))
    return _u8(rgb)


def _preview_heat(counts: np.ndarray) -> np.ndarray:
    """Counts (lights per tile, fragments per pixel) as a black -> red -> yellow -> white heat map
    (scaled to the maximum; all black when every count is 0)."""
    t = np.clip(counts.astype(np.float64) / max(int(counts.max()), 1), 0.0, 1.0)[..., None]
    ramp = np.clip(np.concatenate([t * 3.0, t * 3.0 - 1.0, t * 3.0 - 2.0], -1), 0.0, 1.0)
    return _u8(ramp)


def preview(name: str, data: np.ndarray, background: np.ndarray) -> np.ndarray:
    """A viewable uint8 image of AOV `name`."""
    from clrender.abi.gbuffer import SPEC_POWER_LOG2_MAX, linear_to_srgb8

    if name in ("depth", "linear_depth"):
        return _preview_depth(data, background)
    if name == "normal":
        out = _u8(data * 0.5 + 0.5)
        out[background] = 0
        return out
    if name in ("albedo", "emissive", "base_color"):     # linear [0, 1] colours (emissive before its strength)
        return linear_to_srgb8(data)
    if name in ("specular_intensity", "ao", "transmittance", "occlusion", "metallic", "roughness"):
        # [0, 1] as grey; white = unoccluded / clear / metal / rough
        return _u8(data)
    if name == "specular_power":
        return _u8(np.log2(np.maximum(data, 1.0)) / SPEC_POWER_LOG2_MAX)
    if name in ("triangle_id", "object_id", "material_id"):
        return _preview_ids(data)
    if name == "position":                 # world x, y, z over the frame's foreground box as R, G, B
        return _preview_position(data, background)
    if name == "shading_model":            # black background, grey Blinn-Phong, white glTF BRDF
        return np.array([0, 96, 255], np.uint8)[np.clip(data.astype(np.int64) + 1, 0, 2)][..., None].repeat(3, -1)
    if name == "velocity":
        return _preview_velocity(data)
    if name == "color":                    # linear HDR: Reinhard, as the default image
        return linear_to_srgb8(data / (1.0 + np.maximum(data, 0.0)))
    if name in ("light_count", "fragment_count"):
        return _preview_heat(data)
    if name == "edges":                    # the edge-AA mask: marked pixels white on black
        return np.where(data > 0, 255, 0).astype(np.uint8)
    if name == "shadow":                   # (H, W, K): the darkest shadowed light per pixel, white = lit
        return _u8(data.min(-1) if data.shape[-1] else np.ones(data.shape[:2], np.float32))
    raise ValueError(f"no preview for AOV {name!r}")


LABEL_HEIGHT = 14          # pixels of the name strip above each contact-sheet tile


def contact_sheet(tiles: Sequence[tuple], columns: int = 4) -> np.ndarray:
    """(rows·(H + LABEL_HEIGHT), columns·W, 3) uint8: (name, (H, W, 3) uint8 picture) tiles of one
    size, row by row, each under a dark strip with its name (Pillow's default font)."""
    from PIL import Image, ImageDraw

    if not tiles:
        raise ValueError("a contact sheet needs at least one picture")
    h, w = tiles[0][1].shape[:2]
    if any(t.shape[:2] != (h, w) for _, t in tiles):
        raise ValueError("contact sheet pictures must all have the same size")
    columns = max(1, min(int(columns), len(tiles)))
    rows = -(-len(tiles) // columns)
    sheet = Image.new("RGB", (columns * w, rows * (h + LABEL_HEIGHT)), (24, 24, 24))
    draw = ImageDraw.Draw(sheet)
    for k, (name, picture) in enumerate(tiles):
        x, y = (k % columns) * w, (k // columns) * (h + LABEL_HEIGHT)
        sheet.paste(Image.fromarray(np.ascontiguousarray(picture[..., :3], np.uint8)), (x, y + LABEL_HEIGHT))
        draw.text((x + 3, y + 1), str(name), fill=(235, 235, 235))
    return np.asarray(sheet)


def write_outputs(frame, image: Path, aovs: Sequence[str], bit_depth: int = 8, exr: bool = False,
                  sheet: bool = False) -> None:
    """Write the display image of `frame` to `image` (creating its folder; `bit_depth` 8 or 16),
    then `write_aovs` beside it, with `exr` the multi-layer <stem>.exr (`write_exr`) and with
    `sheet` <stem>.sheet.png: the image and the previews of `aovs`, labelled (`contact_sheet`)."""
    image = Path(image)
    write_image(frame, image, bit_depth)
    write_aovs(frame, image, aovs)
    if exr:
        write_exr(exr_path(image), frame, aovs)
    if sheet:
        _imwrite(str(sheet_path(image)), frame.contact_sheet(["image", *aovs]))


def write_aovs(frame, image: Path, aovs: Sequence[str]) -> None:
    """Write each AOV of `frame` named in `aovs` next to `image`: <stem>.<aov>.npy (exact values)
    and <stem>.<aov>.png (`preview`)."""
    stem = Path(image).with_suffix("")
    background = frame.triangle_id < 0
    for aov in aovs:
        data = np.asarray(frame.aov(aov))
        _save_npy(f"{stem}.{aov}.npy", data)
        _imwrite(f"{stem}.{aov}.png", preview(aov, data, background))


# -- video ------------------------------------------------------------------------------------
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
