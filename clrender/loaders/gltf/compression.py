"""Compressed and quantized glTF data (docs/compression.md), hooked into `clrender.loaders.gltf.document.Document`.

* KHR_mesh_quantization: integer attributes; `Document.accessor` dequantizes normalized ones and
  returns non-normalized vertex attributes as float32 (validation accepts the extension's formats).
* KHR_draco_mesh_compression (DracoPy): a primitive's Draco bufferView decodes, on the first read
  of any accessor it replaces, into all of them (attributes by the extension's unique ids, the
  indices from the decoded faces), converted to each glTF accessor's componentType / normalized.
* EXT_meshopt_compression (meshoptimizer): a bufferView with the extension decodes, on its first
  read, into its own bytes (modes ATTRIBUTES / TRIANGLES / INDICES, the binding's filters).
  Buffers without data (the extension's fallback placeholders) are allowed.
* Image extensions: EXT_texture_webp (Pillow); KHR_texture_basisu (opengl_basisu, clrender.loaders.ktx2).
  Without its decoder a texture falls back to its core `source` (one note per file) and, without
  one, is an error naming the extension and the extra.

The decoders are the libraries' own (`pip install "clrender[compression]"`), imported lazily:
without one, a file that requires the extension, or whose data has no uncompressed fallback, is
a one-line SceneError naming the file, the extension and the package; a file with a fallback
loads from it. Undecodable data is a SceneError naming the mesh / bufferView, never a crash
(DracoPy and meshoptimizer return errors on bad input; the parameters meshoptimizer's C
functions assert on are checked here first).
"""
from __future__ import annotations

import importlib
import warnings
from typing import Optional

import numpy as np

from clrender.loaders import budget
from clrender.loaders.gltf.spec import (  # noqa: F401  (QUANTIZATION, EXTENSIONS: this module's names too)
    BASISU, COMPONENT_TYPES, DRACO, MESHOPT, QUANTIZATION, TYPE_SIZES, WEBP, accessor_bytes)
from clrender.loaders.gltf.spec import COMPRESSION_EXTENSIONS as EXTENSIONS  # noqa: F401
INSTALL = 'pip install "clrender[compression]"'
# extension -> (module to import, the PyPI package that provides it)
PACKAGES = {DRACO: ("DracoPy", "DracoPy"), MESHOPT: ("meshoptimizer", "meshoptimizer"),
            BASISU: ("opengl_basisu", "opengl_basisu")}     # KTX2: clrender.loaders.ktx2
BASISU_WHY = f"the opengl_basisu package that decodes KTX2 is not installed: {INSTALL}"
MESHOPT_MODES = ("ATTRIBUTES", "TRIANGLES", "INDICES")
MESHOPT_FILTERS = ("NONE", "OCTAHEDRAL", "QUATERNION", "EXPONENTIAL")


def _module(name: str):
    try:
        return importlib.import_module(name)
    except ImportError:
        return None


def available(ext: str) -> bool:
    """Whether the package that decodes `ext` imports (extensions without a package: True)."""
    return ext not in PACKAGES or _module(PACKAGES[ext][0]) is not None


def _decoder(doc, ext: str, what: str):
    module = _module(PACKAGES[ext][0])
    if module is None:
        raise missing(doc, ext, what)
    return module


def missing(doc, ext: str, what: str):
    return doc.err(f"{what} uses {ext}, which needs the {PACKAGES[ext][1]} package (not installed): {INSTALL}")


def webp_available() -> bool:
    from PIL import features
    return bool(features.check("webp"))


def image_extension_available(name: str) -> Optional[bool]:
    """True / False for the image extensions clrender knows; None for any other."""
    if name == WEBP:
        return webp_available()
    if name == BASISU:
        return available(BASISU)
    return None


def check_required(doc, required: list) -> None:
    """extensionsRequired: a supported extension whose decoder is missing is an error up front;
    KHR_texture_basisu only used without its decoder: one note that the `source` images are used."""
    used = doc.json.get("extensionsUsed") or []
    if isinstance(used, list) and BASISU in used and BASISU not in required and not available(BASISU):
        warnings.warn(f"{doc.path}: glTF extension {BASISU}: {BASISU_WHY}; textures use their fallback "
                      f"`source` images", stacklevel=4)
    for ext in required:
        if ext in PACKAGES and not available(ext):
            raise doc.err(f"requires glTF extension {ext} (extensionsRequired), which needs the "
                          f"{PACKAGES[ext][1]} package (not installed): {INSTALL}")
        if ext == WEBP and not webp_available():
            raise doc.err(f"requires glTF extension {WEBP} (extensionsRequired), but this Pillow was built "
                          f"without WebP support")


