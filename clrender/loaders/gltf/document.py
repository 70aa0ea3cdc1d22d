"""Reading a glTF 2.0 file (.gltf or .glb) into a validated `Document`.

`load_document(path)` parses the JSON (or the GLB container's JSON and BIN chunks), loads every
buffer (GLB chunk, data URI or external file) and checks what the loader relies on: buffer views
and accessor ranges inside their buffers, every index into every array, attribute types, component
types and counts (NORMAL, TEXCOORD_n, COLOR_n, TANGENT: `ATTRIBUTE_FORMATS`), primitive modes, node
transforms, sampler wrap modes, material alpha modes, every material textureInfo (texture index,
texCoord, scale / strength, KHR_texture_transform) and that the TEXCOORD set each texture reads
exists on the primitives using the material, and extensionsRequired (only
`SUPPORTED_EXTENSIONS` are accepted). Bad input
is a `SceneError` naming the file and the offending element, never a KeyError or a trimesh
traceback. `Document.accessor(i)` then decodes an accessor (strided, sparse, normalized) to NumPy.
Compressed data (KHR_draco_mesh_compression, EXT_meshopt_compression) decodes behind
`Document.accessor` and `Document.view_bytes` (`gltf_compression`, docs/compression.md).
"""
from __future__ import annotations

import base64
import binascii
import json
import struct
from pathlib import Path
from typing import Optional
from urllib.parse import unquote

import numpy as np

from clrender.scene.model import SceneError
from clrender.loaders import budget, confine
from clrender.loaders.gltf import compression
from clrender.loaders.common import fail, parse_nested

COMPONENT_TYPES = {5120: "<i1", 5121: "<u1", 5122: "<i2", 5123: "<u2", 5125: "<u4", 5126: "<f4"}
TYPE_SIZES = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}
WRAP_MODES = {10497: "repeat", 33071: "clamp", 33648: "mirror"}
MODE_TRIANGLES, MODE_STRIP, MODE_FAN = 4, 5, 6
# The extensions clrender implements. A file that lists any other in extensionsRequired is refused
# (SceneError naming it); other extensions it merely uses are ignored with one warning each
# (clrender.loaders.gltf). EXT_texture_webp: `texture_source` reads its image (Pillow decodes WebP);
# KHR_mesh_quantization, KHR_draco_mesh_compression, EXT_meshopt_compression: `gltf_compression`.
SUPPORTED_EXTENSIONS = frozenset({"KHR_materials_emissive_strength", "KHR_materials_unlit", "KHR_texture_transform",
                                  "KHR_lights_punctual", "EXT_texture_webp"}) | compression.EXTENSIONS
# Vertex attribute component types (glTF 2.0, "Meshes"): (componentType, normalized)
FLOAT = {(5126, False)}
UNORM_8_16 = {(5121, True), (5123, True)}
SNORM_8_16 = {(5120, True), (5122, True)}
COMPONENT_NAMES = {5120: "BYTE", 5121: "UNSIGNED_BYTE", 5122: "SHORT", 5123: "UNSIGNED_SHORT",
                   5125: "UNSIGNED_INT", 5126: "FLOAT"}
