"""Independent NumPy (float64) reference of the glTF 2.0 metallic-roughness BRDF (glTF 2.0
specification, Appendix B) and of the KHR_lights_punctual light falloff, written from the
specifications' text, not from kernels/brdf.h.

BRDF, for unit N (surface normal), V (towards the viewer), L (towards the light), H = unit(L + V):

    c_diff = base·(1 − metallic),   F0 = mix(0.04, base, metallic) = 0.04·(1 − metallic) + base·metallic
    α = r², r = max(roughness, 0.01)
    F = F0 + (1 − F0)·(1 − |V·H|)^5                                           (Schlick)
    D = α²·χ+(N·H) / (π·((N·H)²·(α² − 1) + 1)²)                                (Trowbridge-Reitz / GGX)
    Vis = χ+(H·L)·χ+(H·V) · 0.5 / (N·L·sqrt((N·V)²(1 − α²) + α²) + N·V·sqrt((N·L)²(1 − α²) + α²))
                                                                            (Smith, height-correlated)
    f = (1 − F)·c_diff/π + F·D·Vis

Outgoing radiance from a light delivering irradiance E (RGB) on a surface facing it, from L:
    Lo = f · E · max(N·L, 0)
The constant ambient term of clrender's glTF materials: ambient · c_diff · (1 − F0).

Punctual lights (`clrender.abi.structs.light_dtype` records), d = |light position − P|:
    falloff 0 (the report's, made by Scene.add_point_light):  A = (1 − (d/r)²)³ for d < r, else 0
    falloff 1 (KHR_lights_punctual with `range` r):          A = clamp(1 − (d/r)⁴, 0, 1)² / d²
    falloff 2 (KHR_lights_punctual without range; r is only a culling radius): A = 1/d² for d < r, else 0
    spot lights: × t², t = clamp((cos θ − cos_outer)/(cos_inner − cos_outer), 0, 1), θ the angle
    between the spot axis and the direction from the light to P.
    E = A · light colour (candela × colour for glTF lights).

G-buffer quantization (clrender/abi/gbuffer.py: what the opaque pipelines store): base colour as 8-bit
sRGB (IEC 61966-2-1 curve, rounded to the nearest code), metallic and roughness as unorm8
(round(255·x)/255). Transparent fragments are shaded from the material unquantized.

Public API::

    srgb8_roundtrip(linear) -> linear float64 after the 8-bit sRGB encode/decode
    unorm8_roundtrip(x) -> float64
    brdf(N, V, L, base, metallic, roughness) -> (..., 3) f (per channel), N·L
    radiance(N, V, L, E, base, metallic, roughness) -> (..., 3) f·E·max(N·L, 0)
    ambient_term(ambient, base, metallic) -> (..., 3)
    punctual_attenuation(points, light) -> (A (...), L unit (..., 3), d (...))
"""
from __future__ import annotations

import numpy as np

DIELECTRIC_F0 = 0.04
MIN_ROUGHNESS = 0.01        # RenderConfig docs: roughness clamped to >= 0.01 (α >= 1e-4)
FALLOFF_REPORT, FALLOFF_INVERSE_SQUARE, FALLOFF_INVERSE_SQUARE_UNBOUNDED = 0, 1, 2
LIGHT_SPOT = 1


# -- quantization -----------------------------------------------------------------------------------
def srgb_encode(x):
    x = np.clip(np.asarray(x, np.float64), 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * x ** (1.0 / 2.4) - 0.055)


def srgb_decode(s):
    s = np.asarray(s, np.float64)
    return np.where(s <= 0.04045, s / 12.92, ((s + 0.055) / 1.055) ** 2.4)


def srgb8_roundtrip(linear):
    """Linear values through 8-bit sRGB and back (the G-buffer's base colour)."""
    code = np.floor(srgb_encode(linear) * 255.0 + 0.5)
    return srgb_decode(code / 255.0)


def unorm8_roundtrip(x):
    """[0, 1] values through 8-bit unorm and back (the G-buffer's metallic and roughness)."""
    return np.floor(np.clip(np.asarray(x, np.float64), 0.0, 1.0) * 255.0 + 0.5) / 255.0


