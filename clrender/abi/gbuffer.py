"""The G-buffer layout: one table drives allocation, the kernel's pack macros, decoding into
`Frame` fields, and the documentation.

The report (section II.3, figure 3) packs everything into one 128-bit texel with bitwise
operations; clrender keeps that 128-bit texel (planes 0-3) and adds a 32-bit triangle id.
Normals are stored octahedral, 2×12 bits: unlike the report's (x, y) + sign-less z, the
octahedral map covers the whole sphere, so the sign of z survives (the report's figure 5
problem) in 24 bits with under 0.05° of error, which frees a byte for the specular power.
Two shading models share the material bits (kernels/brdf.h): Blinn-Phong pixels store diffuse
albedo, specular intensity and power; glTF-BRDF pixels base colour, metallic and roughness in the
same bits. Which one a pixel is comes from its triangle's material (the id is already stored), so
no bit of the 128 is spent on it.
Each plane is a separate uint32 W×H array (structure of arrays: the shading pass reads only
what it needs).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

SPEC_POWER_LOG2_MAX = 11.0      # specular power in [1, 2048] stored as log2 in 8 bits


@dataclass(frozen=True)
class GField:
    name: str       # Frame attribute it decodes to
    plane: int      # which uint32 plane
    shift: int      # first bit inside the plane
    bits: int
    codec: str      # encoding; kernels/gbuffer.h implements pack_<codec>, this module decodes
    doc: str
    model: str = "any"   # "any", or the shading model whose pixels these bits mean this field on:
                         # "blinn_phong" / "gltf" fields share their bits (kernels/brdf.h)


PLANES = ("albedo_spec", "depth", "normal_power", "velocity", "triangle_id", "emissive_occlusion")

LAYOUT: tuple[GField, ...] = (
    GField("albedo", 0, 0, 24, "srgb8x3", "diffuse albedo, sRGB-encoded 8 bits per channel (R in the low byte)",
           "blinn_phong"),
    GField("base_color", 0, 0, 24, "srgb8x3", "base colour (the BRDF needs it whole: a metal's F0 is its base "
           "colour), sRGB 8 bits per channel", "gltf"),
    GField("specular_intensity", 0, 24, 8, "unorm8", "specular intensity in [0, 1]", "blinn_phong"),
    GField("metallic", 0, 24, 8, "unorm8", "metallic in [0, 1]", "gltf"),
    GField("linear_depth", 1, 0, 32, "float32", "view depth / far (report II.3, 'Question du Z'); +inf on background"),
    GField("normal", 2, 0, 24, "oct12x2", "world-space unit shading normal (normal map applied), octahedral, 2×12-bit unorm (u low)"),
    GField("specular_power", 2, 24, 8, "log2unorm8", "specular power p in [1, 2048] as round(255·log2(p)/11)",
           "blinn_phong"),
    GField("roughness", 2, 24, 8, "unorm8", "perceptual roughness in [0, 1] (α = roughness²); next to the "
           "normal, as the power, so the light pre-pass's thin G-buffer has it", "gltf"),
    GField("velocity", 3, 0, 32, "half2", "screen-space motion in pixels (x low, y high), IEEE half floats"),
    GField("triangle_id", 4, 0, 32, "int32", "input triangle index, -1 on background; its material says which "
           "shading model the pixel's model-dependent bits are for (no bit spent on it)"),
    GField("emissive", 5, 0, 24, "srgb8x3", "emissive colour factor × texture in [0, 1], sRGB 8 bits per channel; "
                                            "shading multiplies it by the material's emissive_strength"),
    GField("occlusion", 5, 24, 8, "unorm8", "material ambient occlusion (occlusionTexture), 1 = open"),
)

FIELDS = {f.name: f for f in LAYOUT}

# The planes each pipeline's geometry pass writes (docs/variants.md); the rest are AOVs that a
# later pass fills. The light pre-pass's thin G-buffer is depth + normal/specular power (what the
# light buffer reads) plus velocity and triangle id; light-indexed keeps depth and id only.
THIN_PLANES = ("depth", "normal_power", "velocity", "triangle_id")    # + emissive_occlusion as an AOV
DEPTH_PLANES = ("depth", "triangle_id")


def geometry_planes(config) -> tuple:
    """The planes a pipeline's first geometry pass writes (docs/variants.md); the material or
    forward pass writes the rest as AOVs. The light pre-pass with msaa > 1 writes the surface
    planes in pass 1 too: its material pass sees sub-samples, not the pixel centre's surface."""
    pipeline = getattr(config, "pipeline", "deferred")
    if pipeline == "light_prepass":
        return THIN_PLANES + (("albedo_spec", "emissive_occlusion") if config.msaa > 1 else ())
    return {"deferred": PLANES, "light_indexed": DEPTH_PLANES}[pipeline]


