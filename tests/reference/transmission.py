"""Independent float64 NumPy truth of see-through glTF materials (KHR_materials_transmission, _volume,
_dispersion) as clrender's screen-space method defines them, written from the extensions' READMEs and
the issue's design (docs/transmission.md), never from the kernels.

Per transmissive fragment (metallic m, base colour c, coverage alpha a, transmission t, unit normal n
facing the viewer, unit v towards the viewer, NV = max(n·v, 1e-4)):

    f0_c  = min(((ior - 1)/(ior + 1))² · specular_color_c, 1) · specular_factor,  f90 = specular_factor
    F_c   = f0_c + (f90 - f0_c)(1 - NV)^5                                (Schlick at the view direction)
    att_c = attenuation_color_c ^ (d / attenuation_distance)             (Beer-Lambert; 1 for d = 0 or inf)
    w_c   = a · t · (1 - m) · c_c · (1 - F_c) · att_c                    (what the surface lets through)

KHR_materials_volume: d = thickness × the node's scale (mesh units -> world); d = 0 is thin-walled.
KHR_materials_dispersion (README, "Implementation"): dispersion = 20 / V_d and n_F - n_C = (n_d - 1)/V_d,
half of that spread on each side of green: iors (R, G, B) = (ior - h, ior, ior + h), h = (ior - 1)·0.025·dispersion
(red has the smallest IOR); only with a volume.

Refraction through the volume: r_c = refract(-v, n, 1/ior_c) (GLSL refract), exit_c = P + unit(r_c)·d; the
lookup of what lies behind moves by the projection of exit_c minus the pixel centre (pixels, x right,
y down); thin-walled: no offset.

Roughness blurs: lod = log2(max(W, H)) · roughness · clamp(2·ior - 2, 0, 1) (the Khronos sample renderer's
applyIorToRoughness), a trilinear lookup in the 2x2-box mip chain of the opaque colour (pixel-index
coordinates, the centre of pixel x at x; level l's texel i covers level-0 pixels [2^l i, 2^l (i+1))).

Blending front to back, per channel:  acc_c += T_c · a · col_c;  T_c *= (1 - a) + w_c;  colour = acc + T·behind.

Public API::

    f0(ior, specular_color=(1, 1, 1), specular_factor=1.0) -> (3,)
    fresnel(nv, ior, specular_color=(1, 1, 1), specular_factor=1.0) -> (..., 3)
    dispersion_iors(ior, dispersion) -> (3,)
    attenuation(color, distance, d) -> (..., 3)
    weight(base, nv, ior=1.5, transmission=1.0, metallic=0.0, alpha=1.0, d=0.0, attenuation_color=(1, 1, 1),
           attenuation_distance=inf, specular_color=(1, 1, 1), specular_factor=1.0) -> (..., 3)
    refract(i, n, eta) -> (..., 3)
    pixel_of(camera, width, height, points) -> (..., 2) continuous pixel coordinates (x right, y down)
    refraction_offsets(camera, width, height, points, n, v, ior, d, dispersion=0.0) -> (..., 3, 2)
    blur_lod(width, height, roughness, ior) -> float
    mip_chain(image) -> [level 0, 1, ...]
    sample(levels, x, y, lod) -> (..., C)  trilinear, pixel-index coordinates
    composite(layers, behind) -> (colour, T)   layers: [(alpha, colour, w)] front to back
    specular_btdf(n, v, l, roughness, ior=1.5) -> (...)
    light_through(n, v, l, E, u, roughness, ior=1.5) -> (..., 3)

Lights seen through (the README's "Transmission BTDF" implementation notes): for a punctual light behind
the surface (n·l < 0; l from the exit point P + unit(r_G)·d towards the light), with the light mirrored onto
the viewer's side, H_T = normalize(v − 2(n·l)n + l) and α = max(roughness·clamp(2·ior − 2, 0, 1), 0.01)²
(applyIorToRoughness; glTF's clamp of α):
    D_T = α² / (π ((n·H_T)²(α² − 1) + 1)²)
    V_T = 1 / ((|n·l| + sqrt(α² + (1 − α²)(n·l)²)) (|n·v| + sqrt(α² + (1 − α²)(n·v)²)))
          (= G_T / (4|n·l||n·v|), the separable Smith form)
    specular_btdf = V_T · D_T;   radiance_c = E_c · specular_btdf · |n·l| · u_c,   u = w / a (the tinted,
    Fresnel-weighted transmitted fraction, the coverage left to the blend).
"""
from __future__ import annotations

import numpy as np


def f0(ior, specular_color=(1.0, 1.0, 1.0), specular_factor=1.0) -> np.ndarray:
    r = ((float(ior) - 1.0) / (float(ior) + 1.0)) ** 2
    return np.minimum(r * np.asarray(specular_color, np.float64), 1.0) * float(specular_factor)


