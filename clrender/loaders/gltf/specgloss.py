"""KHR_materials_pbrSpecularGlossiness (archived) converted to metallic-roughness at load
(docs/materials.md "Specular-glossiness").

The extension's model (KhronosGroup/glTF, extensions/2.0/Archived/KHR_materials_pbrSpecularGlossiness):
c_diff = diffuse.rgb * (1 - max(specular.rgb)), F0 = specular, alpha = (1 - glossiness)^2. It is turned
into base colour / metallic / roughness by the conversion published with that extension (its
convert-between-workflows example; Babylon.js and three.js use the same): metallic solved from the
perceived brightness of diffuse and specular, base colour mixed from the diffuse and the specular
estimates by metallic^2, roughness = 1 - glossiness. One shading model then goes through every
pipeline; tests/test_specgloss.py measures what the approximation costs in reflected radiance.

Factors alone convert exactly here. With a diffuseTexture and/or a specularGlossinessTexture the
conversion runs per texel (`bake`), on the host in float64 row blocks, into two new RGBA8 textures
(base colour: sRGB, with the diffuse alpha; metallic-roughness: linear, G = roughness, B = metallic)
at the per-axis larger of the two images' sizes, the other resampled bilinearly at texel centres
with its own wrap modes. That needs both textures to read the same UVs (texCoord, KHR_texture_transform,
wrap modes); otherwise the factors are converted, the diffuse texture is kept as the base colour
texture and one warning names the material.
"""
from __future__ import annotations

import threading
import warnings

import numpy as np

from clrender.loaders.budget import BudgetError, current
from clrender.loaders.gltf.document import texture_source
from clrender.loaders.gltf.spec import WRAP_MODES
from clrender.loaders.gltf.surface import layer_texture
from clrender.scene.model import SceneError, UVTransform

EXTENSION = "KHR_materials_pbrSpecularGlossiness"
DIELECTRIC_F0 = 0.04            # the conversion's dielectric reflectance (glTF's, IOR 1.5)
EPSILON = 1e-6                  # the published conversion's guard against 1/0
BRIGHTNESS = (0.299, 0.587, 0.114)      # its "perceived brightness" weights (on squared channels)
PROPERTIES = {"diffuseFactor", "diffuseTexture", "specularFactor", "glossinessFactor",
              "specularGlossinessTexture", "extensions", "extras"}
BLOCK_PIXELS = 1 << 16          # pixels per row block of a bake: bounds its float64 scratch
SCRATCH_PER_PIXEL = 640         # bytes of float64 scratch per pixel of a block (about 20 RGBA arrays)


# -- the conversion -----------------------------------------------------------------------------------
def perceived_brightness(rgb) -> np.ndarray:
    """sqrt(0.299 r^2 + 0.587 g^2 + 0.114 b^2) over the last axis."""
    c = np.asarray(rgb, np.float64)
    return np.sqrt(c[..., 0] ** 2 * BRIGHTNESS[0] + c[..., 1] ** 2 * BRIGHTNESS[1] + c[..., 2] ** 2 * BRIGHTNESS[2])


def solve_metallic(diffuse, specular, one_minus_specular_strength) -> np.ndarray:
    """The metallic value whose metallic-roughness material reproduces the brightnesses: the root of
    0.04 m^2 + b m + (0.04 - specular) = 0, b = diffuse (1 - max spec) / 0.96 + specular - 0.08, in [0, 1];
    0 where the specular brightness is below a dielectric's."""
    d, s, k = (np.asarray(x, np.float64) for x in (diffuse, specular, one_minus_specular_strength))
    a = DIELECTRIC_F0
    b = d * k / (1.0 - a) + s - 2.0 * a
    c = a - s
    disc = np.maximum(b * b - 4.0 * a * c, 0.0)     # >= 0 already where s >= 0.04; guards the other lanes
    m = np.clip((-b + np.sqrt(disc)) / (2.0 * a), 0.0, 1.0)
    return np.where(s < a, 0.0, m)


def to_metallic_roughness(diffuse, specular, glossiness):
    """(base colour RGB in [0, 1], metallic, roughness) of linear diffuse RGB, specular RGB and
    glossiness, broadcast over the leading axes (float64)."""
    diffuse = np.asarray(diffuse, np.float64)[..., :3]
    specular = np.asarray(specular, np.float64)[..., :3]
    keep = 1.0 - specular.max(axis=-1)
    metallic = solve_metallic(perceived_brightness(diffuse), perceived_brightness(specular), keep)
    m = metallic[..., None]
    from_diffuse = diffuse * (keep[..., None] / (1.0 - DIELECTRIC_F0) / np.maximum(1.0 - m, EPSILON))
    from_specular = (specular - DIELECTRIC_F0 * (1.0 - m)) / np.maximum(m, EPSILON)
    base = np.clip(from_diffuse + (from_specular - from_diffuse) * (m * m), 0.0, 1.0)
    return base, metallic, 1.0 - np.asarray(glossiness, np.float64)


