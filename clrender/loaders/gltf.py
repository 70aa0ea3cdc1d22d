"""glTF 2.0 (.gltf / .glb) -> Scene.

Geometry and the node hierarchy go through trimesh (`trimesh.load(..., force='scene')`); the
scene graph is flattened to world space by walking `scene.graph.nodes_geometry` and applying each
node's world matrix `scene.graph[node]` to positions and (inverse-transpose, renormalized) normals.
Everything trimesh gets wrong or loses is read from the glTF JSON and buffers directly:

* the file is validated first (JSON, GLB chunks, buffers, buffer views, accessor ranges, indices
  into every array), so bad input is a `SceneError` naming the file, never a trimesh traceback;
* trimesh is handed a copy of the JSON whose nodes are named ``n<node>`` and meshes ``m<mesh>``
  (so every trimesh geometry maps back to its glTF node / mesh / primitive), with camera
  references removed (trimesh 5.2 drops a camera node from its graph, mesh and children included)
  and with materials skipped (we read them from the JSON);
* triangle order is the glTF node traversal order (scene roots in order, depth-first, children in
  order; trimesh's own `nodes_geometry` order is reversed), then primitives in order, then faces in
  file order;
* TEXCOORD_0 is read from its accessor (trimesh flips v in float32, which is not invertible
  exactly, and drops uvs of primitives without a material), so `Scene.uvs` equals the file data;
* NORMAL comes from trimesh's cache of the file normals (process=False: no merging, no
  recomputation); primitives without NORMAL get area-weighted normals in world space;
* the camera is the first perspective camera in traversal order (orthographic ones are skipped).
"""
from __future__ import annotations

import base64
import binascii
import io
import json
import re
import struct
import warnings
from pathlib import Path
from typing import Optional
from urllib.parse import unquote

import numpy as np

from ..camera import Camera
from ..scene import Material, Scene, SceneError, Texture
from .common import (Piece, assemble, check_faces, decode_image, fail, load_images,
                     trimesh_load, trimesh_vertex_normals, world_piece)

COMPONENT_TYPES = {5120: "<i1", 5121: "<u1", 5122: "<i2", 5123: "<u2", 5125: "<u4", 5126: "<f4"}
TYPE_SIZES = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}
WRAP_MODES = {10497: "repeat", 33071: "clamp", 33648: "mirror"}
MODE_TRIANGLES, MODE_STRIP, MODE_FAN = 4, 5, 6
# required extensions whose absence changes geometry or textures: refuse the file
UNSUPPORTED_REQUIRED = {"KHR_draco_mesh_compression", "EXT_meshopt_compression", "KHR_texture_basisu",
                        "MSFT_texture_dds", "EXT_mesh_gpu_instancing", "KHR_mesh_quantization"}
GLB_MAGIC, GLB_JSON, GLB_BIN = 0x46546C67, 0x4E4F534A, 0x004E4942
# zfar absent (infinite projection): far = max(FAR_FROM_NEAR * znear, 2 * farthest scene corner)
FAR_FROM_NEAR = 1000.0


class _Doc:
    """A parsed and validated glTF document with its buffers in memory."""

    def __init__(self, path: Path):
        self.path = path
        self.base = path.parent
        self.json: dict = {}
        self.buffers: list[bytes] = []
        self.glb_bin: Optional[bytes] = None
        self._accessor_cache: dict[int, np.ndarray] = {}

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
        view = self.json["bufferViews"][index]
        start = view.get("byteOffset", 0)
        return memoryview(self.buffers[view["buffer"]])[start:start + view["byteLength"]]

    def accessor(self, index: int) -> np.ndarray:
        """(count, components) array; normalized integers become float32 per the spec."""
        if index in self._accessor_cache:
            return self._accessor_cache[index]
        acc = self.json["accessors"][index]
        dtype = np.dtype(COMPONENT_TYPES[acc["componentType"]])
        ncomp = TYPE_SIZES[acc["type"]]
        count = acc["count"]
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
        if acc.get("normalized") and dtype.kind in "iu":
            info = np.iinfo(dtype)
            arr = arr.astype(np.float32) / np.float32(info.max)
            if dtype.kind == "i":
                arr = np.maximum(arr, np.float32(-1.0))
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
def _read_document(path: Path) -> _Doc:
    doc = _Doc(path)
    try:
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
        doc.json = json.loads(text.decode("utf-8-sig") if isinstance(text, bytes) else text)
    except UnicodeDecodeError as exc:
        raise doc.err(f"the glTF JSON is not UTF-8 ({exc.reason} at byte {exc.start})") from None
    except json.JSONDecodeError as exc:
        raise doc.err(f"invalid glTF JSON: {exc.msg} (line {exc.lineno}, column {exc.colno})") from None
    if not isinstance(doc.json, dict):
        raise doc.err("the glTF JSON must be an object")
    return doc