def fresnel(nv, ior, specular_color=(1.0, 1.0, 1.0), specular_factor=1.0) -> np.ndarray:
    """Schlick's Fresnel at the view direction, per channel: (..., 3)."""
    nv = np.maximum(np.asarray(nv, np.float64), 1e-4)[..., None]
    f = f0(ior, specular_color, specular_factor)
    return f + (float(specular_factor) - f) * (1.0 - nv) ** 5


def dispersion_iors(ior, dispersion) -> np.ndarray:
    h = (float(ior) - 1.0) * 0.025 * float(dispersion)
    return np.array([float(ior) - h, float(ior), float(ior) + h])


def attenuation(color, distance, d) -> np.ndarray:
    d = np.asarray(d, np.float64)[..., None]
    color = np.asarray(color, np.float64)
    if not np.isfinite(distance):
        return np.ones(d.shape[:-1] + (3,))
    with np.errstate(divide="ignore"):
        return np.where(d > 0, color ** (d / float(distance)), 1.0)


def weight(base, nv, ior=1.5, transmission=1.0, metallic=0.0, alpha=1.0, d=0.0, attenuation_color=(1.0, 1.0, 1.0),
           attenuation_distance=np.inf, specular_color=(1.0, 1.0, 1.0), specular_factor=1.0) -> np.ndarray:
    """w_c: the fraction of what lies behind that the fragment lets through, per channel."""
    F = fresnel(nv, ior, specular_color, specular_factor)
    att = attenuation(attenuation_color, attenuation_distance, np.broadcast_to(np.asarray(d, np.float64),
                                                                               np.shape(nv)))
    return alpha * transmission * (1.0 - metallic) * np.asarray(base, np.float64)[..., :3] * (1.0 - F) * att


def refract(i, n, eta) -> np.ndarray:
    """GLSL refract(I, N, eta) for unit I, N: 0 on total internal reflection."""
    i, n = np.asarray(i, np.float64), np.asarray(n, np.float64)
    eta = np.asarray(eta, np.float64)
    ni = np.sum(n * i, -1, keepdims=True)
    k = 1.0 - eta ** 2 * (1.0 - ni ** 2)
    out = eta * i - (eta * ni + np.sqrt(np.maximum(k, 0.0))) * n
    return np.where(k < 0.0, 0.0, out)


def pixel_of(camera, width: int, height: int, points) -> np.ndarray:
    """Continuous pixel coordinates (x right, y down; pixel (i, j)'s centre at (i + 0.5, j + 0.5)) of
    world points, through the camera's float64 view-projection (perspective and orthographic)."""
    m = np.asarray(camera.view_projection(int(width), int(height)), np.float64)
    p = np.asarray(points, np.float64)
    h = p @ m[:3, :3].T + m[:3, 3]
    w = p @ m[3, :3] + m[3, 3]
    x, y = h[..., 0] / w, h[..., 1] / w
    return np.stack([(x + 1.0) / 2.0 * width, (1.0 - y) / 2.0 * height], -1)


def refraction_offsets(camera, width: int, height: int, points, n, v, ior, d, dispersion=0.0) -> np.ndarray:
    """(..., 3, 2): per channel (R, G, B) the lookup's offset in pixels of the point behind a volume
    surface at `points` (normal n, view v): exit = P + unit(refract(-v, n, 1/ior_c))·d projected,
    minus P's own projection (the pixel centre when P lies on its pixel's ray)."""
    points, n, v = (np.asarray(a, np.float64) for a in (points, n, v))
    iors = dispersion_iors(ior, dispersion)
    base = pixel_of(camera, width, height, points)
    out = []
    for c in range(3):
        r = refract(-v, n, 1.0 / iors[c])
        norm = np.linalg.norm(r, axis=-1, keepdims=True)
        r = np.where(norm > 0, r / np.where(norm > 0, norm, 1.0), 0.0)
        out.append(pixel_of(camera, width, height, points + r * np.asarray(d, np.float64)[..., None]) - base)
    return np.stack(out, -2)


def blur_lod(width: int, height: int, roughness: float, ior: float) -> float:
    return float(np.log2(max(width, height)) * roughness * np.clip(2.0 * ior - 2.0, 0.0, 1.0))


