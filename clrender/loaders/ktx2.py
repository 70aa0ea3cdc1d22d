"""KTX2 images with Basis Universal payloads (glTF `KHR_texture_basisu`, docs/compression.md) -> RGBA8.

The transcoder is Binomial's basis_universal, through the `opengl_basisu` package (the
`compression` extra); nothing here decodes blocks. `clrender.loaders.common.decode_image` hands
over any image whose bytes start with the KTX2 identifier (so a KTX2 file is read from wherever
the loader already reads images: the glTF's folder, a data URI or a bufferView) and shares its
cache and budget.

Only mip level 0 is transcoded: the texture pool builds its own mip chain at upload, as for PNG.
The stored values are returned as they are (sRGB-encoded or linear): the material slot decides how
they are read, as for PNG and JPEG; the DFD's transfer function is not consulted.
"""
from __future__ import annotations

import importlib
import io
import os
from pathlib import Path

import numpy as np

from clrender.errors import SceneError

MODULE = "opengl_basisu"                 # import name = PyPI name
EXTENSION = "KHR_texture_basisu"
INSTALL = 'pip install "clrender[compression]"'
IDENTIFIER = b"\xabKTX 20\xbb\r\n\x1a\n"   # KTX 2.0 specification, section 3.1
# the two payloads KHR_texture_basisu allows (opengl_basisu.Codec values: ETC1S/BasisLZ, UASTC LDR 4x4)
CODECS = {0: "ETC1S", 1: "UASTC"}


def decoder():
    """The opengl_basisu module, or None when it is not installed."""
    try:
        return importlib.import_module(MODULE)
    except ImportError:
        return None


def available() -> bool:
    return decoder() is not None


def missing_message() -> str:
    return f"needs the {MODULE} package to decode KTX2 / {EXTENSION} images (not installed): {INSTALL}"


def is_ktx2(source) -> bool:
    """Whether a path or a BytesIO holds a KTX2 file (its 12-byte identifier)."""
    if isinstance(source, io.BytesIO):
        return source.getbuffer()[:12] == IDENTIFIER
    try:
        with open(os.fspath(source), "rb") as f:
            return f.read(12) == IDENTIFIER
    except OSError:
        return False


def decode(source, where: str, name: str) -> np.ndarray:
    """Level 0 of a 2D ETC1S or UASTC KTX2 file as (height, width, 4) uint8, its size charged to the
    load's memory budget before any pixel is transcoded; SceneError naming `where` otherwise."""
    from clrender.loaders.budget import current
    basisu = decoder()
    if basisu is None:
        raise SceneError(f"{where}: {name} is a KTX2 image, which {missing_message()}")
    data = source.getvalue() if isinstance(source, io.BytesIO) else Path(source).read_bytes()
    try:
        tex = basisu.open(data)                 # parses the header and level index only
    except ValueError as exc:                   # BasisuError / UnsupportedError are ValueErrors
        raise SceneError(f"{where}: cannot decode KTX2 image ({exc})") from None
    codec = CODECS.get(int(tex.codec))
    if codec is None:
        raise SceneError(f"{where}: KTX2 image codec {tex.codec.name} is not one {EXTENSION} allows "
                         f"(ETC1S or UASTC)")
    if tex.faces != 1 or tex.is_array or tex.layers != 1 or tex.is_video:
        raise SceneError(f"{where}: KTX2 image is not a 2D texture ({tex.faces} faces, {tex.layers} layers"
                         f"{', video' if tex.is_video else ''}); {EXTENSION} material textures must be 2D")
    w, h = tex.width, tex.height
    # kept: the RGBA array; peak beside it: UASTC's Zstandard-inflated level (16 bytes per 4x4 block)
    kept = current().charge(w * h * 4, where, f"{name} ({w}x{h} pixels, KTX2 {codec}, decoded)",
                            peak=w * h * 5)
    try:
        rgba = tex.transcode(basisu.Target.RGBA8, level=0).data
    except (ValueError, IndexError) as exc:
        current().release(kept)
        raise SceneError(f"{where}: cannot decode KTX2 image ({exc})") from None
    except BaseException:
        current().release(kept)
        raise
    return np.ascontiguousarray(rgba, dtype=np.uint8)
