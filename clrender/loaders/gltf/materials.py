"""glTF 2.0 materials and textures -> clrender Materials and Textures (docs/materials.md).

Every core material property, KHR_materials_emissive_strength, KHR_materials_unlit, the surface
extensions (KHR_materials_ior, _specular, _clearcoat, _sheen, _iridescence, _anisotropy,
_transmission, _volume, _dispersion, _diffuse_transmission: read by clrender.loaders.gltf.surface,
whose out-of-range or ill-typed values are clamped or defaulted with one warning each), and on every
textureInfo its texCoord and KHR_texture_transform (`UVTransform`). Images are decoded in parallel
(`start_images`), while the loader reads the geometry; a texture is shared by (image, wrap modes,
colour space): base colour, emissive, specular colour, sheen colour and diffuse transmission colour
images are sRGB, the others linear.

An image file that is missing or cannot be decoded (and an embedded image that cannot be decoded)
is not an error: one warning names the file and the materials that use it, those materials' slots
get texture index -1 (they render with their factors alone) and the load goes on.
"""
from __future__ import annotations

import warnings
from urllib.parse import unquote

from clrender.scene.material import EXT_TEXTURE_SLOTS, TX_TEXTURE_SLOTS
from clrender.scene.model import TEXTURE_SLOTS, Material, SceneError, Texture, UVTransform
from clrender.loaders import confine
from clrender.loaders.common import decode_image, start_images
from clrender.loaders.gltf.document import Document, texture_source
from clrender.loaders.gltf.spec import EXT_TEXTURE_INFOS, TEXTURE_INFOS, WRAP_MODES
from clrender.loaders.gltf.surface import layer_texture, layer_textures, surface_values
from clrender.loaders.gltf.validate import data_uri, material_textures, texcoord_of

SRGB_SLOTS = {slot: srgb for slot, _, srgb in TEXTURE_INFOS} | {slot: srgb for slot, _, _, srgb in EXT_TEXTURE_INFOS}
NEAREST = 9728
# glTF 2.0 material properties (a misspelt one would otherwise silently give the default material)
MATERIAL_KEYS = {"name", "extensions", "extras", "pbrMetallicRoughness", "normalTexture", "occlusionTexture",
                 "emissiveTexture", "emissiveFactor", "alphaMode", "alphaCutoff", "doubleSided"}
PBR_KEYS = {"baseColorFactor", "baseColorTexture", "metallicFactor", "roughnessFactor", "metallicRoughnessTexture",
            "extensions", "extras"}


def uv_transform(doc: Document, what: str, info: dict) -> UVTransform:
    """A textureInfo's texCoord and KHR_texture_transform (whose texCoord, when given, wins)."""
    k = texcoord_of(doc, what, info)
    tt = (info.get("extensions") or {}).get("KHR_texture_transform") or {}
    try:
        return UVTransform(k, tuple(tt.get("offset", (0.0, 0.0))), float(tt.get("rotation", 0.0)),
                           tuple(tt.get("scale", (1.0, 1.0))))
    except SceneError as exc:
        raise doc.err(f"{what}: {exc}") from None


