"""The environment's file codecs: OpenEXR (through the `OpenEXR` binding) and Radiance RGBE
(.hdr / .pic, no dependency: read, decode, encode, write). What is supported, exactly: the module
docstring of clrender.scene.environment.

Every size a header announces is checked before its pixels are allocated: against the bytes that
follow it (RGBE), then against a memory budget (clrender.budget). `budget`: the Budget to charge,
the active load's when a loader reads the file (clrender.loaders.budget.current()); None: a fresh
one (the limit alone), as outside a load.
"""
from __future__ import annotations

import contextlib
import io
import os
import sys
from pathlib import Path

import numpy as np

from clrender.budget import Budget
from clrender.errors import SceneError

ENVIRONMENT_SUFFIXES = (".exr", ".hdr", ".pic")


def read_environment_file(path: Path, budget=None) -> np.ndarray:
    """(H, W, 3) float32 of an .exr / .hdr / .pic file; SceneError naming it (budget: as `read_exr`)."""
    suffix = path.suffix.lower()
    if suffix not in ENVIRONMENT_SUFFIXES:
        raise SceneError(f"{path}: unsupported environment file type {suffix or '(no suffix)'!r} "
                         f"(supported: {', '.join(ENVIRONMENT_SUFFIXES)}, or 'studio')")
    if not path.exists():
        raise SceneError(f"{path}: environment file not found")
    if not path.is_file():
        raise SceneError(f"{path}: not a file")
    return read_exr(path, budget) if suffix == ".exr" else read_rgbe(path, budget)



# -- OpenEXR -----------------------------------------------------------------------------------------------
@contextlib.contextmanager
def _stderr_captured(lines: list):
    """Redirect file descriptors 2 and 1 (where C and C++ libraries print) into `lines` for the
    block. Other threads' output in that moment lands there too: keep the block short."""
    import tempfile
    sys.stdout.flush()
    sys.stderr.flush()
    saved = [os.dup(1), os.dup(2)]
    streams = sys.stdout, sys.stderr
    text = io.StringIO()                     # the binding's warnings go through Python's sys.stdout
    with tempfile.TemporaryFile() as sink:
        os.dup2(sink.fileno(), 1)
        os.dup2(sink.fileno(), 2)
        sys.stdout = sys.stderr = text
        try:
            yield lines
        finally:
            sys.stdout, sys.stderr = streams
            _flush_c_stdio()                 # C++ iostreams print through C's buffered stdout
            for fd, copy in zip((1, 2), saved):
                os.dup2(copy, fd)
                os.close(copy)
            sink.seek(0)
            lines.extend(sink.read(65536).decode("utf-8", "replace").splitlines())
            lines.extend(text.getvalue().splitlines())


def _flush_c_stdio() -> None:
    try:
        import ctypes
        ctypes.CDLL(None).fflush(None)
    except (OSError, AttributeError):        # no C library to ask (not POSIX): nothing buffered there
        pass


def _exr_complaint(lines: list, path) -> str:
    """The EXR library's first complaint, without the path it starts with and capped."""
    for line in lines:
        text = line.strip()
        if text.startswith(str(path)):
            text = text[len(str(path)):].lstrip(": ")
        if text:
            return text if len(text) <= 160 else text[:157] + "..."
    return ""


def _charge_exr(OpenEXR, path: Path, budget) -> None:
    """Charge the memory budget for the pixels the header announces, before the binding reads them:
    every channel of every part as float32 (the binding reads them all), then the float32 RGB
    stack. A header the binding cannot read is left to the full read to report."""
    try:
        with _stderr_captured([]):      # a corrupt header's complaints: the full read reports them
            parts = OpenEXR.File(str(path), header_only=True).parts
        sizes = []
        for part in parts:
            lo, hi = (np.asarray(v, np.int64) for v in part.header["dataWindow"])
            w, h = (int(x) for x in (hi - lo + 1))
            sizes.append((max(w, 0), max(h, 0), len(part.header.get("channels", ())) or 1))
    except Exception:                   # the full read below says what is wrong, in one line
        return
    total = sum(w * h * (4 * c + 12) for w, h, c in sizes)
    shown = ", ".join(f"{w}x{h}" for w, h, _ in sizes[:3]) + (" ..." if len(sizes) > 3 else "")
    (budget or Budget()).charge(total, path, f"the OpenEXR data window ({shown} pixels)")


