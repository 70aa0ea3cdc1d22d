"""Independent NumPy reference of docs/transparency.md: fragments, their order, shading and blending.

Brute force, built on the other references and on the spec's text, never on kernel code:

* Coverage and depth are `reference.raster` (docs/raster_contract.md): one `setup` of the whole
  scene, then `prim_fragments` per prim. Prims keep their setup order, which is (triangle id, fan
  index), so within a triangle the prim index order is the fan order the kernels use.
* Opaque depth per pixel: the nearest fragment of the non-BLEND prims (exact float32 contract
  depth, +inf where none). A fragment is a (BLEND prim, pixel) pair with z < opaque depth
  (strict) and z <= far (the raster reference already discards z > far).
* Order: (z, triangle id, prim index) ascending, a total order.
* Shading, float64, the model of reference/shading.py (its docstring) on an unquantized surface:
  P = eye + z·dir(pixel) (shading.pixel_directions), N = the interpolated vertex normal,
  normalized, flipped on back faces of double-sided materials, albedo = base_color.rgb,
  specular terms from the material, no SSAO:  c = albedo·(ambient + diffuse) + specular.
  Barycentrics are perspective-correct in the input triangle, from the contract's own edge
  functions at the pixel centre (snapped vertices, weights e_k/w_k in float64) and the prim's
  vertex barycentrics: the identity for a whole triangle, the ones the contract's near clip
  carries for a clipped piece (§2: the clip of the vertices extended by their barycentrics). So
  only float32-vs-float64 rounding separates them from a faithful kernel. (Ray casting against the
  unsnapped triangle, `_ray_barycentrics`, is not close enough for a triangle seen nearly edge-on,
  as a near-clipped one often is: its depth then changes by whole units per pixel.)
* Blending front to back: before shading the next fragment, stop when T < 1e-4
  (TRANSMITTANCE_EPSILON); acc += T·alpha·c; T *= 1 - alpha; color = acc + T·opaque_color.
  alpha = base_color.a · opacity (untextured materials only). `layers=N` keeps only the N
  nearest fragments (depth peeling with N layers, `max_fragments_per_pixel=N`).
* The opaque colour is an input (`opaque_color`, (H, W, 3)). Choice made for the tests: the float64
  reference shading (`shading.shade_frame`) of the renderer's own decoded G-buffer, which with
  transparency holds the opaque surfaces only (opaque shading against that same reference is
  tested in test_lighting.py). `opaque_color_from_frame` does that.

Orthographic cameras (raster contract §11): the raster reference's ortho path, screen-linear
barycentrics (weights e_k, no division), positions on the pixels' parallel rays
(shading.pixel_origins + z·forward) and V = -forward.

Out of scope (ReferenceScopeError / not modelled): textures (alpha and colour), MASK materials
(raster reference), the sun, refraction. Shadows only through a caller's `light_visibility`
(e.g. ray casts), never shadow maps.

Public API::

    blend(scene, camera, width, height, opaque_color, lights=None, ambient=None, layers=None,
          pixels=None, frags=None, light_visibility=None) -> Blend
    opaque_color_from_frame(frame, camera, lights, ambient) -> (H, W, 3) float64
    fragments(scene, camera, width, height) -> Fragments   (unsorted, every fragment)
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import numpy as np

from . import shading
from .raster import (F32, SUB, HALF, Prims, ReferenceScopeError, clip_near, prim_fragments, setup, transform,
                     view_projection_f32)

TRANSMITTANCE_EPSILON = 1e-4


@dataclass
class Fragments:
    """Every transparent fragment of a frame (unsorted) and the opaque surface per pixel."""
    row: np.ndarray          # (F,) int64
    col: np.ndarray          # (F,) int64
    z: np.ndarray            # (F,) float32 contract depth
    tri: np.ndarray          # (F,) int64 triangle id
    prim: np.ndarray         # (F,) int64 prim index (setup order = (triangle id, fan index))
    bary: np.ndarray         # (F, 3) float64 barycentrics in the input triangle
    backface: np.ndarray     # (F,) bool
    clipped: np.ndarray      # (F,) bool: the prim is a near-clipped piece
    opaque_depth: np.ndarray  # (H, W) float32, +inf where no opaque surface
    opaque_id: np.ndarray    # (H, W) int32, -1 where no opaque surface
    stats: dict

    def __len__(self) -> int:
        return int(len(self.z))


@dataclass
class Blend:
    color: np.ndarray           # (H, W, 3) float64
    fragment_count: np.ndarray  # (H, W) int32: every fragment in front of the opaque surface
    transmittance: np.ndarray   # (H, W) float64
    shaded: np.ndarray          # (H, W) int32: fragments actually blended (early stop, layers)
    ambiguous: np.ndarray       # (H, W) bool: a blended fragment sits at N·L ~ 0 for a reaching light
                                #   (specular switches on there) or T lands within 0.01 % of the early stop
    fragments: Fragments


def blend_mask(scene) -> np.ndarray:
    """(T,) bool: triangles whose material is BLEND."""
    is_blend = np.array([m.alpha_mode == "BLEND" for m in scene.materials] or [False])
    return is_blend[np.asarray(scene.triangle_material, np.int64)]


def _subset(prims: Prims, keep: np.ndarray) -> tuple[Prims, np.ndarray]:
    idx = np.flatnonzero(keep)
    return Prims(prims.tri[idx], prims.X[idx], prims.Y[idx], prims.w[idx], prims.area[idx],
                 prims.backface[idx], prims.ortho), idx


def _edge_values(X, Y, rows, cols):
    """E_k (int64) of the contract at the given pixel centres, k = 0, 1, 2."""
    PX = SUB * cols.astype(np.int64) + HALF
    PY = SUB * rows.astype(np.int64) + HALF
    E = []
    for k in range(3):
        k1 = (k + 1) % 3
        dX, dY = int(X[k1]) - int(X[k]), int(Y[k1]) - int(Y[k])
        E.append(dX * (PY - int(Y[k])) - dY * (PX - int(X[k])))
    return E


def _ray_barycentrics(tri_world: np.ndarray, eye: np.ndarray, dirs: np.ndarray) -> np.ndarray:
    """Barycentrics (b0, b1, b2) of the points where rays eye + t·dir meet the triangle's plane."""
    p0, p1, p2 = tri_world
    e1, e2 = p1 - p0, p2 - p0
    n = np.cross(e1, e2)
    t = ((p0 - eye) @ n) / (dirs @ n)
    q = eye + t[:, None] * dirs - p0
    d11, d12, d22 = e1 @ e1, e1 @ e2, e2 @ e2
    q1, q2 = q @ e1, q @ e2
    det = d11 * d22 - d12 * d12
    b1 = (d22 * q1 - d12 * q2) / det
    b2 = (d11 * q2 - d12 * q1) / det
    return np.stack([1.0 - b1 - b2, b1, b2], axis=-1)


