"""The glTF surface extensions (KHR_materials_ior, _specular, _clearcoat, _sheen, _iridescence,
_anisotropy) and the see-through ones (KHR_materials_transmission, _volume, _dispersion,
_diffuse_transmission) read tolerantly into `Material` keyword arguments (docs/materials.md).

The issue's bad-input rule, not the core slots' errors: a value out of its range is clamped to the
range, a value of the wrong JSON type (or a texture index that does not exist) gives the spec's
default, and each such case is one problem string ('what is wrong: what is used instead') that
clrender.loaders.gltf.materials turns into a warning naming the file and the material. Ranges and
defaults are the extensions' schemas (KhronosGroup/glTF, extensions/2.0/Khronos/KHR_materials_*).
attenuationDistance's minimum is exclusive: 0 or less gives the default (+inf, no attenuation), not a
clamp. An extension whose base is missing (a volume without transmission or diffuse transmission, a
dispersion without a volume: `DEPENDS`) is ignored, textures included, with one problem string.
"""
from __future__ import annotations

import numpy as np

from clrender.loaders.gltf.spec import EXT_TEXTURE_INFOS

INF = float("inf")
# extension -> ((property, Material field, default, minimum, maximum), ...); a tuple default is a colour
FACTORS = {
    "KHR_materials_ior": (("ior", "ior", 1.5, 1.0, INF),),   # or exactly 0: the README's special value, kept
    "KHR_materials_specular": (("specularFactor", "specular_factor", 1.0, 0.0, 1.0),
                               ("specularColorFactor", "specular_color", (1.0, 1.0, 1.0), 0.0, INF)),
    "KHR_materials_clearcoat": (("clearcoatFactor", "clearcoat", 0.0, 0.0, 1.0),
                                ("clearcoatRoughnessFactor", "clearcoat_roughness", 0.0, 0.0, 1.0)),
    "KHR_materials_sheen": (("sheenColorFactor", "sheen_color", (0.0, 0.0, 0.0), 0.0, 1.0),
                            ("sheenRoughnessFactor", "sheen_roughness", 0.0, 0.0, 1.0)),
    "KHR_materials_iridescence": (("iridescenceFactor", "iridescence", 0.0, 0.0, 1.0),
                                  ("iridescenceIor", "iridescence_ior", 1.3, 1.0, INF),
                                  ("iridescenceThicknessMinimum", "iridescence_thickness_min", 100.0, 0.0, INF),
                                  ("iridescenceThicknessMaximum", "iridescence_thickness_max", 400.0, 0.0, INF)),
    "KHR_materials_anisotropy": (("anisotropyStrength", "anisotropy_strength", 0.0, 0.0, 1.0),
                                 ("anisotropyRotation", "anisotropy_rotation", 0.0, -INF, INF)),
    "KHR_materials_transmission": (("transmissionFactor", "transmission", 0.0, 0.0, 1.0),),
    "KHR_materials_volume": (("thicknessFactor", "thickness", 0.0, 0.0, INF),
                             ("attenuationDistance", "attenuation_distance", INF, 0.0, INF),   # exclusive minimum
                             ("attenuationColor", "attenuation_color", (1.0, 1.0, 1.0), 0.0, 1.0)),
    "KHR_materials_dispersion": (("dispersion", "dispersion", 0.0, 0.0, INF),),
    "KHR_materials_diffuse_transmission": (("diffuseTransmissionFactor", "diffuse_transmission", 0.0, 0.0, 1.0),
                                           ("diffuseTransmissionColorFactor", "diffuse_transmission_color",
                                            (1.0, 1.0, 1.0), 0.0, 1.0)),
}
# fields whose schema minimum is exclusive: a value at or below it gives the default
EXCLUSIVE_MINIMUM = frozenset({"attenuation_distance"})
# extension -> (the extensions it builds on: one must be present, or it is ignored; why, what is used instead).
# Checked in order, so a dispersion on an ignored volume is ignored too.
DEPENDS = {
    "KHR_materials_volume": (("KHR_materials_transmission", "KHR_materials_diffuse_transmission"),
                             "a volume needs light through its surface", "the material is thin-walled"),
    "KHR_materials_dispersion": (("KHR_materials_volume",), "dispersion applies to a volume",
                                 "no dispersion"),
}
# every property each extension defines (others are reported as unknown, like a misspelt core one)
PROPERTIES = {name: {p[0] for p in props} | {key for _, ext, key, _ in EXT_TEXTURE_INFOS if ext == name}
              | {"extensions", "extras"} for name, props in FACTORS.items()}