INTS_8_16 = {(c, n) for c in (5120, 5121, 5122, 5123) for n in (False, True)}
# attribute -> (allowed types, allowed (componentType, normalized)); TANGENT allows the snorm forms of
# KHR_mesh_quantization, which Document.accessor decodes like any normalized accessor
ATTRIBUTE_FORMATS = {
    "NORMAL": (("VEC3",), None),                       # checked loosely, as before (any component type)
    "TEXCOORD": (("VEC2",), FLOAT | UNORM_8_16),
    "COLOR": (("VEC3", "VEC4"), FLOAT | UNORM_8_16),
    "TANGENT": (("VEC4",), FLOAT | SNORM_8_16),
}
# KHR_mesh_quantization's table, where it widens the core formats (NORMAL, TANGENT: already allowed)
QUANTIZED_FORMATS = {"POSITION": (("VEC3",), FLOAT | INTS_8_16), "TEXCOORD": (("VEC2",), FLOAT | INTS_8_16)}
# vertex attributes whose integer data are values (dequantized to float32 by Document.accessor);
# JOINTS_n and the indices stay integers
FLOAT_ATTRIBUTES = ("POSITION", "NORMAL", "TANGENT", "TEXCOORD", "COLOR")
# material texture slots: (clrender slot, JSON path of its textureInfo, sRGB image)
TEXTURE_INFOS = (("base_color", ("pbrMetallicRoughness", "baseColorTexture"), True),
                 ("metallic_roughness", ("pbrMetallicRoughness", "metallicRoughnessTexture"), False),
                 ("normal", ("normalTexture",), False),
                 ("occlusion", ("occlusionTexture",), False),
                 ("emissive", ("emissiveTexture",), True))
GLB_MAGIC, GLB_JSON, GLB_BIN = 0x46546C67, 0x4E4F534A, 0x004E4942


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
        # compressed data (gltf_compression): accessor -> (primitive label, primitive) of its Draco data;
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


def accessor_bytes(acc: dict) -> int:
    """What decoding an accessor costs: its data, and the float64 copy every loader path makes of it."""
    n = acc["count"] * TYPE_SIZES[acc["type"]]
    return n * (np.dtype(COMPONENT_TYPES[acc["componentType"]]).itemsize + 8)


def accessor_field(index: int, acc: dict) -> str:
    """'accessors[3].count (402653184 x VEC3 of FLOAT)': the field a budget error names."""
    return f"accessors[{index}].count ({acc['count']} x {acc['type']} of {COMPONENT_NAMES[acc['componentType']]})"


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


def validate(doc: Document) -> None:
    """Load the buffers and check every index, range and type the loader relies on; any
    malformed input becomes a SceneError naming the file."""
    try:
        _validate_inner(doc)
    except SceneError:
        raise
    except (KeyError, TypeError, ValueError, AttributeError, IndexError) as exc:
        detail = f"missing property {exc}" if isinstance(exc, KeyError) else f"{type(exc).__name__}: {exc}"
        raise doc.err(f"malformed glTF ({detail})") from None


def _int(value, what: str, doc: Document, minimum: int = 0) -> int:
    if not isinstance(value, int) or isinstance(value, bool) or value < minimum:
        raise doc.err(f"{what} must be an integer >= {minimum}, got {value!r}")
    return value


