"""World matrices and triangles of a glTF document's mesh nodes, for clrender/loaders/gltf/assemble.py.

`NumpyGeometry` reads them straight from the accessors and the node JSON, repeating what trimesh
5.2's glTF loader and scene graph compute (the loader used trimesh until importing it, scipy and
networkx included, became most of a load's time), so the arrays are the same bit for bit:

* a node's edge matrix: `matrix` (column-major) or identity, times translation, times the rotation
  quaternion's matrix (trimesh.transformations.quaternion_matrix), times diag(scale), in that order;
* a node's world matrix: the edge matrices from its root down, plus an identity edge to a primitive
  when the mesh has several (triangle) primitives; a root's own edge is used as is, longer chains drop
  matrices within 1e-8 of identity and multiply the rest with np.linalg.multi_dot; then trimesh's
  fix_rigid (an almost-orthonormal 3x3, off by 1e-13 to 1e-5, is replaced by its SVD rotation).
  multi_dot of equal 4x4s multiplies from the right (A (B (C D))) after an O(n^3) search for that
  order: `_right_product` does the same multiplications without the search. That product cannot be
  extended from a parent to a child, so only chains of at most EXACT_CHAIN kept edges are trimesh's
  bit for bit; a node deeper than that gets its parent's product times its edge (equal up to float
  rounding, ~1e-15 relative per level), so any depth costs one 4x4 product per node (issue 34);
* faces: the indices as (-1, 3) int64, strips unrolled with every other triangle flipped, no
  indices: 0, 1, 2, ...; positions and normals: the accessors as float64.

`TrimeshGeometry` is the trimesh path (CLRENDER_GLTF_TRIMESH=1), kept as the reference the tests
compare with.
"""
from __future__ import annotations

import io
import json
import math
import os
import re

import numpy as np

from clrender.loaders.common import trimesh_load, trimesh_vertex_normals
from clrender.loaders.gltf.document import Document
from clrender.loaders.gltf.spec import MODE_STRIP, MODE_TRIANGLES

ENV_TRIMESH = "CLRENDER_GLTF_TRIMESH"
_EYE = np.eye(4)
_EPS = np.finfo(float).eps * 4.0
# chains of at most this many kept edges are multiplied as trimesh does, bit for bit (module doc)
EXACT_CHAIN = 32


def triangle_primitives(mesh: dict) -> list[tuple[int, dict]]:
    """(index, primitive) of the primitives that are rendered: TRIANGLES and TRIANGLE_STRIP."""
    return [(p, prim) for p, prim in enumerate(mesh["primitives"])
            if prim.get("mode", MODE_TRIANGLES) in (MODE_TRIANGLES, MODE_STRIP)]


def geometry_for(doc: Document, order: list[int]):
    if os.environ.get(ENV_TRIMESH, "0") == "1":
        return TrimeshGeometry(doc, order)
    return NumpyGeometry(doc, order)


# -- the numpy path ---------------------------------------------------------------------------------
def quaternion_matrix(wxyz) -> np.ndarray:
    """trimesh.transformations.quaternion_matrix bit for bit: the norm by numpy's dot as trimesh's, the
    rest the same IEEE operations on Python floats (four times faster on 4-vectors: deep chains)."""
    q = np.array(wxyz, dtype=np.float64).reshape((-1, 4))
    n = np.dot(q * q, [1.0] * 4)
    if n[0] < _EPS:
        return np.eye(4)
    s = math.sqrt(2.0 / float(n[0]))
    w, x, y, z = (float(v) * s for v in q[0])
    return np.array([[1.0 - y * y - z * z, x * y - z * w, x * z + y * w, 0.0],
                     [x * y + z * w, 1.0 - x * x - z * z, y * z - x * w, 0.0],
                     [x * z - y * w, y * z + x * w, 1.0 - x * x - y * y, 0.0],
                     [0.0, 0.0, 0.0, 1.0]])


def _then(m: np.ndarray, factor: np.ndarray) -> np.ndarray:
    """np.dot(m, factor); identity times an affine factor is the factor plus 0.0 (each entry's sum has
    a +0.0 product from the factor's last row, so -0.0 turns +0.0, as in the product), bit for bit."""
    return factor + 0.0 if m is _EYE else np.dot(m, factor)


def edge_matrix(node: dict) -> np.ndarray:
    m = np.array(node["matrix"], dtype=np.float64).reshape((4, 4)).T if "matrix" in node else _EYE
    if "translation" in node:
        t = np.eye(4)
        t[:3, 3] = node["translation"][:3]
        m = _then(m, t)
    if "rotation" in node:
        m = _then(m, quaternion_matrix(np.reshape(node["rotation"], 4)[[3, 0, 1, 2]]))
    if "scale" in node:
        m = _then(m, np.diag(np.concatenate((node["scale"], [1.0]))))
    return m