def texture_source(tex: dict, doc=None, what: str = "texture"):
    """A texture's image index: an image extension's source whose decoder is available (preferred,
    as the extensions ask), else the core `source`, else another extension's source (Pillow may read
    it), else None; with `doc`, a texture whose only sources cannot be decoded is a SceneError."""
    exts = tex.get("extensions") or {}
    sources = [(name, ext["source"]) for name, ext in exts.items() if isinstance(ext, dict) and "source" in ext]
    for name, src in sources:
        if image_extension_available(name):
            return src
    if "source" in tex:
        return tex["source"]
    for name, src in sources:
        if image_extension_available(name) is None:
            return src
    if sources and doc is not None:
        name = sources[0][0]
        why = BASISU_WHY if name == BASISU else "this Pillow was built without WebP support"
        raise doc.err(f"{what} has only a {name} image and no fallback `source`: {why}")
    return None


# -- validation -------------------------------------------------------------------------------------
def placeholder_buffer(doc, k: int, buf: dict) -> bool:
    """A buffer without data that EXT_meshopt_compression allows (fallback placeholder)."""
    ext = (buf.get("extensions") or {}).get(MESHOPT)
    return (isinstance(ext, dict) and bool(ext.get("fallback"))) or MESHOPT in (doc.json.get("extensionsUsed") or [])


def validate_view(doc, v: int, view: dict) -> None:
    """EXT_meshopt_compression on bufferView `v`: the spec's rules, checked before any decoding (the
    C decoder asserts on some of them); registers the view for `Document.view_bytes`."""
    ext = (view.get("extensions") or {}).get(MESHOPT)
    if ext is None:
        if view["buffer"] in doc.placeholder_buffers:
            raise doc.err(f"bufferView {v} reads buffer {view['buffer']}, which has no data (an "
                          f"{MESHOPT} fallback buffer) and is not an {MESHOPT} bufferView")
        return
    what = f"bufferView {v} {MESHOPT}"
    if not isinstance(ext, dict):
        raise doc.err(f"{what} must be an object")
    b = ext.get("buffer")
    doc.get("buffers", b, what)
    if b in doc.placeholder_buffers:
        raise doc.err(f"{what} reads its compressed data from buffer {b}, which has no data")
    off, length = ext.get("byteOffset", 0), ext.get("byteLength")
    stride, count, mode = ext.get("byteStride"), ext.get("count"), ext.get("mode")
    filt = ext.get("filter", "NONE")
    for key, value in (("byteOffset", off), ("byteLength", length), ("byteStride", stride), ("count", count)):
        if not isinstance(value, int) or isinstance(value, bool) or value < (1 if key == "byteStride" else 0):
            raise doc.err(f"{what}: {key} must be a {'positive' if key == 'byteStride' else 'non-negative'} "
                          f"integer, got {value!r}")
    if off + length > len(doc.buffers[b]):
        raise doc.err(f"{what}: bytes {off}..{off + length} run past the end of buffer {b} "
                      f"({len(doc.buffers[b])} bytes)")
    if mode not in MESHOPT_MODES:
        raise doc.err(f"{what}: mode must be one of {', '.join(MESHOPT_MODES)}, got {mode!r}")
    if filt not in MESHOPT_FILTERS:
        raise doc.err(f"{what}: filter must be one of {', '.join(MESHOPT_FILTERS)}, got {filt!r}")
    if view.get("byteStride", stride) != stride:
        raise doc.err(f"{what}: byteStride {stride} differs from the bufferView's {view['byteStride']}")
    if view["byteLength"] != stride * count:
        raise doc.err(f"{what}: count {count} x byteStride {stride} is not the bufferView's byteLength "
                      f"{view['byteLength']}")
    rules = [(mode == "ATTRIBUTES" and (stride % 4 or stride > 256), "ATTRIBUTES needs a byteStride divisible "
              "by 4 and at most 256"),
             (mode == "TRIANGLES" and count % 3, "TRIANGLES needs a count divisible by 3"),
             (mode != "ATTRIBUTES" and stride not in (2, 4), f"{mode} needs a byteStride of 2 or 4"),
             (mode != "ATTRIBUTES" and filt != "NONE", f"{mode} allows no filter"),
             (filt == "OCTAHEDRAL" and stride not in (4, 8), "OCTAHEDRAL needs a byteStride of 4 or 8"),
             (filt == "QUATERNION" and stride != 8, "QUATERNION needs a byteStride of 8"),
             (filt == "EXPONENTIAL" and stride % 4, "EXPONENTIAL needs a byteStride divisible by 4")]
    for broken, rule in rules:
        if broken:
            raise doc.err(f"{what}: {rule} (byteStride {stride}, count {count}, filter {filt})")
    doc.meshopt_views.add(v)