def _read_glb(doc: _Doc, data: bytes) -> bytes:
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


def _validate(doc: _Doc) -> None:
    try:
        _validate_inner(doc)
    except SceneError:
        raise
    except (KeyError, TypeError, ValueError, AttributeError, IndexError) as exc:
        detail = f"missing property {exc}" if isinstance(exc, KeyError) else f"{type(exc).__name__}: {exc}"
        raise doc.err(f"malformed glTF ({detail})") from None


def _int(value, what: str, doc: _Doc, minimum: int = 0) -> int:
    if not isinstance(value, int) or isinstance(value, bool) or value < minimum:
        raise doc.err(f"{what} must be an integer >= {minimum}, got {value!r}")
    return value


def _validate_inner(doc: _Doc) -> None:
    j = doc.json
    version = str(j.get("asset", {}).get("version", ""))
    if not version.startswith("2"):
        raise doc.err(f"only glTF 2.0 is supported (asset.version is {version or 'missing'!r})")
    required = set(j.get("extensionsRequired", []) or [])
    bad = sorted(required & UNSUPPORTED_REQUIRED)
    if bad:
        raise doc.err(f"requires unsupported glTF extension(s): {', '.join(bad)}")

    # buffers
    for k, buf in enumerate(doc.list("buffers")):
        length = _int(buf.get("byteLength"), f"buffers[{k}].byteLength", doc)
        uri = buf.get("uri")
        if uri is None:
            if k == 0 and doc.glb_bin is not None:
                data = doc.glb_bin
            else:
                raise doc.err(f"buffer {k} has no uri (and there is no GLB binary chunk for it)")
        elif uri.startswith("data:"):
            data = _data_uri(doc, uri, f"buffer {k}")
        else:
            file = doc.base / unquote(uri)
            if not file.is_file():
                raise doc.err(f"buffer {k}: file not found: {file}")
            data = file.read_bytes()
        if len(data) < length:
            raise doc.err(f"buffer {k} ({uri or 'GLB chunk'}) has {len(data)} bytes, "
                          f"but its byteLength is {length}")
        doc.buffers.append(data[:length] if len(data) > length else data)

    # buffer views
    for v, view in enumerate(doc.list("bufferViews")):
        b = view.get("buffer")
        doc.get("buffers", b, f"bufferViews[{v}]")
        off = _int(view.get("byteOffset", 0), f"bufferViews[{v}].byteOffset", doc)
        length = _int(view.get("byteLength"), f"bufferViews[{v}].byteLength", doc)
        if off + length > len(doc.buffers[b]):
            raise doc.err(f"bufferView {v} (bytes {off}..{off + length}) runs past the end of buffer {b} "
                          f"({len(doc.buffers[b])} bytes)")
        if "byteStride" in view:
            _int(view["byteStride"], f"bufferViews[{v}].byteStride", doc, 1)

    # accessors
    for a, acc in enumerate(doc.list("accessors")):
        if acc.get("componentType") not in COMPONENT_TYPES:
            raise doc.err(f"accessor {a}: unknown componentType {acc.get('componentType')!r}")
        if acc.get("type") not in TYPE_SIZES:
            raise doc.err(f"accessor {a}: unknown type {acc.get('type')!r}")
        count = _int(acc.get("count"), f"accessors[{a}].count", doc)
        elem = np.dtype(COMPONENT_TYPES[acc["componentType"]]).itemsize * TYPE_SIZES[acc["type"]]
        if "bufferView" in acc:
            view = doc.get("bufferViews", acc["bufferView"], f"accessor {a}")
            _check_range(doc, f"accessor {a}", acc["bufferView"], view,
                         _int(acc.get("byteOffset", 0), f"accessors[{a}].byteOffset", doc),
                         view.get("byteStride") or elem, elem, count)
        sparse = acc.get("sparse")
        if sparse:
            n = _int(sparse.get("count"), f"accessors[{a}].sparse.count", doc)
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
            for name, want in (("NORMAL", "VEC3"), ("TEXCOORD_0", "VEC2")):
                if name in attrs:
                    acc = accessors[attrs[name]]
                    if acc["type"] != want:
                        raise doc.err(f"{what}: {name} must be {want}, got {acc['type']}")
                    if acc["count"] != nv:
                        raise doc.err(f"{what}: {name} has {acc['count']} entries but POSITION has {nv}")
            if "indices" in prim:
                idx = accessor_ref(prim["indices"], f"{what} indices")
                if idx["type"] != "SCALAR" or idx["componentType"] not in (5121, 5123, 5125):
                    raise doc.err(f"{what}: indices must be unsigned integer SCALARs")
                n = idx["count"]
            else:
                n = nv
            if mode == MODE_TRIANGLES and n % 3:
                raise doc.err(f"{what}: {n} indices is not a multiple of 3 for TRIANGLES")

    # nodes, scenes, cameras
    nodes = doc.list("nodes")
    for n, node in enumerate(nodes):
        if not isinstance(node, dict):
            raise doc.err(f"nodes[{n}] must be an object")
        if "mesh" in node:
            doc.get("meshes", node["mesh"], f"node {n}")
        if "camera" in node:
            doc.get("cameras", node["camera"], f"node {n}")
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
        src = _texture_source(tex)
        if src is not None:
            doc.get("images", src, f"texture {t}")
    for i, img in enumerate(doc.list("images")):
        if "bufferView" in img:
            doc.get("bufferViews", img["bufferView"], f"image {i}")
    for m, mat in enumerate(doc.list("materials")):
        info = mat.get("pbrMetallicRoughness", {}).get("baseColorTexture")
        if info is not None:
            doc.get("textures", info.get("index"), f"material {m} ({mat.get('name', '')!r}) baseColorTexture")
        mode = mat.get("alphaMode", "OPAQUE")
        if mode not in ("OPAQUE", "MASK", "BLEND"):
            raise doc.err(f"material {m}: unknown alphaMode {mode!r}")