def mip_chain(image) -> list:
    """Level 0 = the image (H, W, C) float64; each next level the 2x2 box average (an odd last row or
    column averages with itself: edge-clamped), down to 1x1."""
    levels = [np.asarray(image, np.float64)]
    while levels[-1].shape[0] > 1 or levels[-1].shape[1] > 1:
        a = levels[-1]
        h, w = a.shape[:2]
        ys = np.minimum(np.arange((h + 1) // 2)[:, None] * 2 + np.array([0, 1]), h - 1)   # (h', 2)
        xs = np.minimum(np.arange((w + 1) // 2)[:, None] * 2 + np.array([0, 1]), w - 1)
        levels.append(0.25 * (a[ys[:, 0]][:, xs[:, 0]] + a[ys[:, 0]][:, xs[:, 1]]
                              + a[ys[:, 1]][:, xs[:, 0]] + a[ys[:, 1]][:, xs[:, 1]]))
    return levels


def _bilinear(level, u, v):
    h, w = level.shape[:2]
    u = np.clip(u, 0.0, w - 1.0)
    v = np.clip(v, 0.0, h - 1.0)
    x0, y0 = np.floor(u).astype(np.int64), np.floor(v).astype(np.int64)
    x1, y1 = np.minimum(x0 + 1, w - 1), np.minimum(y0 + 1, h - 1)
    fx, fy = (u - x0)[..., None], (v - y0)[..., None]
    top = level[y0, x0] * (1 - fx) + level[y0, x1] * fx
    bottom = level[y1, x0] * (1 - fx) + level[y1, x1] * fx
    return top * (1 - fy) + bottom * fy


def sample(levels, x, y, lod) -> np.ndarray:
    """Trilinear lookup at level-0 pixel-index coordinates (x, y) (pixel i's centre at i), lod clamped
    to the chain; level l's coordinate is (x + 0.5)/2^l - 0.5, clamped to its texels."""
    lod = float(np.clip(lod, 0.0, len(levels) - 1))
    l0 = int(np.floor(lod))
    f = lod - l0
    x, y = np.asarray(x, np.float64), np.asarray(y, np.float64)
    out = _bilinear(levels[l0], (x + 0.5) / 2 ** l0 - 0.5, (y + 0.5) / 2 ** l0 - 0.5)
    if f > 0 and l0 + 1 < len(levels):
        l1 = l0 + 1
        out = out * (1 - f) + f * _bilinear(levels[l1], (x + 0.5) / 2 ** l1 - 0.5, (y + 0.5) / 2 ** l1 - 0.5)
    return out


def composite(layers, behind) -> tuple[np.ndarray, np.ndarray]:
    """Front to back per channel: layers = [(alpha (...), own colour (..., 3), w (..., 3))], nearest first;
    returns (acc + T·behind, T)."""
    behind = np.asarray(behind, np.float64)
    acc = np.zeros_like(behind)
    T = np.ones_like(behind)
    for alpha, col, w in layers:
        a = np.asarray(alpha, np.float64)[..., None] * np.ones_like(behind)
        acc = acc + T * a * np.asarray(col, np.float64)
        T = T * ((1.0 - a) + np.asarray(w, np.float64))
    return acc + T * behind, T


def _clamped_alpha(roughness, ior):
    return max(float(roughness) * float(np.clip(2.0 * float(ior) - 2.0, 0.0, 1.0)), 0.01) ** 2


def specular_btdf(n, v, l, roughness, ior=1.5) -> np.ndarray:
    """The README's V_T·D_T for unit n (facing the viewer), v, l (towards the light); 0 where n·l >= 0."""
    n, v, l = (np.asarray(a, np.float64) for a in (n, v, l))
    nl, nv = np.sum(n * l, -1), np.maximum(np.sum(n * v, -1), 1e-4)
    h = v - 2.0 * nl[..., None] * n + l
    h = h / np.linalg.norm(h, axis=-1, keepdims=True)
    nh = np.sum(n * h, -1)
    a2 = _clamped_alpha(roughness, ior) ** 2
    D = np.where(nh > 0, a2 / (np.pi * (nh * nh * (a2 - 1.0) + 1.0) ** 2), 0.0)
    anl = np.abs(nl)
    V = 1.0 / ((anl + np.sqrt(a2 + (1.0 - a2) * anl ** 2)) * (nv + np.sqrt(a2 + (1.0 - a2) * nv ** 2)))
    return np.where(nl < 0, D * V, 0.0)


def light_through(n, v, l, E, u, roughness, ior=1.5) -> np.ndarray:
    """(..., 3): irradiance E (light colour × falloff, (..., 3) or (3,)) of a light behind the surface seen
    through it: E · specular_btdf · |n·l| · u, u the coverage-free transmitted weight (..., 3)."""
    f = specular_btdf(n, v, l, roughness, ior)
    nl = np.abs(np.sum(np.asarray(n, np.float64) * np.asarray(l, np.float64), -1))
    return np.asarray(E, np.float64) * (f * nl)[..., None] * np.asarray(u, np.float64)