def _validate_inner(doc: Document) -> None:
    j = doc.json
    version = str(j.get("asset", {}).get("version", ""))
    if not version.startswith("2"):
        raise doc.err(f"only glTF 2.0 is supported (asset.version is {version or 'missing'!r})")
    required = j.get("extensionsRequired", []) or []
    if not isinstance(required, list) or not all(isinstance(e, str) for e in required):
        raise doc.err("extensionsRequired must be an array of extension names")
    compression.check_required(doc, required)
    bad = sorted(set(required) - SUPPORTED_EXTENSIONS)
    if bad:
        raise doc.err(f"requires unsupported glTF extension(s) {', '.join(bad)} (extensionsRequired; "
                      f"clrender implements {', '.join(sorted(SUPPORTED_EXTENSIONS))})")

    # buffers
    for k, buf in enumerate(doc.list("buffers")):
        length = _int(buf.get("byteLength"), f"buffers[{k}].byteLength", doc)
        uri = buf.get("uri")
        if uri is None:
            if k == 0 and doc.glb_bin is not None:
                data = doc.glb_bin
            elif compression.placeholder_buffer(doc, k, buf):    # only meshopt bufferViews read it
                doc.placeholder_buffers.add(k)
                data = b""
            else:
                raise doc.err(f"buffer {k} has no uri (and there is no GLB binary chunk for it)")
        elif isinstance(uri, str) and uri.startswith("data:"):
            data = data_uri(doc, uri, f"buffer {k}")
        else:
            file = confine.gltf_uri(doc.path, uri, f"buffer {k} uri")   # inside the scene's folder, or refused
            if not file.is_file():
                raise doc.err(f"buffer {k}: file not found: {file}")
            # only byteLength bytes are used: a larger file is not read whole
            budget.current().charge(min(length, file.stat().st_size), doc.path, f"buffers[{k}] ({uri!r})")
            with open(file, "rb") as fh:
                data = fh.read(length)
        if len(data) < length and k not in doc.placeholder_buffers:
            raise doc.err(f"buffer {k} ({uri or 'GLB chunk'}) has {len(data)} bytes, "
                          f"but its byteLength is {length}")
        doc.buffers.append(data[:length] if len(data) > length else data)

    # buffer views
    for v, view in enumerate(doc.list("bufferViews")):
        b = view.get("buffer")
        doc.get("buffers", b, f"bufferViews[{v}]")
        off = _int(view.get("byteOffset", 0), f"bufferViews[{v}].byteOffset", doc)
        length = _int(view.get("byteLength"), f"bufferViews[{v}].byteLength", doc)
        size = doc.list("buffers")[b]["byteLength"] if b in doc.placeholder_buffers else len(doc.buffers[b])
        if off + length > size:
            raise doc.err(f"bufferView {v} (bytes {off}..{off + length}) runs past the end of buffer {b} "
                          f"({size} bytes)")
        if "byteStride" in view:
            # the schema: a multiple of 4 in [4, 252] (vertex attributes are 4-byte aligned, §3.6.2.4)
            stride = _int(view["byteStride"], f"bufferViews[{v}].byteStride", doc, 1)
            if stride % 4 or not 4 <= stride <= 252:
                raise doc.err(f"bufferViews[{v}].byteStride must be a multiple of 4 in [4, 252], got {stride}")
        compression.validate_view(doc, v, view)

    # accessors
    for a, acc in enumerate(doc.list("accessors")):
        if acc.get("componentType") not in COMPONENT_TYPES:
            raise doc.err(f"accessor {a}: unknown componentType {acc.get('componentType')!r}")
        if acc.get("type") not in TYPE_SIZES:
            raise doc.err(f"accessor {a}: unknown type {acc.get('type')!r}")
        count = _int(acc.get("count"), f"accessors[{a}].count", doc)
        elem = np.dtype(COMPONENT_TYPES[acc["componentType"]]).itemsize * TYPE_SIZES[acc["type"]]
        # without a bufferView the count alone sizes the array (zeros): checked before anything is made
        budget.current().check(accessor_bytes(acc), doc.path, accessor_field(a, acc))
        if "bufferView" in acc:
            view = doc.get("bufferViews", acc["bufferView"], f"accessor {a}")
            stride = view.get("byteStride")
            if stride is not None and stride < elem:        # each element would overlap the next one
                raise doc.err(f"accessors[{a}] ({acc['type']} of {COMPONENT_NAMES[acc['componentType']]}, {elem} "
                              f"bytes each) reads bufferViews[{acc['bufferView']}] with byteStride {stride}, "
                              f"smaller than one element")
            _check_range(doc, f"accessor {a}", acc["bufferView"], view,
                         _int(acc.get("byteOffset", 0), f"accessors[{a}].byteOffset", doc),
                         view.get("byteStride") or elem, elem, count)
        sparse = acc.get("sparse")
        if sparse:
            n = _int(sparse.get("count"), f"accessors[{a}].sparse.count", doc)
            if n > count:
                raise doc.err(f"accessors[{a}].sparse.count ({n}) is more than the accessor's count ({count})")
            for part, size in (("indices", None), ("values", elem)):
                info = sparse[part]
                if part == "indices":
                    if info.get("componentType") not in (5121, 5123, 5125):
                        raise doc.err(f"accessor {a}: bad sparse index componentType")
                    size = np.dtype(COMPONENT_TYPES[info["componentType"]]).itemsize
                view = doc.get("bufferViews", info.get("bufferView"), f"accessor {a} sparse {part}")
                _check_range(doc, f"accessor {a} sparse {part}", info["bufferView"], view,
                             info.get("byteOffset", 0), size, size, n)

    accessors = doc.list("accessors")
    quantized = compression.QUANTIZATION in (doc.json.get("extensionsUsed") or [])
    formats = {**ATTRIBUTE_FORMATS, **QUANTIZED_FORMATS} if quantized else ATTRIBUTE_FORMATS

    def accessor_ref(index, what):
        return doc.get("accessors", index, what)

    # meshes
    for m, mesh in enumerate(doc.list("meshes")):
        prims = mesh.get("primitives")
        if not isinstance(prims, list):
            raise doc.err(f"mesh {m} has no primitives array")
        for p, prim in enumerate(prims):
            what = f"mesh {m} ({mesh.get('name', '')!r}) primitive {p}"
            attrs = prim.get("attributes")
            if not isinstance(attrs, dict):
                raise doc.err(f"{what} has no attributes")
            for name, idx in attrs.items():
                accessor_ref(idx, f"{what} attribute {name}")
                if attribute_kind(name) in FLOAT_ATTRIBUTES:
                    doc.float_accessors.add(idx)
            compression.validate_primitive(doc, what, prim)
            mode = prim.get("mode", MODE_TRIANGLES)
            if mode not in range(7):
                raise doc.err(f"{what}: unknown mode {mode!r}")
            if "material" in prim:
                doc.get("materials", prim["material"], what)
            if mode not in (MODE_TRIANGLES, MODE_STRIP, MODE_FAN):
                continue  # points and lines are not rendered
            if "POSITION" not in attrs:
                raise doc.err(f"{what} has no POSITION attribute")
            pos = accessors[attrs["POSITION"]]
            if pos["type"] != "VEC3":
                raise doc.err(f"{what}: POSITION must be VEC3, got {pos['type']}")
            nv = pos["count"]
            for name, idx in attrs.items():
                kind = attribute_kind(name)
                if kind not in formats:
                    continue
                acc, (types, allowed_formats) = accessors[idx], formats[kind]
                fmt = (acc["componentType"], bool(acc.get("normalized", False)))
                if acc["type"] not in types or (allowed_formats is not None and fmt not in allowed_formats):
                    allowed = " or ".join(sorted({("normalized " if n else "") + COMPONENT_NAMES[c]
                                                  for c, n in (allowed_formats or ())}))
                    got = ("normalized " if fmt[1] else "") + COMPONENT_NAMES[fmt[0]]
                    raise doc.err(f"{what}: attribute {name} (accessor {idx}) must be {' or '.join(types)}"
                                  + (f" of {allowed}" if allowed_formats else "") + f", got {acc['type']} of {got}"
                                  + (f" (needs {compression.QUANTIZATION} in extensionsUsed)"
                                     if not quantized and kind in QUANTIZED_FORMATS and fmt in INTS_8_16 else ""))
                if acc["count"] != nv:
                    raise doc.err(f"{what}: {name} has {acc['count']} entries but POSITION has {nv}")
            if "material" in prim:
                _check_texcoords(doc, what, prim["material"], attrs)
            if "indices" in prim:
                idx = accessor_ref(prim["indices"], f"{what} indices")
                if idx["type"] != "SCALAR" or idx["componentType"] not in (5121, 5123, 5125):
                    raise doc.err(f"{what}: indices must be unsigned integer SCALARs")
                n = idx["count"]
            else:
                n = nv
            if mode == MODE_TRIANGLES and n % 3:
                raise doc.err(f"{what}: {n} indices is not a multiple of 3 for TRIANGLES")

    # names become mesh, object and material names (paths joined with "/", fnmatch patterns): strings only
    for key in ("nodes", "meshes", "materials", "cameras", "animations", "skins", "textures", "images", "scenes"):
        for i, item in enumerate(doc.list(key)):
            if isinstance(item, dict) and "name" in item and not isinstance(item["name"], str):
                raise doc.err(f"{key}[{i}].name must be a string, got {type(item['name']).__name__}")

    # nodes, scenes, cameras, KHR_lights_punctual lights
    lights = punctual_lights(doc)
    _validate_lights(doc, lights)
    nodes = doc.list("nodes")
    for n, node in enumerate(nodes):
        if not isinstance(node, dict):
            raise doc.err(f"nodes[{n}] must be an object")
        if "mesh" in node:
            doc.get("meshes", node["mesh"], f"node {n}")
        if "camera" in node:
            doc.get("cameras", node["camera"], f"node {n}")
        light_ref = node_light(doc, n, node)
        if light_ref is not None:
            _int(light_ref, f"node {n} extensions.KHR_lights_punctual.light", doc)
            if light_ref >= len(lights):
                raise doc.err(f"node {n} references KHR_lights_punctual light {light_ref}, which does not exist "
                              f"(there are {len(lights)})")
        for c in node.get("children", []):
            if not isinstance(c, int) or not 0 <= c < len(nodes):
                raise doc.err(f"node {n} has child {c!r}, which does not exist (there are {len(nodes)} nodes)")
        for key, size in (("matrix", 16), ("translation", 3), ("rotation", 4), ("scale", 3)):
            if key in node:
                value = np.asarray(node[key], dtype=np.float64)
                if value.shape != (size,) or not np.isfinite(value).all():
                    raise doc.err(f"node {n}: {key} must be {size} finite numbers")
    scenes = doc.list("scenes")
    if "scene" in doc.json:
        doc.get("scenes", doc.json["scene"], "the default scene")
    for s, scene in enumerate(scenes):
        for r in scene.get("nodes", []):
            if not isinstance(r, int) or not 0 <= r < len(nodes):
                raise doc.err(f"scene {s} has root node {r!r}, which does not exist")

    # materials -> textures -> images / samplers
    for t, tex in enumerate(doc.list("textures")):
        if "sampler" in tex:
            sampler = doc.get("samplers", tex["sampler"], f"texture {t}")
            for key in ("wrapS", "wrapT"):
                if key in sampler and sampler[key] not in WRAP_MODES:
                    raise doc.err(f"sampler {tex['sampler']}: unknown {key} {sampler[key]!r}")
        src = texture_source(tex, doc, f"texture {t}")
        if src is not None:
            doc.get("images", src, f"texture {t}")
    for i, img in enumerate(doc.list("images")):
        if "bufferView" in img:
            doc.get("bufferViews", img["bufferView"], f"image {i}")
    for m, mat in enumerate(doc.list("materials")):
        if not isinstance(mat, dict):
            raise doc.err(f"materials[{m}] must be an object")
        where = f"material {m} ({mat.get('name', '')!r})"
        for key in ("pbrMetallicRoughness", "extensions"):
            if not isinstance(mat.get(key, {}), dict):
                raise doc.err(f"{where}: {key} must be an object")
        for slot, label, info in material_textures(doc, m, mat):
            doc.get("textures", info.get("index"), f"{where} {label}")
            texcoord_of(doc, f"{where} {label}", info)
            for key, lo, hi in (("scale", -np.inf, np.inf), ("strength", 0.0, 1.0)):
                if key in info:
                    v = _finite(info[key], f"{where} {label}.{key}", doc, lo if lo > -np.inf else None)
                    if v > hi:
                        raise doc.err(f"{where} {label}.{key} must be <= {hi}, got {v!r}")
        mode = mat.get("alphaMode", "OPAQUE")
        if mode not in ("OPAQUE", "MASK", "BLEND"):
            raise doc.err(f"material {m}: unknown alphaMode {mode!r}")


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