def plane_mask(planes) -> int:
    """GB_WRITE for kernels/gbuffer_pack.h: bit i set for plane i."""
    unknown = set(planes) - set(PLANES)
    if unknown:
        raise ValueError(f"unknown G-buffer planes {sorted(unknown)}; planes are {PLANES}")
    return sum(1 << PLANES.index(p) for p in set(planes))


def kernel_defines() -> dict:
    """-D values for kernels/gbuffer.h (its #ifndef defaults must equal these; a test checks)."""
    defines = {"GB_PLANES": len(PLANES)}
    for f in LAYOUT:
        if f.model == "gltf":         # the Blinn-Phong field's bits: kernels use its names
            continue
        defines[f"GB_{f.name.upper()}_PLANE"] = f.plane
        defines[f"GB_{f.name.upper()}_SHIFT"] = f.shift
    return defines


def allocate_host(height: int, width: int) -> np.ndarray:
    return np.empty((len(PLANES), height, width), np.uint32)


# -- codecs (NumPy side; the kernel side is kernels/gbuffer.h) --------------------------------

def _bits(planes: np.ndarray, f: GField) -> np.ndarray:
    word = planes[f.plane]
    return (word >> np.uint32(f.shift)) & np.uint32((1 << f.bits) - 1) if f.bits < 32 else word


_SRGB_TO_LINEAR = None


def srgb_to_linear_lut() -> np.ndarray:
    global _SRGB_TO_LINEAR
    if _SRGB_TO_LINEAR is None:
        c = np.arange(256, dtype=np.float64) / 255.0
        _SRGB_TO_LINEAR = np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4).astype(np.float32)
    return _SRGB_TO_LINEAR


SRGB_ENCODE_INTERVALS = 4096


def srgb_encode_table(n: int = SRGB_ENCODE_INTERVALS) -> np.ndarray:
    """(n, 2) float32 for the kernels' sRGB encoder: linear [0,1] split into n equal intervals;
    entry k = (threshold, base code): code(x) = base + (x >= threshold) for x in interval k.
    At n = 4096 no interval holds two code boundaries (the curve's steepest slope is ~3300
    codes per unit), so the encoder equals rounding the exact curve but for float32 ties."""
    lo = np.arange(n, dtype=np.float64) / n
    base = linear_to_srgb8(lo).astype(np.float64)
    thr = srgb_to_linear_exact((base + 0.5) / 255.0)
    thr = np.where(thr < lo + 1.0 / n, thr, 2.0)
    if np.any(linear_to_srgb8(np.minimum(lo + 1.0 / n, 1.0)) > base + 1):
        raise AssertionError("two sRGB code boundaries in one interval")
    return np.stack([thr, base], 1).astype(np.float32)


def srgb_to_linear_exact(c: np.ndarray) -> np.ndarray:
    c = np.asarray(c, np.float64)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def linear_to_srgb8(x: np.ndarray) -> np.ndarray:
    x = np.clip(np.asarray(x, np.float64), 0.0, 1.0)
    s = np.where(x <= 0.0031308, x * 12.92, 1.055 * x ** (1 / 2.4) - 0.055)
    return np.floor(s * 255.0 + 0.5).astype(np.uint8)