def srgb_to_linear(c) -> np.ndarray:
    c = np.asarray(c, np.float64)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def linear_to_srgb(c) -> np.ndarray:
    c = np.clip(np.asarray(c, np.float64), 0.0, 1.0)
    return np.where(c <= 0.0031308, c * 12.92, 1.055 * c ** (1.0 / 2.4) - 0.055)


def _u8(x) -> np.ndarray:
    return np.floor(np.clip(x, 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8)


# -- reading the extension (the bad-input rule: clamp or default, one warning each) ---------------
def read(obj, textures: int) -> tuple[dict, list[str]]:
    """The extension object -> ({diffuse: 4-tuple, specular: 3-tuple, glossiness, diffuse_texture,
    specular_glossiness_texture: surface.layer_texture dicts or None}, [problems])."""
    out = {"diffuse": (1.0, 1.0, 1.0, 1.0), "specular": (1.0, 1.0, 1.0), "glossiness": 1.0,
           "diffuse_texture": None, "specular_glossiness_texture": None}
    problems = []
    unknown = sorted(k for k in obj if k not in PROPERTIES)
    if unknown:
        problems.append(f"{EXTENSION}: unknown properties ignored: {', '.join(repr(k) for k in unknown)}")
    for key, field, n in (("diffuseFactor", "diffuse", 4), ("specularFactor", "specular", 3),
                          ("glossinessFactor", "glossiness", 1)):
        if key not in obj:
            continue
        v = obj[key]
        vals = [v] if n == 1 else v
        if not (isinstance(vals, list) and len(vals) == n and all(
                isinstance(c, (int, float)) and not isinstance(c, bool) and np.isfinite(c) for c in vals)):
            problems.append(f"{EXTENSION}.{key} must be {n} finite number{'s' * (n > 1)}, got {v!r}: "
                            f"the default {out[field]!r} is used")
            continue
        got = tuple(float(c) for c in vals)
        clamped = tuple(min(max(c, 0.0), 1.0) for c in got)
        if clamped != got:
            problems.append(f"{EXTENSION}.{key} {v!r} is out of its range [0, 1]: clamped to "
                            f"{list(clamped) if n > 1 else clamped[0]!r}")
        out[field] = clamped if n > 1 else clamped[0]
    for key, field in (("diffuseTexture", "diffuse_texture"),
                       ("specularGlossinessTexture", "specular_glossiness_texture")):
        if key in obj:
            tex, bad = layer_texture(obj[key], textures)
            problems += [f"{EXTENSION}.{key} {p}" if p.startswith("must") else f"{EXTENSION}.{key}.{p}" for p in bad]
            out[field] = tex if tex["index"] >= 0 else None
    return out, problems


def convert(doc, where: str, mat: dict, kw: dict, texture, image_job, lists) -> tuple[dict, list, dict]:
    """The materials loader's hook for a material carrying the extension: (the material JSON without
    its pbrMetallicRoughness, which the extension replaces; base colour factor; {"metallicFactor",
    "roughnessFactor"}), with kw given the baked (or kept) base colour and metallic-roughness slots.
    `texture(info, srgb, user)` registers a glTF texture, `image_job(doc, index, image)` makes an image's
    decoding job; `lists` = the loader's (slots, jobs, names, keys, users) registry, where a baked texture
    is added as one more decoding job."""
    obj = (mat.get("extensions") or {})[EXTENSION]
    if not isinstance(obj, dict):
        warnings.warn(f"{doc.path}: {where}: {EXTENSION} must be an object, got {obj!r}: the extension is "
                      f"ignored", stacklevel=3)
        pbr = mat.get("pbrMetallicRoughness") or {}
        return mat, pbr.get("baseColorFactor", [1.0, 1.0, 1.0, 1.0]), pbr
    textures_json = doc.list("textures")
    sg, problems = read(obj, len(textures_json))
    for p in problems:
        warnings.warn(f"{doc.path}: {where}: {p}", stacklevel=3)
    core = {k: v for k, v in mat.items() if k != "pbrMetallicRoughness"}
    d_tex, s_tex = sg["diffuse_texture"], sg["specular_glossiness_texture"]
    base, metallic, roughness = to_metallic_roughness(sg["diffuse"][:3], sg["specular"], sg["glossiness"])
    color = [*(float(c) for c in base), sg["diffuse"][3]]
    pbr = {"metallicFactor": float(metallic), "roughnessFactor": float(roughness)}
    if d_tex is None and s_tex is None:
        return core, color, pbr

    def uv(tex):
        return UVTransform(tex["texcoord"], tex["offset"], tex["rotation"], tex["scale"])

    def sampled(tex):       # (image index or None, wrapS, wrapT) as the loader's texture() reads them
        t = textures_json[tex["index"]]
        sampler = doc.list("samplers")[t["sampler"]] if "sampler" in t else {}
        return (texture_source(t), WRAP_MODES[sampler.get("wrapS", 10497)], WRAP_MODES[sampler.get("wrapT", 10497)])

    d_src, s_src = (sampled(t) if t is not None else None for t in (d_tex, s_tex))
    if d_src is not None and s_src is not None and (uv(d_tex) != uv(s_tex) or d_src[1:] != s_src[1:]):
        warnings.warn(f"{doc.path}: {where}: {EXTENSION}: diffuseTexture and specularGlossinessTexture read "
                      f"different texture coordinates, transforms or wrap modes, so they cannot be converted "
                      f"texel by texel: the factors are converted, the diffuse texture is kept as the base colour "
                      f"texture and specularGlossinessTexture is ignored", stacklevel=3)
        kw["base_color_texture"] = texture({"index": d_tex["index"]}, True, f"{where} {EXTENSION}.diffuseTexture")
        kw["base_color_uv"] = uv(d_tex)
        return core, color, pbr
    images = doc.list("images")
    sources = []
    for tex, src, label in ((d_tex, d_src, "diffuseTexture"), (s_tex, s_src, "specularGlossinessTexture")):
        if src is None or src[0] is None:
            sources.append(None)
        else:
            sources.append((f"{EXTENSION}.{label}", image_job(doc, src[0], images[src[0]])))
    if sources == [None, None]:         # textures without an image: the factors are all there is
        return core, color, pbr
    first = d_tex if d_src is not None and d_src[0] is not None else s_tex
    wraps = (d_src if first is d_tex else s_src)[1:]
    job = _Bake(f"{doc.path}: {where}", sg, sources, wraps)
    ident = (EXTENSION, d_src and d_src[0], s_src and s_src[0], sg["diffuse"], sg["specular"], sg["glossiness"])
    name = mat.get("name") or where
    user = f"{where} {EXTENSION}"
    kw["base_color_texture"] = _register(lists, ((ident, "base"), *wraps, True), lambda: job.part(0),
                                         f"{name} base colour (from specular-glossiness)", user)
    kw["metallic_roughness_texture"] = _register(lists, ((ident, "mr"), *wraps, False), lambda: job.part(1),
                                                 f"{name} metallic-roughness (from specular-glossiness)", user)
    kw["base_color_uv"] = kw["metallic_roughness_uv"] = uv(first)
    # the textures carry the converted values: the factors pass them through (alpha stays a factor)
    return core, [1.0, 1.0, 1.0, sg["diffuse"][3]], {"metallicFactor": 1.0, "roughnessFactor": 1.0}


def _register(lists, key, job, name: str, user: str) -> int:
    """Add a baked texture to the loader's registry (materials.load_materials: the same bookkeeping as
    its texture()): textures with the same key (same sources, factors, wrap modes) are shared."""
    slots, jobs, names, keys, users = lists
    if key not in slots:
        slots[key] = len(jobs)
        jobs.append(job)
        names.append(name)
        keys.append(key)
        users.append([])
    if user not in users[slots[key]]:
        users[slots[key]].append(user)
    return slots[key]


# -- baking the textures ----------------------------------------------------------------------------------
class _Bake:
    """The two textures of one material, computed once by whichever decoding job asks first."""

    def __init__(self, where: str, sg: dict, sources: list, wraps: tuple):
        self.where, self.sg, self.sources, self.wraps = where, sg, sources, wraps
        self.lock = threading.Lock()
        self.result = None

    def part(self, k: int) -> np.ndarray:
        with self.lock:
            if self.result is None:
                self.result = self._run()
        return self.result[k]

    def _run(self):
        imgs = []
        for src in self.sources:
            if src is None:
                imgs.append(None)
                continue
            label, decode = src
            try:
                imgs.append(decode())
            except BudgetError:
                raise
            except SceneError as exc:   # missing or undecodable: the spec's "texture not given" (all 1.0)
                warnings.warn(f"{self.where}: {label}: {exc}: converted as if the texture were absent", stacklevel=2)
                imgs.append(None)
        shapes = [i.shape[:2] for i in imgs if i is not None] or [(1, 1)]
        h, w = max(s[0] for s in shapes), max(s[1] for s in shapes)
        current().charge(2 * h * w * 4, self.where, f"{EXTENSION} textures ({w}x{h} pixels, baked)",
                         peak=2 * h * w * 4 + min(h * w, BLOCK_PIXELS + w) * SCRATCH_PER_PIXEL)
        return bake(imgs[0], imgs[1], self.sg["diffuse"], self.sg["specular"], self.sg["glossiness"], self.wraps)


def bake(diffuse_img, sg_img, diffuse, specular, glossiness, wraps=("repeat", "repeat")):
    """(base colour RGBA8 sRGB, metallic-roughness RGBA8 linear) of RGBA8 diffuse and
    specular-glossiness images (None: absent, every texel 1.0) and the factors, at the per-axis larger
    size of the two; the smaller is resampled bilinearly (texel centres, `wraps` = (wrapS, wrapT))."""
    shapes = [i.shape[:2] for i in (diffuse_img, sg_img) if i is not None] or [(1, 1)]
    h, w = max(s[0] for s in shapes), max(s[1] for s in shapes)
    base_out = np.empty((h, w, 4), np.uint8)
    mr_out = np.empty((h, w, 4), np.uint8)
    rows = max(1, BLOCK_PIXELS // w)
    df, sf = np.asarray(diffuse, np.float64), np.asarray(specular, np.float64)
    for r0 in range(0, h, rows):
        r1 = min(h, r0 + rows)
        d = _texels(diffuse_img, h, w, r0, r1, wraps)
        s = _texels(sg_img, h, w, r0, r1, wraps)
        base, metallic, roughness = to_metallic_roughness(d[..., :3] * df[:3], s[..., :3] * sf, s[..., 3] * glossiness)
        base_out[r0:r1, :, :3] = _u8(linear_to_srgb(base))
        base_out[r0:r1, :, 3] = _u8(d[..., 3])
        mr_out[r0:r1, :, 0] = 0
        mr_out[r0:r1, :, 1] = _u8(roughness)
        mr_out[r0:r1, :, 2] = _u8(metallic)
        mr_out[r0:r1, :, 3] = 255
    return base_out, mr_out


_SRGB_LUT = srgb_to_linear(np.arange(256) / 255.0)


def _texels(img, h: int, w: int, r0: int, r1: int, wraps) -> np.ndarray:
    """Rows r0..r1 of `img` at size (h, w) as float64: RGB decoded from sRGB (both images' RGB are
    sRGB-encoded), A linear; an absent image is 1.0 everywhere."""
    if img is None:
        return np.ones((r1 - r0, w, 4))

    def decode(u8):
        out = np.empty(u8.shape, np.float64)
        out[..., :3] = _SRGB_LUT[u8[..., :3]]
        out[..., 3] = u8[..., 3] / 255.0
        return out
    ih, iw = img.shape[:2]
    if (ih, iw) == (h, w):
        return decode(img[r0:r1])
    y = (np.arange(r0, r1) + 0.5) * (ih / h) - 0.5
    x = (np.arange(w) + 0.5) * (iw / w) - 0.5
    y0, x0 = np.floor(y), np.floor(x)
    fy, fx = (y - y0)[:, None, None], (x - x0)[None, :, None]
    ys = [_wrap(y0.astype(np.int64) + k, ih, wraps[1]) for k in (0, 1)]
    xs = [_wrap(x0.astype(np.int64) + k, iw, wraps[0]) for k in (0, 1)]
    top = decode(img[ys[0]][:, xs[0]]) * (1 - fx) + decode(img[ys[0]][:, xs[1]]) * fx
    bottom = decode(img[ys[1]][:, xs[0]]) * (1 - fx) + decode(img[ys[1]][:, xs[1]]) * fx
    return top * (1 - fy) + bottom * fy


def _wrap(i: np.ndarray, n: int, mode: str) -> np.ndarray:
    """Texel indices wrapped as the sampler's mode does (glTF REPEAT, CLAMP_TO_EDGE, MIRRORED_REPEAT)."""
    if mode == "clamp":
        return np.clip(i, 0, n - 1)
    if mode == "mirror":
        k = np.mod(i, 2 * n)
        return np.where(k < n, k, 2 * n - 1 - k)
    return np.mod(i, n)
