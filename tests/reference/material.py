"""Independent NumPy (float64) reference of the per-pixel material evaluation (docs/materials.md).

For every foreground pixel of a rendered (or reference-rasterized) `triangle_id`:

* **Surface point.** The view ray through the pixel centre (NDC x = (px + 0.5)/W·2 − 1,
  y = 1 − (py + 0.5)/H·2, unprojected through the inverse of `camera.view_projection`, so
  perspective and orthographic cameras alike) is intersected with the plane of the pixel's
  world-space triangle (Cramer's rule): the barycentrics are the perspective-correct ones, with
  no edge functions involved. The rays of the right (px + 1) and lower (py + 1) neighbours are
  intersected with the same plane (extended beyond the triangle when they miss it); an
  attribute's screen derivative is its value there minus its value at the pixel.
* **Textures** follow GL: texel centres at (i + 0.5)/size, wrap repeat / clamp-to-edge /
  mirrored-repeat applied to integer texel indices (GL 4.6 §8.14.2), bilinear, trilinear between
  mip levels floor(λ) and floor(λ) + 1 (the last level repeated), λ = log2 of the longer
  screen-footprint axis in level-0 texels, clamped to [0, levels − 1]. sRGB slots (base colour,
  emissive) decode each texel through `clrender.abi.gbuffer.srgb_to_linear_lut()` before filtering,
  linear slots (metallic-roughness, normal, occlusion) use byte/255. Mip levels come from
  `clrender.render.texture_pool.mip_chain` (host preprocessing, not the kernels under test), rebuilt with
  the slot's colour space when the Texture's own flag disagrees with it.
* **Material** (docs/materials.md "Evaluation per pixel"): slot coordinates uv_s = M_s·(u, v, 1)
  from `UVTransform.matrix()` and the slot's TEXCOORD set; base = factor × texture × vertex
  colour; metallic-roughness m = metallic × tex.B, r = roughness × tex.G → albedo = base·(1 − m),
  intensity = 0.04(1 − m) + m·luminance(base), power = clamp(2/α² − 2, 1, 2048), α =
  max(r, 0.01)²; normal maps through the Gram-Schmidt tangent frame, B = cross(N, T)·sign(w);
  the final normal negated on back faces; ao = 1 + strength·(tex.R − 1); e = emissive ×
  texture; unlit: albedo = base, intensity 0.
* **Shading** (`lit`): colour = albedo·(ambient·ssao·ao + Σdiffuse) + Σspecular +
  e·emissive_strength, unlit: colour = albedo; point and spot lights through
  `reference.shading.light_factor`, the sun as a directional light (shadows only through a
  given sun visibility, e.g. a Frame's shadow plane).
* **Tangents** without `Scene.tangents` come from `clrender.scene.tangents.generate_tangents` on the
  normal map's uv set (host preprocessing, as the upload does), unless `tangents=` is given.
* **LOD log2**: `log2="exact"` is GL's; `log2="fast"` reproduces the approximation the kernels
  document (kernels/texture_vec.h: the float's exponent plus a linear mantissa, up to 0.086 off),
  so that tests can tell a LOD-weight difference from a real error.

The `mr_channels` argument of `evaluate` (default ("B", "G"): metallic from B, roughness from G)
exists so that a test can evaluate a deliberately broken mapping and show it fails.

Public API::

    pixel_rays(camera, width, height, px, py) -> (origins, directions) float64
    texture_levels(texture, srgb) -> [(h, w, 4) float64 linear] level 0 first
    texture_lod(size, duv_dx, duv_dy, log2="exact") -> λ before clamping
    sample(texture, uv, duv_dx, duv_dy, srgb, log2="exact") -> (N, 4) float64
    mr_to_blinn_phong(base_rgb, metallic, roughness) -> (albedo, intensity, power)
    evaluate(scene, camera, width, height, triangle_id, mr_channels=("B", "G"), tangents=None,
             log2="exact") -> dict of per-pixel arrays (see `evaluate`)
    lit(ev, scene, ssao=None, ambient=None, lights=None, sun="scene", sun_visibility=None) -> (H, W, 3)
    boundary_mask(triangle_id, radius=1) -> (H, W) bool: within `radius` px of another id
"""
from __future__ import annotations

import numpy as np