def attribute_kind(name: str) -> str:
    """'TEXCOORD_1' -> 'TEXCOORD', 'COLOR_0' -> 'COLOR', 'NORMAL' -> 'NORMAL'."""
    head, _, tail = name.rpartition("_")
    return head if head and tail.isdigit() else name


def attribute_sets(attrs: dict, kind: str) -> list[int]:
    """The set indices n of the `kind`_n attributes (e.g. TEXCOORD_0, TEXCOORD_2 -> [0, 2]), sorted."""
    return sorted(int(a.rpartition("_")[2]) for a in attrs if attribute_kind(a) == kind and a != kind)


def material_textures(doc: Document, m: int, mat: dict) -> list[tuple[str, str, dict]]:
    """(clrender slot, JSON label, textureInfo) of every texture the material references."""
    out = []
    for slot, path, _ in TEXTURE_INFOS:
        info = mat.get(path[0]) if len(path) == 1 else (mat.get(path[0]) or {}).get(path[1])
        if info is None:
            continue
        label = ".".join(path)
        if not isinstance(info, dict):
            raise doc.err(f"material {m} ({mat.get('name', '')!r}) {label} must be an object")
        out.append((slot, label, info))
    return out


def texcoord_of(doc: Document, what: str, info: dict) -> int:
    """The TEXCOORD set a textureInfo reads: KHR_texture_transform's texCoord when given, else its own
    texCoord (default 0); validates the transform's fields on the way."""
    k = _int(info.get("texCoord", 0), f"{what}.texCoord", doc)
    ext = (info.get("extensions") or {})
    if not isinstance(ext, dict):
        raise doc.err(f"{what}.extensions must be an object")
    tt = ext.get("KHR_texture_transform")
    if tt is None:
        return k
    if not isinstance(tt, dict):
        raise doc.err(f"{what}: KHR_texture_transform must be an object")
    for key, n in (("offset", 2), ("scale", 2)):
        if key in tt:
            v = tt[key]
            if not isinstance(v, list) or len(v) != n:
                raise doc.err(f"{what}: KHR_texture_transform.{key} must be {n} numbers, got {v!r}")
            for x in v:
                _finite(x, f"{what}: KHR_texture_transform.{key}", doc)
    if "rotation" in tt:
        _finite(tt["rotation"], f"{what}: KHR_texture_transform.rotation", doc)
    if "texCoord" in tt:
        k = _int(tt["texCoord"], f"{what}: KHR_texture_transform.texCoord", doc)
    return k


