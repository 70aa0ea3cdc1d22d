"""Reading a glTF 2.0 file (.gltf or .glb) into a validated `Document`.

`load_document(path)` parses the JSON (or the GLB container's JSON and BIN chunks), loads every
buffer (GLB chunk, data URI or external file) and checks what the loader relies on: buffer views
and accessor ranges inside their buffers, every index into every array, attribute types, component
types and counts (NORMAL, TEXCOORD_n, COLOR_n, TANGENT: `spec.ATTRIBUTE_FORMATS`), primitive modes, node
transforms, sampler wrap modes, material alpha modes, every material textureInfo (texture index,
texCoord, scale / strength, KHR_texture_transform) and that the TEXCOORD set each texture reads
exists on the primitives using the material, and extensionsRequired (only
`spec.SUPPORTED_EXTENSIONS` are accepted): the checks, part by part, are in `validate`. Bad input
is a `SceneError` naming the file and the offending element, never a KeyError or a trimesh
traceback. `Document.accessor(i)` then decodes an accessor (strided, sparse, normalized) to NumPy.
Compressed data (KHR_draco_mesh_compression, EXT_meshopt_compression) decodes behind
`Document.accessor` and `Document.view_bytes` (`compression`, docs/compression.md).
"""
from __future__ import annotations

import json
import struct
from pathlib import Path
from typing import Optional

import numpy as np

from clrender.scene.model import SceneError
from clrender.loaders import budget
from clrender.loaders.gltf import compression
from clrender.loaders.common import fail, parse_nested
from clrender.loaders.gltf.spec import COMPONENT_TYPES, GLB_BIN, GLB_JSON, TYPE_SIZES, accessor_bytes, accessor_field
from clrender.loaders.gltf.validate import validate


class Document:
    """A parsed and validated glTF document with its buffers in memory."""

    def __init__(self, path: Path):
        self.path = path
        self.base = path.parent
        self.json: dict = {}
        self.buffers: list[bytes] = []
        self.glb_bin: Optional[bytes] = None
        self._accessor_cache: dict[int, np.ndarray] = {}
        self.float_accessors: set[int] = set()     # FLOAT_ATTRIBUTES accessors (filled by validate)
        # compressed data (compression): accessor -> (primitive label, primitive) of its Draco data;
        # EXT_meshopt_compression bufferViews, their decoded bytes; buffers without data (meshopt fallback)
        self.draco_accessors: dict[int, tuple] = {}
        self.meshopt_views: set[int] = set()
        self._view_cache: dict[int, memoryview] = {}
        self.placeholder_buffers: set[int] = set()

    def err(self, message: str) -> SceneError:
        return fail(self.path, message)

    def list(self, key: str) -> list:
        value = self.json.get(key, [])
        if not isinstance(value, list):
            raise self.err(f"top-level {key!r} must be an array")
        return value

    def get(self, key: str, index, what: str) -> dict:
        items = self.list(key)
        if not isinstance(index, int) or isinstance(index, bool) or not 0 <= index < len(items):
            raise self.err(f"{what} references {key}[{index!r}], which does not exist "
                           f"(there are {len(items)})")
        item = items[index]
        if not isinstance(item, dict):
            raise self.err(f"{key}[{index}] must be an object")
        return item

    # -- buffers ------------------------------------------------------------------------------
    def view_bytes(self, index: int) -> memoryview:
        if index in self.meshopt_views:
            data = compression.meshopt_view(self, index)    # None: no decoder, the fallback data is there
            if data is not None:
                return data
        view = self.json["bufferViews"][index]
        start = view.get("byteOffset", 0)
        return memoryview(self.buffers[view["buffer"]])[start:start + view["byteLength"]]

    def accessor(self, index: int) -> np.ndarray:
        """(count, components) array; normalized integers become float32 per the spec."""
        if index in self._accessor_cache:
            return self._accessor_cache[index]
        if index in self.draco_accessors:
            arr = compression.draco_accessor(self, index)   # None: no decoder, the fallback data is there
            if arr is not None:
                return arr
        acc = self.json["accessors"][index]
        dtype = np.dtype(COMPONENT_TYPES[acc["componentType"]])
        ncomp = TYPE_SIZES[acc["type"]]
        count = acc["count"]
        budget.current().charge(accessor_bytes(acc), self.path, accessor_field(index, acc))
        if "bufferView" in acc:
            arr = _strided(self.view_bytes(acc["bufferView"]), acc.get("byteOffset", 0),
                           self.json["bufferViews"][acc["bufferView"]].get("byteStride"),
                           dtype, ncomp, count)
        else:
            arr = np.zeros((count, ncomp), dtype)
        sparse = acc.get("sparse")
        if sparse:
            arr = arr.copy()
            idx_info, val_info = sparse["indices"], sparse["values"]
            n = sparse["count"]
            idx = _strided(self.view_bytes(idx_info["bufferView"]), idx_info.get("byteOffset", 0), None,
                           np.dtype(COMPONENT_TYPES[idx_info["componentType"]]), 1, n)[:, 0]
            vals = _strided(self.view_bytes(val_info["bufferView"]), val_info.get("byteOffset", 0), None,
                            dtype, ncomp, n)
            if n and idx.max() >= count:
                raise self.err(f"accessor {index}: sparse index {int(idx.max())} out of range ({count})")
            arr[idx.astype(np.int64)] = vals
        return self.store_accessor(index, arr)

    def store_accessor(self, index: int, arr: np.ndarray) -> np.ndarray:
        """Cache accessor `index`'s raw data `arr` (its componentType) as `accessor` returns it:
        normalized integers to float32 per the spec, integer vertex attributes to float32
        (KHR_mesh_quantization's non-normalized forms are plain values), read-only."""
        acc = self.json["accessors"][index]
        if acc.get("normalized") and arr.dtype.kind in "iu":
            info = np.iinfo(arr.dtype)
            arr = arr.astype(np.float32) / np.float32(info.max)
            if info.min < 0:
                arr = np.maximum(arr, np.float32(-1.0))
        elif index in self.float_accessors and arr.dtype.kind in "iu":
            arr = arr.astype(np.float32)
        arr.setflags(write=False)
        self._accessor_cache[index] = arr
        return arr


