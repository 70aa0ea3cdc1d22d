"""glTF node animation: translation / rotation / scale channels posed at a time t.

The loader (`clrender.loaders.gltf`, which reads the animations in clrender.loaders.gltf.animation)
keeps, for an animated file, one `Animation` on `Scene.animation` (None for static files and other
formats): every node's rest TRS (or matrix) and parent, the animation channels, which node each
Scene mesh piece hangs from (one piece per node x primitive, `Scene.mesh_names`), and which nodes
carry the camera and the KHR_lights_punctual lights.

API (posing in place, chosen over a `scene.at(t)` copy so that the geometry arrays, textures
and materials are shared and only the transforms change between frames)::

    previous = scene.pose(t, dt=1 / 24)         # == scene.animation.pose(scene, t, dt)
    frame = Renderer(w, h).render(scene, previous_camera=previous)

`pose(scene, t, dt=None)` places, at time t (seconds):

* every mesh under an animated node with `Scene.set_transform(mesh, W(t) @ B^-1, previous=W(t - dt)
  @ B^-1)`, W being its node's world matrix and B the matrix its vertices were built with at load
  (the rest world matrix), so the velocity AOV sees the objects' own motion over dt (no motion when
  dt is None). A posed matrix that is singular (a key with scale 0) is regularised: its singular
  values are raised to 1e-4 x the largest (1e-6 when all are 0), a practically invisible object;
* `scene.camera`, when its node (the loader's camera: the first camera in traversal order) is
  animated: eye = the node's world origin, looking down its -Z with its +Y up; projection kept;
* the point and spot lights of animated nodes (`scene.lights` position and direction = the
  transformed origin and -Z, as at load) and the sun (the first directional light: `scene.sun`
  and `settings["directional_lights"]` directions).

It returns the camera at t - dt (pass it as `previous_camera` for camera motion in the velocity
AOV), or None when dt is None. Posing is absolute: any t in any order gives the same result.

Sampling follows the glTF 2.0 spec (Appendix C): times before the first key clamp to the first
value, after the last to the last; LINEAR interpolates linearly, rotations by the spec's slerp of
unit quaternions along the shortest path; STEP holds a key's value until the next key;
CUBICSPLINE reads (in-tangent, value, out-tangent) triplets and evaluates the cubic Hermite spline
with tangents scaled by the key interval; a rotation result is normalized. All animations of the
file play together on one timeline (a later channel on the same node and path wins); `duration`
is the last key time over all channels. Channels on morph target `weights`, channels without a
target node (KHR_animation_pointer) and channels on nodes given by a `matrix` (not allowed by the
spec) are ignored with one warning per file and kind, through the loader's feature warnings.

Morph target `weights` channels (one value per target and key; CUBICSPLINE: in-tangent, value and
out-tangent triplets of T values each) sample the same way; with the joint nodes' world matrices
they become the pose state of `Scene.deformation` (clrender.scene.deform), which the device applies. Node
transforms are computed for every node of the file (joints may sit outside the default scene).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Optional

import numpy as np

from clrender.errors import SceneError

PATHS = {"translation": 3, "rotation": 4, "scale": 3}
INTERPOLATIONS = ("LINEAR", "STEP", "CUBICSPLINE")
# posing times are rounded to 1 / this of a second (Animation._state_at)
TICKS_PER_SECOND = 1e9
# singular values below this fraction of the largest are raised to it when posing (see module doc)
MIN_RELATIVE_SCALE = 1e-4


# -- math ---------------------------------------------------------------------------------------------
def quat_matrix(q) -> np.ndarray:
    """3x3 rotation of a quaternion (x, y, z, w), normalized first (zero: identity)."""
    x, y, z, w = np.asarray(q, np.float64)
    norm = np.sqrt(x * x + y * y + z * z + w * w)
    if not norm > 0:
        return np.eye(3)
    x, y, z, w = x / norm, y / norm, z / norm, w / norm
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def trs_matrix(translation=(0.0, 0.0, 0.0), rotation=(0.0, 0.0, 0.0, 1.0), scale=(1.0, 1.0, 1.0)) -> np.ndarray:
    """4x4 T . R . S (glTF local matrix of a node given by TRS)."""
    m = np.eye(4)
    m[:3, :3] = quat_matrix(rotation) * np.asarray(scale, np.float64)
    m[:3, 3] = translation
    return m


def trs_matrices(translation: np.ndarray, rotation: np.ndarray, scale: np.ndarray) -> np.ndarray:
    """(N, 4, 4) T . R . S of N nodes, as trs_matrix (quaternions normalized; zero: identity)."""
    q = np.asarray(rotation, np.float64)
    norm = np.sqrt((q * q).sum(1))
    q = np.where(norm[:, None] > 0, q / np.where(norm > 0, norm, 1.0)[:, None], [0.0, 0.0, 0.0, 1.0])
    x, y, z, w = q.T
    r = np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w),
                  2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w),
                  2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], 1).reshape(-1, 3, 3)
    m = np.zeros((len(q), 4, 4))
    m[:, :3, :3] = r * np.asarray(scale, np.float64)[:, None, :]
    m[:, :3, 3] = translation
    m[:, 3, 3] = 1.0
    return m


def slerp(q0, q1, t: float) -> np.ndarray:
    """The glTF spec's slerp (Appendix C): shortest path between unit quaternions q0 and q1.
    a = acos(|q0.q1|), s = sign(q0.q1); (sin(a(1-t)) q0 + s sin(at) q1) / sin(a); nearly equal
    keys (sin(a) tiny) fall back to normalized linear interpolation."""
    q0, q1 = np.asarray(q0, np.float64), np.asarray(q1, np.float64)
    d = float(np.dot(q0, q1))
    s = -1.0 if d < 0 else 1.0
    a = np.arccos(min(abs(d), 1.0))
    sin_a = np.sin(a)
    if sin_a < 1e-9:
        q = (1.0 - t) * q0 + s * t * q1
    else:
        q = (np.sin(a * (1.0 - t)) / sin_a) * q0 + s * (np.sin(a * t) / sin_a) * q1
    return q / np.linalg.norm(q)


def normalized_quaternions(q: np.ndarray) -> np.ndarray:
    """Unit quaternions along the last axis (zero ones stay zero)."""
    n = np.linalg.norm(q, axis=-1, keepdims=True)
    return np.where(n > 0, q / np.where(n > 0, n, 1.0), q)


@dataclass
class Sampler:
    """Key times (K,) and values: (K, C), or (3K, C) (in-tangent, value, out-tangent) for CUBICSPLINE."""
    times: np.ndarray
    values: np.ndarray
    interpolation: str = "LINEAR"

    def sample(self, t: float, rotation: bool = False) -> np.ndarray:
        """The value at time t (glTF spec Appendix C; clamped outside the keys)."""
        times, cubic = self.times, self.interpolation == "CUBICSPLINE"
        value = (lambda k: self.values[3 * k + 1]) if cubic else (lambda k: self.values[k])
        last = len(times) - 1
        if t <= times[0] or last == 0:
            out = value(0)
        elif t >= times[last]:
            out = value(last)
        else:
            k = int(np.searchsorted(times, t, side="right")) - 1
            td = float(times[k + 1] - times[k])
            u = (t - float(times[k])) / td
            if self.interpolation == "STEP":
                out = value(k)
            elif cubic:
                p0, m0 = self.values[3 * k + 1], td * self.values[3 * k + 2]
                p1, m1 = self.values[3 * (k + 1) + 1], td * self.values[3 * (k + 1)]
                u2, u3 = u * u, u * u * u
                out = ((2 * u3 - 3 * u2 + 1) * p0 + (u3 - 2 * u2 + u) * m0 + (-2 * u3 + 3 * u2) * p1
                       + (u3 - u2) * m1)
            elif rotation:
                out = slerp(value(k), value(k + 1), u)
            else:
                out = (1.0 - u) * value(k) + u * value(k + 1)
        out = np.asarray(out, np.float64)
        return normalized_quaternions(out) if rotation else out


@dataclass
class Channel:
    node: int
    path: str                     # translation, rotation, scale or weights
    sampler: Sampler


@dataclass
class Animation:
    """What is needed to pose a loaded glTF scene at any time (see the module docstring)."""
    rest: dict                    # node -> {"matrix": 4x4} or {"translation", "rotation", "scale"}
    parent: dict                  # node -> parent node (roots absent)
    order: list                   # nodes of the default scene, parents before children
    channels: list                # Channel
    source: str = "<glTF>"
    meshes: list = field(default_factory=list)         # (scene mesh index, node, inverse build matrix)
    camera_node: Optional[int] = None
    light_nodes: list = field(default_factory=list)    # (index in scene.lights, node)
    directional_nodes: list = field(default_factory=list)  # (index in settings["directional_lights"], node)

    def __post_init__(self):
        self._rest_local = None      # node -> rest local matrix (local_matrices)
        self._recent: list = []      # [(t, (world, weights))]: the last two states (_state_at)
        targeted = {c.node for c in self.channels}
        self.animated = set()     # nodes whose world matrix changes: targeted ones and their descendants
        for n in self.order:
            if n in targeted or self.parent.get(n) in self.animated:
                self.animated.add(n)

    @property
    def duration(self) -> float:
        """The last key time over all channels (seconds)."""
        return max((float(c.sampler.times[-1]) for c in self.channels), default=0.0)

    # -- node transforms ------------------------------------------------------------------------------
    def local_matrices(self, t: float, rest: bool = False) -> dict:
        """node -> local 4x4 at time t (rest: the nodes' own transforms, no channel). The rest
        matrices are computed once; a sampler shared by several channels is sampled once."""
        if self._rest_local is None:
            self._rest_local = {n: _local(r) for n, r in self.rest.items()}
        out = dict(self._rest_local)
        if rest:
            return out
        trs, sampled = {}, {}
        for c in self.channels:
            if c.path == "weights":
                continue
            key = (id(c.sampler), c.path == "rotation")
            if key not in sampled:
                sampled[key] = c.sampler.sample(float(t), rotation=c.path == "rotation")
            trs.setdefault(c.node, dict(self.rest[c.node]))[c.path] = sampled[key]
        if trs:                      # the animated nodes' T . R . S at once (thousands in a crowd)
            nodes = list(trs)
            matrices = trs_matrices(np.array([trs[n].get("translation", (0.0, 0.0, 0.0)) for n in nodes], np.float64),
                                    np.array([trs[n].get("rotation", (0.0, 0.0, 0.0, 1.0)) for n in nodes], np.float64),
                                    np.array([trs[n].get("scale", (1.0, 1.0, 1.0)) for n in nodes], np.float64))
            out.update(zip(nodes, matrices))
        return out

    def world_matrices(self, t: float, rest: bool = False) -> dict:
        """node -> world 4x4 at time t (rest: the nodes' own transforms)."""
        local = self.local_matrices(t, rest)
        world: dict = {}
        for n in self.order:
            world[n] = world[self.parent[n]] @ local[n] if n in self.parent else local[n]
        return world

    def node_weights(self, t: float) -> dict:
        """node -> morph weights (T,) at time t, for the nodes a `weights` channel animates."""
        return {c.node: c.sampler.sample(float(t)) for c in self.channels if c.path == "weights"}

    def _state_at(self, t: float) -> tuple:
        """(world matrices, node weights) at time t rounded to the nanosecond (TICKS_PER_SECOND), so that
        a frame's t - dt and the previous frame's t, equal up to float rounding, are one time: the
        same pose bits whatever order frames render in, and the pose pass can keep the last frame's
        positions as the previous ones (clrender/passes/pose.py). The last two states are kept, so
        a frame sequence samples once per frame."""
        if abs(t) < 1e6:
            t = round(t * TICKS_PER_SECOND) / TICKS_PER_SECOND     # the decimal's nearest double
        for kept_t, state in self._recent:
            if kept_t == t:
                return state
        state = (self.world_matrices(t), self.node_weights(t))
        self._recent = [(t, state)] + self._recent[:1]
        return state

    def node_matrix(self, node: int, t: float) -> np.ndarray:
        return self.world_matrices(t)[node]

    # -- load-time binding ---------------------------------------------------------------------------
    def add_mesh(self, mesh_index: int, node: int, matrix) -> np.ndarray:
        """Record that Scene mesh `mesh_index` hangs from `node` and is built with `matrix`; returns
        the matrix to build it with (identity when `matrix` is singular, so the rest geometry is
        not collapsed)."""
        matrix = np.asarray(matrix, np.float64)
        if node in self.animated:
            if abs(np.linalg.det(matrix[:3, :3])) <= 1e-12 * max(np.abs(matrix[:3, :3]).max(), 1e-300) ** 3:
                matrix = np.eye(4)
            self.meshes.append((mesh_index, node, np.linalg.inv(matrix)))
        return matrix

    # -- posing -----------------------------------------------------------------------------------------
    def camera_at(self, camera, world: dict):
        """`camera` moved to the camera node's world transform in `world` (unchanged if not animated)."""
        if camera is None or self.camera_node not in self.animated:
            return camera
        from dataclasses import replace
        m = world[self.camera_node]
        eye, forward, up = m[:3, 3], -m[:3, 2], m[:3, 1]
        norm = float(np.linalg.norm(forward))
        if not (np.isfinite(norm) and norm > 0):
            return camera
        try:
            return replace(camera, eye=eye, target=eye + forward / norm, up=up)
        except ValueError:       # degenerate up vector at this time: keep the camera
            return camera

    def pose(self, scene, t: float, dt: Optional[float] = None):
        """Pose `scene` in place at time t (module docstring); returns the camera at t - dt (None
        when dt is None)."""
        t = float(t)
        if not np.isfinite(t) or (dt is not None and not np.isfinite(float(dt))):
            raise SceneError(f"{self.source}: animation time must be finite, got t={t!r} dt={dt!r}")
        before, before_weights = (None, None) if dt is None else self._state_at(t - float(dt))
        world, weights = self._state_at(t)
        deformation = getattr(scene, "deformation", None)
        if deformation is not None:        # skins and morph targets: the device poses them (clrender.scene.deform)
            deformation.set_pose(world, weights, before, before_weights)
        for m, node, inv_build in self.meshes:
            cur = _regular(world[node] @ inv_build)
            prev = None if before is None else _regular(before[node] @ inv_build)
            scene.set_transform(m, cur, previous=prev)
        previous_camera = None if before is None else self.camera_at(scene.camera, before)
        scene.camera = self.camera_at(scene.camera, world)
        lights = [(i, n) for i, n in self.light_nodes if n in self.animated and i < len(scene.lights)]
        if lights:
            arr = scene.lights.copy()
            for i, n in lights:
                m = world[n]
                arr["position"][i] = m[:3, 3]
                d = m[:3, :3] @ np.array([0.0, 0.0, -1.0])
                norm = float(np.linalg.norm(d))
                if np.isfinite(norm) and norm > 0:
                    arr["direction"][i] = d / norm
            scene.lights = arr
        directional = scene.settings.get("directional_lights")
        moved = [(j, n) for j, n in self.directional_nodes
                 if n in self.animated and directional is not None and j < len(directional)]
        if moved:
            directional = [dict(d) for d in directional]
            for j, n in moved:
                d = world[n][:3, :3] @ np.array([0.0, 0.0, -1.0])
                norm = float(np.linalg.norm(d))
                if np.isfinite(norm) and norm > 0:
                    directional[j]["direction"] = (d / norm).tolist()
                    if j == 0 and scene.sun is not None:
                        from clrender.scene.model import Sun
                        sun = scene.sun
                        scene.sun = Sun(d / norm, sun.color, sun.shadow, sun.shadow_map_size)
            scene.settings["directional_lights"] = directional
        return previous_camera


def _local(r: dict) -> np.ndarray:
    """A node's local 4x4 from its rest/animated {"matrix"} or {"translation", "rotation", "scale"}."""
    if "matrix" in r:
        return np.asarray(r["matrix"], np.float64)
    return trs_matrix(r.get("translation", (0.0, 0.0, 0.0)), r.get("rotation", (0.0, 0.0, 0.0, 1.0)),
                      r.get("scale", (1.0, 1.0, 1.0)))


def _regular(matrix: np.ndarray) -> np.ndarray:
    """`matrix` with its 3x3 singular values raised to MIN_RELATIVE_SCALE x the largest (1e-6 when
    all are 0), so `Scene.set_transform` accepts it; unchanged when already well conditioned."""
    a = matrix[:3, :3]
    u, s, vt = np.linalg.svd(a)
    top = float(s.max())
    floor = MIN_RELATIVE_SCALE * top if top > 0 else 1e-6
    if s.min() >= floor:
        return matrix
    out = matrix.copy()
    out[:3, :3] = (u * np.maximum(s, floor)) @ vt
    return out