def read_exr(path, budget=None) -> np.ndarray:
    """(H, W, 3) float32: the R, G, B channels of the first part of an OpenEXR file that has all three."""
    path = Path(path)
    try:
        import OpenEXR
    except ImportError:
        raise SceneError(f"{path}: reading .exr environments needs the OpenEXR package: pip install OpenEXR") from None
    if not path.is_file():
        raise SceneError(f"{path}: environment file not found")
    _charge_exr(OpenEXR, path, budget)
    chatter: list = []
    try:
        # The EXR library prints its complaints about a corrupt file (on file descriptors 2 and 1)
        # and the binding then returns no channels: keep them, say the real problem in one line
        names, planes = [], None
        with _stderr_captured(chatter), OpenEXR.File(str(path), separate_channels=True) as f:
            for part in f.parts:
                channels = part.channels
                names.extend(channels)
                if all(c in channels for c in "RGB"):
                    planes = [np.asarray(channels[c].pixels) for c in "RGB"]
                    break
        if planes is None:
            complaint = _exr_complaint(chatter, path)
            if complaint:
                raise SceneError(f"{path}: cannot read OpenEXR file ({complaint})")
            shown = ", ".join(sorted(set(names))) or "none"
            missing = ", ".join(c for c in "RGB" if c not in names)
            raise SceneError(f"{path}: OpenEXR file has no {missing} channel (channels: {shown}; an "
                             f"environment needs R, G and B)")
    except SceneError:
        raise
    except Exception as exc:            # the binding raises RuntimeError / ValueError / OSError on bad files
        text = " ".join(str(exc).split()) or type(exc).__name__
        raise SceneError(f"{path}: cannot read OpenEXR file ({text})") from None
    if len({p.shape for p in planes}) != 1 or planes[0].ndim != 2:
        raise SceneError(f"{path}: OpenEXR R, G, B channels differ in size (subsampled channels are not supported)")
    return np.ascontiguousarray(np.stack([p.astype(np.float32) for p in planes], axis=-1))


# -- Radiance RGBE (.hdr / .pic) ---------------------------------------------------------------------------
RGBE_MAX_HEADER = 64 * 1024


def read_rgbe(path, budget=None) -> np.ndarray:
    """(H, W, 3) float32 linear RGB of a Radiance RGBE file (clrender.scene.environment's docstring:
    what is supported)."""
    path = Path(path)
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        raise SceneError(f"{path}: environment file not found") from None
    except OSError as exc:
        raise SceneError(f"{path}: cannot read file ({exc.strerror or exc})") from None
    return decode_rgbe(data, str(path), budget)


def _excerpt(text: str, limit: int = 40) -> str:
    return text if len(text) <= limit else text[:limit] + "..."


