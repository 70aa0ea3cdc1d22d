"""Skins and morph targets (glTF 2.0 §3.7.2.2 morph targets, §3.7.3 skins): the bind-pose data of
every deformed mesh piece and the pose (joint matrices, morph weights) the device applies each frame
(kernels/pose.cl, clrender/passes/pose.py).

A deformed piece (a `Deformer`: one glTF node x primitive that has a skin or morph targets) keeps
its bind attributes in the mesh's own space; `Scene.positions` / `normals` / `tangents` hold the
pose at load (the nodes' rest transforms, the default weights), computed here in float64
(`Deformation.posed`), so bounds, the default camera and every host reader see real geometry.
Posing (`Scene.pose(t, dt)`) then only changes the pose *state*: the palette of joint matrices and
the morph weights at t and t - dt. The device pre-pass writes the posed positions, normals,
tangents and previous positions into the scene's buffers; the host arrays keep the load pose.

The rules (the same in pose.cl, in `posed` here and in the tests' independent NumPy reference):

1. morph (before skinning): p = p0 + sum_t w_t dP_t, n = n0 + sum_t w_t dN_t, t = t0 + sum_t w_t dT_t
   (xyz; w untouched);
2. skin: M = sum_k w_k J[j_k] with J[j] = world(joint j) . inverseBindMatrix[j] (a 3x4 affine
   matrix); the weights of a vertex are renormalized to sum 1 at load. A mesh with morph targets
   and no skin has one influence: its node's world matrix (the mesh node's transform, which a
   skinned mesh ignores, as the spec says);
3. position M (p, 1); normal normalize(M3^-T n), computed as sign(det M3) cof(M3) n (no inverse);
   tangent xyz normalize(M3 t), w kept for skins (the issue's rule: winding as stored, handedness
   kept) and times sign(det M3) for a rigid (node) transform, as a static mesh's; a zero-length
   result keeps the bind direction (normals) or stays zero (tangents).

Bounds: `bounds()` is conservative without posing a vertex: per (deformer, influence) the box of the
vertices it moves (morph deltas as intervals scaled by the current weights), its 8 corners through
the influence's matrix; a convex combination of points in those boxes lies in their union.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Optional

import numpy as np

from clrender.errors import SceneError

WEIGHT_SUM_TOLERANCE = 1e-3        # a file's weights off their sum 1 by more than this: warned once
MAX_PALETTE = 1 << 24              # joint matrices a scene may use (pose.cl indexes them with int)
_CHUNK = 1 << 16                   # host posing works on this many vertices at a time (memory)


@dataclass(eq=False)
class Skin:
    name: str
    joints: list                   # glTF node per joint
    inverse_bind: np.ndarray       # (J, 4, 4) float64


@dataclass(eq=False)
class Deformer:
    """One deformed piece: its bind attributes (mesh space) and influences."""
    name: str
    mesh: int                      # the scene mesh (piece) index: Scene.mesh_names
    node: int                      # the glTF node holding the mesh (its weights, its rigid transform)
    skin: int                      # index into Deformation.skins; -1: rigid (the node's world matrix)
    positions: np.ndarray          # (V, 3) float64 bind positions
    normals: np.ndarray            # (V, 3) float64
    tangents: Optional[np.ndarray]  # (V, 4) float64 or None (the scene has no tangents)
    joints: np.ndarray             # (V, K) int32 joint index within the skin (rigid: zeros)
    weights: np.ndarray            # (V, K) float32, each row sums to 1 (rigid: (1, 0, ...))
    target_positions: Optional[np.ndarray] = None   # (T, V, 3) float32 deltas or None
    target_normals: Optional[np.ndarray] = None
    target_tangents: Optional[np.ndarray] = None
    default_weights: np.ndarray = field(default_factory=lambda: np.zeros(0))   # (T,) at rest
    first: int = 0                 # first vertex in the scene arrays (set by Deformation.attach)

    @property
    def count(self) -> int:
        return len(self.positions)

    @property
    def targets(self) -> int:
        return len(self.default_weights)


class Deformation:
    """Every deformer of a scene, the skins, and the current pose state (see the module doc).

    rig: a clrender.scene.animation.Animation (possibly without channels) giving node world matrices.
    Palette layout: each skin's joints, then one slot per rigid deformer. Weights layout: each
    deformer's targets in deformer order."""

    def __init__(self, deformers: list, skins: list, rig, source: str = "<glTF>"):
        self.deformers, self.skins, self.rig, self.source = list(deformers), list(skins), rig, source
        offsets, n = [], 0
        for s in self.skins:
            offsets.append(n)
            n += len(s.joints)
        self.skin_offsets = offsets
        self.rigid_slot = {}
        for i, d in enumerate(self.deformers):
            if d.skin < 0:
                self.rigid_slot[i] = n
                n += 1
        self.palette_size = n
        if n > MAX_PALETTE:
            raise SceneError(f"{source}: {n} joint matrices, more than {MAX_PALETTE}")
        self.weight_offsets = np.cumsum([0] + [d.targets for d in self.deformers]).astype(np.int64)
        self.influences = max((d.joints.shape[1] for d in self.deformers), default=1)
        self.version = 0
        self.palette = self.previous_palette = None
        self.morph_weights = self.previous_morph_weights = None
        self._boxes = None
        self._bounds = None          # (version, bounds of that pose)
        self._joint_nodes = self._inverse_bind = None     # every skin's joints and matrices, stacked (state)

    # -- layout -----------------------------------------------------------------------------------
    @property
    def vertex_count(self) -> int:
        return sum(d.count for d in self.deformers)

    @property
    def meshes(self) -> set:
        return {d.mesh for d in self.deformers}

    def attach(self, mesh_first_vertex: dict) -> None:
        """Set each deformer's first scene vertex from {scene mesh: first vertex}."""
        for d in self.deformers:
            d.first = int(mesh_first_vertex[d.mesh])

    def palette_index(self, i: int) -> np.ndarray:
        """(V, K) int32 palette slots of deformer i's influences."""
        d = self.deformers[i]
        if d.skin < 0:
            return np.full(d.joints.shape, self.rigid_slot[i], np.int32)
        return (d.joints + self.skin_offsets[d.skin]).astype(np.int32)

    # -- pose state -------------------------------------------------------------------------------
    def state(self, world: dict, node_weights: dict) -> tuple:
        """(palette (P, 3, 4) float64, morph weights (W,) float64) for node world matrices `world`
        and animated weights {node: (T,)} (others: the deformer's default weights)."""
        palette = np.zeros((max(self.palette_size, 1), 3, 4))
        if self.skins:
            if self._joint_nodes is None:
                self._joint_nodes = [n for skin in self.skins for n in skin.joints]
                self._inverse_bind = np.concatenate([skin.inverse_bind for skin in self.skins])
            joints = np.stack([world[n] for n in self._joint_nodes])
            palette[: len(joints)] = np.einsum("jab,jbc->jac", joints[:, :3], self._inverse_bind)
        weights = np.zeros(max(int(self.weight_offsets[-1]), 1))
        for i, d in enumerate(self.deformers):
            if d.skin < 0:
                palette[self.rigid_slot[i]] = world[d.node][:3]
            w = node_weights.get(d.node, d.default_weights)
            weights[self.weight_offsets[i]:self.weight_offsets[i + 1]] = np.asarray(w, np.float64)[: d.targets]
        return palette, weights

    def set_pose(self, world: dict, node_weights: dict, previous_world: Optional[dict] = None,
                 previous_weights: Optional[dict] = None) -> None:
        """The pose the next render applies (previous: at t - dt, for the velocity AOV; None: no motion)."""
        self.palette, self.morph_weights = self.state(world, node_weights)
        if previous_world is None:
            self.previous_palette = self.previous_morph_weights = None
        else:
            self.previous_palette, self.previous_morph_weights = self.state(previous_world, previous_weights or {})
        self.version += 1

    def rest(self) -> None:
        """The pose at load: the nodes' rest transforms and default weights."""
        self.set_pose(self.rig.world_matrices(0.0, rest=True), {})

    # -- host posing (load pose, tests of the API) --------------------------------------------------
    def posed(self, i: int, palette: Optional[np.ndarray] = None, weights: Optional[np.ndarray] = None):
        """Deformer i posed on the host in float64: (positions, normals, tangents or None)."""
        d = self.deformers[i]
        palette = self.palette if palette is None else palette
        weights = self.morph_weights if weights is None else weights
        w = np.asarray(weights[self.weight_offsets[i]:self.weight_offsets[i + 1]], np.float64)
        slots = self.palette_index(i)
        rigid_sign = d.skin < 0
        out_p, out_n = np.empty((d.count, 3)), np.empty((d.count, 3))
        out_t = None if d.tangents is None else np.empty((d.count, 4))
        for a in range(0, d.count, _CHUNK):
            b = min(a + _CHUNK, d.count)
            p, n = d.positions[a:b].copy(), d.normals[a:b].copy()
            t = None if d.tangents is None else d.tangents[a:b].copy()
            for k in range(d.targets):
                if w[k] == 0.0:
                    continue
                if d.target_positions is not None:
                    p += w[k] * d.target_positions[k, a:b]
                if d.target_normals is not None:
                    n += w[k] * d.target_normals[k, a:b]
                if t is not None and d.target_tangents is not None:
                    t[:, :3] += w[k] * d.target_tangents[k, a:b]
            m = np.einsum("vk,vkij->vij", d.weights[a:b].astype(np.float64), palette[slots[a:b]])
            out_p[a:b] = np.einsum("vij,vj->vi", m[:, :, :3], p) + m[:, :, 3]
            c0, c1, c2 = m[:, :, 0], m[:, :, 1], m[:, :, 2]
            x12 = np.cross(c1, c2)
            det = np.einsum("vi,vi->v", c0, x12)
            nn = n[:, :1] * x12 + n[:, 1:2] * np.cross(c2, c0) + n[:, 2:3] * np.cross(c0, c1)
            nn *= np.where(det < 0, -1.0, 1.0)[:, None]
            length = np.linalg.norm(nn, axis=1, keepdims=True)
            bind_n = n / np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
            out_n[a:b] = np.where(length > 0, nn / np.where(length > 0, length, 1.0), bind_n)
            if t is not None:
                tt = np.einsum("vij,vj->vi", m[:, :, :3], t[:, :3])
                length = np.linalg.norm(tt, axis=1, keepdims=True)
                out_t[a:b, :3] = np.where(length > 0, tt / np.where(length > 0, length, 1.0), 0.0)
                out_t[a:b, 3] = t[:, 3] * (np.where(det < 0, -1.0, 1.0) if rigid_sign else 1.0)
        return out_p, out_n, out_t

    # -- conservative bounds -----------------------------------------------------------------------
    def _influence_boxes(self):
        """The boxes of every (deformer, palette slot) pair, stacked: (slots (B,), lo (B, 3), hi (B, 3),
        morphs [(first box, count, deformer index, morph lo (T, b, 3), morph hi (T, b, 3))]): the box of
        the bind vertices each slot moves (weight > 0), and of their position deltas per target."""
        if self._boxes is None:
            keys, los, his, morphs, b0 = [], [], [], [], 0
            for i, d in enumerate(self.deformers):
                slots = self.palette_index(i)
                used = d.weights > 0
                k = np.unique(slots[used])
                lo, hi = np.full((len(k), 3), np.inf), np.full((len(k), 3), -np.inf)
                t = d.targets if d.target_positions is not None else 0
                mlo, mhi = np.zeros((t, len(k), 3)), np.zeros((t, len(k), 3))
                for b, key in enumerate(k):
                    v = np.flatnonzero((used & (slots == key)).any(1))
                    lo[b], hi[b] = d.positions[v].min(0), d.positions[v].max(0)
                    if t:
                        mlo[:, b], mhi[:, b] = d.target_positions[:, v].min(1), d.target_positions[:, v].max(1)
                if t:
                    morphs.append((b0, len(k), i, mlo, mhi))
                keys.append(k)
                los.append(lo)
                his.append(hi)
                b0 += len(k)
            cat = (lambda xs, shape: np.concatenate(xs) if xs else np.zeros(shape))   # noqa: E731
            self._boxes = (cat(keys, (0,)).astype(np.int64), cat(los, (0, 3)), cat(his, (0, 3)), morphs)
        return self._boxes

    def bounds(self, palette: Optional[np.ndarray] = None, weights: Optional[np.ndarray] = None) -> np.ndarray:
        """(2, 3) float64 box containing every posed deformed vertex (module doc); the current
        pose's is computed once per pose (the pose pass asks every frame)."""
        if palette is None and weights is None:
            if self._bounds is None or self._bounds[0] != self.version:
                self._bounds = (self.version, self.bounds(self.palette, self.morph_weights))
            return self._bounds[1]
        keys, lo, hi, morphs = self._influence_boxes()
        if not len(keys):
            return np.stack([np.full(3, np.inf), np.full(3, -np.inf)])
        lo, hi = lo.copy(), hi.copy()
        for b0, count, i, mlo, mhi in morphs:           # the deltas as intervals scaled by the weights
            w = np.asarray(weights[self.weight_offsets[i]:self.weight_offsets[i + 1]], np.float64)[:, None, None]
            lo[b0:b0 + count] += np.minimum(w * mlo, w * mhi).sum(0)
            hi[b0:b0 + count] += np.maximum(w * mlo, w * mhi).sum(0)
        corners = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], np.float64)
        pts = lo[:, None, :] + corners[None] * (hi - lo)[:, None, :]              # (B, 8, 3)
        m = palette[keys]                                                        # (B, 3, 4)
        world = (np.einsum("bij,bcj->bci", m[:, :, :3], pts) + m[:, None, :, 3]).reshape(-1, 3)
        return np.stack([world.min(0), world.max(0)])


def normalize_weights(weights: np.ndarray, what: str) -> tuple[np.ndarray, bool]:
    """Rows renormalized to sum 1; (weights, whether any sum was off by > WEIGHT_SUM_TOLERANCE).
    SceneError for a negative or non-finite weight or a row summing to 0."""
    w = np.asarray(weights, np.float64)
    if not np.isfinite(w).all():
        raise SceneError(f"{what}: skin weights must be finite (vertex {int(np.argmax(~np.isfinite(w).all(1)))})")
    if (w < 0).any():
        raise SceneError(f"{what}: skin weights must not be negative (vertex {int(np.argmax((w < 0).any(1)))})")
    total = w.sum(1)
    if (total <= 0).any():
        raise SceneError(f"{what}: vertex {int(np.argmax(total <= 0))} has skin weights summing to 0")
    off = bool((np.abs(total - 1.0) > WEIGHT_SUM_TOLERANCE).any())
    return (w / total[:, None]).astype(np.float32), off