# -- the BRDF ---------------------------------------------------------------------------------------
def _dot(a, b):
    return np.einsum("...i,...i->...", a, b)


def _unit(v):
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def brdf(N, V, L, base, metallic, roughness):
    """f of Appendix B per RGB channel (..., 3) and N·L (...). N, V, L unit (..., 3); base (..., 3)
    or (3,); metallic, roughness scalars or (...)."""
    N, V, L = (np.asarray(a, np.float64) for a in (N, V, L))
    base = np.asarray(base, np.float64)
    m = np.asarray(metallic, np.float64)[..., None]
    r = np.maximum(np.asarray(roughness, np.float64), MIN_ROUGHNESS)
    a2 = (r * r) ** 2
    H = _unit(L + V)
    nl, nv, nh, vh = _dot(N, L), _dot(N, V), _dot(N, H), _dot(V, H)
    nv_ = np.maximum(nv, 0.0)
    nl_ = np.maximum(nl, 0.0)
    c_diff = base * (1.0 - m)
    f0 = DIELECTRIC_F0 * (1.0 - m) + base * m
    F = f0 + (1.0 - f0) * ((1.0 - np.abs(vh)) ** 5)[..., None]
    q = nh * nh * (a2 - 1.0) + 1.0
    D = np.where(nh > 0, a2 / (np.pi * q * q), 0.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        vis = 0.5 / (nl_ * np.sqrt(nv_ * nv_ * (1.0 - a2) + a2) + nv_ * np.sqrt(nl_ * nl_ * (1.0 - a2) + a2))
    vis = np.where(np.isfinite(vis), vis, 0.0)
    f = (1.0 - F) * c_diff / np.pi + F * (D * vis)[..., None]
    return f, nl


def radiance(N, V, L, E, base, metallic, roughness):
    """Outgoing radiance f·E·max(N·L, 0) (..., 3); E (3,) or (..., 3)."""
    f, nl = brdf(N, V, L, base, metallic, roughness)
    return f * np.asarray(E, np.float64) * np.maximum(nl, 0.0)[..., None]


def ambient_term(ambient, base, metallic):
    """The constant ambient light's contribution: ambient · c_diff · (1 − F0)."""
    base = np.asarray(base, np.float64)
    m = np.asarray(metallic, np.float64)[..., None]
    f0 = DIELECTRIC_F0 * (1.0 - m) + base * m
    return float(ambient) * base * (1.0 - m) * (1.0 - f0)


# -- punctual lights --------------------------------------------------------------------------------
def punctual_attenuation(points, light):
    """(A, L, d): the light's attenuation × spot factor at `points` (..., 3), the unit direction
    towards the light and the distance, for the record's falloff (module doc)."""
    points = np.asarray(points, np.float64)
    lv = np.asarray(light["position"], np.float64) - points
    d = np.linalg.norm(lv, axis=-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        L = lv / d[..., None]
    r = float(light["radius"])
    falloff = int(light["falloff"])
    with np.errstate(invalid="ignore", divide="ignore"):
        if falloff == FALLOFF_REPORT:
            A = np.where(d < r, np.clip(1.0 - (d / r) ** 2, 0.0, None) ** 3, 0.0)
        elif falloff == FALLOFF_INVERSE_SQUARE:
            A = np.clip(1.0 - (d / r) ** 4, 0.0, 1.0) ** 2 / (d * d)
        elif falloff == FALLOFF_INVERSE_SQUARE_UNBOUNDED:
            A = np.where(d < r, 1.0 / (d * d), 0.0)
        else:
            raise ValueError(f"unknown falloff {falloff}")
    if int(light["type"]) == LIGHT_SPOT:
        axis = np.asarray(light["direction"], np.float64)
        cos_outer, cos_inner = float(light["cos_outer"]), float(light["cos_inner"])
        t = np.clip((_dot(-L, axis) - cos_outer) / (cos_inner - cos_outer), 0.0, 1.0)
        A = A * t * t
    return A, L, d
