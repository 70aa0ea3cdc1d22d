"""Skins and morph targets of a glTF document -> clrender.scene.deform.Deformer / Skin (for gltf.py).

What is read (glTF 2.0 §3.7.2.2, §3.7.3; the rules of posing are clrender/scene/deform.py's):

* a skin's `joints` and `inverseBindMatrices` (MAT4, identity when absent, at least one per joint);
* JOINTS_n / WEIGHTS_n for every set n a primitive has (unsigned byte/short joints; float or
  normalized unsigned byte/short weights), side by side: K = 4 x sets influences per vertex.
  Weights are renormalized to sum 1 per vertex (as three.js and Blender do); a file whose sums
  are off by more than 1e-3 is warned once (the loader's feature warnings);
* morph targets' POSITION, NORMAL and TANGENT deltas (sparse accessors included, the document's
  reader), `mesh.weights` as defaults and `node.weights` overriding them.

Bad input is a SceneError naming the mesh, primitive and accessor: a joint index past the skin's
joints, weights negative / non-finite / summing to 0, JOINTS_n without WEIGHTS_n, a morph target
whose vertex count is not the primitive's, default weights of the wrong length.
"""
from __future__ import annotations

from typing import Optional

import numpy as np

from clrender.scene.deform import Deformer, Skin, normalize_weights
from clrender.errors import SceneError
from clrender.loaders import budget
from clrender.scene.geometry import BAD_COORDINATES, bad_vertex, coordinates_text
from clrender.loaders.gltf.document import Document
from clrender.loaders.gltf.spec import attribute_sets

MORPH_ATTRIBUTES = ("POSITION", "NORMAL", "TANGENT")


def read_skins(doc: Document) -> list:
    """Every skin of the document as a Skin (joint nodes, inverse bind matrices)."""
    skins = []
    nodes = doc.list("nodes")
    for s, skin in enumerate(doc.list("skins")):
        what = f"skin {s}" + (f" ({skin['name']!r})" if skin.get("name") else "")
        joints = skin.get("joints")
        if not isinstance(joints, list) or not joints:
            raise doc.err(f"{what}: joints must be a non-empty array of node indices")
        for j in joints:
            if not isinstance(j, int) or isinstance(j, bool) or not 0 <= j < len(nodes):
                raise doc.err(f"{what}: joint {j!r} is not a node (there are {len(nodes)})")
        root = skin.get("skeleton")          # not needed to pose; still a node when given
        if root is not None and (not isinstance(root, int) or isinstance(root, bool) or not 0 <= root < len(nodes)):
            raise doc.err(f"{what}: skeleton {root!r} is not a node (there are {len(nodes)})")
        if "inverseBindMatrices" in skin:
            a = skin["inverseBindMatrices"]
            doc.get("accessors", a, f"{what} inverseBindMatrices")
            m = doc.accessor(a).astype(np.float64)
            if m.ndim != 2 or m.shape[1] != 16 or len(m) < len(joints):
                raise doc.err(f"{what}: inverseBindMatrices (accessor {a}) must hold a MAT4 per joint "
                              f"({len(joints)}), got shape {m.shape}")
            if not np.isfinite(m).all():
                raise doc.err(f"{what}: inverseBindMatrices (accessor {a}) has non-finite values")
            inverse_bind = m[: len(joints)].reshape(-1, 4, 4).transpose(0, 2, 1)     # column-major
        else:
            inverse_bind = np.tile(np.eye(4), (len(joints), 1, 1))
        skins.append(Skin(skin.get("name") or f"skin{s}", list(joints), inverse_bind))
    return skins