def validate_primitive(doc, what: str, prim: dict) -> None:
    """KHR_draco_mesh_compression on a primitive: its bufferView and attribute map; registers the
    accessors it replaces for `Document.accessor`."""
    ext = (prim.get("extensions") or {}).get(DRACO)
    if ext is None:
        return
    where = f"{what} {DRACO}"
    if not isinstance(ext, dict):
        raise doc.err(f"{where} must be an object")
    doc.get("bufferViews", ext.get("bufferView"), where)
    attrs = ext.get("attributes")
    if not isinstance(attrs, dict):
        raise doc.err(f"{where} has no attributes object")
    for name, uid in attrs.items():
        if name not in prim["attributes"]:
            raise doc.err(f"{where}: attribute {name} is not one of the primitive's attributes")
        if not isinstance(uid, int) or isinstance(uid, bool) or uid < 0:
            raise doc.err(f"{where}: attribute {name} needs a non-negative integer id, got {uid!r}")
    if prim.get("mode", 4) not in (0, 4):
        raise doc.err(f"{where}: only TRIANGLES (and POINTS) primitives can be Draco-compressed, "
                      f"mode is {prim.get('mode')}")
    for name in attrs:
        doc.draco_accessors[prim["attributes"][name]] = (what, prim)
    if "indices" in prim:
        doc.draco_accessors[prim["indices"]] = (what, prim)


# -- decoding -------------------------------------------------------------------------------------------
def draco_accessor(doc, index: int) -> Optional[np.ndarray]:
    """Accessor `index` decoded from its primitive's Draco data (every accessor the primitive's Draco
    data replaces goes into the document's cache at once); None when DracoPy is missing and the
    accessor has uncompressed fallback data."""
    what, prim = doc.draco_accessors[index]
    if not available(DRACO) and "bufferView" in doc.json["accessors"][index]:
        return None
    draco = _decoder(doc, DRACO, what)
    ext = prim["extensions"][DRACO]
    v = ext["bufferView"]
    where = f"{what}: the {DRACO} data (bufferView {v})"
    # the decoded arrays are the accessors' sizes (checked against them after decoding): their
    # counts are charged to the load's memory budget before DracoPy allocates anything
    filled = {prim["attributes"][n] for n in ext["attributes"]}
    filled |= {prim["indices"]} if "indices" in prim else set()
    budget.current().charge(sum(accessor_bytes(doc.json["accessors"][a]) for a in filled), doc.path,
                            f"{where}: the counts of accessors {sorted(filled)}")
    data = bytes(doc.view_bytes(v))
    if not data.startswith(b"DRACO"):       # what DracoPy checks too; a clearer message
        raise doc.err(f"{where} is not Draco data (no 'DRACO' header)")
    try:
        mesh = draco.decode(data)
    except Exception as exc:                # DracoPy raises its own exception types
        raise doc.err(f"{where} cannot be decoded ({type(exc).__name__}: {exc})") from None
    for name, uid in ext["attributes"].items():
        a = prim["attributes"][name]
        attribute = mesh.get_attribute_by_unique_id(uid)
        if attribute is None:
            raise doc.err(f"{where} has no attribute with unique id {uid} for {name} (accessor {a})")
        _store(doc, where, f"{name} (accessor {a})", a, np.asarray(attribute["data"]))
    if "indices" in prim:
        faces = getattr(mesh, "faces", None)
        if faces is None:
            raise doc.err(f"{where} is a point cloud, but the primitive has indices (accessor {prim['indices']})")
        _store(doc, where, f"indices (accessor {prim['indices']})", prim["indices"],
               np.asarray(faces).reshape(-1, 1))
    if index not in doc._accessor_cache:    # a shared accessor another primitive's Draco data filled
        raise doc.err(f"{where} did not produce accessor {index}")
    return doc._accessor_cache[index]


