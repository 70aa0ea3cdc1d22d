"""Uploading a Scene to a device: geometry, material records and the mipmapped texture pool.

Uploads are cached per (scene, device) and rebuilt when the scene's arrays change identity
or shape (an upload replaces its predecessor; both are dropped when the scene is collected).
Between animation frames (Scene.set_transform replaces positions, normals, tangents, triangles
and previous_positions) only the replaced arrays are written into the existing buffers; the
texture pool, materials, uvs... stay as they are. The scene and its lights are validated whenever
they are (re)uploaded (a pose-only update checks what changed), so arrays edited after
construction cannot reach a kernel with an out-of-range index or a NaN light. The mipmapped
texture pool is clrender/render/texture_pool.py's (box filter in linear space, as GL's glGenerateMipmap
does for sRGB textures; built on the device when it has doubles).
"""
from __future__ import annotations

import weakref

import numpy as np
import pyopencl.array as cla

from clrender.scene import model as scene_module
from clrender.abi import structs
from clrender.passes.base import Resources
from clrender.passes.fragments import transparent_triangle_count  # noqa: F401  (kept here: its old home)
from clrender.scene.model import TEXTURE_SLOTS, Scene, SceneError, Texture
from clrender.render.texture_pool import upload_pool


def _slot_record(tex: int, uv) -> tuple:
    return (uv.matrix().reshape(-1).astype(np.float32), tex, uv.texcoord)


def shares_base_footprint(scene: Scene, m, slot: str) -> bool:
    """Whether slot `slot` of material m can be read through its base colour texture's trilinear
    footprint (kernels/material_eval.h sample_slot_shared): same texture size (so the same mip
    chain), wrap modes, uv set and transform, and the slot's glTF colour space (sRGB for emissive,
    linear for the others), so the kernel only fetches its texels."""
    base, tex = m.base_color_texture, getattr(m, f"{slot}_texture")
    if base < 0 or tex < 0:
        return False
    a, b = scene.textures[base], scene.textures[tex]
    return (a.rgba.shape == b.rgba.shape and (a.wrap_s, a.wrap_t) == (b.wrap_s, b.wrap_t)
            and m.base_color_uv == getattr(m, f"{slot}_uv") and b.srgb == (slot == "emissive"))


_ORM_CACHE: "weakref.WeakKeyDictionary[Texture, dict]" = weakref.WeakKeyDictionary()


def orm_texture(occlusion: Texture, metallic_roughness: Texture) -> Texture:
    """glTF's ORM packing of two linear images of one size: R from the occlusion image, G, B, A
    from the metallic-roughness one. Mip levels filter channels independently, so the merged
    texture's texels are the two images' texels: the kernels read both slots with one fetch."""
    per = _ORM_CACHE.setdefault(occlusion, {})
    merged = per.get(metallic_roughness)
    if merged is None:
        rgba = metallic_roughness.rgba.copy()
        rgba[..., 0] = occlusion.rgba[..., 0]
        merged = Texture(f"{occlusion.name}+{metallic_roughness.name}", rgba, metallic_roughness.wrap_s,
                         metallic_roughness.wrap_t, srgb=False)
        per[metallic_roughness] = merged
    return merged


def device_materials(scene: Scene) -> tuple[list[Texture], np.ndarray]:
    """The textures the device holds (the scene's, plus ORM merges) and the Material records.
    A material whose occlusion and metallic-roughness images are distinct but both read through the
    base colour's footprint gets one merged ORM texture for both slots (orm_texture)."""
    textures = list(scene.textures)
    merged_index: dict = {}
    slots = []
    for m in scene.materials:
        tex = {s: getattr(m, f"{s}_texture") for s in TEXTURE_SLOTS}
        occ, mr = tex["occlusion"], tex["metallic_roughness"]
        if (occ >= 0 and mr >= 0 and occ != mr and scene.textures[occ].rgba.shape == scene.textures[mr].rgba.shape
                and shares_base_footprint(scene, m, "occlusion") and shares_base_footprint(scene, m, "metallic_roughness")):
            key = (occ, mr)
            if key not in merged_index:
                merged_index[key] = len(textures)
                textures.append(orm_texture(scene.textures[occ], scene.textures[mr]))
            tex["occlusion"] = tex["metallic_roughness"] = merged_index[key]
        slots.append(tex)
    return textures, material_records(scene, slots)