def influences(doc: Document, what: str, attrs: dict, count: int, n_joints: int, warn: dict) -> tuple:
    """(joints (V, K) int32, weights (V, K) float32 renormalized) of every JOINTS_n/WEIGHTS_n set."""
    sets = attribute_sets(attrs, "JOINTS")
    if sets != attribute_sets(attrs, "WEIGHTS"):
        raise doc.err(f"{what}: JOINTS_n and WEIGHTS_n sets must come in pairs, got JOINTS {sets} and "
                      f"WEIGHTS {attribute_sets(attrs, 'WEIGHTS')}")
    if not sets:
        raise doc.err(f"{what}: the node has a skin but the primitive has no JOINTS_0 / WEIGHTS_0")
    joints, weights = [], []
    for n in sets:
        for name, out in ((f"JOINTS_{n}", joints), (f"WEIGHTS_{n}", weights)):
            a = doc.accessor(attrs[name])
            if a.shape != (count, 4):
                raise doc.err(f"{what}: {name} (accessor {attrs[name]}) must be VEC4 with {count} entries, "
                              f"got shape {a.shape}")
            out.append(a)
        j = np.asarray(joints[-1])
        if j.dtype.kind not in "iu":
            raise doc.err(f"{what}: JOINTS_{n} (accessor {attrs[f'JOINTS_{n}']}) must be unsigned integers")
        if j.size and int(j.max()) >= n_joints:
            v = int(np.argmax((j >= n_joints).any(1)))
            raise doc.err(f"{what}: JOINTS_{n} (accessor {attrs[f'JOINTS_{n}']}) vertex {v} uses joint "
                          f"{int(j.max())}, but the skin lists {n_joints} joints")
    j = np.concatenate(joints, 1).astype(np.int32)
    try:
        w, off = normalize_weights(np.concatenate(weights, 1), f"{what} (WEIGHTS accessors "
                                   f"{', '.join(str(attrs[f'WEIGHTS_{n}']) for n in sets)})")
    except SceneError as exc:
        raise doc.err(str(exc)) from None
    if off:
        warn.setdefault("skin weights that do not sum to 1", "renormalized per vertex (as three.js and Blender do)")
    return j, w


def morph_targets(doc: Document, what: str, prim: dict, count: int) -> dict:
    """{attribute: (T, V, 3) float32 deltas or None} of the primitive's morph targets."""
    targets = prim.get("targets") or []
    if not isinstance(targets, list):
        raise doc.err(f"{what}: targets must be an array")
    out: dict = {a: None for a in MORPH_ATTRIBUTES}
    for a in MORPH_ATTRIBUTES:
        if not any(a in t for t in targets):
            continue
        # targets x vertices float32 deltas: a short list naming one accessor many times is a large array
        budget.current().charge(len(targets) * count * 12, doc.path,
                                f"{what}: {a} morph targets ({len(targets)} targets x {count} vertices)")
        deltas = np.zeros((len(targets), count, 3), np.float32)
        for k, target in enumerate(targets):
            if a not in target:
                continue
            acc = target[a]
            doc.get("accessors", acc, f"{what} morph target {k} {a}")
            d = doc.accessor(acc)
            if d.shape != (count, 3):
                raise doc.err(f"{what}: morph target {k} {a} (accessor {acc}) has shape {d.shape}, the primitive "
                              f"has {count} vertices (VEC3 each)")
            i = bad_vertex(d)          # deltas add to positions: the same bound (NaN, inf, beyond 1e30)
            if i >= 0:
                raise doc.err(f"{what}: morph target {k} {a} (accessors[{acc}]): vertex {i} is "
                              f"{coordinates_text(d[i])}: {BAD_COORDINATES.replace('vertex coordinates', 'deltas')}")
            deltas[k] = d
        out[a] = deltas
    return out


def default_weights(doc: Document, what: str, node: dict, mesh: dict, targets: int) -> np.ndarray:
    """node.weights, else mesh.weights, else zeros (T,)."""
    for owner, w in (("node", node.get("weights")), ("mesh", mesh.get("weights"))):
        if w is None:
            continue
        try:
            w = np.asarray(w, np.float64).reshape(-1)
        except (TypeError, ValueError):       # {"x": 1}, [[1], [2, 3]], strings: not numbers
            raise doc.err(f"{what}: {owner}.weights must be {targets} finite numbers (one per morph target), "
                          f"got {type(w).__name__}") from None
        if len(w) != targets or not np.isfinite(w).all():
            raise doc.err(f"{what}: {owner}.weights must be {targets} finite numbers (one per morph target), "
                          f"got {len(w)}")
        return w
    return np.zeros(targets)


def deformer(doc: Document, what: str, name: str, mesh_index: int, n: int, node: dict, mesh: dict, prim: dict,
             positions, normals, tangents: Optional[np.ndarray], skins: list, warn: dict) -> Deformer:
    """The Deformer of one primitive of node n (bind attributes in mesh space)."""
    count = len(positions)
    attrs = prim["attributes"]
    skin = node.get("skin", -1)
    if skin >= 0:
        joints, weights = influences(doc, what, attrs, count, len(skins[skin].joints), warn)
    else:
        joints, weights = np.zeros((count, 1), np.int32), np.ones((count, 1), np.float32)
    deltas = morph_targets(doc, what, prim, count)
    targets = len(prim.get("targets") or [])
    return Deformer(name, mesh_index, n, skin, np.asarray(positions, np.float64), np.asarray(normals, np.float64),
                    None if tangents is None else np.asarray(tangents, np.float64), joints, weights,
                    deltas["POSITION"], deltas["NORMAL"], deltas["TANGENT"],
                    default_weights(doc, what, node, mesh, targets))
