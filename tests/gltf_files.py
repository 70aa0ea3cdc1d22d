"""Small synthetic glTF files for tests: quads (or any triangles) with the materials, textures and
vertex attributes a test needs, written to one .gltf with an embedded (data URI) buffer and PNG
images next to it.

    from gltf_files import primitive, write_gltf, QUAD_UVS
    path = write_gltf(tmp_path / "q.gltf",
                      primitives=[primitive(material=0, COLOR_0=colors, TEXCOORD_1=uv1)],
                      materials=[{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}],
                      images=[rgba])                       # one texture per image unless `textures`

Attribute arrays give the accessor: float32 (float64 is converted) -> FLOAT; uint8 / uint16 / int8 /
int16 -> that component type, `normalized: true` (except JOINTS_n); the type (VEC2/3/4, SCALAR) from
the column count. Indices: uint16 / uint32 (non-negative int64 becomes uint32).
"""
from __future__ import annotations

import base64
import json
from pathlib import Path
from typing import Callable, Optional

import numpy as np

# A unit quad in the z = 0 plane facing +Z, counter-clockwise seen from +Z.
QUAD_POSITIONS = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], np.float32)
QUAD_NORMALS = np.tile(np.array([0, 0, 1], np.float32), (4, 1))
# The image upright seen from +Z (glTF: v = 0 is the top row of the image): u along +X, v along -Y.
QUAD_UVS = np.array([[0, 1], [1, 1], [1, 0], [0, 0]], np.float32)
QUAD_INDICES = np.array([0, 1, 2, 0, 2, 3], np.uint16)

COMPONENT_TYPES = {np.dtype(np.int8): 5120, np.dtype(np.uint8): 5121, np.dtype(np.int16): 5122,
                   np.dtype(np.uint16): 5123, np.dtype(np.uint32): 5125, np.dtype(np.float32): 5126}
TYPES = {1: "SCALAR", 2: "VEC2", 3: "VEC3", 4: "VEC4", 16: "MAT4"}


def primitive(positions=QUAD_POSITIONS, indices=QUAD_INDICES, material: Optional[int] = None,
              mode: Optional[int] = None, normals=QUAD_NORMALS, uvs=QUAD_UVS, **attributes) -> dict:
    """A primitive description for `write_gltf`: POSITION, NORMAL (None: none), TEXCOORD_0 (None:
    none) and any other attribute as NAME=array; `targets=[{"POSITION": array}, ...]` adds morph
    targets; indices None: non-indexed."""
    targets = attributes.pop("targets", None)
    attrs = {"POSITION": positions, "NORMAL": normals, "TEXCOORD_0": uvs, **attributes}
    prim = {"attributes": {k: v for k, v in attrs.items() if v is not None}, "indices": indices}
    if material is not None:
        prim["material"] = material
    if mode is not None:
        prim["mode"] = mode
    if targets is not None:
        prim["targets"] = targets
    return prim


def write_gltf(path: Path, primitives: Optional[list] = None, materials: Optional[list] = None,
               images: Optional[list] = None, textures: Optional[list] = None, samplers: Optional[list] = None,
               nodes: Optional[list] = None, meshes: Optional[list] = None, edit: Optional[Callable] = None,
               **top_level) -> Path:
    """Write a glTF: one mesh of `primitives` (default: one plain quad) on node 0 (or `nodes`;
    `meshes` = several lists of primitives), `materials` as JSON, `images` as (H, W, 4) uint8 arrays
    saved as PNG (`<stem>_image<i>.png`), `textures` JSON (default: texture i = image i, no
    sampler), `samplers` JSON; `top_level` keys (animations, skins, extensionsUsed,
    extensionsRequired, ...) are copied into the document (an animation sampler's `input` /
    `output` given as an array becomes an accessor); `edit(doc)` may change it last."""
    import imageio.v3 as iio

    path = Path(path)
    blob, views, accessors = bytearray(), [], []

    def add(array, target=None, name="") -> int:
        a = np.ascontiguousarray(array)
        if a.dtype == np.float64:
            a = a.astype(np.float32)
        elif a.dtype == np.int64 and (not a.size or a.min() >= 0):
            a = a.astype(np.uint32)
        if a.ndim == 1:
            a = a[:, None]
        blob.extend(b"\0" * (-len(blob) % 4))
        view = {"buffer": 0, "byteOffset": len(blob), "byteLength": a.nbytes}
        if target:
            view["target"] = target
        views.append(view)
        blob.extend(a.tobytes())
        acc = {"bufferView": len(views) - 1, "componentType": COMPONENT_TYPES[a.dtype], "count": len(a),
               "type": TYPES[a.shape[1]]}
        if a.dtype.kind in "iu" and target == 34962 and not name.startswith("JOINTS_"):
            acc["normalized"] = True
        if name == "POSITION" and len(a):
            acc["min"], acc["max"] = a.min(0).tolist(), a.max(0).tolist()
        accessors.append(acc)
        return len(accessors) - 1

    def encode(prim: dict) -> dict:
        out = {k: v for k, v in prim.items() if k not in ("attributes", "indices", "targets")}
        out["attributes"] = {k: add(v, 34962, k) for k, v in prim["attributes"].items()}
        if prim.get("indices") is not None:
            out["indices"] = add(np.asarray(prim["indices"]).reshape(-1), 34963)
        if prim.get("targets") is not None:
            out["targets"] = [{k: add(v, 34962, k) for k, v in t.items()} for t in prim["targets"]]
        return out

    mesh_lists = meshes if meshes is not None else [primitives if primitives is not None else [primitive()]]
    doc = {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}],
           "nodes": nodes if nodes is not None else [{"mesh": 0}],
           "meshes": [{"name": f"mesh{i}", "primitives": [encode(p) for p in prims]}
                      for i, prims in enumerate(mesh_lists)]}
    if nodes is not None:
        children = {c for n in nodes for c in n.get("children", [])}
        doc["scenes"] = [{"nodes": [i for i in range(len(nodes)) if i not in children]}]
    if materials is not None:
        doc["materials"] = materials
    if images:
        doc["images"] = []
        for i, rgba in enumerate(images):
            name = f"{path.stem}_image{i}.png"
            iio.imwrite(path.parent / name, np.asarray(rgba, np.uint8))
            doc["images"].append({"uri": name})
        doc["textures"] = [{"source": i} for i in range(len(images))]
    if textures is not None:
        doc["textures"] = textures
    if samplers is not None:
        doc["samplers"] = samplers
    for anim in top_level.get("animations", []):   # sampler input/output arrays become accessors
        for sampler in anim.get("samplers", []):
            for key in ("input", "output"):
                if isinstance(sampler.get(key), np.ndarray):
                    sampler[key] = add(sampler[key])
    for skin in top_level.get("skins", []):         # inverse bind matrices (J, 4, 4) become a MAT4 accessor
        if isinstance(skin.get("inverseBindMatrices"), np.ndarray):
            m = np.asarray(skin["inverseBindMatrices"], np.float32).reshape(-1, 4, 4)
            skin["inverseBindMatrices"] = add(m.transpose(0, 2, 1).reshape(-1, 16))      # column-major
    doc.update(top_level)
    doc["accessors"], doc["bufferViews"] = accessors, views
    doc["buffers"] = [{"byteLength": len(blob),
                       "uri": "data:application/octet-stream;base64," + base64.b64encode(bytes(blob)).decode()}]
    if edit is not None:
        edit(doc)
    path.write_text(json.dumps(doc))
    return path