def material_records(scene: Scene, slot_textures: list | None = None) -> np.ndarray:
    """Material[] for the device; slot_textures: per material, {slot: device texture index}
    (device_materials' remapping; default: the materials' own indices)."""
    out = np.zeros(len(scene.materials), structs.material_dtype)
    for i, m in enumerate(scene.materials):
        flags = (structs.MAT_DOUBLE_SIDED if m.double_sided else 0)
        flags |= {"OPAQUE": 0, "MASK": structs.MAT_MASK, "BLEND": structs.MAT_BLEND}[m.alpha_mode]
        flags |= (structs.MAT_METALLIC_ROUGHNESS if m.metallic is not None else 0)
        flags |= (structs.MAT_UNLIT if m.unlit else 0)
        flags |= (structs.MAT_GLTF_BRDF if m.metallic is not None and not m.unlit else 0)
        for k, slot in enumerate(TEXTURE_SLOTS[1:]):
            flags |= (structs.MAT_SHARES_FIRST << k) if shares_base_footprint(scene, m, slot) else 0
        color = m.base_color[:3] + (m.base_color[3] * m.opacity,)     # opacity folds into alpha
        door = 1.0
        if m.transmissive:      # the transparent-fragment path, shaded with its MaterialTx (tx_records)
            flags |= structs.MAT_BLEND | structs.MAT_TRANSMISSION
            flags |= structs.MAT_TX_ALPHA if m.alpha_mode == "BLEND" else 0    # else alpha is not coverage
            door = 1.0 - m.transmission * (1.0 - m.metallic)      # screen door: what is not let through
        tex = slot_textures[i] if slot_textures is not None else {s: getattr(m, f"{s}_texture") for s in TEXTURE_SLOTS}
        slots = [_slot_record(tex[s], getattr(m, f"{s}_uv")) for s in TEXTURE_SLOTS]
        out[i] = (color, m.emissive, m.emissive_strength, m.specular_intensity, m.specular_power,
                  0.0 if m.metallic is None else m.metallic, m.roughness, m.normal_scale, m.occlusion_strength,
                  m.alpha_cutoff, flags, m.refraction, -1, -1, door, slots)
    return out


def blinn_phong_records(records: np.ndarray, materials: list) -> np.ndarray:
    """The material records with no glTF-BRDF flag: the metallic-roughness mapping onto the
    report's Blinn-Phong terms (kernels/material_eval.h) shades everything, layers included.
    Transmission is a glTF-BRDF feature: a transmissive material (`materials`: the scene's) is
    opaque here unless its alpha mode is BLEND."""
    out = records.copy()
    out["flags"] &= np.uint32(~structs.MAT_GLTF_BRDF & ~structs.MAT_TRANSMISSION & ~structs.MAT_TX_ALPHA & 0xFFFFFFFF)
    for i, m in enumerate(materials):
        if m.transmissive and m.alpha_mode != "BLEND":
            out["flags"][i] &= np.uint32(~structs.MAT_BLEND & 0xFFFFFFFF)
    out["ext"] = out["tx"] = -1
    out["door_alpha"] = 1.0
    return out


def material_layers(m) -> frozenset:
    """The surface layers of material m (Material.layers; none on a material without the fields)."""
    return frozenset(getattr(m, "layers", ()))


