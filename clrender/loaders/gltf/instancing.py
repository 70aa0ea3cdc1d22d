"""EXT_mesh_gpu_instancing: a mesh node's per-instance TRANSLATION / ROTATION / SCALE accessors
(KhronosGroup/glTF, extensions/2.0/Vendor/EXT_mesh_gpu_instancing).

Spec: the attributes are optional and must all have the same count; TRANSLATION and SCALE are VEC3
FLOAT, ROTATION a VEC4 quaternion (x, y, z, w) of FLOAT or normalized BYTE / SHORT. The instance
matrix is Translation · Rotation · Scale (the order of a node's TRS), and a vertex lands at
NodeWorld · Instance · position (column vectors); the mesh itself is not drawn without an instance.

clrender expands the instances at load (clrender.loaders.gltf.assemble): each instance becomes its
own Scene meshes and its own object (`Frame.object_id`), named "<node>#<i>". Attributes whose names
start with "_" are application data (spec) and are not read.
"""
from __future__ import annotations

from typing import Optional

import numpy as np

from clrender.loaders.gltf.document import Document
from clrender.loaders.gltf.spec import SNORM_8_16

NAME = "EXT_mesh_gpu_instancing"
FLOAT = 5126
# attribute -> (accessor type, allowed (componentType, normalized))
ATTRIBUTES = {"TRANSLATION": ("VEC3", {(FLOAT, False)}),
              "ROTATION": ("VEC4", {(FLOAT, False)} | {f for f in SNORM_8_16}),
              "SCALE": ("VEC3", {(FLOAT, False)})}


def node_instances(doc: Document, n: int, node: dict, prims: list, features: dict) -> Optional[np.ndarray]:
    """EXT_mesh_gpu_instancing's (K, 4, 4) instance matrices of node `n`, or None: not instanced
    (no extension; a skinned or morphing node, drawn once with a warning: its pose runs on the
    device per node; no TRANSLATION/ROTATION/SCALE: drawn once)."""
    attrs = instance_extension(doc, n, node)
    if attrs is None:
        return None
    if "skin" in node or any(prim.get("targets") for prim in prims):
        features.setdefault(f"extension {NAME} on a skinned or morphing node",
                            f"drawn once, not instanced (first: node {n})")
        return None
    matrices = instance_matrices(doc, n, attrs)
    if matrices is None:
        features.setdefault(f"extension {NAME} without TRANSLATION, ROTATION or SCALE",
                            f"drawn once (first: node {n})")
    return matrices


def instance_extension(doc: Document, n: int, node: dict) -> Optional[dict]:
    """The node's EXT_mesh_gpu_instancing attributes {name: accessor}, or None when it has none."""
    ext = node.get("extensions")
    if not isinstance(ext, dict) or NAME not in ext:
        return None
    value = ext[NAME]
    attrs = value.get("attributes") if isinstance(value, dict) else None
    if not isinstance(attrs, dict):
        raise doc.err(f"node {n}: extensions.{NAME} needs an attributes object")
    return attrs


def instance_matrices(doc: Document, n: int, attrs: dict) -> Optional[np.ndarray]:
    """(K, 4, 4) float64 instance matrices T·R·S of node `n` (rotation quaternions normalized, a zero
    one is the identity, as for node rotations); None when no TRANSLATION/ROTATION/SCALE is given.
    A wrong accessor type, format or count is a SceneError naming the node and the attribute."""
    values, count = {}, None
    for name, (kind, formats) in ATTRIBUTES.items():
        if name not in attrs:
            continue
        what = f"node {n} {NAME} attribute {name}"
        acc = doc.get("accessors", attrs[name], what)
        fmt = (acc.get("componentType"), bool(acc.get("normalized", False)))
        if acc.get("type") != kind or fmt not in formats:
            raise doc.err(f"{what} (accessor {attrs[name]}) must be {kind} of FLOAT"
                          + (" or normalized BYTE/SHORT" if name == "ROTATION" else "")
                          + f", got {acc.get('type')} of componentType {fmt[0]}"
                          + (" normalized" if fmt[1] else ""))
        if count is not None and acc["count"] != count:
            raise doc.err(f"{what} has {acc['count']} entries, the other instance attributes {count} "
                          f"(the spec needs one count)")
        count = acc["count"]
        v = doc.accessor(attrs[name]).astype(np.float64)
        if not np.isfinite(v).all():
            raise doc.err(f"{what} (accessor {attrs[name]}) has non-finite values")
        values[name] = v
    if count is None:
        return None
    m = np.zeros((count, 4, 4))
    m[:, 3, 3] = 1.0
    m[:, :3, :3] = _rotations(values.get("ROTATION"), count) * values.get("SCALE", np.ones((count, 3)))[:, None, :]
    m[:, :3, 3] = values.get("TRANSLATION", np.zeros((count, 3)))
    return m


def volume_scales(world: np.ndarray, instances: Optional[np.ndarray] = None) -> np.ndarray:
    """SceneObject.volume_scale of a node drawn by its world matrix (shape (1,)), or of each of its
    instances, world · instance (shape (K,)): |det|^(1/3) of the 3x3, the factor by which the
    transform scales lengths on average (exact for a uniform scale; KHR_materials_volume's thickness is
    in mesh units and the node's transform applies to it). A transform that flattens the mesh (det 0)
    keeps 1: no length scale is meaningful there."""
    det = abs(float(np.linalg.det(np.asarray(world, np.float64)[:3, :3])))
    if instances is not None:
        det = det * np.abs(np.linalg.det(np.asarray(instances, np.float64)[:, :3, :3]))
    scale = np.cbrt(np.atleast_1d(det))
    return np.where(np.isfinite(scale) & (scale > 0), scale, 1.0)


def _rotations(q: Optional[np.ndarray], count: int) -> np.ndarray:
    """(K, 3, 3) rotation matrices of unit quaternions (x, y, z, w)."""
    if q is None:
        return np.tile(np.eye(3), (count, 1, 1))
    norm = np.linalg.norm(q, axis=1, keepdims=True)
    q = np.where(norm > 0, q / np.where(norm > 0, norm, 1.0), q)
    x, y, z, w = q.T
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], -1),
        np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], -1),
        np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], -1)], 1)