def _clipped_vertex_barycentrics(clip: np.ndarray, near, prim_w: np.ndarray, back: bool,
                                 depth_row: int = 3) -> np.ndarray:
    """(3, 3) barycentrics (rows: prim vertices) of a near-clipped piece: the contract's clip (§2,
    `raster.clip_near`, float32) of the clip-space vertices extended by their barycentric coordinates,
    fan-triangulated; the piece is the one whose clip w (orthographic: z, depth_row 2) are the prim's
    (in its stored vertex order)."""
    ext = np.concatenate([clip.astype(np.float32), np.eye(3, dtype=np.float32)], axis=1)
    poly = clip_near(ext, clip[:, depth_row].astype(np.float32) - F32(near))
    order = [0, 1, 2] if back else [0, 2, 1]
    for k in range(1, len(poly) - 1):
        piece = np.stack([poly[0], poly[k], poly[k + 1]])[order]
        if np.array_equal(piece[:, depth_row], prim_w):
            return piece[:, 4:].astype(np.float64)
    raise ReferenceScopeError("a clipped prim matches no piece of the reference's near clip (guard band?)")


def fragments(scene, camera, width: int, height: int) -> Fragments:
    W, H = int(width), int(height)
    far = F32(camera.far)
    prims, stats = setup(scene, camera, W, H)
    blend_tri = blend_mask(scene)
    prim_blend = blend_tri[prims.tri] if len(prims) else np.zeros(0, bool)

    # Opaque surface: the nearest non-BLEND fragment (ties to the lower triangle id, prim index).
    opaque, _ = _subset(prims, ~prim_blend)
    opaque_depth = np.full((H, W), np.inf, np.float32)
    opaque_id = np.full((H, W), -1, np.int32)
    for n in range(len(opaque)):
        r, c, d = prim_fragments(opaque.X[n], opaque.Y[n], opaque.w[n], opaque.area[n], W, H, far,
                                 ortho=prims.ortho)
        win = d < opaque_depth[r, c]
        opaque_depth[r[win], c[win]] = d[win]
        opaque_id[r[win], c[win]] = opaque.tri[n]

    # Which BLEND prims are a whole triangle (not near-clipped): the same three clip w, in the
    # prim's vertex order (front faces had v1/v2 swapped by setup).
    M = view_projection_f32(camera, W, H)
    tris = np.asarray(scene.triangles, np.int64)
    clip_all = transform(np.asarray(scene.positions, np.float32), M)
    depth_row = 2 if prims.ortho else 3              # the clip component the prims interpolate
    clip_w = clip_all[:, depth_row]
    near = F32(camera.near)
    pieces = np.bincount(prims.tri, minlength=len(tris)) if len(prims) else np.zeros(len(tris), np.int64)

    out = {k: [] for k in ("row", "col", "z", "tri", "prim", "bary", "backface", "clipped")}
    for n in np.flatnonzero(prim_blend):
        r, c, z = prim_fragments(prims.X[n], prims.Y[n], prims.w[n], prims.area[n], W, H, far,
                                 ortho=prims.ortho)
        front = z < opaque_depth[r, c]
        r, c, z = r[front], c[front], z[front]
        if not len(r):
            continue
        t = int(prims.tri[n])
        back = bool(prims.backface[n])
        order = np.array([0, 1, 2]) if back else np.array([0, 2, 1])     # prim vertex k = triangle vertex order[k]
        whole = pieces[t] == 1 and np.array_equal(prims.w[n], clip_w[tris[t]][order])
        # Barycentrics of the prim's vertices in the input triangle: the identity (permuted) for a whole
        # triangle, else the ones the contract's clipper carries (§2), found by redoing the clip.
        vb = np.eye(3)[order] if whole else _clipped_vertex_barycentrics(clip_all[tris[t]], near, prims.w[n], back,
                                                                         depth_row)
        E = _edge_values(prims.X[n], prims.Y[n], r, c)
        wd = np.ones(3) if prims.ortho else prims.w[n].astype(np.float64)     # ortho: screen-linear weights
        wts = np.stack([E[1] / wd[0], E[2] / wd[1], E[0] / wd[2]], axis=-1).astype(np.float64)
        wts /= wts.sum(-1, keepdims=True)
        bary = wts @ vb
        out["row"].append(r)
        out["col"].append(c)
        out["z"].append(z)
        out["tri"].append(np.full(len(r), t, np.int64))
        out["prim"].append(np.full(len(r), n, np.int64))
        out["bary"].append(bary)
        out["backface"].append(np.full(len(r), back))
        out["clipped"].append(np.full(len(r), not whole))
    empty = dict(row=np.zeros(0, np.int64), col=np.zeros(0, np.int64), z=np.zeros(0, np.float32),
                 tri=np.zeros(0, np.int64), prim=np.zeros(0, np.int64), bary=np.zeros((0, 3)),
                 backface=np.zeros(0, bool), clipped=np.zeros(0, bool))
    arrays = {k: (np.concatenate(v) if v else empty[k]) for k, v in out.items()}
    return Fragments(**arrays, opaque_depth=opaque_depth, opaque_id=opaque_id, stats=stats)


