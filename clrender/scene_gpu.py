"""Uploading a Scene to a device: geometry, material records and the mipmapped texture pool.

Uploads are cached per (scene, device) and rebuilt when the scene's arrays change identity
or shape. Mip chains are built once per texture object (box filter in linear space, as
GL's glGenerateMipmap does for sRGB textures).
"""
from __future__ import annotations

import weakref

import numpy as np
import pyopencl.array as cla
from PIL import Image

from . import structs
from .gbuffer import linear_to_srgb8, srgb_to_linear_lut
from .passes.base import Resources
from .scene import Scene, Texture

_MIP_CACHE: "weakref.WeakKeyDictionary[Texture, list[np.ndarray]]" = weakref.WeakKeyDictionary()


def mip_chain(tex: Texture) -> list[np.ndarray]:
    """RGBA8 levels, level 0 first, down to 1×1; sizes halve with floor as in GL."""
    cached = _MIP_CACHE.get(tex)
    if cached is not None:
        return cached
    levels = [tex.rgba]
    lut = srgb_to_linear_lut()
    h, w = tex.rgba.shape[:2]
    if max(h, w) > 1:
        linear = [lut[tex.rgba[..., c]] if (tex.srgb and c < 3) else tex.rgba[..., c].astype(np.float32) / 255.0
                  for c in range(4)]
        while max(h, w) > 1:
            h, w = max(h // 2, 1), max(w // 2, 1)
            linear = [np.asarray(Image.fromarray(ch, mode="F").resize((w, h), Image.BOX)) for ch in linear]
            level = np.empty((h, w, 4), np.uint8)
            for c in range(4):
                level[..., c] = (linear_to_srgb8(linear[c]) if (tex.srgb and c < 3)
                                 else np.floor(np.clip(linear[c], 0, 1) * 255 + 0.5).astype(np.uint8))
            levels.append(level)
    _MIP_CACHE[tex] = levels
    return levels


def texture_pool(textures: list[Texture]):
    """(texels uint32[N], TexInfo[T], TexLevel[L]) for all textures."""
    infos = np.zeros(max(len(textures), 1), structs.texinfo_dtype)
    level_records, chunks, offset = [], [], 0
    for t, tex in enumerate(textures):
        chain = mip_chain(tex)
        infos[t] = (len(level_records), len(chain), structs.WRAP[tex.wrap_s], structs.WRAP[tex.wrap_t])
        for level in chain:
            h, w = level.shape[:2]
            level_records.append((offset, w, h, 0))
            chunks.append(np.ascontiguousarray(level).view(np.uint32).reshape(-1))
            offset += w * h
    if offset >= 2**31:
        raise ValueError(f"textures need {offset} texels; more than 2^31 is not supported")
    levels = np.array(level_records or [(0, 1, 1, 0)], structs.texlevel_dtype)
    texels = np.concatenate(chunks) if chunks else np.zeros(1, np.uint32)
    return texels, infos, levels


def material_records(scene: Scene) -> np.ndarray:
    out = np.zeros(len(scene.materials), structs.material_dtype)
    for i, m in enumerate(scene.materials):
        flags = (structs.MAT_DOUBLE_SIDED if m.double_sided else 0)
        flags |= {"OPAQUE": 0, "MASK": structs.MAT_MASK, "BLEND": structs.MAT_BLEND}[m.alpha_mode]
        out[i] = (m.base_color, m.base_color_texture, m.specular_intensity, m.specular_power,
                  m.alpha_cutoff, flags, (0, 0, 0))
    return out


def _fingerprint(scene: Scene) -> tuple:
    arrays = (scene.positions, scene.normals, scene.uvs, scene.triangles, scene.triangle_material)
    return tuple((id(a), a.shape) for a in arrays) + (tuple(map(id, scene.materials)), tuple(map(id, scene.textures)))


_UPLOADS: dict = {}
_LIGHTS: dict = {}


def upload_lights(scene: Scene, device) -> dict:
    """The scene's lights as a device Light[] (re-uploaded when `scene.lights` changes)."""
    key = (id(scene), device.info.id)
    lights = scene.lights
    entry = _LIGHTS.get(key)
    if entry is not None and entry[0]() is scene and entry[1] is lights and entry[2] == lights.tobytes():
        return entry[3]
    data = np.ascontiguousarray(lights, structs.light_dtype)
    buf = cla.to_device(device.queue, data if len(data) else np.zeros(1, structs.light_dtype))
    values = {"lights": buf, "n_lights": int(len(data))}
    for k in [k for k, v in _LIGHTS.items() if v[0]() is None]:
        del _LIGHTS[k]
    _LIGHTS[key] = (weakref.ref(scene), lights, lights.tobytes(), values)
    return values


def upload(scene: Scene, device) -> Resources:
    """Device buffers for `scene` (cached while the scene object lives and is unchanged)."""
    key = (id(scene), device.info.id)
    entry = _UPLOADS.get(key)
    fingerprint = _fingerprint(scene)
    if entry is not None and entry[0]() is scene and entry[1] == fingerprint:
        return entry[2]
    q = device.queue

    def put(a, dtype):
        a = np.ascontiguousarray(a, dtype=dtype).reshape(-1)
        return cla.to_device(q, a if a.size else np.zeros(1, dtype))

    texels, infos, levels = texture_pool(scene.textures)
    res = Resources(buffers={
        "positions": put(scene.positions, np.float32),
        "normals": put(scene.normals, np.float32),
        "uvs": put(scene.uvs, np.float32),
        "triangles": put(scene.triangles, np.int32),
        "tri_material": put(scene.triangle_material, np.int32),
        "materials": cla.to_device(q, material_records(scene)),
        "texels": cla.to_device(q, texels),
        "tex_infos": cla.to_device(q, infos),
        "tex_levels": cla.to_device(q, levels),
        "srgb_lut": cla.to_device(q, srgb_to_linear_lut()),
    }, values={"n_tris": scene.triangle_count})
    for k in [k for k, v in _UPLOADS.items() if v[0]() is None]:
        del _UPLOADS[k]
    _UPLOADS[key] = (weakref.ref(scene), fingerprint, res)
    return res