def fix_rigid(matrix: np.ndarray, max_deviance: float = 1e-5) -> np.ndarray:
    check = np.abs(np.dot(matrix[:3, :3], matrix[:3, :3].T) - _EYE[:3, :3]).max()
    if 1e-13 < check < max_deviance:
        u, _, v = np.linalg.svd(matrix[:3, :3])
        repaired = np.eye(4)
        repaired[:3, :3] = np.dot(u, v)
        repaired[:3, 3] = matrix[:3, 3]
        return repaired
    return matrix


def _kept(m: np.ndarray) -> bool:
    """trimesh drops edges within 1e-8 of identity from chains of two or more edges."""
    return bool(np.abs(m - _EYE).max() > 1e-8)


def _right_product(kept: list[np.ndarray]) -> np.ndarray:
    """np.linalg.multi_dot(kept) bit for bit for 4x4 matrices, in linear time: with equal shapes every
    order costs the same, and numpy's search keeps the first split, A (B (C ...)), for n = 3 too."""
    matrix = kept[-1]
    for m in reversed(kept[:-1]):
        matrix = np.dot(m, matrix)
    return matrix


def chain_matrix(edges: list[np.ndarray]) -> np.ndarray:
    """World matrix of a frame reached through `edges` from the scene's base frame (trimesh's)."""
    if len(edges) == 1:
        matrix = edges[0]
    else:
        kept = [m for m in edges if _kept(m)]
        matrix = _EYE if not kept else _right_product(kept)
    return fix_rigid(matrix)


def strip_faces(strip: np.ndarray) -> np.ndarray:
    blob = np.asarray(strip, np.int64).reshape(-1)
    tri = np.array([blob[:-2], blob[1:-1], blob[2:]], dtype=np.int64).T
    tri[1::2] = np.fliplr(tri[1::2])
    return tri


class NumpyGeometry:
    def __init__(self, doc: Document, order: list[int]):
        self.doc = doc
        nodes = doc.list("nodes")
        parent = {c: n for n in order for c in nodes[n].get("children", [])}
        self._root_edge: dict[int, np.ndarray] = {}     # a root's own edge (a one-edge chain is used as is)
        # node -> (count, cell): its kept edges from the root as a shared linked list, cell = (edge,
        # parent's cell), while count <= EXACT_CHAIN; O(1) memory per node whatever the depth
        self._chain: dict[int, tuple] = {}
        self._product: dict[int, np.ndarray] = {}       # deeper nodes: parent's product . edge
        for n in order:                       # pre-order: parents first
            edge = edge_matrix(nodes[n])
            keep = _kept(edge)
            p = parent.get(n)
            if p is None:
                self._root_edge[n] = edge
                self._chain[n] = (1, (edge, None)) if keep else (0, None)
            elif p in self._product:
                self._product[n] = np.dot(self._product[p], edge) if keep else self._product[p]
            elif not keep:
                self._chain[n] = self._chain[p]
            elif self._chain[p][0] < EXACT_CHAIN:
                count, cell = self._chain[p]
                self._chain[n] = (count + 1, (edge, cell))
            else:                             # one past the exact bound: the parent's exact product . edge
                self._product[n] = np.dot(self._exact(p), edge)

    def _exact(self, n: int) -> np.ndarray:
        """The raw (before fix_rigid) product of n's kept edges, as multi_dot: from the node up."""
        count, cell = self._chain[n]
        if count == 0:
            return _EYE
        matrix, cell = cell
        while cell is not None:
            edge, cell = cell
            matrix = np.dot(edge, matrix)
        return matrix

    def world(self, n: int, extra_edge: bool = False) -> np.ndarray:
        """chain_matrix of n's edges from its root (plus an identity edge to a primitive when
        `extra_edge`), in at most EXACT_CHAIN products (module doc)."""
        if n in self._product:
            return fix_rigid(self._product[n])
        if n in self._root_edge and not extra_edge:
            return fix_rigid(self._root_edge[n])
        return fix_rigid(self._exact(n))

    def node_matrix(self, n: int) -> np.ndarray:
        return self.world(n)

    def primitive(self, n: int, mesh_index: int, p: int, prim: dict):
        """(world matrix, positions float64, faces int64 (-1, 3), file normals float64 or None)."""
        doc, mesh = self.doc, self.doc.list("meshes")[mesh_index]
        several = len(triangle_primitives(mesh)) > 1
        matrix = self.world(n, extra_edge=several)
        attrs = prim["attributes"]
        positions = doc.accessor(attrs["POSITION"]).astype(np.float64)
        strip = prim.get("mode", MODE_TRIANGLES) == MODE_STRIP
        if "indices" in prim:
            indices = doc.accessor(prim["indices"]).reshape(-1)
        else:
            indices = np.arange(len(positions), dtype=np.int64)
        if strip:
            faces = strip_faces(indices)
        elif len(indices) % 3:
            raise doc.err(f"mesh {mesh_index} primitive {p}: {len(indices)} indices are not whole triangles")
        else:
            faces = np.asarray(indices, np.int64).reshape((-1, 3))
        normals = doc.accessor(attrs["NORMAL"]).astype(np.float64) if "NORMAL" in attrs else None
        return matrix, positions, faces, normals