from clrender.abi.gbuffer import srgb_to_linear_lut
from clrender.scene.model import Texture

# docs/materials.md constants (deliberately restated, not imported from clrender.scene)
F0_DIELECTRIC = 0.04
LUMINANCE = np.array([0.2126, 0.7152, 0.0722])
ROUGHNESS_MIN = 0.01
POWER_RANGE = (1.0, 2048.0)
SRGB_SLOTS = ("base_color", "emissive")
SLOTS = ("base_color", "metallic_roughness", "normal", "occlusion", "emissive")
CHANNEL = {"R": 0, "G": 1, "B": 2, "A": 3}


# -- rays and barycentrics -----------------------------------------------------------------------
def pixel_rays(camera, width: int, height: int, px, py) -> tuple[np.ndarray, np.ndarray]:
    """(origins, directions) (..., 3) float64 of the rays through pixel centres (px, py): the
    points of NDC depth −1 and +1 unprojected through the inverse view-projection."""
    inv = np.linalg.inv(np.asarray(camera.view_projection(int(width), int(height)), np.float64))
    px = np.asarray(px, np.float64)
    py = np.asarray(py, np.float64)
    x = (px + 0.5) / width * 2.0 - 1.0
    y = 1.0 - (py + 0.5) / height * 2.0
    pts = []
    for z in (-1.0, 1.0):
        h = np.stack([x, y, np.full_like(x, z), np.ones_like(x)], -1) @ inv.T
        pts.append(h[..., :3] / h[..., 3:])
    return pts[0], pts[1] - pts[0]


def _plane_barycentrics(o, d, p0, e1, e2):
    """(b1, b2, t) of o + t·d = p0 + b1·e1 + b2·e2 (the plane, not the triangle)."""
    pvec = np.cross(d, e2)
    det = np.einsum("ni,ni->n", e1, pvec)
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / det
        tvec = o - p0
        b1 = np.einsum("ni,ni->n", tvec, pvec) * inv
        qvec = np.cross(tvec, e1)
        b2 = np.einsum("ni,ni->n", d, qvec) * inv
        t = np.einsum("ni,ni->n", e2, qvec) * inv
    return b1, b2, t


def boundary_mask(triangle_id: np.ndarray, radius: int = 1) -> np.ndarray:
    """(H, W) bool: pixels with a different triangle id (or the image border) within `radius`
    pixels (Chebyshev), i.e. pixels whose neighbours may lie on another triangle."""
    tid = np.asarray(triangle_id)
    h, w = tid.shape
    pad = np.pad(tid, radius, constant_values=-2)
    out = np.zeros((h, w), bool)
    for dy in range(-radius, radius + 1):
        for dx in range(-radius, radius + 1):
            out |= pad[radius + dy:radius + dy + h, radius + dx:radius + dx + w] != tid
    return out


# -- textures ------------------------------------------------------------------------------------
_LEVELS: dict = {}


def texture_levels(texture: Texture, srgb: bool) -> list[np.ndarray]:
    """Mip levels of `texture` as (h, w, 4) float64, decoded per texel: RGB through the sRGB
    table when `srgb`, else byte/255; alpha byte/255 always."""
    key = (id(texture), bool(srgb))
    hit = _LEVELS.get(key)
    if hit is not None and hit[0] is texture:
        return hit[1]
    from clrender.render.texture_pool import mip_chain
    source = texture if bool(texture.srgb) == bool(srgb) else \
        Texture(texture.name, texture.rgba, texture.wrap_s, texture.wrap_t, bool(srgb))
    lut = srgb_to_linear_lut().astype(np.float64)
    out = []
    for level in mip_chain(source):
        f = level.astype(np.float64) / 255.0
        if srgb:
            f[..., :3] = lut[level[..., :3]]
        out.append(f)
    _LEVELS[key] = (texture, out)
    return out


def _wrap_index(i: np.ndarray, size: int, mode: str) -> np.ndarray:
    if mode == "repeat":
        return np.mod(i, size)
    if mode == "clamp":
        return np.clip(i, 0, size - 1)
    if mode == "mirror":             # GL: (size − 1) − mirror((i mod 2·size) − size)
        a = np.mod(i, 2 * size) - size
        return (size - 1) - np.where(a >= 0, a, -(1 + a))
    raise ValueError(f"unknown wrap mode {mode!r}")