def layer_records(scene: Scene, records: np.ndarray) -> np.ndarray:
    """MaterialExt[] of the materials with layers (kernels/structs.h), and each one's index set in
    `records["ext"]` (-1 elsewhere). A scene without layers gets no record: nothing is uploaded or
    built for it (clrender/passes/surface_layers.py)."""
    from clrender.scene.material import EXT_TEXTURE_SLOTS
    rows = []
    for i, m in enumerate(scene.materials):
        layers = material_layers(m)
        if not layers:
            continue
        records["ext"][i] = len(rows)
        slots = [_slot_record(getattr(m, f"{s}_texture"), getattr(m, f"{s}_uv")) for s in EXT_TEXTURE_SLOTS]
        bits = sum(structs.LAYER_BITS[name] for name in layers)
        rows.append((m.specular_color, m.specular_factor, m.ior, m.clearcoat, m.clearcoat_roughness,
                     m.clearcoat_normal_scale, m.sheen_color, m.sheen_roughness, m.iridescence, m.iridescence_ior,
                     m.iridescence_thickness_min, m.iridescence_thickness_max, m.anisotropy_strength,
                     np.cos(m.anisotropy_rotation), np.sin(m.anisotropy_rotation), bits, m.diffuse_transmission,
                     m.diffuse_transmission_color, slots))
    return np.array(rows, structs.material_ext_dtype)


def tx_records(scene: Scene, records: np.ndarray) -> np.ndarray:
    """MaterialTx[] of the transmissive materials (kernels/structs.h), and each one's index set in
    `records["tx"]` (-1 elsewhere). Thickness and dispersion are 0 (thin-walled, no dispersion, no
    thickness texture read) unless the material has a volume; an infinite attenuation distance
    stays +inf. A scene without transmissive materials gets no record: nothing is uploaded or built."""
    from clrender.scene.material import TX_TEXTURE_SLOTS
    rows = []
    for i, m in enumerate(scene.materials):
        if not m.transmissive:
            continue
        records["tx"][i] = len(rows)
        volume = m.has_volume
        slots = [_slot_record(getattr(m, f"{s}_texture") if (volume or s != "thickness") else -1,
                              getattr(m, f"{s}_uv")) for s in TX_TEXTURE_SLOTS]
        rows.append((m.transmission, m.thickness if volume else 0.0, m.attenuation_distance,
                     m.dispersion if volume else 0.0, m.attenuation_color, m.ior, m.specular_color,
                     m.specular_factor, slots))
    return np.array(rows, structs.material_tx_dtype)


def triangle_volume_scales(scene: Scene) -> np.ndarray:
    """float32[T]: each triangle's object's volume_scale (KHR_materials_volume: the node's scale
    applies to the thickness) when a material has a volume; else [1.0] (never read)."""
    scales = _volume_scales(scene)
    if not scales:
        return np.ones(1, np.float32)
    return np.asarray(scales, np.float32)[scene.triangle_object]


def _volume_scales(scene: Scene) -> tuple:
    """The objects' volume scales when a material has a volume (what tri_volume_scale reads), else ()."""
    if not any(m.has_volume for m in scene.materials):
        return ()
    return tuple(getattr(o, "volume_scale", 1.0) for o in scene.objects)    # validate() rejects non-objects