def oct_encode(n: np.ndarray, bits: int = 12) -> np.ndarray:
    """Unit vectors (...,3) -> packed uint (u low, v high)."""
    n = np.asarray(n, np.float64)
    n = n / np.maximum(np.abs(n).sum(-1, keepdims=True), 1e-30)
    x, y, z = n[..., 0], n[..., 1], n[..., 2]
    sx, sy = np.where(x >= 0, 1.0, -1.0), np.where(y >= 0, 1.0, -1.0)
    ox = np.where(z < 0, (1 - np.abs(y)) * sx, x)
    oy = np.where(z < 0, (1 - np.abs(x)) * sy, y)
    scale = (1 << bits) - 1
    u = np.floor((ox * 0.5 + 0.5) * scale + 0.5).astype(np.uint32)
    v = np.floor((oy * 0.5 + 0.5) * scale + 0.5).astype(np.uint32)
    return u | (v << np.uint32(bits))


def oct_decode(packed: np.ndarray, bits: int = 12) -> np.ndarray:
    scale = float((1 << bits) - 1)
    fx = (packed & np.uint32((1 << bits) - 1)).astype(np.float32) / scale * 2 - 1
    fy = (packed >> np.uint32(bits)).astype(np.float32) / scale * 2 - 1
    fz = 1 - np.abs(fx) - np.abs(fy)
    t = np.maximum(-fz, 0)
    fx = fx + np.where(fx >= 0, -t, t)
    fy = fy + np.where(fy >= 0, -t, t)
    n = np.stack([fx, fy, fz], -1)
    return (n / np.linalg.norm(n, axis=-1, keepdims=True)).astype(np.float32)


def pack_float2(a: np.ndarray, b: np.ndarray, bits: int = 16) -> np.ndarray:
    """The report's pack_float2: two [0,1] values in one word (rounded rather than truncated)."""
    scale = (1 << bits) - 1
    hi = np.floor(np.clip(a, 0, 1) * scale + 0.5).astype(np.uint32)
    lo = np.floor(np.clip(b, 0, 1) * scale + 0.5).astype(np.uint32)
    return (hi << np.uint32(bits)) | lo


def unpack_float2(word: np.ndarray, bits: int = 16) -> tuple[np.ndarray, np.ndarray]:
    scale = float((1 << bits) - 1)
    mask = np.uint32((1 << bits) - 1)
    return ((word >> np.uint32(bits)) & mask) / scale, (word & mask) / scale


def decode(planes: np.ndarray, name: str, far: float = 1.0) -> np.ndarray:
    """Decode field `name` from planes (P, H, W) into the Frame's float/int representation."""
    f = FIELDS[name]
    raw = _bits(planes, f)
    if f.codec == "srgb8x3":
        lut = srgb_to_linear_lut()
        return np.stack([lut[(raw >> np.uint32(8 * c)) & np.uint32(255)] for c in range(3)], -1)
    if f.codec == "unorm8":
        return (raw.astype(np.float32) / 255.0).astype(np.float32)
    if f.codec == "float32":
        return raw.view(np.float32)
    if f.codec == "oct12x2":
        return oct_decode(raw, 12)
    if f.codec == "log2unorm8":
        return np.exp2(raw.astype(np.float32) * np.float32(SPEC_POWER_LOG2_MAX / 255.0)).astype(np.float32)
    if f.codec == "half2":
        return raw.astype(np.uint32).view(np.float16).reshape(*raw.shape, 2).astype(np.float32)
    if f.codec == "int32":
        return raw.view(np.int32)
    raise ValueError(f"unknown codec {f.codec}")


def layout_markdown() -> str:
    """The layout as a Markdown table (docs/gbuffer.md is generated from this)."""
    rows = ["| plane | bits | field | pixels | encoding | meaning |", "|---|---|---|---|---|---|"]
    who = {"any": "all", "blinn_phong": "Blinn-Phong", "gltf": "glTF BRDF"}
    for f in LAYOUT:
        rows.append(f"| {f.plane} `{PLANES[f.plane]}` | {f.shift}–{f.shift + f.bits - 1} | `{f.name}` "
                    f"| {who[f.model]} | {f.codec} | {f.doc} |")
    return "\n".join(rows)