def _check_range(doc, what, view_index, view, offset, stride, elem, count) -> None:
    length = view["byteLength"]
    if count and offset + (count - 1) * stride + elem > length:
        raise doc.err(f"{what}: {count} elements of {elem} bytes (stride {stride}) from byte {offset} "
                      f"run past the end of bufferView {view_index} ({length} bytes)")


def _data_uri(doc: _Doc, uri: str, what: str) -> bytes:
    head, _, payload = uri.partition(",")
    try:
        if head.endswith(";base64"):
            return base64.b64decode(payload, validate=False)
        return unquote(payload).encode("latin-1")
    except (binascii.Error, ValueError) as exc:
        raise doc.err(f"{what}: bad data URI ({exc})") from None


def _texture_source(tex: dict):
    if "source" in tex:
        return tex["source"]
    for ext in (tex.get("extensions") or {}).values():  # e.g. EXT_texture_webp
        if isinstance(ext, dict) and "source" in ext:
            return ext["source"]
    return None


# -- traversal --------------------------------------------------------------------------------------
def _traversal(doc: _Doc) -> list[int]:
    """Node indices of the default scene, depth-first pre-order, roots and children in file order."""
    scenes = doc.list("scenes")
    if not scenes:
        return []
    roots = scenes[doc.json.get("scene", 0)].get("nodes", [])
    nodes = doc.list("nodes")
    order, seen = [], set()
    stack = list(reversed(roots))
    while stack:
        n = stack.pop()
        if n in seen:
            raise doc.err(f"node {n} is reached twice: the glTF node hierarchy must be a tree")
        seen.add(n)
        order.append(n)
        stack.extend(reversed(nodes[n].get("children", [])))
    return order