def shade_fragments(points, normals, albedo, spec_intensity, spec_power, eye, lights, ambient,
                    light_visibility=None, camera=None):
    """The shading model of reference/shading.py on flat arrays: (color (F, 3), min |N·L| (F,)).
    light_visibility(points, light index) -> (F,) factor in [0, 1] (shadows), default 1.
    camera: when given, V comes from it (shading.view_vectors: -forward if orthographic)."""
    lights = np.asarray(lights, shading.structs.light_dtype).reshape(-1)
    V = (shading.view_vectors(points, camera) if camera is not None
         else shading._unit(np.asarray(eye, np.float64) - points))
    diffuse = np.zeros_like(points)
    specular = np.zeros_like(points)
    min_abs = np.full(len(points), np.inf)
    for i, light in enumerate(lights):
        w_ls, L, _ = shading.light_factor(points, light)
        if light_visibility is not None:
            w_ls = w_ls * light_visibility(points, i)
        on = w_ls > 0
        if not on.any():
            continue
        ndotl = (normals * L).sum(-1)
        Hv = shading._unit(L + V)
        ndoth = np.maximum((normals * Hv).sum(-1), 0.0)
        spec = np.where(ndotl > 0, spec_intensity * ndoth ** spec_power, 0.0)
        color = np.asarray(light["color"], np.float64)
        diffuse += (w_ls * np.maximum(ndotl, 0.0))[:, None] * color
        specular += (w_ls * spec)[:, None] * color
        min_abs = np.where(on, np.minimum(min_abs, np.abs(ndotl)), min_abs)
    c = albedo * (float(np.float32(ambient)) + diffuse) + specular
    return c, min_abs