def bilinear(level: np.ndarray, uv: np.ndarray, wrap_s: str, wrap_t: str) -> np.ndarray:
    """GL bilinear lookup of one level (h, w, 4) at uv (N, 2) -> (N, 4)."""
    h, w = level.shape[:2]
    fx = uv[:, 0] * w - 0.5
    fy = uv[:, 1] * h - 0.5
    x0 = np.floor(fx)
    y0 = np.floor(fy)
    ax = (fx - x0)[:, None]
    ay = (fy - y0)[:, None]
    x0 = x0.astype(np.int64)
    y0 = y0.astype(np.int64)
    xa, xb = _wrap_index(x0, w, wrap_s), _wrap_index(x0 + 1, w, wrap_s)
    ya, yb = _wrap_index(y0, h, wrap_t), _wrap_index(y0 + 1, h, wrap_t)
    top = level[ya, xa] * (1 - ax) + level[ya, xb] * ax
    bottom = level[yb, xa] * (1 - ax) + level[yb, xb] * ax
    return top * (1 - ay) + bottom * ay


def _fast_log2(x: np.ndarray) -> np.ndarray:
    """The kernels' documented approximation (texture_vec.h): float32 exponent + linear mantissa."""
    bits = np.asarray(x, np.float32).view(np.int32)
    mant = ((bits & 0x007FFFFF) | 0x3F800000).view(np.float32).astype(np.float64)
    return ((bits >> 23) - 127).astype(np.float64) + (mant - 1.0)


def texture_lod(size, duv_dx: np.ndarray, duv_dy: np.ndarray, log2: str = "exact") -> np.ndarray:
    """GL's λ (unclamped): log2 of the longer footprint axis, in level-0 texels. size = (w, h)."""
    s = np.asarray(size, np.float64)
    rho2 = np.maximum(((duv_dx * s) ** 2).sum(-1), ((duv_dy * s) ** 2).sum(-1))
    rho2 = np.clip(np.nan_to_num(rho2, nan=1e-20), 1e-20, 1e30)
    return 0.5 * (np.log2(rho2) if log2 == "exact" else _fast_log2(rho2))


def sample(texture: Texture, uv, duv_dx, duv_dy, srgb: bool, log2: str = "exact") -> np.ndarray:
    """Trilinear GL lookup (N, 4) float64 linear of `texture` at uv (N, 2) with screen
    derivatives duv_dx, duv_dy (N, 2)."""
    uv = np.asarray(uv, np.float64).reshape(-1, 2)
    levels = texture_levels(texture, srgb)
    n = len(levels)
    h0, w0 = levels[0].shape[:2]
    lod = np.clip(texture_lod((w0, h0), np.asarray(duv_dx, np.float64).reshape(-1, 2),
                              np.asarray(duv_dy, np.float64).reshape(-1, 2), log2), 0.0, n - 1)
    l0 = np.floor(lod).astype(np.int64)
    l1 = np.minimum(l0 + 1, n - 1)
    f = (lod - l0)[:, None]
    out = np.zeros((len(uv), 4))
    for k in np.unique(np.concatenate([l0, l1])):
        a = l0 == k
        if a.any():
            out[a] += (1 - f[a]) * bilinear(levels[k], uv[a], texture.wrap_s, texture.wrap_t)
        b = (l1 == k) & (f[:, 0] > 0)
        if b.any():
            out[b] += f[b] * bilinear(levels[k], uv[b], texture.wrap_s, texture.wrap_t)
    return out


# -- the mapping ----------------------------------------------------------------------------------
def mr_to_blinn_phong(base_rgb, metallic, roughness):
    """(albedo (..., 3), specular intensity, specular power) of docs/materials.md step 3."""
    base_rgb = np.asarray(base_rgb, np.float64)
    m = np.asarray(metallic, np.float64)
    r = np.maximum(np.asarray(roughness, np.float64), ROUGHNESS_MIN)
    albedo = base_rgb * (1.0 - m)[..., None]
    intensity = np.clip(F0_DIELECTRIC * (1.0 - m) + m * (base_rgb @ LUMINANCE), 0.0, 1.0)
    alpha = r * r
    power = np.clip(2.0 / (alpha * alpha) - 2.0, *POWER_RANGE)
    return albedo, intensity, power