def _triangle_primitives(mesh: dict) -> list[tuple[int, dict]]:
    """(index, primitive) of the primitives that are rendered: TRIANGLES and TRIANGLE_STRIP."""
    return [(p, prim) for p, prim in enumerate(mesh["primitives"])
            if prim.get("mode", MODE_TRIANGLES) in (MODE_TRIANGLES, MODE_STRIP)]


def _trimesh_scene(doc: _Doc):
    """trimesh's Scene for a renamed, triangles-only, material-less, camera-less copy of the document."""
    j = doc.json
    meshes = doc.list("meshes")
    header = {k: j[k] for k in ("asset", "scene", "scenes", "accessors", "bufferViews") if k in j}
    header["nodes"] = []
    for i, node in enumerate(doc.list("nodes")):
        keep = {k: v for k, v in node.items() if k in ("children", "matrix", "translation", "rotation", "scale")}
        # a node whose mesh has no triangle primitive would be left out of trimesh's graph,
        # children included: give it no mesh instead
        if "mesh" in node and _triangle_primitives(meshes[node["mesh"]]):
            keep["mesh"] = node["mesh"]
        header["nodes"].append(dict(keep, name=f"n{i}"))
    header["meshes"] = [{"name": f"m{i}", "primitives": [
        {"attributes": {a: prim["attributes"][a] for a in ("POSITION", "NORMAL") if a in prim["attributes"]},
         **{k: prim[k] for k in ("indices", "mode") if k in prim}}
        for _, prim in _triangle_primitives(mesh)]} for i, mesh in enumerate(meshes)]
    header["buffers"] = [{"uri": f"buffer{k}.bin", "byteLength": len(b)} for k, b in enumerate(doc.buffers)]
    resolver = {f"buffer{k}.bin": b for k, b in enumerate(doc.buffers)}
    stream = io.BytesIO(json.dumps(header).encode("utf-8"))
    return trimesh_load(stream, file_type="gltf", resolver=resolver, skip_materials=True,
                        process=False, where=doc.path)


def _primitive_names(doc: _Doc) -> dict[tuple[int, int], str]:
    """(mesh, primitive) -> trimesh geometry name, computed exactly as trimesh names them."""
    from trimesh.util import unique_name

    names: dict[str, None] = {}
    counts: dict = {}
    out = {}
    for i, mesh in enumerate(doc.list("meshes")):
        for p, _ in _triangle_primitives(mesh):
            name = unique_name(f"m{i}", names, counts=counts)
            names[name] = None
            out[(i, p)] = name
    return out


