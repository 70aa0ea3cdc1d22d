"""The table of a frame's outputs (AOVs): one row per array a `Frame` offers, read by everything
that handles AOVs, so adding one is one row here plus its decode:

- `Frame` (clrender/render/frame.py): an accessor per row (`source` says where its values come from);
- the readback (clrender/render/readback.py): a device source, or the `fill` constant, per "buffer" row;
- the writers (clrender/outputs/): the `.png` preview of each row (`preview`), its EXR channels (`exr`);
- the CLI: `--aov` accepts `WRITTEN` (every row but `image`, the main output).

NumPy only: the CLI's parser reads this table without importing OpenCL.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import numpy as np

VARIABLE = -1        # `channels` of an AOV whose channel count depends on the frame (shadow: one per light)

# How a row's values are made (AOV.source):
SOURCES = {
    "buffer": "its own device buffer, read as it lies (a pass that did not run: the constant `fill`)",
    "gbuffer": "the G-buffer field `field`, decoded (clrender.abi.gbuffer.decode); a shading model's field "
               "(FIELDS[field].model) is 0 on the other model's pixels (Frame's own depth, normal and albedo "
               "scale by far, zero the background, fill glTF pixels)",
    "host": "computed on the host by Frame from other AOVs and the scene's per-triangle tables",
}

# Preview pictures (AOV.preview; clrender/outputs/previews.py draws them): `--aov` writes <stem>.<aov>.png.
PREVIEWS = {
    "depth": "near white to far dark grey, background black",
    "normal": "the unit vector's x, y, z as R, G, B, background black",
    "srgb": "a linear [0, 1] colour, sRGB-encoded",
    "unit": "[0, 1] as grey",
    "log_power": "specular power as grey, log2 over its 8-bit range",
    "ids": "stable hashed colours per id, background black",
    "position": "world x, y, z over the frame's foreground box as R, G, B",
    "shading_model": "black background, grey Blinn-Phong, white glTF BRDF",
    "velocity": "colour wheel: hue the direction, brightness the speed",
    "hdr": "linear HDR, Reinhard tone-mapped",
    "heat": "a count as a black-red-yellow-white heat map",
    "mask": "marked pixels white on black",
    "shadow": "the darkest shadowed light per pixel, white = lit",
    "picture": "the picture itself",
}


@dataclass(frozen=True)
class AOV:
    name: str                # Frame attribute
    dtype: str               # numpy dtype of the Frame's array
    channels: int            # per pixel: 1 -> (H, W); n -> (H, W, n); VARIABLE -> (H, W, K)
    source: str              # SOURCES
    preview: str             # PREVIEWS
    exr: Optional[str]       # EXR channel suffixes, one character per channel ("RGB": color.R...); "" one
                             # channel named by the AOV itself ("ao"); "#" numbered (shadow.0 ..);
                             # None: not in the float EXR (integer ids, counts per pixel, masks; the image)
    doc: str
    field: Optional[str] = None       # "gbuffer": the G-buffer field it decodes (clrender.abi.gbuffer.FIELDS)
    resolution: str = "output"        # "buffer": "output" (after the resolve) or "internal" (k·W × k·H with
                                      # supersample k: the Frame takes each output pixel's nearest sample)
    packing: str = "planar"           # "buffer": "planar" (a plane per channel) or "rgba8" (one RGBA word per pixel)
    fill: Optional[float] = None      # "buffer": the value everywhere when no pass wrote it (None: always written)

    @property
    def integer(self) -> bool:
        return np.dtype(self.dtype).kind in "iub"

    def shape(self, height: int, width: int, channels: Optional[int] = None) -> tuple:
        """The Frame array's shape; `channels` for a VARIABLE row (shadow: the shadowed lights)."""
        c = self.channels if self.channels != VARIABLE else channels
        if c is None:
            raise ValueError(f"AOV {self.name!r} has a per-frame channel count: pass channels")
        return (height, width) if self.channels == 1 else (height, width, c)


_F, _I = "float32", "int32"