def decode_rgbe(data: bytes, where: str = "<bytes>", budget=None) -> np.ndarray:
    """Decode the bytes of a Radiance RGBE file (read_rgbe); SceneError naming `where`."""
    def bad(message: str) -> SceneError:
        return SceneError(f"{where}: not a readable Radiance RGBE file ({message})")

    if not data.startswith(b"#?"):
        raise bad("no '#?' magic line")
    pos = 0
    lines = []
    while True:                          # header lines up to the blank line, then the resolution line
        end = data.find(b"\n", pos)
        if end < 0 or end > RGBE_MAX_HEADER:
            raise bad("header not terminated")
        line = data[pos:end].rstrip(b"\r")
        pos = end + 1
        if not line and lines:
            break
        lines.append(line)
    for line in lines[1:]:
        if line.startswith(b"FORMAT="):
            fmt = line[7:].strip()
            if fmt != b"32-bit_rle_rgbe":
                raise SceneError(f"{where}: Radiance file format {_excerpt(fmt.decode('latin-1'))!r} is not supported "
                                 f"(only 32-bit_rle_rgbe)")
    end = data.find(b"\n", pos)
    if end < 0:
        raise bad("no resolution line")
    resolution = data[pos:end].decode("latin-1").strip()
    shown = _excerpt(resolution)         # a garbled line may run into the pixel bytes: quote its start
    pos = end + 1
    parts = resolution.split()
    if len(parts) != 4 or not (parts[1].isdigit() and parts[3].isdigit()):
        raise bad(f"bad resolution line {shown!r}")
    if (parts[0], parts[2]) != ("-Y", "+X"):
        raise SceneError(f"{where}: Radiance image orientation {shown!r} is not supported (only "
                         f"'-Y H +X W': rows top to bottom, left to right)")
    height, width = int(parts[1]), int(parts[3])
    if height < 1 or width < 1:
        raise bad(f"empty image {shown!r}")
    buf = memoryview(data)
    n = len(data)
    rle_possible = 8 <= width < 0x8000
    # The header's size is checked against the bytes that follow before anything is allocated: the
    # smallest scanline is 4 bytes of RLE header and a 2-byte run per 127 pixels of each channel
    # (a flat one: 4 bytes a pixel). Then the decoded image (RGBE, then float64 and float32 RGB)
    # against the memory budget (the load's, when a loader passes it).
    smallest = min(4 * width, 4 + 8 * -(-width // 127)) if rle_possible else 4 * width
    if height * smallest > n - pos:
        raise bad(f"resolution {shown!r} needs at least {height * smallest:,} bytes of pixels, "
                  f"the file has {n - pos:,}")
    (budget or Budget()).charge(16 * height * width, where, f"the image size {shown!r}", peak=52 * height * width)
    out = np.empty((height, width, 4), np.uint8)
    for row in range(height):
        if rle_possible and pos + 4 <= n and data[pos] == 2 and data[pos + 1] == 2 and \
                (data[pos + 2] << 8 | data[pos + 3]) == width:
            pos += 4
            for c in range(4):
                channel = out[row, :, c]
                x = 0
                while x < width:
                    if pos >= n:
                        raise bad(f"data ends in scanline {row}")
                    count = data[pos]
                    if count > 128:            # a run
                        count -= 128
                        if x + count > width or pos + 1 >= n:
                            raise bad(f"run overflows scanline {row}")
                        channel[x:x + count] = data[pos + 1]
                        pos += 2
                    else:                      # literal bytes
                        if count == 0 or x + count > width or pos + 1 + count > n:
                            raise bad(f"bad run length in scanline {row}")
                        channel[x:x + count] = np.frombuffer(buf[pos + 1:pos + 1 + count], np.uint8)
                        pos += 1 + count
                    x += count
        else:                                  # a flat scanline: width RGBE pixels
            size = 4 * width
            if pos + size > n:
                raise bad(f"data ends in scanline {row}")
            out[row] = np.frombuffer(buf[pos:pos + size], np.uint8).reshape(width, 4)
            pos += size
    return rgbe_to_float(out)


def rgbe_to_float(rgbe: np.ndarray) -> np.ndarray:
    """(..., 4) uint8 RGBE -> (..., 3) float32: (c + 0.5) * 2^(e - 136), 0 where e = 0."""
    rgbe = np.asarray(rgbe, np.uint8)
    e = rgbe[..., 3].astype(np.int32)
    scale = np.ldexp(1.0, e - 136)
    out = (rgbe[..., :3].astype(np.float64) + 0.5) * scale[..., None]
    out[e == 0] = 0.0
    return out.astype(np.float32)


def float_to_rgbe(pixels: np.ndarray) -> np.ndarray:
    """(..., 3) float -> (..., 4) uint8 RGBE (Radiance's setcolr: mantissas truncated); values
    below 1e-32 (and negatives) encode as 0."""
    rgb = np.maximum(np.asarray(pixels, np.float64), 0.0)
    peak = rgb.max(axis=-1)
    mantissa, exponent = np.frexp(peak)
    tiny = peak < 1e-32
    safe = np.where(tiny, 1.0, peak)
    scale = np.where(tiny, 0.0, mantissa * 256.0 / safe)
    out = np.zeros(rgb.shape[:-1] + (4,), np.uint8)
    out[..., :3] = np.clip(np.floor(rgb * scale[..., None]), 0, 255).astype(np.uint8)
    out[..., 3] = np.where(tiny, 0, np.clip(exponent + 128, 0, 255)).astype(np.uint8)
    return out


def _rle_channel(values: bytes) -> bytes:
    """One channel of a scanline in new-style RLE: runs of >= 4 equal bytes as (128 + n, byte),
    n <= 127; the rest as literal chunks (n, n bytes), n <= 128."""
    out = bytearray()
    n, x = len(values), 0
    while x < n:
        run_start, run_len = x, 0          # the next run of >= 4 equal bytes at or after x
        while run_start < n:
            run_len = 1
            while run_start + run_len < n and run_len < 127 and values[run_start + run_len] == values[run_start]:
                run_len += 1
            if run_len >= 4:
                break
            run_start += run_len
        while x < run_start:                # literal bytes before it
            chunk = min(128, run_start - x)
            out.append(chunk)
            out.extend(values[x:x + chunk])
            x += chunk
        if run_start < n and run_len >= 4:
            out.append(128 + run_len)
            out.append(values[run_start])
            x = run_start + run_len
    return bytes(out)


def encode_rgbe(pixels, rle: bool = True) -> bytes:
    """The bytes of a Radiance RGBE file (-Y H +X W) of (H, W, 3) linear RGB: new-style RLE
    scanlines when `rle` (and 8 <= W < 32768), else flat ones."""
    rgbe = float_to_rgbe(pixels)
    height, width = rgbe.shape[:2]
    parts = [b"#?RADIANCE\n# written by clrender.scene.environment.encode_rgbe\nFORMAT=32-bit_rle_rgbe\n\n",
             f"-Y {height} +X {width}\n".encode()]
    use_rle = rle and 8 <= width < 0x8000
    for row in rgbe:
        if use_rle:
            parts.append(bytes((2, 2, width >> 8, width & 255)))
            parts.extend(_rle_channel(row[:, c].tobytes()) for c in range(4))
        else:
            parts.append(row.tobytes())
    return b"".join(parts)


def write_rgbe(path, pixels, rle: bool = True) -> Path:
    """Write (H, W, 3) linear RGB as a Radiance .hdr file (encode_rgbe; used by the tests)."""
    path = Path(path)
    path.write_bytes(encode_rgbe(pixels, rle))
    return path