def _strided(buf: memoryview, offset: int, stride: Optional[int], dtype: np.dtype, ncomp: int,
             count: int) -> np.ndarray:
    elem = dtype.itemsize * ncomp
    if count == 0:
        return np.zeros((0, ncomp), dtype)
    if not stride or stride == elem:
        return np.frombuffer(buf, dtype=dtype, count=count * ncomp, offset=offset).reshape(count, ncomp)
    raw = np.frombuffer(buf, dtype=np.uint8, count=(count - 1) * stride + elem, offset=offset)
    rows = np.lib.stride_tricks.as_strided(raw, (count, elem), (stride, 1))
    return np.ascontiguousarray(rows).view(dtype).reshape(count, ncomp)


# -- reading and validation -----------------------------------------------------------------------
def load_document(path) -> Document:
    """Read and validate `path` (a .gltf or .glb): `read_document` then `validate`."""
    doc = read_document(Path(path))
    validate(doc)
    return doc


def read_document(path: Path) -> Document:
    """The JSON (and GLB binary chunk) of `path`; buffers are loaded by `validate`."""
    doc = Document(path)
    try:
        budget.current().charge(path.stat().st_size, path, "the file itself")
        data = path.read_bytes()
    except OSError as exc:
        raise doc.err(f"cannot read file ({exc.strerror or exc})") from None
    if data[:4] == b"glTF":
        text = _read_glb(doc, data)
    elif path.suffix.lower() == ".glb":
        raise doc.err("not a binary glTF file (the GLB magic 'glTF' is missing)")
    else:
        text = data
    try:
        doc.json = parse_nested(doc.path, json.loads, text.decode("utf-8-sig") if isinstance(text, bytes) else text,
                                "the glTF JSON")
    except UnicodeDecodeError as exc:
        raise doc.err(f"the glTF JSON is not UTF-8 ({exc.reason} at byte {exc.start})") from None
    except json.JSONDecodeError as exc:
        raise doc.err(f"invalid glTF JSON: {exc.msg} (line {exc.lineno}, column {exc.colno})") from None
    if not isinstance(doc.json, dict):
        raise doc.err("the glTF JSON must be an object")
    return doc


def _read_glb(doc: Document, data: bytes) -> bytes:
    if len(data) < 20:
        raise doc.err(f"GLB file is truncated ({len(data)} bytes)")
    magic, version, length = struct.unpack_from("<3I", data, 0)
    if version != 2:
        raise doc.err(f"GLB container version {version} is not supported (glTF 2.0 needs 2)")
    if length > len(data):
        raise doc.err(f"GLB header says {length} bytes but the file has {len(data)}")
    pos, text = 12, None
    while pos + 8 <= length:
        chunk_len, chunk_type = struct.unpack_from("<2I", data, pos)
        start, end = pos + 8, pos + 8 + chunk_len
        if end > length:
            raise doc.err(f"GLB chunk at byte {pos} ({chunk_len} bytes) runs past the end of the file")
        if text is None:
            if chunk_type != GLB_JSON:
                raise doc.err("the first GLB chunk is not JSON")
            text = data[start:end]
        elif chunk_type == GLB_BIN and doc.glb_bin is None:
            doc.glb_bin = data[start:end]
        pos = end
    if text is None:
        raise doc.err("GLB file has no JSON chunk")
    return text


def extensions_in_use(doc: Document) -> dict[str, str]:
    """{extension name: where it first appears} over extensionsUsed and every `extensions` object of
    the document (root, materials, textureInfos, nodes, primitives, ...); `extras` are not searched."""
    found: dict[str, str] = {}

    def where(at) -> str:           # at = (parent's at, key or index): spelled out only when needed
        parts = []
        while at is not None:
            at, part = at
            parts.append(f"[{part}]" if isinstance(part, int) else f".{part}")
        return "".join(reversed(parts)).lstrip(".") or "the top level"

    stack = [(doc.json, None)]      # depth-first, in document order, without recursion (issue 34)
    while stack:
        value, at = stack.pop()
        if isinstance(value, dict):
            ext = value.get("extensions")
            if isinstance(ext, dict):
                for name in ext:
                    if str(name) not in found:
                        found[str(name)] = where(at)
            stack.extend((child, (at, key)) for key, child in reversed(value.items())
                         if key != "extras" and isinstance(child, (dict, list)))
        elif isinstance(value, list):
            stack.extend((value[i], (at, i)) for i in range(len(value) - 1, -1, -1)
                         if isinstance(value[i], (dict, list)))
    for name in doc.json.get("extensionsUsed", []) or []:
        if isinstance(name, str):
            found.setdefault(name, "extensionsUsed")
    return found


def texture_source(tex: dict, doc: Optional[Document] = None, what: str = "texture"):
    """A texture's image index: an image extension's source (EXT_texture_webp) when its decoder is
    available, else `source`, else None (with `doc`: SceneError when only undecodable extension
    images are given, e.g. KHR_texture_basisu); see compression.texture_source."""
    return compression.texture_source(tex, doc, what)