def blend(scene, camera, width: int, height: int, opaque_color, lights=None, ambient=None,
          layers: Optional[int] = None, pixels: Optional[np.ndarray] = None,
          frags: Optional[Fragments] = None, light_visibility=None) -> Blend:
    """The expected transparent composite. `pixels` ((H, W) bool) restricts shading and blending
    (elsewhere color = opaque_color, counts still full); `frags` reuses a `fragments()` result;
    `light_visibility(points (F, 3), light index) -> (F,)` shadows the fragments (default: none)."""
    W, H = int(width), int(height)
    lights = scene.lights if lights is None else lights
    ambient = scene.ambient if ambient is None else ambient
    fr = frags if frags is not None else fragments(scene, camera, W, H)
    for m in scene.materials:
        if m.alpha_mode == "BLEND" and m.base_color_texture >= 0:
            raise ReferenceScopeError(f"material {m.name!r}: textured BLEND materials are out of the reference's scope")
    count = np.zeros((H, W), np.int32)
    np.add.at(count, (fr.row, fr.col), 1)

    pix = fr.row * W + fr.col
    order = np.lexsort((fr.prim, fr.tri, fr.z, pix))            # by pixel, then (z, tri, prim)
    pix_s = pix[order]
    start = np.searchsorted(pix_s, pix_s, side="left")
    rank = np.arange(len(order)) - start                         # 0 = nearest fragment of its pixel

    mats = scene.materials
    tri_mat = np.asarray(scene.triangle_material, np.int64)
    albedo_m = np.array([m.base_color[:3] for m in mats], np.float64).reshape(-1, 3)
    alpha_m = np.array([m.base_color[3] * m.opacity for m in mats], np.float64)
    spec_i_m = np.array([m.specular_intensity for m in mats], np.float64)
    spec_p_m = np.array([m.specular_power for m in mats], np.float64)
    normals_v = np.asarray(scene.normals, np.float64)
    tris = np.asarray(scene.triangles, np.int64)
    eye = np.asarray(camera.eye, np.float64)
    dirs_img = shading.pixel_directions(camera, W, H)
    origins_img = shading.pixel_origins(camera, W, H)       # the eye, or the eye plane (orthographic)

    acc = np.zeros((H * W, 3))
    T = np.ones(H * W)
    shaded = np.zeros(H * W, np.int32)
    ambiguous = np.zeros(H * W, bool)
    use = np.ones(H * W, bool) if pixels is None else np.asarray(pixels, bool).reshape(-1)
    max_rank = int(rank.max()) + 1 if len(rank) else 0
    if layers is not None:
        max_rank = min(max_rank, int(layers))
    for k in range(max_rank):
        sel = order[rank == k]
        p = pix[sel]
        near_stop = use[p] & (np.abs(T[p] / TRANSMITTANCE_EPSILON - 1.0) < 1e-4)   # float32 T: either side
        ambiguous[p[near_stop]] = True
        live = use[p] & (T[p] >= TRANSMITTANCE_EPSILON)
        sel, p = sel[live], p[live]
        if not len(sel):
            continue
        t = fr.tri[sel]
        m = tri_mat[t]
        b = fr.bary[sel]
        n = (b[:, 0:1] * normals_v[tris[t, 0]] + b[:, 1:2] * normals_v[tris[t, 1]]
             + b[:, 2:3] * normals_v[tris[t, 2]])
        n = shading._unit(n)
        n[fr.backface[sel]] *= -1.0
        P = (origins_img[fr.row[sel], fr.col[sel]]
             + fr.z[sel].astype(np.float64)[:, None] * dirs_img[fr.row[sel], fr.col[sel]])
        c, min_abs = shade_fragments(P, n, albedo_m[m], spec_i_m[m], spec_p_m[m], eye, lights, ambient,
                                     light_visibility, camera)
        ambiguous[p] |= (min_abs < 1e-4) & (spec_i_m[m] > 0)
        a = alpha_m[m]
        acc[p] += (T[p] * a)[:, None] * c
        T[p] *= 1.0 - a
        shaded[p] += 1
    color = acc + T[:, None] * np.asarray(opaque_color, np.float64).reshape(-1, 3)
    return Blend(color.reshape(H, W, 3), count, T.reshape(H, W), shaded.reshape(H, W),
                 ambiguous.reshape(H, W), fr)


def opaque_color_from_frame(frame, camera, lights, ambient) -> np.ndarray:
    """The reference shading of the frame's decoded (opaque-only) G-buffer: see the module doc."""
    return shading.shade_frame(frame, camera, lights, ambient)