def _number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and bool(np.isfinite(v))


def _fmt(x) -> str:
    return "[" + ", ".join(repr(float(c)) for c in x) + "]" if isinstance(x, tuple) else repr(float(x))


def ignored_extensions(ext) -> dict[str, str]:
    """{extension: 'why: what is used instead'} of the extensions in a material's `extensions` object
    that are ignored because none of the extensions they build on (`DEPENDS`) is there (an extension
    that is not an object counts as not there: surface_values reports it)."""
    out: dict[str, str] = {}
    ext = ext if isinstance(ext, dict) else {}
    for name, (needs, why, instead) in DEPENDS.items():
        if isinstance(ext.get(name), dict) and not any(isinstance(ext.get(n), dict) and n not in out for n in needs):
            out[name] = (f"{name} without {' or '.join(needs)} ({why}): the extension is ignored, "
                         f"{instead}")
    return out


def surface_values(ext: dict) -> tuple[dict, list[str]]:
    """The factors of the surface extensions present in a material's `extensions` object:
    ({Material field: value}, [problems]). Absent extensions and properties keep Material's
    defaults (the same as the schemas'); textures are read by `layer_texture`."""
    kw, problems = {}, []
    ignored = ignored_extensions(ext)
    for name, props in FACTORS.items():
        if name not in ext:
            continue
        if name in ignored:
            problems.append(ignored[name])
            continue
        obj = ext[name]
        if not isinstance(obj, dict):
            problems.append(f"{name} must be an object, got {obj!r}: the extension is ignored")
            continue
        unknown = sorted(k for k in obj if k not in PROPERTIES[name])
        if unknown:
            problems.append(f"{name}: unknown properties ignored: {', '.join(repr(k) for k in unknown)}")
        for key, field, default, lo, hi in props:
            if key not in obj:
                continue
            v, what = obj[key], f"{name}.{key}"
            if isinstance(default, tuple):
                if not (isinstance(v, list) and len(v) == 3 and all(_number(c) for c in v)):
                    problems.append(f"{what} must be 3 finite numbers, got {v!r}: the default {_fmt(default)} is used")
                    continue
                got = tuple(float(c) for c in v)
                kw[field] = tuple(min(max(c, lo), hi) for c in got)
            else:
                if not _number(v):
                    problems.append(f"{what} must be a finite number, got {v!r}: the default {_fmt(default)} is used")
                    continue
                got = float(v)
                if field in EXCLUSIVE_MINIMUM and got <= lo:
                    problems.append(f"{what} {v!r} is out of its range > {lo}: the default {_fmt(default)} is used")
                    continue
                kw[field] = 0.0 if field == "ior" and got == 0.0 else min(max(got, lo), hi)
            if kw[field] != got:
                bounds = f"[{lo}, {hi}]" if hi < INF else f">= {lo}" + (" or exactly 0" if field == "ior" else "")
                problems.append(f"{what} {v!r} is out of its range {bounds}: clamped to {_fmt(kw[field])}")
    lo = kw.get("iridescence_thickness_min", 100.0)
    hi = kw.get("iridescence_thickness_max", 400.0)
    if lo > hi:     # without a texture the thickness is the maximum: keeping it keeps that look
        problems.append(f"KHR_materials_iridescence.iridescenceThicknessMinimum ({lo!r}) is larger than "
                        f"iridescenceThicknessMaximum ({hi!r}): the minimum is clamped to {hi!r}")
        kw["iridescence_thickness_min"] = hi
    return kw, problems