def multiscatter_buffers(scene: Scene, device) -> dict:
    """RenderConfig.multiscatter: {"materials", "material_ext"} with every glTF-BRDF material given a
    MaterialExt record (layers 0 where it has none), so the surface-layers pass shades them all with
    the energy compensation; made on first use and kept with the scene's upload."""
    upload_res = _UPLOADS[(id(scene), device.info.id)][2]
    if "materials_multiscatter" not in upload_res.buffers:
        q = device.queue
        materials = upload_res.buffers["materials"].get(q)
        layered = layer_records(scene, materials)
        extra = [i for i, m in enumerate(scene.materials) if materials["ext"][i] < 0
                 and materials["flags"][i] & structs.MAT_GLTF_BRDF]
        plain = np.zeros(len(extra), structs.material_ext_dtype)
        plain["specular_color"], plain["specular_factor"], plain["ior"] = 1.0, 1.0, 1.5
        plain["iridescence_ior"], plain["iridescence_thickness_max"], plain["anisotropy_cos"] = 1.3, 400.0, 1.0
        plain["diffuse_transmission_color"] = 1.0
        plain["slots"]["texture"] = -1
        materials["ext"][extra] = len(layered) + np.arange(len(extra))
        records = np.concatenate([layered, plain]) if len(extra) else layered
        upload_res.buffers["materials_multiscatter"] = cla.to_device(q, materials)
        upload_res.buffers["material_ext_multiscatter"] = cla.to_device(q, records if len(records) else
                                                                        np.zeros(1, structs.material_ext_dtype))
        upload_res.values["layered_multiscatter"] = len(records)
    return {"materials": upload_res.buffers["materials_multiscatter"],
            "material_ext": upload_res.buffers["material_ext_multiscatter"],
            "layered_materials": upload_res.values["layered_multiscatter"]}


def surface_extras(scene: Scene) -> bool:
    """Whether a material emits, has an occlusion texture or is unlit: the shading then reads the
    G-buffer's emissive_occlusion plane and the materials (docs/materials.md)."""
    return any(m.emits or m.occlusion_texture >= 0 or m.unlit for m in scene.materials)


def vertex_tangents(scene: Scene):
    """The scene's tangents; generated (clrender/scene/tangents.py) when a material has a normal map,
    a clearcoat normal map or anisotropy and the scene has none; None when nothing needs them."""
    if scene.tangents is not None:
        return scene.tangents
    sets = tangent_uv_sets(scene)
    if not sets:
        return None
    from clrender.scene.tangents import generate_tangents
    return generate_tangents(scene.positions, scene.normals, scene.uv_set(sets[0]), scene.triangles)


def tangent_uv_sets(scene: Scene) -> list:
    """The UV sets of the maps that need tangents (normal, clearcoat normal, anisotropy), sorted."""
    return sorted({m.normal_uv.texcoord for m in scene.materials if m.normal_texture >= 0}
                  | {m.clearcoat_normal_uv.texcoord for m in scene.materials
                     if getattr(m, "clearcoat_normal_texture", -1) >= 0}
                  | {m.anisotropy_uv.texcoord if m.anisotropy_texture >= 0 else m.normal_uv.texcoord
                     for m in scene.materials if "anisotropy" in material_layers(m)})


def vertex_bytes(scene: Scene) -> int:
    """Device bytes of upload()'s per-vertex buffers: positions, normals, every UV set, tangents
    (the scene's or generated), colours (clrender/render/memory.py's estimate)."""
    v = len(scene.positions)
    uv_sets = 1 + (0 if scene.extra_uvs is None else len(scene.extra_uvs))
    tangents = scene.tangents is not None or bool(tangent_uv_sets(scene))
    return v * (12 + 12 + 8 * uv_sets + (16 if tangents else 0) + (16 if scene.colors is not None else 0))


# The arrays an upload reads. An entry keeps them (strong references, so that an identity compared
# later cannot be a new array's at a recycled address) with their shapes, materials and textures.
_ARRAYS = ("positions", "normals", "uvs", "triangles", "triangle_material", "previous_positions", "colors",
           "tangents", "extra_uvs")
# Per-vertex / per-triangle geometry that posing replaces (Scene.set_transform): array -> buffer name.
_POSED = {"positions": "positions", "normals": "normals", "tangents": "tangents", "triangles": "triangles",
          "previous_positions": "prev_positions"}
_DTYPES = {"positions": np.float32, "normals": np.float32, "tangents": np.float32, "triangles": np.int32,
           "previous_positions": np.float32}


def _fingerprint(scene: Scene) -> tuple:
    arrays = tuple(getattr(scene, name) for name in _ARRAYS)
    return (arrays, tuple(np.shape(a) for a in arrays), tuple(scene.materials), tuple(scene.textures),
            _volume_scales(scene))


