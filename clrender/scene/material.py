"""Materials: what the G-buffer resolve evaluates per pixel (docs/materials.md).

`Material` holds either Blinn-Phong terms as the report's G-buffer stores them (OBJ/MTL, TOML)
or glTF 2.0 metallic-roughness inputs, with every texture slot's uv set and KHR_texture_transform
(`UVTransform`); `metallic_roughness_to_blinn_phong` is the documented mapping, which
kernels/material_eval.h evaluates per texel.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import numpy as np

from clrender.errors import SceneError

ALPHA_MODES = ("OPAQUE", "MASK", "BLEND")
TEXTURE_SLOTS = ("base_color", "metallic_roughness", "normal", "occlusion", "emissive")


@dataclass(frozen=True)
class UVTransform:
    """Where a material's texture slot reads its coordinates (glTF textureInfo.texCoord and
    KHR_texture_transform): uv' = T(offset) · R(rotation) · S(scale) · uv, with uv the vertex
    set TEXCOORD_`texcoord` (0 = `Scene.uvs`, k >= 1 = `Scene.extra_uvs[k - 1]`); rotation in
    radians, counter-clockwise in UV space, as the extension defines it."""
    texcoord: int = 0
    offset: tuple = (0.0, 0.0)
    rotation: float = 0.0
    scale: tuple = (1.0, 1.0)

    def __post_init__(self):
        if not (isinstance(self.texcoord, (int, np.integer)) and not isinstance(self.texcoord, bool)
                and 0 <= self.texcoord < 2**16):
            raise SceneError(f"texture transform: texcoord must be an integer >= 0, got {self.texcoord!r}")
        vals = {}
        for name, n in (("offset", 2), ("scale", 2), ("rotation", 1)):
            v = np.asarray(getattr(self, name), np.float64).reshape(-1) if not isinstance(getattr(self, name), str) \
                else np.zeros(0)
            if v.shape != (n,) or not np.isfinite(v).all():
                raise SceneError(f"texture transform: {name} must be {n} finite number(s), got {getattr(self, name)!r}")
            vals[name] = v
        object.__setattr__(self, "texcoord", int(self.texcoord))
        object.__setattr__(self, "offset", tuple(float(x) for x in vals["offset"]))
        object.__setattr__(self, "scale", tuple(float(x) for x in vals["scale"]))
        object.__setattr__(self, "rotation", float(vals["rotation"][0]))

    def matrix(self) -> np.ndarray:
        """(2, 3) float64: uv' = M[:, :2] @ uv + M[:, 2]."""
        c, s = np.cos(self.rotation), np.sin(self.rotation)
        rot = np.array([[c, s], [-s, c]])
        return np.concatenate([rot * np.asarray(self.scale), np.asarray(self.offset)[:, None]], 1)


