"""Per-vertex tangent frames for tangent-space normal maps (glTF `TANGENT` when a file has none).

`generate_tangents(positions, normals, uvs, triangles)` returns (V, 4) float32: a unit tangent
xyz perpendicular to the vertex normal and a handedness w = ±1, in glTF's convention: the
bitangent is B = cross(N, T) · w, T points along +u and B along the image's "up" (−v: glTF's v
runs down the image, and a normal map's green channel points up the image).

Method (Lengyel 2001, weighted like MikkTSpace):

0. like MikkTSpace, vertices with equal position, normal and uv are welded first (they share one
   frame, so a seam split only for another attribute stays invisible);
1. per triangle, the surface derivatives from the UV derivatives: with edges e1 = p1 − p0,
   e2 = p2 − p0 and (du1, dv1), (du2, dv2) their uv deltas, dP/du = (dv2 e1 − dv1 e2) / det and
   dP/dv = (du1 e2 − du2 e1) / det, det = du1 dv2 − du2 dv1; both are normalized (a triangle's
   size or uv density gives it no extra weight). A triangle whose uv area is zero (|det| ≤ 1e-12 ×
   the uv extent²) or whose positions/uvs are not finite contributes nothing;
2. per corner, both directions are projected onto the plane of that vertex's normal, normalized
   and accumulated weighted by the corner's ANGLE (between the two edges leaving the vertex,
   projected onto the same plane, as MikkTSpace does; angle weighting makes the result
   independent of how a polygon is triangulated -- not area weighting);
3. per vertex, T = the accumulated tangent, Gram-Schmidt against N, normalized; w = +1 where
   dot(cross(N, T), B) >= 0 with B = −(accumulated dP/dv), else −1;
4. a vertex whose tangent degenerates (no valid triangle, zero accumulation, or parallel to N)
   gets a stable perpendicular: the world axis least aligned with N (X, else Y, else Z)
   projected off N, w = +1. A non-finite or zero normal is taken as (0, 0, 1). No NaN ever.

Differences from MikkTSpace: MikkTSpace gives each triangle corner its own frame, splitting a
vertex whose triangles disagree on the uv orientation (mirrored uv islands sharing a vertex) or
on smoothing groups; a glTF vertex cannot be split here (the vertex count is fixed), so such a
vertex gets one frame and one w (that of the angle-weighted majority). MikkTSpace also lets
zero-uv-area triangles take their neighbours' frame instead of the fallback.

Measured against the tangents sample files were exported with (regenerated from each file's own
local positions, normals, TEXCOORD_0 and indices; the angle is taken to the file's tangent made
orthogonal to the normal, as the G-buffer resolve uses it; vertices without a tangent frame -- only
zero-uv-area triangles, or a file tangent parallel to N -- left out);
`tests/test_gltf_materials.py::test_mikktspace_agreement` asserts bounds just above these:

    file (exporter)                      vertices  median   p95     max      w agrees
    AlphaBlendModeTest (Blender, Mikk)        137  0.000°   0.010°   0.010°  100 %     (137/137)
    VertexColorTest (Blender, Mikk)            56  0.000°   0.000°   0.000°  92.9 %    (52/56; 16 left out)
    24_animation_pointer (UnityGLTF),        8757  0.001°   1.27°   61.1°    99.91 %   (8749/8757)
      without the TextMeshPro text meshes
    Suzanne (VKTS exporter)                 11808  3.70°   17.8°    64.8°    0 %
    AnimatedCube (VKTS exporter)               36  0.000°   0.000°   0.000°  0 %

* Blender / MikkTSpace: exact. The 4 w disagreements of VertexColorTest are one quad on the back
  (-Z) face whose uv mapping is mirrored as seen along its normal (w = -1 here); the file has
  w = +1 on every vertex. Its 16 left-out vertices only touch zero-uv-area triangles (the file's
  tangent there is parallel to the normal).
* Unity: the planes, cubes and cylinder match exactly (both signs of w); the built-in spheres
  differ at the poles (up to 61°) and along the uv seam, where Unity splits/welds differently;
  each sphere has one pole vertex with w = -1 in the file.
* The VKTS files (Suzanne, AnimatedCube) were NOT exported with MikkTSpace: Suzanne's tangents are
  per face (equal on a triangle's 3 corners, not orthogonal to the vertex normals: |T·N| up to
  0.89), and both files use the opposite handedness: their bitangent cross(N, T) · w is +dP/dv
  (down the image). AnimatedCube has w of both signs in the file, every one the opposite of
  ours; the Blender and Unity files above agree with ours on both signs (Unity's cylinder has 32
  vertices with w = -1, all matched), as does three.js (`computeMikkTSpaceTangents` negates
  MikkTSpace's w on glTF uvs).
"""
from __future__ import annotations

import numpy as np

__all__ = ["generate_tangents", "fallback_tangents", "NO_TANGENT"]

# The tangent of a vertex that has none (no TANGENT, no normal map): zero xyz, which the G-buffer
# resolve treats as "no tangent frame" (the normal map is not applied there); w = +1.
NO_TANGENT = (0.0, 0.0, 0.0, 1.0)
DEGENERATE_UV = 1e-12      # |det| below this × (uv extent)² counts as zero uv area