def _identical(xs, ys) -> bool:
    """The same objects, in the same order (identity, not equality)."""
    return len(xs) == len(ys) and all(x is y for x, y in zip(xs, ys))


def _same(a: tuple, b: tuple) -> bool:
    """Fingerprints of the same objects (compared by identity) and shapes."""
    return (a[1] == b[1] and _identical(a[0], b[0]) and _identical(a[2], b[2]) and _identical(a[3], b[3])
            and a[4] == b[4])


_UPLOADS: dict = {}
_LIGHTS: dict = {}
_WATCHED: set = set()


def _forget(key) -> None:
    _UPLOADS.pop(key, None)
    _LIGHTS.pop(key, None)
    _WATCHED.discard(key)


def _watch(scene: Scene, key) -> None:
    """Free the scene's device buffers as soon as the scene is collected (one finalizer per key)."""
    if key not in _WATCHED:
        _WATCHED.add(key)
        weakref.finalize(scene, _forget, key)


def check_lights(lights: np.ndarray, where: str) -> None:
    """SceneError for a light no kernel can use: non-finite position, color or direction, a
    negative color, or a radius that is not positive and finite."""
    bad = {"position": ~np.isfinite(lights["position"]).all(1),
           "direction": ~np.isfinite(lights["direction"]).all(1),
           "color": ~(np.isfinite(lights["color"]) & (lights["color"] >= 0)).all(1),
           "radius": ~(np.isfinite(lights["radius"]) & (lights["radius"] > 0))}
    for field, mask in bad.items():
        if mask.any():
            i = int(np.argmax(mask))
            need = {"color": "finite and >= 0", "radius": "positive and finite"}.get(field, "finite")
            raise SceneError(f"{where}: light {i}: {field} must be {need}, got {np.asarray(lights[field][i]).tolist()}")


def shadow_indices(data: np.ndarray, where: str) -> np.ndarray:
    """Sets `shadow` (index among shadowed spots, -1 = none) in the light records; returns the
    mask of shadowed lights. Only spot lights have shadow maps (SceneError otherwise)."""
    from clrender.scene.model import SHADOW_MAP_SIZES
    wants = data["shadow_size"] != 0
    bad = wants & ((data["type"] != structs.LIGHT_SPOT) | (data["shadow_size"] < SHADOW_MAP_SIZES[0])
                   | (data["shadow_size"] > SHADOW_MAP_SIZES[1]))
    if bad.any():
        i = int(np.argmax(bad))
        raise SceneError(f"{where}: light {i}: shadow_size {int(data['shadow_size'][i])} needs a spot light and a "
                         f"size in {list(SHADOW_MAP_SIZES)}")
    data["shadow"] = -1
    data["shadow"][wants] = np.arange(int(wants.sum()), dtype=np.int32)
    return wants


def upload_lights(scene: Scene, device) -> dict:
    """The scene's lights as a device Light[] (re-uploaded when `scene.lights` changes)."""
    key = (id(scene), device.info.id)
    lights = scene.lights
    entry = _LIGHTS.get(key)
    if entry is not None and entry[0]() is scene and entry[1] is lights and entry[2] == lights.tobytes():
        return entry[3]
    data = np.array(lights, structs.light_dtype).reshape(-1)      # a copy: `shadow` is set below
    check_lights(data, scene.source)
    shadowed = shadow_indices(data, scene.source)
    _LIGHTS.pop(key, None)                    # release the previous upload before allocating
    buf = cla.to_device(device.queue, data if len(data) else np.zeros(1, structs.light_dtype))
    values = {"lights": buf, "n_lights": int(len(data)), "shadow_lights": data[shadowed], "lights_blinn_phong": buf}
    if len(data) and np.any(data["falloff"] != structs.FALLOFF_REPORT):
        # RenderConfig.shading = "blinn_phong": the report's falloff for glTF lights too
        report = data.copy()
        report["falloff"] = structs.FALLOFF_REPORT
        values["lights_blinn_phong"] = cla.to_device(device.queue, report)
    _LIGHTS[key] = (weakref.ref(scene), lights, lights.tobytes(), values)
    _watch(scene, key)
    return values


