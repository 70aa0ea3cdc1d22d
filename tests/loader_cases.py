"""Files and paths shared by the loader tests (test_loaders*.py): the repository's demo scenes and
their generator (scenes/make_demo.py), a PNG writer and a one-mesh glTF writer whose documents a
test may break (`edit`)."""
from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
SCENES = REPO / "scenes"


def make_demo_module():
    spec = importlib.util.spec_from_file_location("make_demo", SCENES / "make_demo.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def write_png(path: Path, rgba: np.ndarray):
    from PIL import Image
    Image.fromarray(rgba, "RGBA").save(path)


TRI_POS = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]], np.float32)
TRI_IDX = np.array([0, 1, 2, 2, 1, 3], np.uint16)


def write_gltf(path: Path, positions=TRI_POS, indices=TRI_IDX, normals=None, uvs=None, materials=None,
               nodes=None, prim_extra=None, edit=None, glb=False) -> Path:
    """A one-mesh glTF; `edit(doc)` may break it afterwards."""
    blob, views, accessors = bytearray(), [], []

    def add(array, kind, target):
        array = np.ascontiguousarray(array)
        blob.extend(b"\0" * (-len(blob) % 4))
        views.append({"buffer": 0, "byteOffset": len(blob), "byteLength": array.nbytes, "target": target})
        blob.extend(array.tobytes())
        ct = {np.float32: 5126, np.uint16: 5123, np.uint32: 5125}[array.dtype.type]
        accessors.append({"bufferView": len(views) - 1, "componentType": ct, "count": len(array), "type": kind})
        return len(accessors) - 1

    attrs = {"POSITION": add(positions, "VEC3", 34962)}
    if normals is not None:
        attrs["NORMAL"] = add(normals, "VEC3", 34962)
    if uvs is not None:
        attrs["TEXCOORD_0"] = add(uvs, "VEC2", 34962)
    prim = {"attributes": attrs, "indices": add(indices, "SCALAR", 34963), **(prim_extra or {})}
    doc = {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}],
           "nodes": nodes or [{"mesh": 0}], "meshes": [{"name": "tri", "primitives": [prim]}],
           "accessors": accessors, "bufferViews": views,
           "buffers": [{"uri": path.stem + ".bin", "byteLength": len(blob)}]}
    if materials is not None:
        doc["materials"] = materials
    if edit:
        edit(doc)
    if glb:
        demo = make_demo_module()
        for b in doc["buffers"]:
            b.pop("uri", None)
        path.write_bytes(demo.to_glb(doc, bytes(blob), path.parent))
    else:
        (path.parent / (path.stem + ".bin")).write_bytes(bytes(blob))
        path.write_text(json.dumps(doc))
    return path