# -- materials and textures -----------------------------------------------------------------------------
def _materials(doc: _Doc) -> tuple[list[Material], list[Texture]]:
    images = doc.list("images")
    textures_json = doc.list("textures")
    samplers = doc.list("samplers")
    slots: dict[tuple, int] = {}
    jobs, names, wraps = [], [], []
    materials = []
    for m, mat in enumerate(doc.list("materials")):
        name = mat.get("name") or f"material{m}"
        pbr = mat.get("pbrMetallicRoughness", {}) or {}
        color = pbr.get("baseColorFactor", [1.0, 1.0, 1.0, 1.0])
        if len(color) != 4:
            raise doc.err(f"material {m} ({name!r}): baseColorFactor needs 4 numbers")
        tex_index = -1
        info = pbr.get("baseColorTexture")
        if info is not None:
            if info.get("texCoord", 0) != 0:
                warnings.warn(f"{doc.path}: material {name!r} uses TEXCOORD_{info['texCoord']} for its base "
                              f"color; only TEXCOORD_0 is loaded", stacklevel=3)
            if "KHR_texture_transform" in (info.get("extensions") or {}):
                warnings.warn(f"{doc.path}: material {name!r}: KHR_texture_transform is ignored", stacklevel=3)
            tex = textures_json[info["index"]]
            src = _texture_source(tex)
            if src is not None:
                sampler = samplers[tex["sampler"]] if "sampler" in tex else {}
                key = (src, WRAP_MODES[sampler.get("wrapS", 10497)], WRAP_MODES[sampler.get("wrapT", 10497)])
                if key not in slots:
                    slots[key] = len(jobs)
                    jobs.append(_image_job(doc, src, images[src]))
                    names.append(_image_name(images[src], src))
                    wraps.append(key[1:])
                tex_index = slots[key]
        materials.append(Material.from_metallic_roughness(
            name, color, pbr.get("metallicFactor", 1.0), pbr.get("roughnessFactor", 1.0),
            base_color_texture=tex_index,
            double_sided=bool(mat.get("doubleSided", False)),
            alpha_mode=mat.get("alphaMode", "OPAQUE"),
            alpha_cutoff=float(mat.get("alphaCutoff", 0.5))))
    pixels = load_images(jobs)
    textures = [Texture(n, rgba, ws, wt, srgb=True) for n, rgba, (ws, wt) in zip(names, pixels, wraps)]
    return materials, textures


def _image_name(img: dict, index: int) -> str:
    if img.get("name"):
        return str(img["name"])
    uri = img.get("uri", "")
    if uri and not uri.startswith("data:"):
        return unquote(uri).replace("\\", "/").rsplit("/", 1)[-1]
    return f"image{index}"


def _image_job(doc: _Doc, index: int, img: dict):
    where = f"{doc.path}: image {index}"
    if "bufferView" in img:
        data = bytes(doc.view_bytes(img["bufferView"]))
        return lambda: decode_image(data, where)
    uri = img.get("uri")
    if not uri:
        raise doc.err(f"image {index} has neither a uri nor a bufferView")
    if uri.startswith("data:"):
        data = _data_uri(doc, uri, f"image {index}")
        return lambda: decode_image(data, where)
    file = doc.base / unquote(uri)
    if not file.is_file():
        raise doc.err(f"texture file not found: {file} (image {index})")
    return lambda: decode_image(file, where)


# -- camera ------------------------------------------------------------------------------------------------
def _camera(doc: _Doc, order: list[int], tm_scene, scene: Scene) -> Optional[Camera]:
    nodes = doc.list("nodes")
    for n in order:
        if "camera" not in nodes[n]:
            continue
        cam = doc.json["cameras"][nodes[n]["camera"]]
        if cam.get("type") != "perspective" or "perspective" not in cam:
            continue  # orthographic cameras are ignored
        persp = cam["perspective"]
        try:
            matrix = np.asarray(tm_scene.graph[f"n{n}"][0], np.float64)
            eye = matrix[:3, 3]
            forward = -matrix[:3, 2]
            up = matrix[:3, 1]
            norm = np.linalg.norm(forward)
            znear = float(persp["znear"])
            zfar = persp.get("zfar")
            if zfar is None:
                lo, hi = scene.bounds().astype(np.float64)
                corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1])
                                    for z in (lo[2], hi[2])])
                reach = float(np.linalg.norm(corners - eye, axis=1).max()) if scene.triangle_count else 0.0
                zfar = max(FAR_FROM_NEAR * znear, 2.0 * reach)
            return Camera.look_at(eye, eye + forward / norm, up, np.degrees(float(persp["yfov"])),
                                  near=znear, far=float(zfar))
        except (KeyError, TypeError, ValueError, ZeroDivisionError, FloatingPointError) as exc:
            raise doc.err(f"camera {nodes[n]['camera']} (node {n}) is not usable: {exc}") from None
    return None