def _unit(v):
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        return v / n


def _default_tangents(scene):
    """scene.tangents, else the host generator's (clrender/scene/tangents.py: what the upload uses for
    a scene without them; host preprocessing like the mip chain, not the kernels under test),
    from the uv set of the first normal-mapped material."""
    if scene.tangents is not None:
        return np.asarray(scene.tangents, np.float64)
    from clrender.scene.tangents import generate_tangents
    sets = [m.normal_uv.texcoord for m in scene.materials if m.normal_texture >= 0] or [0]
    return np.asarray(generate_tangents(scene.positions, scene.normals, scene.uv_set(sets[0]), scene.triangles),
                      np.float64)


def evaluate(scene, camera, width: int, height: int, triangle_id, mr_channels=("B", "G"), tangents=None,
             log2: str = "exact") -> dict:
    """The material terms of every foreground pixel of `triangle_id` (H, W; −1 background).

    Returns a dict of float64 arrays (0 on background unless said):
      mask (H, W) bool foreground; albedo, base (H, W, 3); alpha, specular_intensity,
      specular_power (NaN for unlit), occlusion, emissive_strength (H, W); emissive, normal
      (final, unit), vertex_normal (interpolated, unit, flipped like the final one), position,
      view (unit, towards the eye) (H, W, 3); unlit, backface (H, W) bool; material (H, W)
      int (−1 background); uv (H, W, K, 2) per TEXCOORD set; metallic, roughness (H, W)
      (NaN where the material has no metallic factor); lod (H, W, 5) per slot (NaN without texture).
    `tangents` (V, 4) overrides scene.tangents (else scene.tangents, else clrender.scene.tangents).
    `log2` "exact" (GL) or "fast" (the kernels' approximation) for the mip LOD."""
    tid = np.asarray(triangle_id)
    H, W = tid.shape
    assert (int(height), int(width)) == (H, W), "triangle_id shape does not match width × height"
    mc, rc = CHANNEL[mr_channels[0]], CHANNEL[mr_channels[1]]
    py, px = np.nonzero(tid >= 0)
    t = tid[py, px].astype(np.int64)
    N = len(t)
    tris = np.asarray(scene.triangles, np.int64)[t]                      # (N, 3)
    P = np.asarray(scene.positions, np.float64)
    p0, p1, p2 = P[tris[:, 0]], P[tris[:, 1]], P[tris[:, 2]]
    e1, e2 = p1 - p0, p2 - p0

    def bary(qx, qy):
        o, d = pixel_rays(camera, W, H, qx, qy)
        b1, b2, s = _plane_barycentrics(o, d, p0, e1, e2)
        return np.stack([1.0 - b1 - b2, b1, b2], -1), o + s[:, None] * d, d

    c, pos, ray = bary(px, py)
    cx, _, _ = bary(px + 1, py)
    cy, _, _ = bary(px, py + 1)
    dcx, dcy = cx - c, cy - c

    def interp(attr, cc=c):
        a = np.asarray(attr, np.float64)
        return cc[:, 0:1] * a[tris[:, 0]] + cc[:, 1:2] * a[tris[:, 1]] + cc[:, 2:3] * a[tris[:, 2]]

    def dinterp(attr, dc):
        a = np.asarray(attr, np.float64)
        return dc[:, 0:1] * a[tris[:, 0]] + dc[:, 1:2] * a[tris[:, 1]] + dc[:, 2:3] * a[tris[:, 2]]

    uv_sets = [scene.uv_set(k) for k in range(scene.uv_set_count)]
    uvs = np.stack([interp(u) for u in uv_sets], 1)                     # (N, K, 2)
    duv_dx = np.stack([dinterp(u, dcx) for u in uv_sets], 1)
    duv_dy = np.stack([dinterp(u, dcy) for u in uv_sets], 1)
    vcol = interp(scene.colors) if scene.colors is not None else np.ones((N, 4))

    geo = np.cross(e1, e2)
    backface = np.einsum("ni,ni->n", geo, ray) > 0
    n_interp = interp(scene.normals)
    degenerate = ~((n_interp ** 2).sum(-1) > 1e-20)
    n_interp = np.where(degenerate[:, None], geo, n_interp)
    Nv = _unit(n_interp)

    mat_idx = np.asarray(scene.triangle_material, np.int64)[t]
    out_albedo = np.zeros((N, 3))
    out_base = np.zeros((N, 3))
    out_alpha = np.zeros(N)
    out_si = np.zeros(N)
    out_sp = np.full(N, np.nan)
    out_n = Nv.copy()
    out_ao = np.ones(N)
    out_e = np.zeros((N, 3))
    out_es = np.zeros(N)
    out_unlit = np.zeros(N, bool)
    out_m = np.full(N, np.nan)
    out_r = np.full(N, np.nan)
    out_lod = np.full((N, len(SLOTS)), np.nan)
    tan_all = None

    for mi in np.unique(mat_idx):
        mat = scene.materials[mi]
        sel = mat_idx == mi
        k = int(sel.sum())

        def tex(slot):
            ti = getattr(mat, f"{slot}_texture")
            if ti < 0:
                return None
            tr = getattr(mat, f"{slot}_uv")
            M = tr.matrix()
            uv = uvs[sel, tr.texcoord] @ M[:, :2].T + M[:, 2]
            dx = duv_dx[sel, tr.texcoord] @ M[:, :2].T
            dy = duv_dy[sel, tr.texcoord] @ M[:, :2].T
            texture = scene.textures[ti]
            levels = texture_levels(texture, slot in SRGB_SLOTS)
            h0, w0 = levels[0].shape[:2]
            out_lod[np.flatnonzero(sel), SLOTS.index(slot)] = np.clip(
                texture_lod((w0, h0), dx, dy, log2), 0, len(levels) - 1)
            return sample(texture, uv, dx, dy, slot in SRGB_SLOTS, log2)

        base = np.tile(np.asarray(mat.base_color, np.float64), (k, 1))
        base[:, 3] *= mat.opacity
        tb = tex("base_color")
        if tb is not None:
            base = base * tb
        base = base * vcol[sel]
        out_base[sel] = base[:, :3]
        out_alpha[sel] = base[:, 3]

        if mat.unlit:
            out_albedo[sel] = base[:, :3]
            out_si[sel] = 0.0
            out_unlit[sel] = True
        elif mat.metallic is not None:
            m = np.full(k, mat.metallic)
            r = np.full(k, mat.roughness)
            tmr = tex("metallic_roughness")
            if tmr is not None:
                m = m * tmr[:, mc]
                r = r * tmr[:, rc]
            out_m[sel], out_r[sel] = m, r
            out_albedo[sel], out_si[sel], out_sp[sel] = mr_to_blinn_phong(base[:, :3], m, r)
        else:
            out_albedo[sel] = base[:, :3]
            out_si[sel] = mat.specular_intensity
            out_sp[sel] = mat.specular_power

        n = Nv[sel]
        tn = tex("normal")
        if tn is not None:
            if tan_all is None:
                tan_all = np.asarray(tangents, np.float64) if tangents is not None else _default_tangents(scene)
                if tan_all is None:
                    raise ValueError("a material has a normal map but the scene has no tangents "
                                     "(pass tangents=)")
            tv = interp(tan_all)[sel]
            T = tv[:, :3] - n * np.einsum("ni,ni->n", tv[:, :3], n)[:, None]
            tlen = np.linalg.norm(T, axis=-1)
            ok = tlen > 1e-6
            T = np.where(ok[:, None], T / np.where(ok, tlen, 1.0)[:, None], 0.0)
            sign = np.where(tv[:, 3] < 0, -1.0, 1.0)
            B = np.cross(n, T) * sign[:, None]
            tt = 2.0 * tn[:, :3] - 1.0
            tt[:, :2] *= mat.normal_scale
            mapped = _unit(tt[:, 0:1] * T + tt[:, 1:2] * B + tt[:, 2:3] * n)
            n = np.where(ok[:, None], mapped, n)
        out_n[sel] = n

        to = tex("occlusion")
        if to is not None:
            out_ao[sel] = 1.0 + mat.occlusion_strength * (to[:, 0] - 1.0)
        e = np.tile(np.asarray(mat.emissive, np.float64), (k, 1))
        te = tex("emissive")
        if te is not None:
            e = e * te[:, :3]
        out_e[sel] = np.clip(e, 0.0, 1.0)
        out_es[sel] = mat.emissive_strength

    flip = np.where(backface, -1.0, 1.0)[:, None]
    out_n *= flip
    Nv = Nv * flip

    def full(values, fill=0.0, dtype=np.float64):
        arr = np.full((H, W) + values.shape[1:], fill, dtype)
        arr[py, px] = values
        return arr

    return {
        "mask": tid >= 0, "albedo": full(out_albedo), "base": full(out_base), "alpha": full(out_alpha),
        "specular_intensity": full(out_si), "specular_power": full(out_sp, np.nan),
        "normal": full(out_n), "vertex_normal": full(Nv), "occlusion": full(out_ao, 1.0),
        "emissive": full(out_e), "emissive_strength": full(out_es), "unlit": full(out_unlit, False, bool),
        "backface": full(backface, False, bool), "material": full(mat_idx, -1, np.int64),
        "position": full(pos, np.nan), "view": full(_unit(-ray)), "uv": full(uvs, np.nan),
        "metallic": full(out_m, np.nan), "roughness": full(out_r, np.nan), "lod": full(out_lod, np.nan),
    }