@dataclass(frozen=True)
class Material:
    """A surface as the G-buffer resolve evaluates it (colours are linear; docs/materials.md).

    Two models: with `metallic` None, the Blinn-Phong terms `specular_intensity` and
    `specular_power` are used as given (OBJ/MTL, TOML); with `metallic` set (glTF's
    metallic-roughness), metallic and roughness are evaluated per pixel (factor × texture) and
    mapped into them. Every `<slot>_texture` is an index into Scene.textures (-1 = none), read
    through `<slot>_uv`."""
    name: str = "default"
    base_color: tuple[float, float, float, float] = (1.0, 1.0, 1.0, 1.0)
    base_color_texture: int = -1          # index into Scene.textures, -1 = none
    specular_intensity: float = 0.04
    specular_power: float = 32.0
    double_sided: bool = True
    alpha_mode: str = "OPAQUE"
    alpha_cutoff: float = 0.5
    opacity: float = 1.0                  # multiplies alpha; < 1 makes an OPAQUE material BLEND
    refraction: float = 0.0               # BLEND: distortion of what lies behind (docs/transparency.md)
    metallic: Optional[float] = None      # metallic-roughness model when set (factor, [0, 1])
    roughness: float = 1.0                # factor, [0, 1]
    metallic_roughness_texture: int = -1  # B = metallic, G = roughness (linear)
    normal_texture: int = -1              # tangent-space normal map (linear), needs tangents
    normal_scale: float = 1.0             # scales the map's x and y
    occlusion_texture: int = -1           # R = ambient occlusion (linear)
    occlusion_strength: float = 1.0       # ao = 1 + strength · (R - 1)
    emissive: tuple[float, float, float] = (0.0, 0.0, 0.0)   # linear factor, [0, 1] each
    emissive_texture: int = -1            # sRGB
    emissive_strength: float = 1.0        # KHR_materials_emissive_strength
    unlit: bool = False                   # KHR_materials_unlit: colour = base colour
    base_color_uv: UVTransform = UVTransform()
    metallic_roughness_uv: UVTransform = UVTransform()
    normal_uv: UVTransform = UVTransform()
    occlusion_uv: UVTransform = UVTransform()
    emissive_uv: UVTransform = UVTransform()

    def __post_init__(self):
        if self.alpha_mode not in ALPHA_MODES:
            raise SceneError(f"material {self.name!r}: alpha_mode must be one of {ALPHA_MODES}, got {self.alpha_mode!r}")
        ranges = (("opacity", 0.0, 1.0), ("refraction", 0.0, np.inf), ("roughness", 0.0, 1.0),
                  ("normal_scale", -np.inf, np.inf), ("occlusion_strength", 0.0, 1.0),
                  ("emissive_strength", 0.0, np.inf))
        ranges += (("metallic", 0.0, 1.0),) if self.metallic is not None else ()
        for name, lo, hi in ranges:
            v = getattr(self, name)
            if not (isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, bool)
                    and np.isfinite(v) and lo <= float(v) <= hi):
                raise SceneError(f"material {self.name!r}: {name} must be a finite number in [{lo}, {hi}], got {v!r}")
            object.__setattr__(self, name, float(v))
        if self.opacity < 1.0:
            if self.alpha_mode == "MASK":
                raise SceneError(f"material {self.name!r}: opacity {self.opacity} < 1 needs alpha_mode OPAQUE or BLEND, "
                                 f"not MASK")
            object.__setattr__(self, "alpha_mode", "BLEND")
        if len(self.base_color) != 4:
            raise SceneError(f"material {self.name!r}: base_color needs 4 components")
        object.__setattr__(self, "base_color", tuple(float(c) for c in self.base_color))
        e = np.asarray(self.emissive, np.float64).reshape(-1)
        if e.shape != (3,) or not np.isfinite(e).all() or (e < 0).any() or (e > 1).any():
            raise SceneError(f"material {self.name!r}: emissive must be 3 numbers in [0, 1] "
                             f"(emissive_strength scales it), got {self.emissive!r}")
        object.__setattr__(self, "emissive", tuple(float(c) for c in e))
        for slot in TEXTURE_SLOTS:
            t = getattr(self, f"{slot}_texture")
            if not (isinstance(t, (int, np.integer)) and not isinstance(t, bool) and t >= -1):
                raise SceneError(f"material {self.name!r}: {slot}_texture must be a texture index or -1, got {t!r}")
            object.__setattr__(self, f"{slot}_texture", int(t))
            if not isinstance(getattr(self, f"{slot}_uv"), UVTransform):
                raise SceneError(f"material {self.name!r}: {slot}_uv must be a UVTransform")
        if not isinstance(self.unlit, (bool, np.bool_)):
            raise SceneError(f"material {self.name!r}: unlit must be True or False, got {self.unlit!r}")
        object.__setattr__(self, "unlit", bool(self.unlit))

    @property
    def emits(self) -> bool:
        return self.emissive_strength > 0 and any(c > 0 for c in self.emissive)

    def textures_used(self) -> dict:
        """{slot: (texture index, UVTransform)} of the slots with a texture."""
        return {s: (getattr(self, f"{s}_texture"), getattr(self, f"{s}_uv")) for s in TEXTURE_SLOTS
                if getattr(self, f"{s}_texture") >= 0}

    @staticmethod
    def from_metallic_roughness(name, base_color, metallic, roughness, **kw) -> "Material":
        """A glTF metallic-roughness material (mapped per pixel: docs/materials.md). The Blinn-Phong
        fields are set from the factors alone, for readers of `specular_intensity/power`."""
        si, sp = metallic_roughness_to_blinn_phong(base_color[:3], metallic, roughness)
        return Material(name=name, base_color=tuple(base_color), metallic=float(metallic),
                        roughness=float(roughness), specular_intensity=si, specular_power=sp, **kw)


# The metallic-roughness mapping (docs/materials.md); kernels/material_eval.h evaluates it per
# pixel in float32 and tests/reference/material.py independently in float64.
DIELECTRIC_F0 = 0.04
LUMA = (0.2126, 0.7152, 0.0722)
MIN_ROUGHNESS = 0.01     # avoids 1/0; 2 / r^4 - 2 reaches the 2048 cap at r = 0.177 already


def metallic_roughness_to_blinn_phong(base_rgb, metallic, roughness) -> tuple[float, float]:
    """(specular intensity, specular power) of a texel: intensity = the luminance of F0 =
    mix(0.04, base, metallic) (untinted), power = 2 / alpha^2 - 2 with alpha = roughness^2
    (Walter et al.'s Beckmann/Blinn-Phong equivalence), clamped to [1, 2048]."""
    lum = float(np.dot(LUMA, np.asarray(base_rgb, np.float64)))
    m = float(metallic)
    r = max(float(roughness), MIN_ROUGHNESS)
    return (float(np.clip(DIELECTRIC_F0 * (1 - m) + lum * m, 0.0, 1.0)),
            float(np.clip(2.0 / r**4 - 2.0, 1.0, 2048.0)))