def layer_textures(mat: dict) -> list[tuple[str, str, object]]:
    """(clrender slot, 'extension.property', textureInfo as written) of every surface-extension texture
    the material gives (spec.EXT_TEXTURE_INFOS); extension objects that are not objects, and ignored
    extensions (`ignored_extensions`), are skipped (the materials loader warns about them)."""
    ext = mat.get("extensions") or {}
    ignored = ignored_extensions(ext)
    out = []
    for slot, name, key, _ in EXT_TEXTURE_INFOS:
        obj = ext.get(name) if isinstance(ext, dict) and name not in ignored else None
        if isinstance(obj, dict) and key in obj:
            out.append((slot, f"{name}.{key}", obj[key]))
    return out


def layer_texture(info, textures: int, normal: bool = False) -> tuple[dict, list[str]]:
    """A surface-extension textureInfo read tolerantly (the issue's bad-input rule: a warning and the
    default, not an error): ({index (-1: none), texcoord, offset, rotation, scale, normal_scale},
    [problems, each 'what is wrong: what is used instead']). texCoord and KHR_texture_transform as
    `validate.texcoord_of` reads them for the core slots; `normal`: a normalTextureInfo (its scale)."""
    out = {"index": -1, "texcoord": 0, "offset": (0.0, 0.0), "rotation": 0.0, "scale": (1.0, 1.0),
           "normal_scale": 1.0}
    if not isinstance(info, dict):
        return out, [f"must be an object, got {info!r}: no texture is used"]
    problems = []
    index = info.get("index")
    if not (isinstance(index, int) and not isinstance(index, bool) and 0 <= index < textures):
        problems.append(f"index {index!r} is not a texture of the file (there are {textures}): no texture is used")
    else:
        out["index"] = index

    def texcoord(v, what):
        if isinstance(v, int) and not isinstance(v, bool) and 0 <= v < 2**16:
            return v
        problems.append(f"{what} must be an integer >= 0, got {v!r}: {out['texcoord']} is used")
        return out["texcoord"]

    if "texCoord" in info:
        out["texcoord"] = texcoord(info["texCoord"], "texCoord")
    if normal and "scale" in info:      # normalTextureInfo (clearcoatNormalTexture)
        if _number(info["scale"]):
            out["normal_scale"] = float(info["scale"])
        else:
            problems.append(f"scale must be a finite number, got {info['scale']!r}: 1.0 is used")
    ext = info.get("extensions") or {}
    if not isinstance(ext, dict):
        problems.append(f"extensions must be an object, got {ext!r}: no transform is used")
        ext = {}
    tt = ext.get("KHR_texture_transform")
    if tt is not None and not isinstance(tt, dict):
        problems.append(f"KHR_texture_transform must be an object, got {tt!r}: no transform is used")
    elif tt is not None:
        for key in ("offset", "scale"):
            if key in tt:
                v = tt[key]
                if isinstance(v, list) and len(v) == 2 and all(_number(x) for x in v):
                    out[key] = (float(v[0]), float(v[1]))
                else:
                    problems.append(f"KHR_texture_transform.{key} must be 2 finite numbers, got {v!r}: "
                                    f"{list(out[key])} is used")
        if "rotation" in tt:
            if _number(tt["rotation"]):
                out["rotation"] = float(tt["rotation"])
            else:
                problems.append(f"KHR_texture_transform.rotation must be a finite number, got {tt['rotation']!r}: "
                                f"0.0 is used")
        if "texCoord" in tt:             # wins over the textureInfo's own texCoord
            out["texcoord"] = texcoord(tt["texCoord"], "KHR_texture_transform.texCoord")
    return out, problems
