"""Validating a read glTF `Document` (clrender.loaders.gltf.document), part by part, and the checked
getters that validation and the assembly share.

`validate(doc)` loads the buffers and checks every index, range and type the loader relies on, in
file order of the parts: the asset and extensionsRequired, buffers, buffer views, accessors,
meshes (attribute formats: `spec.ATTRIBUTE_FORMATS`, TEXCOORD sets the materials read), names,
nodes / scenes / KHR_lights_punctual lights, then textures, samplers, images and materials. Any
malformed input becomes a SceneError naming the file, never a KeyError.
"""
from __future__ import annotations

import base64
import binascii
import itertools
from typing import TYPE_CHECKING
from urllib.parse import unquote

import numpy as np

from clrender.scene.model import SceneError
from clrender.loaders import budget, confine
from clrender.loaders.gltf import compression
from clrender.loaders.gltf.surface import layer_texture, layer_textures
from clrender.loaders.gltf.spec import (
    ATTRIBUTE_FORMATS, COMPONENT_NAMES, COMPONENT_TYPES, FLOAT_ATTRIBUTES, INTS_8_16, LIGHT_TYPES, MODE_FAN,
    MODE_STRIP, MODE_TRIANGLES, QUANTIZED_FORMATS, SUPPORTED_EXTENSIONS, TEXTURE_INFOS, TYPE_SIZES, WRAP_MODES,
    accessor_bytes, accessor_field, attribute_kind, attribute_sets)

if TYPE_CHECKING:                       # annotations only: document.py imports this module
    from clrender.loaders.gltf.document import Document


def validate(doc: Document) -> None:
    """Load the buffers and check every index, range and type the loader relies on; any
    malformed input becomes a SceneError naming the file."""
    try:
        for part in (_check_asset, _load_buffers, _check_views, _check_accessors, _check_meshes, _check_names,
                     _check_nodes, _check_materials):
            part(doc)
    except SceneError:
        raise
    except (KeyError, TypeError, ValueError, AttributeError, IndexError) as exc:
        detail = f"missing property {exc}" if isinstance(exc, KeyError) else f"{type(exc).__name__}: {exc}"
        raise doc.err(f"malformed glTF ({detail})") from None


def _check_asset(doc: Document) -> None:
    """asset.version (2.x) and extensionsRequired (only SUPPORTED_EXTENSIONS)."""
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


def _load_buffers(doc: Document) -> None:
    """Every buffer's bytes (GLB chunk, data URI or a confined file), byteLength checked."""
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


def _check_views(doc: Document) -> None:
    """bufferViews inside their buffers, byteStride per the schema."""
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


def _check_accessors(doc: Document) -> None:
    """componentType, type, count (against the budget) and ranges, sparse ones too."""
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


def _check_meshes(doc: Document) -> None:
    """Primitives: attributes and their formats and counts, modes, materials, indices."""
    accessors = doc.list("accessors")
    quantized = compression.QUANTIZATION in (doc.json.get("extensionsUsed") or [])
    formats = {**ATTRIBUTE_FORMATS, **QUANTIZED_FORMATS} if quantized else ATTRIBUTE_FORMATS

    def accessor_ref(index, what):
        return doc.get("accessors", index, what)

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


def _check_names(doc: Document) -> None:
    """Names become mesh, object and material names (paths joined with "/", fnmatch patterns): strings only."""
    for key in ("nodes", "meshes", "materials", "cameras", "animations", "skins", "textures", "images", "scenes"):
        for i, item in enumerate(doc.list(key)):
            if isinstance(item, dict) and "name" in item and not isinstance(item["name"], str):
                raise doc.err(f"{key}[{i}].name must be a string, got {type(item['name']).__name__}")


def _check_nodes(doc: Document) -> None:
    """Nodes, scenes, cameras and KHR_lights_punctual lights."""
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


def _check_materials(doc: Document) -> None:
    """Textures -> samplers / images, and materials (textureInfos, alphaMode)."""
    for t, tex in enumerate(doc.list("textures")):
        if "sampler" in tex:
            sampler = doc.get("samplers", tex["sampler"], f"texture {t}")
            for key in ("wrapS", "wrapT"):
                if key in sampler and sampler[key] not in WRAP_MODES:
                    raise doc.err(f"sampler {tex['sampler']}: unknown {key} {sampler[key]!r}")
        src = compression.texture_source(tex, doc, f"texture {t}")
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



def _int(value, what: str, doc: Document, minimum: int = 0) -> int:
    if not isinstance(value, int) or isinstance(value, bool) or value < minimum:
        raise doc.err(f"{what} must be an integer >= {minimum}, got {value!r}")
    return value



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
    validator's MESH_PRIMITIVE_TOO_FEW_TEXCOORDS is an error, not a warning). The surface
    extensions' textures too, where well-formed (a malformed one is dropped with a warning when the
    materials load: clrender.loaders.gltf.surface)."""
    mat = doc.get("materials", m, what)
    core = ((label, texcoord_of(doc, f"material {m} ({mat.get('name', '')!r}) {label}", info))
            for slot, label, info in material_textures(doc, m, mat))
    layers = ((label, tex["texcoord"]) for label, (tex, _) in
              ((label, layer_texture(info, len(doc.list("textures")))) for slot, label, info in layer_textures(mat))
              if tex["index"] >= 0)
    for label, k in itertools.chain(core, layers):
        if f"TEXCOORD_{k}" not in attrs:
            have = ", ".join(f"TEXCOORD_{n}" for n in attribute_sets(attrs, "TEXCOORD")) or "none"
            raise doc.err(f"{what}: material {m} ({mat.get('name', '')!r}) reads its {label} from TEXCOORD_{k}, "
                          f"which the primitive does not have (texture coordinate sets: {have})")


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