def needs_upload(scene: Scene, device) -> bool:
    """Whether `upload()` would (re)build or update the scene's device buffers."""
    entry = _UPLOADS.get((id(scene), device.info.id))
    return entry is None or entry[0]() is not scene or not _same(entry[1], _fingerprint(scene))


def upload(scene: Scene, device) -> Resources:
    """Device buffers for `scene` (cached while the scene object lives and is unchanged). When only
    posed geometry changed since the last upload (`_update`), the new data is written into the
    existing buffers instead."""
    key = (id(scene), device.info.id)
    entry = _UPLOADS.get(key)
    fingerprint = _fingerprint(scene)
    if entry is not None and entry[0]() is scene:
        if _same(entry[1], fingerprint):
            return entry[2]
        if _update(scene, device, entry[1], fingerprint, entry[2]):
            _UPLOADS[key] = (entry[0], fingerprint, entry[2])
            return entry[2]
    for name, cols in (("positions", 3), ("triangles", 3)):    # arrays may have been replaced since construction
        shape = np.shape(getattr(scene, name))
        if len(shape) != 2 or shape[1] != cols:
            raise SceneError(f"{scene.source}: {name} must have shape (N, {cols}), got {shape}")
    scene.validate()
    _UPLOADS.pop(key, None)                   # release the previous upload before allocating
    q = device.queue

    def put(a, dtype):
        a = np.ascontiguousarray(a, dtype=dtype).reshape(-1)
        return cla.to_device(q, a if a.size else np.zeros(1, dtype))

    textures, materials = device_materials(scene)
    layers = layer_records(scene, materials)          # sets materials["ext"]
    tx = tx_records(scene, materials)                 # sets materials["tx"]
    uvs = scene.uvs if scene.extra_uvs is None else np.concatenate([scene.uvs[None], scene.extra_uvs])
    tangents = vertex_tangents(scene)
    res = Resources(buffers={
        "positions": put(scene.positions, np.float32),
        "normals": put(scene.normals, np.float32),
        "uvs": put(uvs, np.float32),
        "tangents": put(np.zeros(0) if tangents is None else tangents, np.float32),
        "colors": put(np.zeros(0) if scene.colors is None else scene.colors, np.float32),
        "triangles": put(scene.triangles, np.int32),
        "tri_material": put(scene.triangle_material, np.int32),
        "materials": cla.to_device(q, materials),
        # RenderConfig.shading = "blinn_phong": every material through the report's model
        "materials_blinn_phong": cla.to_device(q, blinn_phong_records(materials, scene.materials)),
        **upload_pool(device, textures),             # texels, tex_infos, tex_levels, srgb_lut
        **({"material_ext": cla.to_device(q, layers)} if len(layers) else {}),
    }, values={"n_tris": scene.triangle_count, "scene_bounds": scene.bounds(),   # bounds: sun shadow fit
               "layered_materials": len(layers), "has_tangents": int(tangents is not None),
               "n_transparent_tris": transparent_triangle_count(scene), "n_vertices": len(scene.positions),
               "has_colors": int(scene.colors is not None), "n_textures": len(textures), "surface_extras": int(surface_extras(scene)),
               "gltf_scene": int(np.any(materials["flags"] & structs.MAT_GLTF_BRDF)),
               "transmissive_materials": len(tx)})
    if len(tx):                                  # see-through materials (clrender/passes/transmission.py)
        res.buffers["material_tx"] = cla.to_device(q, tx)
        res.buffers["tri_volume_scale"] = cla.to_device(q, triangle_volume_scales(scene))
        _transmission_args(res)
    if scene.previous_positions is not None:     # objects moved (Scene.set_transform): the G-buffer's velocity
        res.buffers["prev_positions"] = put(scene.previous_positions, np.float32)
    _UPLOADS[key] = (weakref.ref(scene), fingerprint, res)
    _watch(scene, key)
    return res


