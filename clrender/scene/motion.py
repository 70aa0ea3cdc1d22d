"""Object motion of the scene model: `Scene.set_transform` (a mesh placed by an affine transform,
from its rest pose, with the previous frame's transform for the velocity AOV) and `Scene.pose`
(an animation's pose at a time). A base class of `clrender.scene.model.Scene`: these methods read
and write the Scene's arrays and its rest poses (`_rest_poses`, `_rest_tangents`).
"""
from __future__ import annotations

from typing import Optional

import numpy as np

from clrender.errors import SceneError
from clrender.scene.camera import Camera
from clrender.scene.geometry import BAD_COORDINATES, affine_matrix, bad_vertex, coordinates_text


class SceneMotion:
    """`set_transform` and `pose` of a Scene (module docstring)."""

    def set_transform(self, mesh, matrix, previous=None) -> None:
        """Place mesh `mesh` (a name in `mesh_names` or an index) with the 4×4 affine world transform
        `matrix` (column vectors: p' = matrix @ (x, y, z, 1), translation in the last column),
        applied to the mesh's vertices as they were before its first set_transform (its rest
        pose); normals follow by the inverse transpose, and a mirroring matrix (negative
        determinant) flips the winding. `previous` is the mesh's transform at the previous frame
        (default: `matrix`, no motion): the G-buffer velocity of those vertices then reprojects
        their previous positions with the previous camera (`Frame.velocity`, motion blur). A
        previous transform holds until the mesh's next set_transform. Vertices the mesh shares
        with other meshes are duplicated first, so triangle ids do not change."""
        m = self._mesh_index(mesh)
        if self.deformation is not None and m in self.deformation.meshes:
            raise SceneError(f"{self.source}: mesh {self.mesh_names[m]!r} is deformed by a skin or morph targets; "
                             f"pose it with scene.pose(t) (its joints and weights), not set_transform")
        cur = affine_matrix(matrix, "matrix")
        prev = cur if previous is None else affine_matrix(previous, "previous")
        vertices, rest_p, rest_n, rest_tris = self._rest_pose(m)
        for label, mat in (("matrix", cur), ("previous", prev)):   # finite but huge: beyond float32's range
            placed = rest_p @ mat[:3, :3].T + mat[:3, 3]
            i = bad_vertex(placed)
            if i >= 0:
                raise SceneError(f"{self.source}: set_transform of mesh {self.mesh_names[m]!r}: {label} places "
                                 f"vertex {int(vertices[i])} at {coordinates_text(placed[i])}: {BAD_COORDINATES}")
        a = cur[:3, :3]
        positions, normals = self.positions.copy(), self.normals.copy()
        positions[vertices] = rest_p @ a.T + cur[:3, 3]
        n = rest_n @ np.linalg.inv(a)               # (A^-T n) for row vectors
        length = np.linalg.norm(n, axis=1, keepdims=True)
        normals[vertices] = np.where(length > 0, n / np.where(length > 0, length, 1.0), rest_n)
        if self.tangents is not None:          # tangents are surface directions: A t; mirroring flips w
            rest_t = self._rest_tangents.setdefault(m, self.tangents[vertices].astype(np.float64))
            t = rest_t[:, :3] @ a.T
            length = np.linalg.norm(t, axis=1, keepdims=True)
            tangents = self.tangents.copy()
            tangents[vertices, :3] = np.where(length > 0, t / np.where(length > 0, length, 1.0), 0.0)
            tangents[vertices, 3] = rest_t[:, 3] * np.sign(np.linalg.det(a))
            self.tangents = tangents
        triangles = self.triangles.copy()
        triangles[self.triangle_mesh == m] = rest_tris[:, [0, 2, 1]] if np.linalg.det(a) < 0 else rest_tris
        before = self.previous_positions if self.previous_positions is not None else self.positions
        previous_positions = before.copy()
        previous_positions[vertices] = rest_p @ prev[:3, :3].T + prev[:3, 3]
        self.positions, self.normals, self.triangles = positions, normals, triangles
        # No vertex moved: no buffer of previous positions at all (frames exactly as without motion).
        self.previous_positions = None if np.array_equal(previous_positions, positions) else previous_positions

    def pose(self, t: float, dt: Optional[float] = None) -> Optional[Camera]:
        """Pose the scene in place at time `t` (seconds) from its `animation` (clrender.scene.animation):
        animated meshes by set_transform (motion over `dt` for the velocity AOV), the camera and
        the lights. Returns the camera at t - dt to pass as `previous_camera` (None when dt is
        None). A static scene (animation None) is left as it is."""
        if self.animation is None:
            return None if dt is None else self.camera
        return self.animation.pose(self, t, dt)

    def _mesh_index(self, mesh) -> int:
        if isinstance(mesh, str):
            hits = [i for i, name in enumerate(self.mesh_names) if name == mesh]
            if not hits:
                shown = ", ".join(map(repr, self.mesh_names[:8])) + (", ..." if len(self.mesh_names) > 8 else "")
                raise SceneError(f"{self.source}: no mesh named {mesh!r} (meshes: {shown})")
            if len(hits) > 1:
                raise SceneError(f"{self.source}: {len(hits)} meshes are named {mesh!r}; pass its index instead")
            return hits[0]
        if isinstance(mesh, (int, np.integer)) and not isinstance(mesh, bool):
            if not 0 <= mesh < len(self.mesh_names):
                raise SceneError(f"{self.source}: mesh index {mesh} out of range (there are {len(self.mesh_names)})")
            return int(mesh)
        raise SceneError(f"{self.source}: a mesh is a name or an index into mesh_names, got {mesh!r}")

    def _rest_pose(self, m: int) -> tuple:
        """(vertex indices, rest positions, rest normals (float64), rest triangles) of mesh m; on
        first use, vertices shared with other meshes are duplicated for this mesh's triangles."""
        rest = self._rest_poses.get(m)
        nv = len(self.positions)
        if rest is not None and rest[0].size and rest[0].max() < nv and np.shape(self.triangles) == rest[4]:
            return rest[:4]
        mine = self.triangle_mesh == m
        if not mine.any():
            raise SceneError(f"{self.source}: mesh {self.mesh_names[m]!r} has no triangles to transform")
        used = np.unique(self.triangles[mine])
        shared = np.intersect1d(used, np.unique(self.triangles[~mine]))
        if shared.size:
            remap = np.arange(nv, dtype=np.int64)
            remap[shared] = np.arange(nv, nv + shared.size)
            self.positions = np.concatenate([self.positions, self.positions[shared]])
            self.normals = np.concatenate([self.normals, self.normals[shared]])
            self.uvs = np.concatenate([self.uvs, self.uvs[shared]])
            for name in ("colors", "tangents"):
                a = getattr(self, name)
                if a is not None:
                    setattr(self, name, np.concatenate([a, a[shared]]))
            if self.extra_uvs is not None:
                self.extra_uvs = np.concatenate([self.extra_uvs, self.extra_uvs[:, shared]], axis=1)
            if self.previous_positions is not None:
                self.previous_positions = np.concatenate([self.previous_positions, self.previous_positions[shared]])
            triangles = self.triangles.copy()
            triangles[mine] = remap[triangles[mine]]
            self.triangles = triangles
            used = np.unique(self.triangles[mine])
        rest = (used, self.positions[used].astype(np.float64), self.normals[used].astype(np.float64),
                self.triangles[mine].copy(), self.triangles.shape)
        self._rest_poses[m] = rest
        if self.tangents is not None:
            self._rest_tangents[m] = self.tangents[used].astype(np.float64)
        return rest[:4]
