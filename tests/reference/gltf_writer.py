"""A minimal glTF 2.0 writer for synthetic test assets (tests/test_materials.py).

One mesh with one triangle-list primitive on one node (identity transform), a .bin buffer and
PNG images next to the .gltf. Everything the file says is given explicitly, so a test knows
what a correct loader must produce.

    write_gltf(path, positions, indices, normals=None, uvs=None, uvs1=None, colors=None,
               color_format="f4", tangents=None, material=None, images=(), samplers=(),
               textures=None, extensions_used=(), extensions_required=()) -> Path

`material` is the glTF material JSON (textureInfo `index` refer to `textures`); `images` are
(H, W, 4) or (H, W, 3) uint8 arrays written as PNG; `textures` defaults to one texture per image
with sampler 0 when `samplers` is given; `color_format` "f4" (float VEC4), "u1" / "u2"
(normalized unsigned byte / short VEC4), or "f4-vec3" (float VEC3).
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from PIL import Image

REPEAT, CLAMP, MIRROR = 10497, 33071, 33648
LINEAR, LINEAR_MIPMAP_LINEAR = 9729, 9987

_COMPONENT = {"f4": 5126, "u1": 5121, "u2": 5123, "u4": 5125}
_TYPE = {1: "SCALAR", 2: "VEC2", 3: "VEC3", 4: "VEC4"}


def write_gltf(path, positions, indices, normals=None, uvs=None, uvs1=None, colors=None, color_format="f4",
               tangents=None, material=None, images=(), samplers=(), textures=None, extensions_used=(),
               extensions_required=()) -> Path:
    path = Path(path)
    blob = bytearray()
    views, accessors = [], []

    def add(array, fmt, target, normalized=False, minmax=False):
        a = np.ascontiguousarray(array, np.dtype("<" + fmt))
        while len(blob) % 4:
            blob.append(0)
        views.append({"buffer": 0, "byteOffset": len(blob), "byteLength": a.nbytes, "target": target})
        blob.extend(a.tobytes())
        ncomp = 1 if a.ndim == 1 else a.shape[1]
        acc = {"bufferView": len(views) - 1, "componentType": _COMPONENT[fmt], "count": int(a.shape[0]),
               "type": _TYPE[ncomp]}
        if normalized:
            acc["normalized"] = True
        if minmax:
            acc["min"] = a.min(0).tolist()
            acc["max"] = a.max(0).tolist()
        accessors.append(acc)
        return len(accessors) - 1

    attrs = {"POSITION": add(np.asarray(positions, np.float32), "f4", 34962, minmax=True)}
    if normals is not None:
        attrs["NORMAL"] = add(np.asarray(normals, np.float32), "f4", 34962)
    if uvs is not None:
        attrs["TEXCOORD_0"] = add(np.asarray(uvs, np.float32), "f4", 34962)
    if uvs1 is not None:
        attrs["TEXCOORD_1"] = add(np.asarray(uvs1, np.float32), "f4", 34962)
    if tangents is not None:
        attrs["TANGENT"] = add(np.asarray(tangents, np.float32), "f4", 34962)
    if colors is not None:
        c = np.asarray(colors, np.float64)
        if color_format == "f4":
            attrs["COLOR_0"] = add(c.astype(np.float32), "f4", 34962)
        elif color_format == "f4-vec3":
            attrs["COLOR_0"] = add(c[:, :3].astype(np.float32), "f4", 34962)
        elif color_format in ("u1", "u2"):
            scale = 255 if color_format == "u1" else 65535
            q = np.floor(np.clip(c, 0, 1) * scale + 0.5).astype(np.uint8 if scale == 255 else np.uint16)
            attrs["COLOR_0"] = add(q, color_format, 34962, normalized=True)
        else:
            raise ValueError(f"unknown color_format {color_format!r}")
    idx = add(np.asarray(indices, np.uint32).reshape(-1), "u4", 34963)

    image_json = []
    for k, img in enumerate(images):
        name = f"{path.stem}_image{k}.png"
        arr = np.asarray(img, np.uint8)
        Image.fromarray(arr, "RGBA" if arr.shape[2] == 4 else "RGB").save(path.parent / name)
        image_json.append({"uri": name})
    if textures is None:
        textures = [({"source": k, "sampler": 0} if samplers else {"source": k}) for k in range(len(images))]

    bin_name = f"{path.stem}.bin"
    (path.parent / bin_name).write_bytes(bytes(blob))
    prim = {"attributes": attrs, "indices": idx, "mode": 4}
    doc = {
        "asset": {"version": "2.0", "generator": "clrender tests/reference/gltf_writer.py"},
        "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [prim]}],
        "buffers": [{"uri": bin_name, "byteLength": len(blob)}],
        "bufferViews": views, "accessors": accessors,
    }
    if material is not None:
        prim["material"] = 0
        doc["materials"] = [material]
    if image_json:
        doc["images"] = image_json
        doc["textures"] = list(textures)
    if samplers:
        doc["samplers"] = list(samplers)
    if extensions_used:
        doc["extensionsUsed"] = list(extensions_used)
    if extensions_required:
        doc["extensionsRequired"] = list(extensions_required)
    path.write_text(json.dumps(doc, indent=1))
    return path