def load_materials(doc: Document, features: dict):
    """Every glTF material as a `Material` (docs/materials.md), and `textures() -> [Texture]`: the
    textures they use, one per (image, wrapS, wrapT, sRGB), so an image read both as colour (base
    colour, emissive: sRGB) and as data (metallic-roughness, normal, occlusion: linear) becomes two.
    The images decode in a thread pool from this call on; textures() waits for them (and raises a
    decoding error); textures.cancel() drops the ones not started."""
    images = doc.list("images")
    textures_json = doc.list("textures")
    samplers = doc.list("samplers")
    slots: dict[tuple, int] = {}
    jobs, names, keys, users = [], [], [], []
    materials = []

    def texture(info: dict, srgb: bool, user: str) -> int:
        tex = textures_json[info["index"]]
        src = texture_source(tex)
        if src is None:
            return -1
        sampler = samplers[tex["sampler"]] if "sampler" in tex else {}
        if sampler.get("magFilter") == NEAREST:
            features.setdefault("nearest-neighbour magnification (sampler magFilter NEAREST)",
                                "textures are filtered trilinearly")
        key = (src, WRAP_MODES[sampler.get("wrapS", 10497)], WRAP_MODES[sampler.get("wrapT", 10497)], srgb)
        if key not in slots:
            slots[key] = len(jobs)
            jobs.append(_tolerant(_image_job(doc, src, images[src])))
            names.append(_image_name(images[src], src))
            keys.append(key)
            users.append([])
        if user not in users[slots[key]]:
            users[slots[key]].append(user)
        return slots[key]

    for m, mat in enumerate(doc.list("materials")):
        name = mat.get("name") or f"material{m}"
        where = f"material {m} ({name!r})"
        pbr = mat.get("pbrMetallicRoughness", {}) or {}
        ext = mat.get("extensions") or {}
        unknown = [f"'{k}'" for k in mat if k not in MATERIAL_KEYS]
        unknown += [f"'pbrMetallicRoughness.{k}'" for k in (pbr if isinstance(pbr, dict) else {}) if k not in PBR_KEYS]
        if unknown:
            warnings.warn(f"{doc.path}: material {m} ({name!r}): unknown properties ignored: {', '.join(unknown)}",
                          stacklevel=3)
        color = pbr.get("baseColorFactor", [1.0, 1.0, 1.0, 1.0])
        if not isinstance(color, list) or len(color) != 4:
            raise doc.err(f"{where}: baseColorFactor needs 4 numbers")
        kw = {}
        if "KHR_materials_pbrSpecularGlossiness" in ext:    # archived model: converted at load (specgloss.py)
            from clrender.loaders.gltf.specgloss import convert
            mat, color, pbr = convert(doc, where, mat, kw, texture, _image_job, (slots, jobs, names, keys, users))
        for slot, label, info in material_textures(doc, m, mat):
            kw[f"{slot}_texture"] = texture(info, SRGB_SLOTS[slot], f"material {m} ({name!r}) {label}")
            kw[f"{slot}_uv"] = uv_transform(doc, f"{where} {label}", info)
        if "normalTexture" in mat:
            kw["normal_scale"] = mat["normalTexture"].get("scale", 1.0)
        if "occlusionTexture" in mat:
            kw["occlusion_strength"] = mat["occlusionTexture"].get("strength", 1.0)
        strength = ext.get("KHR_materials_emissive_strength")
        if strength is not None:
            kw["emissive_strength"] = (strength or {}).get("emissiveStrength", 1.0)
        values, problems = surface_values(ext)
        kw.update(values)
        for slot, label, info in layer_textures(mat):
            tex, bad = layer_texture(info, len(textures_json), normal=slot == "clearcoat_normal")
            problems += [f"{label} {p}" if p.startswith("must") else f"{label}.{p}" for p in bad]
            if tex["index"] >= 0:
                kw[f"{slot}_texture"] = texture({"index": tex["index"]}, SRGB_SLOTS[slot], f"{where} {label}")
                kw[f"{slot}_uv"] = UVTransform(tex["texcoord"], tex["offset"], tex["rotation"], tex["scale"])
            if slot == "clearcoat_normal":
                kw["clearcoat_normal_scale"] = tex["normal_scale"]
        for p in problems:      # the bad-input rule: one warning each, the load goes on
            warnings.warn(f"{doc.path}: {where}: {p}", stacklevel=3)
        try:
            materials.append(Material.from_metallic_roughness(
                name, tuple(color), pbr.get("metallicFactor", 1.0), pbr.get("roughnessFactor", 1.0),
                emissive=tuple(mat.get("emissiveFactor", (0.0, 0.0, 0.0))),
                unlit="KHR_materials_unlit" in ext,
                double_sided=bool(mat.get("doubleSided", False)),
                alpha_mode=mat.get("alphaMode", "OPAQUE"),
                alpha_cutoff=float(mat.get("alphaCutoff", 0.5)), **kw))
        except (SceneError, TypeError, ValueError) as exc:
            raise doc.err(f"{where}: {exc}") from None
    wait = start_images(jobs)

    def textures() -> list[Texture]:
        images_ = wait()
        kept = [j for j, rgba in enumerate(images_) if not isinstance(rgba, SceneError)]
        failed: dict = {}               # image index -> (its error, the users of every texture made from it)
        for j, rgba in enumerate(images_):
            if isinstance(rgba, SceneError):
                error, who = failed.setdefault(keys[j][0], (rgba, []))
                who.extend(u for u in users[j] if u not in who)
        for error, who in failed.values():
            warnings.warn(f"{error} (used by {'; '.join(who)}): the texture is left out, the material renders "
                          f"with its factors", stacklevel=2)
        if len(kept) < len(images_):
            _drop_textures(materials, {j: k for k, j in enumerate(kept)}, len(images_))
        return [Texture(names[j], images_[j], ws, wt, srgb=srgb) for j, (_, ws, wt, srgb) in
                ((j, keys[j]) for j in kept)]
    textures.cancel = wait.cancel
    return materials, textures


def _tolerant(job):
    """The image job, returning its SceneError (missing or undecodable file) instead of raising it.
    An image over the memory budget is raised: the load fails rather than silently losing it."""
    from clrender.loaders.budget import BudgetError

    def run():
        try:
            return job()
        except BudgetError:
            raise
        except SceneError as exc:
            return exc
    return run


def _drop_textures(materials: list, remap: dict, count: int) -> None:
    """Renumber the materials' texture indices after failed images were left out (`remap`: old
    index -> new; a missing one -> -1). The Material objects are changed in place: the loader made
    them and the Scene being assembled already holds these very objects (common.assemble copies
    the list before it calls textures()), so replacing them in `materials` would not reach it."""
    for m in materials:
        for slot in TEXTURE_SLOTS + EXT_TEXTURE_SLOTS + TX_TEXTURE_SLOTS:
            t = getattr(m, f"{slot}_texture")
            if 0 <= t < count:
                object.__setattr__(m, f"{slot}_texture", remap.get(t, -1))


def _image_name(img: dict, index: int) -> str:
    if img.get("name"):
        return str(img["name"])
    uri = img.get("uri", "")
    if uri and not uri.startswith("data:"):
        return unquote(uri).replace("\\", "/").rsplit("/", 1)[-1]
    return f"image{index}"


def _image_job(doc: Document, index: int, img: dict):
    where = f"{doc.path}: image {index}"
    if "bufferView" in img:
        data = bytes(doc.view_bytes(img["bufferView"]))
        return lambda: decode_image(data, where)
    uri = img.get("uri")
    if not uri:
        raise doc.err(f"image {index} has neither a uri nor a bufferView")
    if isinstance(uri, str) and uri.startswith("data:"):
        data = data_uri(doc, uri, f"image {index}")
        return lambda: decode_image(data, where)
    # outside the scene's folder: an error now (not the tolerant warning of a missing file)
    file = confine.gltf_uri(doc.path, uri, f"image {index} uri")
    return lambda: decode_image(file, where)        # a missing file: SceneError "texture file not found"