def _store(doc, where: str, label: str, a: int, data: np.ndarray) -> None:
    """Decoded `data` as glTF accessor `a` (its componentType, type, count and normalized flag)."""
    acc = doc.json["accessors"][a]
    dtype, ncomp, count = np.dtype(COMPONENT_TYPES[acc["componentType"]]), TYPE_SIZES[acc["type"]], acc["count"]
    data = data.reshape(len(data), -1) if data.ndim != 2 else data
    if data.shape != (count, ncomp):
        raise doc.err(f"{where} decodes {label} to {data.shape[0]} x {data.shape[1]} values, but the accessor "
                      f"is {count} x {acc['type']}")
    if dtype.kind in "iu":
        if data.dtype.kind == "f":
            raise doc.err(f"{where} decodes {label} to floats, but the accessor is {dtype.name}")
        info = np.iinfo(dtype)
        if data.size and (data.min() < info.min or data.max() > info.max):
            raise doc.err(f"{where} decodes {label} to values outside the accessor's {dtype.name} range")
    doc.store_accessor(a, data.astype(dtype))


def meshopt_view(doc, index: int) -> Optional[memoryview]:
    """bufferView `index` decoded from its EXT_meshopt_compression data (cached); None when
    meshoptimizer is missing and the view's own buffer has the uncompressed data."""
    if index in doc._view_cache:
        return doc._view_cache[index]
    view = doc.json["bufferViews"][index]
    what = f"bufferView {index}"
    if not available(MESHOPT) and view["buffer"] not in doc.placeholder_buffers:
        return None
    meshopt = _decoder(doc, MESHOPT, what)
    ext = view["extensions"][MESHOPT]
    off, length = ext.get("byteOffset", 0), ext["byteLength"]
    count, stride, mode, filt = ext["count"], ext["byteStride"], ext["mode"], ext.get("filter", "NONE")
    # count x byteStride decoded bytes (plus the decoder's own copy) from a few compressed ones
    budget.current().charge(2 * count * stride, doc.path,
                            f"bufferViews[{index}].extensions.{MESHOPT}.count ({count} x byteStride {stride})")
    src = bytes(memoryview(doc.buffers[ext["buffer"]])[off:off + length])
    try:
        if count == 0:
            out = b""
        elif mode == "ATTRIBUTES":
            raw = np.ascontiguousarray(meshopt.decode_vertex_buffer(count, stride, src)).view(np.uint8).reshape(-1)
            if filt != "NONE":
                apply = {"OCTAHEDRAL": meshopt.decode_filter_oct, "QUATERNION": meshopt.decode_filter_quat,
                         "EXPONENTIAL": meshopt.decode_filter_exp}[filt]
                raw = apply(raw, count, stride)
            out = raw.tobytes()
        else:
            # the bitstreams do not depend on the index size: decode to 32 bits, then narrow
            decode = meshopt.decode_index_buffer if mode == "TRIANGLES" else meshopt.decode_index_sequence
            idx = decode(count, 4, src)
            if stride == 2 and idx.size and idx.max() > 0xFFFF:
                raise RuntimeError("an index does not fit the 16-bit byteStride")
            out = idx.astype("<u2" if stride == 2 else "<u4").tobytes()
    except (RuntimeError, ValueError) as exc:
        raise doc.err(f"{what}: the {MESHOPT} data ({mode}, buffer {ext['buffer']}) cannot be decoded "
                      f"({exc})") from None
    if len(out) != view["byteLength"]:
        raise doc.err(f"{what}: the {MESHOPT} data decoded to {len(out)} bytes, not {view['byteLength']}")
    doc._view_cache[index] = memoryview(out)
    return doc._view_cache[index]