def _needs_own_reader(accessor: dict) -> bool:
    """trimesh ignores sparse data and the `normalized` flag: read those accessors ourselves."""
    return "sparse" in accessor or accessor.get("componentType") != 5126


# -- entry point -------------------------------------------------------------------------------------------
def load_gltf(path) -> Scene:
    path = Path(path)
    doc = _read_document(path)
    _validate(doc)
    order = _traversal(doc)
    materials, textures = _materials(doc)

    tm_scene = _trimesh_scene(doc)
    prim_names = _primitive_names(doc)
    parents = tm_scene.graph.transforms.parents
    node_re = re.compile(r"n(\d+)$")
    instances: dict[tuple[int, str], str] = {}
    for gnode in tm_scene.graph.nodes_geometry:
        match = node_re.match(gnode) or node_re.match(str(parents.get(gnode, "")))
        if match is None:
            raise doc.err(f"internal: cannot map trimesh node {gnode!r} back to a glTF node")
        _, gname = tm_scene.graph[gnode]
        instances[(int(match.group(1)), gname)] = gnode

    nodes_json, meshes_json = doc.list("nodes"), doc.list("meshes")
    accessors = doc.list("accessors")
    default_material = None
    pieces: list[Piece] = []
    for n in order:
        node = nodes_json[n]
        if "mesh" not in node:
            continue
        mi = node["mesh"]
        mesh = meshes_json[mi]
        prims = mesh["primitives"]
        node_name = node.get("name") or f"node{n}"
        mesh_name = mesh.get("name") or f"mesh{mi}"
        for p, prim in enumerate(prims):
            mode = prim.get("mode", MODE_TRIANGLES)
            what = f"mesh {mi} ({mesh_name!r}) primitive {p}"
            if mode not in (MODE_TRIANGLES, MODE_STRIP):
                if mode == MODE_FAN:  # trimesh does not read fans
                    warnings.warn(f"{path}: {what}: TRIANGLE_FAN primitives are not loaded", stacklevel=2)
                continue  # points and lines are not rendered
            gnode = instances.get((n, prim_names[(mi, p)]))
            if gnode is None:
                raise doc.err(f"internal: trimesh lost node {n} {what}")
            matrix, gname = tm_scene.graph[gnode]
            geom = tm_scene.geometry[gname]
            attrs = prim["attributes"]
            positions = np.asarray(geom.vertices, np.float64)
            faces = np.asarray(geom.faces, np.int64).reshape(-1, 3)
            nv = accessors[attrs["POSITION"]]["count"]
            if len(positions) != nv:
                raise doc.err(f"internal: trimesh returned {len(positions)} vertices for {what}, "
                              f"the POSITION accessor has {nv}")
            if _needs_own_reader(accessors[attrs["POSITION"]]):
                positions = doc.accessor(attrs["POSITION"]).astype(np.float64)
            check_faces(faces, nv, path, what)
            normals = None
            if "NORMAL" in attrs:
                normals = trimesh_vertex_normals(geom)
                if normals is None or _needs_own_reader(accessors[attrs["NORMAL"]]):
                    normals = doc.accessor(attrs["NORMAL"]).astype(np.float64)
            uvs = doc.accessor(attrs["TEXCOORD_0"]) if "TEXCOORD_0" in attrs else None
            if "material" in prim:
                mat = prim["material"]
            else:
                if default_material is None:
                    default_material = len(materials)
                    materials.append(Material.from_metallic_roughness(
                        "default", (1.0, 1.0, 1.0, 1.0), 1.0, 1.0, double_sided=False))
                mat = default_material
            name = f"{node_name}/{mesh_name}" + (f"/{p}" if len(prims) > 1 else "")
            pieces.append(world_piece(name, matrix, positions, faces, mat, normals, uvs))

    scene = assemble(pieces, materials, textures, str(path))
    scene.camera = _camera(doc, order, tm_scene, scene)
    return scene