def _check_texcoords(doc: Document, what: str, m: int, attrs: dict) -> None:
    """Every texture of material `m` reads a TEXCOORD set that primitive `what` has (the glTF
    validator's MESH_PRIMITIVE_TOO_FEW_TEXCOORDS is an error, not a warning)."""
    mat = doc.get("materials", m, what)
    for slot, label, info in material_textures(doc, m, mat):
        k = texcoord_of(doc, f"material {m} ({mat.get('name', '')!r}) {label}", info)
        if f"TEXCOORD_{k}" not in attrs:
            have = ", ".join(f"TEXCOORD_{n}" for n in attribute_sets(attrs, "TEXCOORD")) or "none"
            raise doc.err(f"{what}: material {m} ({mat.get('name', '')!r}) reads its {label} from TEXCOORD_{k}, "
                          f"which the primitive does not have (texture coordinate sets: {have})")


LIGHT_TYPES = ("directional", "point", "spot")


def punctual_lights(doc: Document) -> list:
    """The `KHR_lights_punctual` lights array of the document (empty when the extension is absent)."""
    ext = doc.json.get("extensions") or {}
    if not isinstance(ext, dict):
        raise doc.err("top-level extensions must be an object")
    lp = ext.get("KHR_lights_punctual")
    if lp is None:
        return []
    if not isinstance(lp, dict) or not isinstance(lp.get("lights", []), list):
        raise doc.err("extensions.KHR_lights_punctual.lights must be an array")
    return lp.get("lights", [])