TABLE: tuple[AOV, ...] = (
    AOV("color", _F, 3, "buffer", "hdr", "RGB", "linear HDR"),
    AOV("light_count", _I, 1, "buffer", "heat", "", "lights the culling assigned to the pixel's tile",
        resolution="internal"),
    AOV("depth", _F, 1, "gbuffer", "depth", "Z", "z-depth along the optical axis (linear_depth × far), "
        "+inf on background; the nearest transmissive surface's where one is in front", field="linear_depth"),
    AOV("linear_depth", _F, 1, "gbuffer", "depth", "Z", "depth / far", field="linear_depth"),
    AOV("normal", _F, 3, "gbuffer", "normal", "XYZ", "world-space unit normal, 0 on background", field="normal"),
    AOV("albedo", _F, 3, "gbuffer", "srgb", "RGB", "diffuse albedo (glTF BRDF pixels: base colour × (1 − metallic))",
        field="albedo"),
    AOV("triangle_id", _I, 1, "gbuffer", "ids", None, "input triangle index, -1 on background", field="triangle_id"),
    AOV("velocity", _F, 2, "gbuffer", "velocity", "XY", "screen-space motion in pixels", field="velocity"),
    AOV("specular_intensity", _F, 1, "gbuffer", "unit", "", "Blinn-Phong pixels' specular intensity; 0 elsewhere",
        field="specular_intensity"),
    AOV("specular_power", _F, 1, "gbuffer", "log_power", "", "Blinn-Phong pixels' specular power; 0 elsewhere", field="specular_power"),
    # base_color's EXR channels are numbered (the writers named them so before this table; a change of
    # file format, not of this table, would make them R, G, B)
    AOV("base_color", _F, 3, "gbuffer", "srgb", "012", "glTF-BRDF pixels' linear base colour; 0 elsewhere", field="base_color"),
    AOV("metallic", _F, 1, "gbuffer", "unit", "", "glTF-BRDF pixels' metallic; 0 elsewhere", field="metallic"),
    AOV("roughness", _F, 1, "gbuffer", "unit", "", "glTF-BRDF pixels' perceptual roughness; 0 elsewhere", field="roughness"),
    AOV("shading_model", "int8", 1, "host", "shading_model", None, "0 Blinn-Phong, 1 glTF BRDF, -1 background"),
    AOV("emissive", _F, 3, "gbuffer", "srgb", "RGB", "emissive factor × texture in [0, 1], before the material's emissive_strength", field="emissive"),
    AOV("occlusion", _F, 1, "gbuffer", "unit", "", "the material's ambient occlusion (occlusionTexture), 1 = open, 0 on background", field="occlusion"),
    AOV("object_id", _I, 1, "host", "ids", None, "index into scene.objects, -1 on background"),
    AOV("material_id", _I, 1, "host", "ids", None, "index into scene.materials, -1 on background"),
    AOV("position", _F, 3, "host", "position", "XYZ", "world-space position at the pixel centre, NaN on background"),
    AOV("ao", _F, 1, "buffer", "unit", "", "ambient occlusion in [0, 1], 1 = open; all ones without SSAO", resolution="internal", fill=1.0),
    AOV("shadow", _F, VARIABLE, "buffer", "shadow", "#", "visibility per shadowed light (sun first), K = 0 without",
        resolution="internal", fill=1.0),
    AOV("fragment_count", _I, 1, "buffer", "heat", None, "transparent fragments in front of the opaque surface (A-buffer, peeling)",
        resolution="internal", fill=0),
    AOV("transmittance", _F, 1, "buffer", "unit", "", "what the transparent layers leave of what lies behind (1 = nothing; "
        "the mean of the channels' behind tinted glass)",
        resolution="internal", fill=1.0),
    AOV("edges", "uint8", 1, "buffer", "mask", None, "1 where edge_aa marked an edge pixel (all 0 without edge_aa)", fill=0),
    AOV("image", "uint8", 3, "buffer", "picture", None, "sRGB, the tone-mapped colour", packing="rgba8"),
)

AOVS = {a.name: a for a in TABLE}
NAMES = tuple(AOVS)
# What `--aov` writes beside the image: every AOV but `image`, the main output.
WRITTEN = tuple(n for n in NAMES if n != "image")
# The written AOVs kept out of the float EXR (ids, per-pixel counts, masks; light_count goes in as floats).
INT_AOVS = tuple(n for n in WRITTEN if AOVS[n].exr is None)


def aov(name: str) -> AOV:
    """The row of AOV `name` (ValueError naming the AOVs if unknown)."""
    try:
        return AOVS[name]
    except KeyError:
        raise ValueError(f"unknown AOV {name!r}; available: {', '.join(NAMES)}") from None


def by_source(source: str) -> tuple[AOV, ...]:
    if source not in SOURCES:
        raise ValueError(f"unknown AOV source {source!r}; sources are {tuple(SOURCES)}")
    return tuple(a for a in TABLE if a.source == source)


def exr_suffixes(name: str, channels: Optional[int]) -> list:
    """The EXR channel names' suffixes of AOV `name` with `channels` channels (None: an (H, W) array):
    [""] for a one-channel AOV named by itself, else one suffix per channel; numbered when the table
    has no letters for that many channels (or does not know `name`)."""
    letters = AOVS[name].exr if name in AOVS else None
    if channels is None:
        return [letters if letters and letters != "#" else ""]
    if letters is None or letters == "#" or len(letters) != channels:
        return [str(i) for i in range(channels)]
    return list(letters)
