"""An independent glTF reader (json + numpy) for the loader tests: the JSON read with `json`,
accessors with numpy, node matrices from TRS, so a loaded Scene is compared against the file's own
data, not against clrender's document reader.

    raw = RawGltf(path)
    check_against_raw(load_scene(path), raw)     # positions, normals, uvs, triangles in load order
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

_CT = {5120: "<i1", 5121: "<u1", 5122: "<i2", 5123: "<u2", 5125: "<u4", 5126: "<f4"}
_NC = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT4": 16}


class RawGltf:
    def __init__(self, path: Path):
        self.path = path
        self.j = json.loads(path.read_text())
        self.buffers = [(path.parent / b["uri"]).read_bytes() for b in self.j["buffers"]]

    def accessor(self, i: int) -> np.ndarray:
        a = self.j["accessors"][i]
        v = self.j["bufferViews"][a["bufferView"]]
        dt = np.dtype(_CT[a["componentType"]])
        n = _NC[a["type"]]
        elem = dt.itemsize * n
        stride = v.get("byteStride", elem)
        base = v.get("byteOffset", 0) + a.get("byteOffset", 0)
        buf = self.buffers[v["buffer"]]
        rows = [np.frombuffer(buf, dt, n, base + k * stride) for k in range(a["count"])] if stride != elem \
            else [np.frombuffer(buf, dt, n * a["count"], base)]
        return np.concatenate(rows).reshape(a["count"], n)

    def local_matrix(self, node: dict) -> np.ndarray:
        if "matrix" in node:
            return np.array(node["matrix"], np.float64).reshape(4, 4).T
        t = np.eye(4)
        t[:3, 3] = node.get("translation", [0, 0, 0])
        q = np.array(node.get("rotation", [0, 0, 0, 1]), np.float64)
        x, y, z, w = q / np.linalg.norm(q)                 # file quaternions are unit to ~1e-7 only
        r = np.eye(4)
        r[:3, :3] = [[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]]
        s = np.diag([*node.get("scale", [1, 1, 1]), 1.0])
        return t @ r @ s

    def instances(self):
        """(node index, world matrix) of every node of the default scene, depth-first pre-order."""
        out = []

        def walk(n, parent):
            world = parent @ self.local_matrix(self.j["nodes"][n])
            out.append((n, world))
            for c in self.j["nodes"][n].get("children", []):
                walk(c, world)

        for root in self.j["scenes"][self.j.get("scene", 0)]["nodes"]:
            walk(root, np.eye(4))
        return out

    def expected(self):
        """Concatenated world positions, normals (or None per primitive), uvs, triangles in load order."""
        pos, nrm, uvs, tris, offset = [], [], [], [], 0
        for n, world in self.instances():
            node = self.j["nodes"][n]
            if "mesh" not in node:
                continue
            for prim in self.j["meshes"][node["mesh"]]["primitives"]:
                attrs = prim["attributes"]
                p = self.accessor(attrs["POSITION"]).astype(np.float64)
                pos.append(p @ world[:3, :3].T + world[:3, 3])
                if "NORMAL" in attrs:
                    q = self.accessor(attrs["NORMAL"]).astype(np.float64) @ np.linalg.inv(world[:3, :3])
                    nrm.append(q / np.linalg.norm(q, axis=1, keepdims=True))
                else:
                    nrm.append(None)
                uvs.append(self.accessor(attrs["TEXCOORD_0"]) if "TEXCOORD_0" in attrs else None)
                idx = self.accessor(prim["indices"]).reshape(-1, 3).astype(np.int64)
                if np.linalg.det(world[:3, :3]) < 0:
                    idx = idx[:, [0, 2, 1]]
                tris.append(idx + offset)
                offset += len(p)
        return pos, nrm, uvs, tris


def check_against_raw(scene, raw: RawGltf):
    pos, nrm, uvs, tris = raw.expected()
    assert scene.triangle_count == sum(len(t) for t in tris)
    np.testing.assert_allclose(scene.positions, np.concatenate(pos), rtol=1e-6, atol=1e-6)
    np.testing.assert_array_equal(scene.triangles, np.concatenate(tris))
    start = 0
    for p, n, uv in zip(pos, nrm, uvs):
        sl = slice(start, start + len(p))
        if n is not None:
            np.testing.assert_allclose(scene.normals[sl], n, rtol=0, atol=2e-7)
        if uv is not None:
            # exactly the file's TEXCOORD_0 (glTF convention, no flip)
            np.testing.assert_array_equal(scene.uvs[sl], uv)
        start += len(p)