def _unit(v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(normalized rows, ok mask); rows of zero or non-finite length stay zero."""
    length = np.linalg.norm(v, axis=-1, keepdims=True)
    ok = np.isfinite(length[..., 0]) & (length[..., 0] > 0)
    return np.divide(v, length, out=np.zeros_like(v), where=ok[..., None]), ok


def fallback_tangents(normals: np.ndarray) -> np.ndarray:
    """(V, 3) unit vectors perpendicular to unit `normals`: the world axis least aligned with N
    (ties: X before Y before Z) made orthogonal to N."""
    n = np.asarray(normals, np.float64).reshape(-1, 3)
    axis = np.argmin(np.abs(n), axis=1)
    e = np.zeros_like(n)
    e[np.arange(len(n)), axis] = 1.0
    t = e - n * np.einsum("ij,ij->i", n, e)[:, None]
    t, _ = _unit(t)
    return t


def generate_tangents(positions, normals, uvs, triangles) -> np.ndarray:
    """(V, 4) float32 tangents (xyz unit, perpendicular to the normal; w = ±1) for the vertices
    of `triangles` (T, 3) over `positions` (V, 3), `normals` (V, 3) and `uvs` (V, 2, glTF
    convention). See the module docstring for the method and its agreement with MikkTSpace."""
    p = np.asarray(positions, np.float64).reshape(-1, 3)
    nv = len(p)
    n = np.asarray(normals, np.float64).reshape(-1, 3)
    uv = np.asarray(uvs, np.float64).reshape(-1, 2)
    tri = np.asarray(triangles, np.int64).reshape(-1, 3)
    if n.shape != (nv, 3) or uv.shape != (nv, 2):
        raise ValueError(f"generate_tangents: normals {n.shape} and uvs {uv.shape} need one row per position ({nv})")
    if tri.size and (tri.min() < 0 or tri.max() >= nv):
        raise ValueError(f"generate_tangents: a triangle index is out of range ({nv} vertices)")
    # MikkTSpace welds vertices whose position, normal and uv are all equal: they share a frame
    key = np.concatenate([p, n, uv], 1)
    if nv:
        key, first, group = np.unique(key, axis=0, return_index=True, return_inverse=True)
        group = group.reshape(-1)
    else:
        first, group = np.zeros(0, np.int64), np.zeros(0, np.int64)
    ng = len(first)
    n, n_ok = _unit(n[first])
    n[~n_ok] = (0.0, 0.0, 1.0)
    p, uv, tri = p[first], uv[first], group[tri]

    acc_t = np.zeros((ng, 3))
    acc_b = np.zeros((ng, 3))
    if len(tri):
        P = p[tri]                                   # (T, 3, 3)
        U = uv[tri]                                  # (T, 3, 2)
        with np.errstate(invalid="ignore", over="ignore"):
            e1, e2 = P[:, 1] - P[:, 0], P[:, 2] - P[:, 0]
            d1, d2 = U[:, 1] - U[:, 0], U[:, 2] - U[:, 0]
            det = d1[:, 0] * d2[:, 1] - d2[:, 0] * d1[:, 1]
            extent = np.maximum(np.abs(np.concatenate([d1, d2], 1)).max(1), 0.0)
            valid = (np.isfinite(P).all((1, 2)) & np.isfinite(U).all((1, 2)) & np.isfinite(det)
                     & (np.abs(det) > DEGENERATE_UV * extent * extent))
        e1, e2, d1, d2, det = e1[valid], e2[valid], d1[valid], d2[valid], det[valid]
        tv, P = tri[valid], P[valid]
        sign = np.sign(det)[:, None]
        # dP/du and dP/dv up to the positive factor 1/|det| (normalized just below)
        s_dir, _ = _unit((d2[:, 1:2] * e1 - d1[:, 1:2] * e2) * sign)
        t_dir, _ = _unit((d1[:, 0:1] * e2 - d2[:, 0:1] * e1) * sign)
        corners, add_t, add_b = [], [], []
        for k in range(3):
            v = tv[:, k]
            nk = n[v]
            a = P[:, (k + 1) % 3] - P[:, k]
            b = P[:, (k + 2) % 3] - P[:, k]
            a, _ = _unit(a - nk * np.einsum("ij,ij->i", nk, a)[:, None])     # edges in the normal's plane
            b, _ = _unit(b - nk * np.einsum("ij,ij->i", nk, b)[:, None])
            angle = np.arccos(np.clip(np.einsum("ij,ij->i", a, b), -1.0, 1.0))[:, None]
            ts, _ = _unit(s_dir - nk * np.einsum("ij,ij->i", nk, s_dir)[:, None])
            tt, _ = _unit(t_dir - nk * np.einsum("ij,ij->i", nk, t_dir)[:, None])
            corners.append(v)
            add_t.append(ts * angle)
            add_b.append(tt * angle)
        # Sums per vertex in corner order (all first corners, then second, then third): bincount
        # adds in input order from 0, as np.add.at did corner by corner, so the same bits, ~10x faster.
        corners = np.concatenate(corners)
        for acc, add in ((acc_t, np.concatenate(add_t)), (acc_b, np.concatenate(add_b))):
            for c in range(3):
                acc[:, c] = np.bincount(corners, weights=add[:, c], minlength=ng)

    t = acc_t - n * np.einsum("ij,ij->i", n, acc_t)[:, None]
    length = np.linalg.norm(t, axis=1)
    scale = np.linalg.norm(acc_t, axis=1)
    ok = np.isfinite(length) & (length > 1e-6 * np.maximum(scale, 1e-300)) & (length > 0)
    t[ok] /= length[ok, None]
    t[~ok] = fallback_tangents(n[~ok])
    # glTF: B = cross(N, T) · w points up the image, i.e. along -dP/dv
    w = np.where(np.einsum("ij,ij->i", np.cross(n, t), -acc_b) < 0, -1.0, 1.0)
    w[~ok] = 1.0
    return np.concatenate([t, w[:, None]], 1)[group].astype(np.float32)
