"""Independent NumPy reference for glTF posing (skins and morph targets), written from the glTF 2.0
spec (§3.7.2.2 morph targets, §3.7.3 skins, Appendix C interpolation) for the tests. It reads the
file itself (JSON, buffers, accessors with strides, normalized integers and sparse data) and shares
no code with clrender: not its document reader, not its Animation, not clrender.scene.deform.

    ref = GltfReference(path)
    positions, normals, tangents = ref.pose(node, primitive, t)       # float64, world space

Rules (as the issue states them; clrender implements the same): morph then skin; weights
renormalized per vertex; skinned: the mesh node's own transform ignored; normals by the inverse
transpose of the blended 3x3, normalized; tangents by the blended 3x3, normalized, w kept
(a mesh without skin: the node's world matrix, w times the sign of its determinant).
"""
from __future__ import annotations

import base64
import json
from pathlib import Path

import numpy as np

_DTYPES = {5120: np.int8, 5121: np.uint8, 5122: np.int16, 5123: np.uint16, 5125: np.uint32, 5126: np.float32}
_COMPONENTS = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT4": 16}


class GltfReference:
    def __init__(self, path):
        self.path = Path(path)
        self.j = json.loads(self.path.read_text())
        self.buffers = []
        for b in self.j["buffers"]:
            uri = b["uri"]
            if uri.startswith("data:"):
                self.buffers.append(base64.b64decode(uri.split(",", 1)[1]))
            else:
                self.buffers.append((self.path.parent / uri).read_bytes())
        nodes = self.j["nodes"]
        self.parent = {c: i for i, n in enumerate(nodes) for c in n.get("children", [])}

    # -- accessors ----------------------------------------------------------------------------------
    def _view(self, index, offset, dtype, ncomp, count, stride=None):
        v = self.j["bufferViews"][index]
        data = self.buffers[v["buffer"]]
        base = v.get("byteOffset", 0) + offset
        item = np.dtype(dtype).itemsize * ncomp
        stride = stride or v.get("byteStride") or item
        out = np.empty((count, ncomp), dtype)
        for i in range(count):                   # element by element: independent of numpy striding tricks
            start = base + i * stride
            out[i] = np.frombuffer(data[start:start + item], dtype)
        return out

    def accessor(self, i) -> np.ndarray:
        a = self.j["accessors"][i]
        dtype, ncomp = _DTYPES[a["componentType"]], _COMPONENTS[a["type"]]
        if "bufferView" in a:
            out = self._view(a["bufferView"], a.get("byteOffset", 0), dtype, ncomp, a["count"])
        else:
            out = np.zeros((a["count"], ncomp), dtype)
        if "sparse" in a:
            s = a["sparse"]
            idx = self._view(s["indices"]["bufferView"], s["indices"].get("byteOffset", 0),
                             _DTYPES[s["indices"]["componentType"]], 1, s["count"])[:, 0]
            val = self._view(s["values"]["bufferView"], s["values"].get("byteOffset", 0), dtype, ncomp, s["count"])
            for k, v in zip(idx, val):
                out[int(k)] = v
        out = out.astype(np.float64)
        if a.get("normalized"):
            top = float(np.iinfo(dtype).max)
            out = np.maximum(out / top, -1.0)
        return out

    # -- animation ------------------------------------------------------------------------------------
    def _sample(self, sampler, t, rotation):
        times = self.accessor(sampler["input"])[:, 0]
        values = self.accessor(sampler["output"])
        interp = sampler.get("interpolation", "LINEAR")
        n = len(times)
        if interp == "CUBICSPLINE":
            values = values.reshape(n, 3, -1)
            key = lambda k: values[k, 1]          # noqa: E731
        else:
            values = values.reshape(n, -1)
            key = lambda k: values[k]             # noqa: E731
        if t <= times[0]:
            out = key(0)
        elif t >= times[-1]:
            out = key(n - 1)
        else:
            k = 0
            while times[k + 1] <= t:
                k += 1
            t0, t1 = times[k], times[k + 1]
            s = (t - t0) / (t1 - t0)
            if interp == "STEP":
                out = key(k)
            elif interp == "CUBICSPLINE":
                d = t1 - t0
                p0, b0 = values[k, 1], values[k, 2]
                p1, a1 = values[k + 1, 1], values[k + 1, 0]
                out = ((2 * s**3 - 3 * s**2 + 1) * p0 + (s**3 - 2 * s**2 + s) * d * b0
                       + (-2 * s**3 + 3 * s**2) * p1 + (s**3 - s**2) * d * a1)
            elif rotation:
                a, b = key(k) / np.linalg.norm(key(k)), key(k + 1) / np.linalg.norm(key(k + 1))
                c = float(a @ b)
                if c < 0:
                    b, c = -b, -c
                if c > 1 - 1e-12:
                    out = a + s * (b - a)
                else:
                    th = np.arccos(c)
                    out = (np.sin((1 - s) * th) * a + np.sin(s * th) * b) / np.sin(th)
            else:
                out = (1 - s) * key(k) + s * key(k + 1)
        out = np.asarray(out, np.float64)
        return out / np.linalg.norm(out) if rotation else out

    def _animated(self, t):
        """{(node, path): value} at time t, all animations together (a later channel wins)."""
        out = {}
        for anim in self.j.get("animations", []):
            for ch in anim["channels"]:
                tgt = ch["target"]
                if "node" not in tgt:
                    continue
                out[(tgt["node"], tgt["path"])] = self._sample(anim["samplers"][ch["sampler"]], t,
                                                               tgt["path"] == "rotation")
        return out

    def world(self, node, t, animated=None) -> np.ndarray:
        animated = self._animated(t) if animated is None else animated
        n = self.j["nodes"][node]
        if "matrix" in n:
            local = np.array(n["matrix"], np.float64).reshape(4, 4).T
        else:
            tr = animated.get((node, "translation"), np.array(n.get("translation", [0, 0, 0]), np.float64))
            q = animated.get((node, "rotation"), np.array(n.get("rotation", [0, 0, 0, 1]), np.float64))
            sc = animated.get((node, "scale"), np.array(n.get("scale", [1, 1, 1]), np.float64))
            x, y, z, w = q / np.linalg.norm(q)
            r = np.array([[w*w + x*x - y*y - z*z, 2*(x*y - w*z), 2*(x*z + w*y)],
                          [2*(x*y + w*z), w*w - x*x + y*y - z*z, 2*(y*z - w*x)],
                          [2*(x*z - w*y), 2*(y*z + w*x), w*w - x*x - y*y + z*z]])
            local = np.eye(4)
            local[:3, :3] = r @ np.diag(sc)
            local[:3, 3] = tr
        if node in self.parent:
            return self.world(self.parent[node], t, animated) @ local
        return local

    # -- posing -----------------------------------------------------------------------------------------
    def pose(self, node, prim_index, t):
        """(positions (V, 3), normals (V, 3), tangents (V, 4) or None) of node's mesh primitive at t
        (t None: the nodes' own transforms and default weights, no animation)."""
        n = self.j["nodes"][node]
        mesh = self.j["meshes"][n["mesh"]]
        prim = mesh["primitives"][prim_index]
        attrs = prim["attributes"]
        animated = {} if t is None else self._animated(t)
        p = self.accessor(attrs["POSITION"])
        nrm = self.accessor(attrs["NORMAL"]) if "NORMAL" in attrs else None
        tan = self.accessor(attrs["TANGENT"]) if "TANGENT" in attrs else None
        targets = prim.get("targets", [])
        if targets:
            w = animated.get((node, "weights"))
            if w is None:
                w = np.array(n.get("weights", mesh.get("weights", [0.0] * len(targets))), np.float64)
            for k, target in enumerate(targets):
                if "POSITION" in target:
                    p = p + w[k] * self.accessor(target["POSITION"])
                if "NORMAL" in target and nrm is not None:
                    nrm = nrm + w[k] * self.accessor(target["NORMAL"])
                if "TANGENT" in target and tan is not None:
                    tan = tan.copy()
                    tan[:, :3] += w[k] * self.accessor(target["TANGENT"])
        v = len(p)
        if "skin" in n:
            skin = self.j["skins"][n["skin"]]
            joints = skin["joints"]
            if "inverseBindMatrices" in skin:
                ibm = self.accessor(skin["inverseBindMatrices"]).reshape(-1, 4, 4).transpose(0, 2, 1)
            else:
                ibm = np.tile(np.eye(4), (len(joints), 1, 1))
            mats = np.array([self.world(jn, t, animated) @ ibm[i] for i, jn in enumerate(joints)])
            sets = sorted(int(a.split("_")[1]) for a in attrs if a.startswith("JOINTS_"))
            jj = np.concatenate([self.accessor(attrs[f"JOINTS_{s}"]) for s in sets], 1).astype(int)
            ww = np.concatenate([self.accessor(attrs[f"WEIGHTS_{s}"]) for s in sets], 1)
            ww = ww / ww.sum(1, keepdims=True)
            m = np.zeros((v, 4, 4))
            for k in range(jj.shape[1]):
                m += ww[:, k, None, None] * mats[jj[:, k]]
            rigid = False
        else:
            m = np.tile(self.world(node, t, animated), (v, 1, 1))
            rigid = True
        a = m[:, :3, :3]
        pos = np.einsum("vij,vj->vi", a, p) + m[:, :3, 3]
        normals = tangents = None
        if nrm is not None:
            nn = np.einsum("vji,vj->vi", np.linalg.inv(a), nrm)           # (A^-1)^T n
            normals = nn / np.linalg.norm(nn, axis=1, keepdims=True)
        if tan is not None:
            tt = np.einsum("vij,vj->vi", a, tan[:, :3])
            tt = tt / np.linalg.norm(tt, axis=1, keepdims=True)
            w = tan[:, 3] * (np.sign(np.linalg.det(a)) if rigid else 1.0)
            tangents = np.concatenate([tt, w[:, None]], 1)
        return pos, normals, tangents
