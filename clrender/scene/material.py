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
# the surface extensions' texture slots (KHR_materials_specular, _clearcoat, _sheen, _iridescence,
# _anisotropy, _diffuse_transmission), in MaterialExt order; sRGB: specular_color, sheen_color and
# diffuse_transmission_color, the others linear
EXT_TEXTURE_SLOTS = ("specular", "specular_color", "clearcoat", "clearcoat_roughness", "clearcoat_normal",
                     "sheen_color", "sheen_roughness", "iridescence", "iridescence_thickness", "anisotropy",
                     "diffuse_transmission", "diffuse_transmission_color")
# KHR_materials_transmission's and _volume's texture slots, in MaterialTx order (both linear)
TX_TEXTURE_SLOTS = ("transmission", "thickness")
LAYERS = ("specular", "clearcoat", "sheen", "iridescence", "anisotropy", "diffuse_transmission")


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
    # glTF surface extensions (defaults: the extension absent; docs/materials.md "Surface extensions")
    ior: float = 1.5                      # KHR_materials_ior: >= 1, or exactly 0 (F0 = 1)
    specular_factor: float = 1.0          # KHR_materials_specular, [0, 1]; texture A multiplies
    specular_texture: int = -1
    specular_color: tuple = (1.0, 1.0, 1.0)   # linear, >= 0 (above 1 allowed); texture RGB (sRGB) multiplies
    specular_color_texture: int = -1
    clearcoat: float = 0.0                # KHR_materials_clearcoat, [0, 1]; texture R multiplies
    clearcoat_texture: int = -1
    clearcoat_roughness: float = 0.0      # [0, 1]; texture G multiplies
    clearcoat_roughness_texture: int = -1
    clearcoat_normal_texture: int = -1    # the coat's tangent-space normal map (linear)
    clearcoat_normal_scale: float = 1.0
    sheen_color: tuple = (0.0, 0.0, 0.0)  # KHR_materials_sheen, linear [0, 1]; texture RGB (sRGB) multiplies
    sheen_color_texture: int = -1
    sheen_roughness: float = 0.0          # [0, 1]; texture A multiplies
    sheen_roughness_texture: int = -1
    iridescence: float = 0.0              # KHR_materials_iridescence, [0, 1]; texture R multiplies
    iridescence_texture: int = -1
    iridescence_ior: float = 1.3          # >= 1
    iridescence_thickness_min: float = 100.0  # nm, >= 0
    iridescence_thickness_max: float = 400.0  # nm, >= min; thickness = mix(min, max, texture G)
    iridescence_thickness_texture: int = -1
    anisotropy_strength: float = 0.0      # KHR_materials_anisotropy, [0, 1]; texture B multiplies
    anisotropy_rotation: float = 0.0      # radians, counter-clockwise from the tangent
    anisotropy_texture: int = -1          # RG: direction (2x - 1), B: strength (linear)
    specular_uv: UVTransform = UVTransform()
    specular_color_uv: UVTransform = UVTransform()
    clearcoat_uv: UVTransform = UVTransform()
    clearcoat_roughness_uv: UVTransform = UVTransform()
    clearcoat_normal_uv: UVTransform = UVTransform()
    sheen_color_uv: UVTransform = UVTransform()
    sheen_roughness_uv: UVTransform = UVTransform()
    iridescence_uv: UVTransform = UVTransform()
    iridescence_thickness_uv: UVTransform = UVTransform()
    anisotropy_uv: UVTransform = UVTransform()
    # see-through extensions (docs/transmission.md; defaults: the extension absent)
    transmission: float = 0.0             # KHR_materials_transmission, [0, 1]; texture R multiplies
    transmission_texture: int = -1
    thickness: float = 0.0                # KHR_materials_volume, mesh units, >= 0 (0: thin-walled); texture G
    thickness_texture: int = -1           #   multiplies; the node's scale applies (SceneObject.volume_scale)
    attenuation_distance: float = np.inf  # world units, > 0 (inf: no attenuation)
    attenuation_color: tuple = (1.0, 1.0, 1.0)   # linear [0, 1]
    dispersion: float = 0.0               # KHR_materials_dispersion, >= 0 (20 / Abbe number)
    diffuse_transmission: float = 0.0     # KHR_materials_diffuse_transmission, [0, 1]; texture A multiplies
    diffuse_transmission_texture: int = -1
    diffuse_transmission_color: tuple = (1.0, 1.0, 1.0)  # linear [0, 1]; texture RGB (sRGB) multiplies
    diffuse_transmission_color_texture: int = -1
    transmission_uv: UVTransform = UVTransform()
    thickness_uv: UVTransform = UVTransform()
    diffuse_transmission_uv: UVTransform = UVTransform()
    diffuse_transmission_color_uv: UVTransform = UVTransform()

    def __post_init__(self):
        if self.alpha_mode not in ALPHA_MODES:
            raise SceneError(f"material {self.name!r}: alpha_mode must be one of {ALPHA_MODES}, got {self.alpha_mode!r}")
        ranges = (("opacity", 0.0, 1.0), ("refraction", 0.0, np.inf), ("roughness", 0.0, 1.0),
                  ("normal_scale", -np.inf, np.inf), ("occlusion_strength", 0.0, 1.0),
                  ("emissive_strength", 0.0, np.inf), ("specular_factor", 0.0, 1.0), ("clearcoat", 0.0, 1.0),
                  ("clearcoat_roughness", 0.0, 1.0), ("clearcoat_normal_scale", -np.inf, np.inf),
                  ("sheen_roughness", 0.0, 1.0), ("iridescence", 0.0, 1.0), ("iridescence_ior", 1.0, np.inf),
                  ("iridescence_thickness_min", 0.0, np.inf), ("iridescence_thickness_max", 0.0, np.inf),
                  ("anisotropy_strength", 0.0, 1.0), ("anisotropy_rotation", -np.inf, np.inf),
                  ("transmission", 0.0, 1.0), ("thickness", 0.0, np.inf), ("dispersion", 0.0, np.inf),
                  ("diffuse_transmission", 0.0, 1.0))
        ranges += (("metallic", 0.0, 1.0),) if self.metallic is not None else ()
        for name, lo, hi in ranges:
            v = getattr(self, name)
            if not (isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, bool)
                    and np.isfinite(v) and lo <= float(v) <= hi):
                raise SceneError(f"material {self.name!r}: {name} must be a finite number in [{lo}, {hi}], got {v!r}")
            object.__setattr__(self, name, float(v))
        if self.iridescence_thickness_max < self.iridescence_thickness_min:
            raise SceneError(f"material {self.name!r}: iridescence_thickness_max ({self.iridescence_thickness_max}) "
                             f"must be >= iridescence_thickness_min ({self.iridescence_thickness_min})")
        v = self.ior        # KHR_materials_ior: >= 1, or exactly 0 (the spec's special value: F0 = 1)
        if not (isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, bool)
                and np.isfinite(v) and (float(v) >= 1.0 or float(v) == 0.0)):
            raise SceneError(f"material {self.name!r}: ior must be a finite number >= 1 or exactly 0, got {v!r}")
        object.__setattr__(self, "ior", float(v))
        v = self.attenuation_distance   # KHR_materials_volume: > 0, +inf (the default) = no attenuation
        if not (isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, bool)
                and float(v) > 0.0 and not np.isnan(v)):
            raise SceneError(f"material {self.name!r}: attenuation_distance must be a number > 0 (inf: no "
                             f"attenuation), got {v!r}")
        object.__setattr__(self, "attenuation_distance", float(v))
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
        for name, hi in (("specular_color", np.inf), ("sheen_color", 1.0), ("attenuation_color", 1.0),
                         ("diffuse_transmission_color", 1.0)):
            c = getattr(self, name)
            c = np.asarray(c, np.float64).reshape(-1) if not isinstance(c, str) else np.zeros(0)
            if c.shape != (3,) or not np.isfinite(c).all() or (c < 0).any() or (c > hi).any():
                raise SceneError(f"material {self.name!r}: {name} must be 3 finite numbers in [0, {hi}], "
                                 f"got {getattr(self, name)!r}")
            object.__setattr__(self, name, tuple(float(x) for x in c))
        for slot in TEXTURE_SLOTS + EXT_TEXTURE_SLOTS + TX_TEXTURE_SLOTS:
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
        """{slot: (texture index, UVTransform)} of the base slots (TEXTURE_SLOTS) with a texture."""
        return {s: (getattr(self, f"{s}_texture"), getattr(self, f"{s}_uv")) for s in TEXTURE_SLOTS
                if getattr(self, f"{s}_texture") >= 0}

    def layer_textures_used(self) -> dict:
        """{slot: (texture index, UVTransform)} of the surface extensions' slots (EXT_TEXTURE_SLOTS)
        with a texture."""
        return {s: (getattr(self, f"{s}_texture"), getattr(self, f"{s}_uv")) for s in EXT_TEXTURE_SLOTS
                if getattr(self, f"{s}_texture") >= 0}

    def tx_textures_used(self) -> dict:
        """{slot: (texture index, UVTransform)} of the transmission and volume slots (TX_TEXTURE_SLOTS)
        with a texture."""
        return {s: (getattr(self, f"{s}_texture"), getattr(self, f"{s}_uv")) for s in TX_TEXTURE_SLOTS
                if getattr(self, f"{s}_texture") >= 0}

    @property
    def transmissive(self) -> bool:
        """KHR_materials_transmission applies: a glTF-BRDF material, not unlit, transmission > 0 (a
        texture only multiplies the factor). Such triangles take the transparent-fragment path."""
        return self.metallic is not None and not self.unlit and self.transmission > 0

    @property
    def see_through(self) -> bool:
        """Drawn on the transparent-fragment path (not the G-buffer): alpha BLEND, or transmissive."""
        return self.alpha_mode == "BLEND" or self.transmissive

    @property
    def has_volume(self) -> bool:
        """Transmissive with a volume (thickness > 0: refraction, attenuation, dispersion); else thin-walled."""
        return self.transmissive and self.thickness > 0

    @property
    def layers(self) -> frozenset:
        """The surface-extension layers this material shades with (a subset of LAYERS). Empty for the
        Blinn-Phong model and unlit materials, and where every extension value is degenerate (the
        material then IS its base layer): the layers pass skips it."""
        if self.metallic is None or self.unlit:
            return frozenset()
        on = {"specular": (self.ior != 1.5 or self.specular_factor != 1.0 or self.specular_color != (1.0, 1.0, 1.0)
                           or self.specular_texture >= 0 or self.specular_color_texture >= 0),
              "clearcoat": self.clearcoat > 0, "sheen": max(self.sheen_color) > 0,
              "iridescence": self.iridescence > 0, "anisotropy": self.anisotropy_strength > 0,
              "diffuse_transmission": self.diffuse_transmission > 0}
        return frozenset(k for k in LAYERS if on[k])

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