def _transmission_args(res: Resources) -> None:
    res.values["transmission_args"] = (res.buffers["material_tx"].data, res.buffers["tri_volume_scale"].data)


def _update(scene: Scene, device, old: tuple, new: tuple, res: Resources) -> bool:
    """Between animation frames: when only posed geometry (_POSED) was replaced, by arrays of the
    same shapes (previous_positions may also appear or disappear), and uvs, colors, materials,
    textures... are the same objects, write the replaced arrays into the existing device buffers and
    update the values derived from them; False (nothing done) when a full upload is needed. Checks
    what Scene.validate() checks of the replaced arrays. Objects' changed volume scales (same objects
    count) rewrite tri_volume_scale. A rewritten buffer gets a new Array object
    over the same device memory, so caches keyed by buffer identity (the shadow pass's kept maps)
    see the change as they see a full upload's new buffers."""
    changed = []
    for k, name in enumerate(_ARRAYS):
        a, b, shape = old[0][k], new[0][k], new[1][k]
        if a is b and old[1][k] == shape:
            continue
        if name not in _POSED or (old[1][k] != shape and not (name == "previous_positions" and
                                                                (a is None or b is None))):
            return False
        changed.append(name)
    if not (_identical(old[2], new[2]) and _identical(old[3], new[3])):     # materials, textures
        return False
    if len(old[4]) != len(new[4]):          # objects added or removed
        return False
    where, nv = scene.source, len(scene.positions)
    if "triangles" in changed and scene.triangle_count and (scene.triangles.min() < 0
                                                              or scene.triangles.max() >= nv):
        raise SceneError(f"{where}: a triangle index is out of range (there are {nv} vertices)")
    for name in ("positions", "previous_positions"):
        if name in changed and getattr(scene, name) is not None:
            scene_module.check_positions(getattr(scene, name), where, name)
    if "tangents" in changed and scene.tangents is not None and not np.isfinite(scene.tangents).all():
        raise SceneError(f"{where}: tangents must be finite with shape {(nv, 4)}, got {np.shape(scene.tangents)}")
    if scene.previous_positions is not None and np.shape(scene.previous_positions) != (nv, 3):
        raise SceneError(f"{where}: previous_positions must have shape ({nv}, 3) like positions, "
                         f"got {np.shape(scene.previous_positions)}")
    if scene.tangents is None and "tangents" not in changed and {"positions", "normals", "triangles"} & set(changed):
        changed.append("tangents")          # generated from positions, normals, uvs, triangles (if at all)
    q = device.queue
    for name in changed:
        buffer = _POSED[name]
        if name == "tangents":
            data = vertex_tangents(scene)
            if data is None:
                continue                    # nothing needs tangents: the buffer stays a placeholder
        else:
            data = getattr(scene, name)
        if data is None:                    # previous_positions gone: no motion
            res.buffers.pop(buffer, None)
            continue
        data = np.ascontiguousarray(data, dtype=_DTYPES[name]).reshape(-1)
        current = res.buffers.get(buffer)
        if current is None:                 # previous_positions appeared
            res.buffers[buffer] = cla.to_device(q, data if data.size else np.zeros(1, data.dtype))
        elif data.size:
            current.set(data, queue=q)
            res.buffers[buffer] = current.view()
    if {"positions", "triangles"} & set(changed):
        res.values["scene_bounds"] = scene.bounds()
    if old[4] != new[4]:                    # an object's volume scale changed (materials are the same)
        current = res.buffers["tri_volume_scale"]
        current.set(triangle_volume_scales(scene), queue=q)
        res.buffers["tri_volume_scale"] = current.view()
        _transmission_args(res)
    return True