# -- shading --------------------------------------------------------------------------------------
def lit(ev: dict, scene, ssao=None, ambient=None, lights=None, sun="scene", sun_visibility=None) -> np.ndarray:
    """Linear HDR colour (H, W, 3) of docs/materials.md "Shading" from the fields of `ev`
    (an `evaluate` result, possibly with some fields replaced by a Frame's decoded G-buffer):
    colour = albedo·(ambient·ssao·ao + Σdiffuse) + Σspecular + e·emissive_strength; unlit
    pixels: albedo. `ssao` (H, W) defaults to 1; `ambient` to scene.ambient (as float32, like the
    kernels); `lights` to scene.lights; `sun` to scene.sun (None: no sun). Shadows are not
    modelled except `sun_visibility` (H, W), e.g. a Frame's shadow plane of the sun, which scales
    the sun's diffuse and specular terms."""
    from reference.shading import light_factor
    mask = np.asarray(ev["mask"], bool)
    P = np.asarray(ev["position"], np.float64)[mask]
    V = np.asarray(ev["view"], np.float64)[mask]
    Nn = _unit(np.asarray(ev["normal"], np.float64)[mask])
    alb = np.asarray(ev["albedo"], np.float64)[mask]
    s = np.asarray(ev["specular_intensity"], np.float64)[mask]
    p = np.nan_to_num(np.asarray(ev["specular_power"], np.float64)[mask], nan=1.0)
    ao = np.asarray(ev["occlusion"], np.float64)[mask]
    ss = np.ones(len(P)) if ssao is None else np.asarray(ssao, np.float64)[mask]
    amb = float(np.float32(scene.ambient if ambient is None else ambient))
    lights = scene.lights if lights is None else lights
    sun = scene.sun if isinstance(sun, str) and sun == "scene" else sun
    diffuse = np.zeros_like(P)
    specular = np.zeros_like(P)

    def add(w_ls, L, color):
        ndotl = np.einsum("ni,ni->n", Nn, L)
        Hh = _unit(L + V)
        ndoth = np.maximum(np.einsum("ni,ni->n", Nn, Hh), 0.0)
        spec = np.where(ndotl > 0, s * ndoth ** p, 0.0)
        color = np.asarray(color, np.float64)
        diffuse[:] += (w_ls * np.maximum(ndotl, 0.0))[:, None] * color
        specular[:] += (w_ls * spec)[:, None] * color

    for light in np.asarray(lights).reshape(-1):
        w_ls, L, _ = light_factor(P, light)
        if (w_ls > 0).any():
            add(w_ls, L, light["color"])
    if sun is not None:
        L = np.broadcast_to(-np.asarray(sun.direction, np.float64), P.shape)
        vis = np.ones(len(P)) if sun_visibility is None else np.asarray(sun_visibility, np.float64)[mask]
        add(vis, L, sun.color)
    color = alb * ((amb * ss * ao)[:, None] + diffuse)
    color = color + specular + np.asarray(ev["emissive"], np.float64)[mask] * \
        np.asarray(ev["emissive_strength"], np.float64)[mask][:, None]
    unlit = np.asarray(ev["unlit"], bool)[mask]
    color[unlit] = alb[unlit]
    out = np.zeros(mask.shape + (3,))
    out[mask] = color
    return out