def node_light(doc: Document, n: int, node: dict):
    """The KHR_lights_punctual light index a node references, or None."""
    ext = node.get("extensions") or {}
    if not isinstance(ext, dict):
        raise doc.err(f"node {n}: extensions must be an object")
    ref = ext.get("KHR_lights_punctual")
    if ref is None:
        return None
    if not isinstance(ref, dict) or "light" not in ref:
        raise doc.err(f"node {n}: extensions.KHR_lights_punctual needs a 'light' index")
    return ref["light"]


def _finite(value, what: str, doc: Document, minimum=None, exclusive=False) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not np.isfinite(value):
        raise doc.err(f"{what} must be a finite number, got {value!r}")
    if minimum is not None and (value <= minimum if exclusive else value < minimum):
        raise doc.err(f"{what} must be {'>' if exclusive else '>='} {minimum}, got {value!r}")
    return float(value)


def _validate_lights(doc: Document, lights: list) -> None:
    """KHR_lights_punctual: types, colors, intensities, ranges and spot cone angles."""
    for k, light in enumerate(lights):
        if not isinstance(light, dict):
            raise doc.err(f"KHR_lights_punctual light {k} must be an object")
        what = f"KHR_lights_punctual light {k}" + (f" ({light['name']!r})" if light.get("name") else "")
        kind = light.get("type")
        if kind not in LIGHT_TYPES:
            raise doc.err(f"{what}: type must be one of {LIGHT_TYPES}, got {kind!r}")
        color = light.get("color", [1.0, 1.0, 1.0])
        if not isinstance(color, list) or len(color) != 3:
            raise doc.err(f"{what}: color must be 3 numbers, got {color!r}")
        for c in color:
            _finite(c, f"{what}: color", doc, 0.0)
        _finite(light.get("intensity", 1.0), f"{what}: intensity", doc, 0.0)
        if "range" in light:
            _finite(light["range"], f"{what}: range", doc, 0.0, exclusive=True)
        if kind == "spot":
            spot = light.get("spot", {})
            if not isinstance(spot, dict):
                raise doc.err(f"{what}: spot must be an object")
            inner = _finite(spot.get("innerConeAngle", 0.0), f"{what}: spot.innerConeAngle", doc, 0.0)
            outer = _finite(spot.get("outerConeAngle", np.pi / 4), f"{what}: spot.outerConeAngle", doc, 0.0)
            if inner > outer:
                raise doc.err(f"{what}: spot.innerConeAngle ({inner}) is larger than spot.outerConeAngle ({outer})")
            if outer > np.pi / 2 + 1e-6:
                raise doc.err(f"{what}: spot.outerConeAngle ({outer}) must be <= pi/2")


def _check_range(doc, what, view_index, view, offset, stride, elem, count) -> None:
    length = view["byteLength"]
    if count and offset + (count - 1) * stride + elem > length:
        raise doc.err(f"{what}: {count} elements of {elem} bytes (stride {stride}) from byte {offset} "
                      f"run past the end of bufferView {view_index} ({length} bytes)")


def data_uri(doc: Document, uri: str, what: str) -> bytes:
    """The bytes of a `data:` URI (base64 or percent-encoded)."""
    head, _, payload = uri.partition(",")
    try:
        if head.endswith(";base64"):
            return base64.b64decode(payload, validate=False)
        return unquote(payload).encode("latin-1")
    except (binascii.Error, ValueError) as exc:
        raise doc.err(f"{what}: bad data URI ({exc})") from None


def texture_source(tex: dict, doc: Optional[Document] = None, what: str = "texture"):
    """A texture's image index: an image extension's source (EXT_texture_webp) when its decoder is
    available, else `source`, else None (with `doc`: SceneError when only undecodable extension
    images are given, e.g. KHR_texture_basisu); see gltf_compression.texture_source."""
    return compression.texture_source(tex, doc, what)