# -- the trimesh path ---------------------------------------------------------------------------------
def _trimesh_scene(doc: Document):
    """trimesh's Scene for a renamed, triangles-only, material-less, camera-less copy of the document
    (nodes named n<node>, meshes m<mesh>: every trimesh geometry maps back to its node and primitive;
    trimesh 5.2 drops a camera node from its graph, mesh and children included)."""
    j = doc.json
    meshes = doc.list("meshes")
    header = {k: j[k] for k in ("asset", "scene", "scenes", "accessors", "bufferViews") if k in j}
    header["nodes"] = []
    for i, node in enumerate(doc.list("nodes")):
        keep = {k: v for k, v in node.items() if k in ("children", "matrix", "translation", "rotation", "scale")}
        # a node whose mesh has no triangle primitive would be left out of trimesh's graph,
        # children included: give it no mesh instead
        if "mesh" in node and triangle_primitives(meshes[node["mesh"]]):
            keep["mesh"] = node["mesh"]
        header["nodes"].append(dict(keep, name=f"n{i}"))
    header["meshes"] = [{"name": f"m{i}", "primitives": [
        {"attributes": {a: prim["attributes"][a] for a in ("POSITION", "NORMAL") if a in prim["attributes"]},
         **{k: prim[k] for k in ("indices", "mode") if k in prim}}
        for _, prim in triangle_primitives(mesh)]} for i, mesh in enumerate(meshes)]
    header["buffers"] = [{"uri": f"buffer{k}.bin", "byteLength": len(b)} for k, b in enumerate(doc.buffers)]
    resolver = {f"buffer{k}.bin": b for k, b in enumerate(doc.buffers)}
    stream = io.BytesIO(json.dumps(header).encode("utf-8"))
    return trimesh_load(stream, file_type="gltf", resolver=resolver, skip_materials=True,
                        process=False, where=doc.path)


def _primitive_names(doc: Document) -> dict[tuple[int, int], str]:
    """(mesh, primitive) -> trimesh geometry name, computed exactly as trimesh names them."""
    from trimesh.util import unique_name

    names: dict[str, None] = {}
    counts: dict = {}
    out = {}
    for i, mesh in enumerate(doc.list("meshes")):
        for p, _ in triangle_primitives(mesh):
            name = unique_name(f"m{i}", names, counts=counts)
            names[name] = None
            out[(i, p)] = name
    return out


class TrimeshGeometry:
    def __init__(self, doc: Document, order: list[int]):
        self.doc = doc
        self.tm_scene = _trimesh_scene(doc)
        self.prim_names = _primitive_names(doc)
        parents = self.tm_scene.graph.transforms.parents
        node_re = re.compile(r"n(\d+)$")
        self.instances: dict[tuple[int, str], str] = {}
        for gnode in self.tm_scene.graph.nodes_geometry:
            match = node_re.match(gnode) or node_re.match(str(parents.get(gnode, "")))
            if match is None:
                raise doc.err(f"internal: cannot map trimesh node {gnode!r} back to a glTF node")
            _, gname = self.tm_scene.graph[gnode]
            self.instances[(int(match.group(1)), gname)] = gnode

    def node_matrix(self, n: int) -> np.ndarray:
        return np.asarray(self.tm_scene.graph[f"n{n}"][0], np.float64)

    def primitive(self, n: int, mesh_index: int, p: int, prim: dict):
        doc = self.doc
        gnode = self.instances.get((n, self.prim_names[(mesh_index, p)]))
        if gnode is None:
            raise doc.err(f"internal: trimesh lost node {n} mesh {mesh_index} primitive {p}")
        matrix, gname = self.tm_scene.graph[gnode]
        geom = self.tm_scene.geometry[gname]
        attrs = prim["attributes"]
        accessors = doc.list("accessors")
        positions = np.asarray(geom.vertices, np.float64)
        faces = np.asarray(geom.faces, np.int64).reshape(-1, 3)
        nv = accessors[attrs["POSITION"]]["count"]
        if len(positions) != nv:
            raise doc.err(f"internal: trimesh returned {len(positions)} vertices for mesh {mesh_index} primitive "
                          f"{p}, the POSITION accessor has {nv}")
        if _needs_own_reader(accessors[attrs["POSITION"]]):
            positions = doc.accessor(attrs["POSITION"]).astype(np.float64)
        normals = None
        if "NORMAL" in attrs:
            normals = trimesh_vertex_normals(geom)
            if normals is None or _needs_own_reader(accessors[attrs["NORMAL"]]):
                normals = doc.accessor(attrs["NORMAL"]).astype(np.float64)
        return matrix, positions, faces, normals


def _needs_own_reader(accessor: dict) -> bool:
    """trimesh ignores sparse data and the `normalized` flag: read those accessors ourselves."""
    return "sparse" in accessor or accessor.get("componentType") != 5126
