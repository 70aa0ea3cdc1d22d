"""Synthetic material content, the comparison with the float64 reference tests/reference/material.py
and its bounds, shared by test_materials.py, test_materials_reference.py and test_materials_khronos.py.

Units of the per-pixel comparisons (the G-buffer quantizes every field; "codes" are its 8-bit
steps):
  * albedo, emissive: sRGB8 codes (the reference's value encoded with
    clrender.abi.gbuffer.linear_to_srgb8; the Frame's decoded value re-encodes exactly), worst channel;
  * specular intensity, occlusion: unorm8 codes (|Δ|·255);
  * specular power: codes of round(255·log2(p)/11), i.e. |Δlog2 p|·255/11;
  * normal: degrees between the Frame's and the reference's normal (octahedral 2×12 bits).
Bounds are (max, 99th percentile) per field:
  * TIGHT (1 code albedo/emissive, 0.75 code unorm/log, 0.1°): quantization only. A rounded
    field is within 0.5 code of the float64 value; float32 and the raster's 1/256-px vertex snap
    add < 0.05 code (measured on the quads: max 0.54 code, 0.044°).
  * MINIFIED / ASSET_GL, against GL's exact-log2 LOD: the kernels compute log2 of the footprint
    from the float's exponent and a linear mantissa (kernels/texture_vec.h, as texture units
    do), up to 0.086 off, so the trilinear weight moves by up to 0.043 where textures are
    minified. `check_material` therefore demands TIGHT against the reference with either log2
    (GL's or the kernels' approximation: whichever the kernels use, every pixel is then exact
    up to quantization) and the looser bound against GL's.
  * ASSET_TIGHT: the Khronos textures have sharp edges at level 0, where the 1/256-px vertex
    snap moves a few pixels' values by more than float error (p99 stays at quantization).
Excluded pixels: those within 1 px of the background or of the image border (silhouettes,
where the neighbour rays that give the texture footprint graze the surface). Edges between
triangles are kept: the reference evaluates the Frame's own triangle there, as the kernels do.
Every bound was measured (numbers in the tests' docstrings) and each test shows that it can
fail: the reference with the MR texture's G and B swapped, without a texture transform, without
vertex colours, with a flipped normal-map green channel, all exceed the same bounds. Fixed
seeds throughout.
"""
from __future__ import annotations

import numpy as np

from clrender import Camera, Material, Scene
from clrender.abi.gbuffer import SPEC_POWER_LOG2_MAX, linear_to_srgb8
from clrender.scene.model import Texture, UVTransform
from reference import material as ref


# -- synthetic content ----------------------------------------------------------------------------
def smooth_noise(rng, size: int, cells: int, channels: int) -> np.ndarray:
    """(size, size, channels) float in [0, 1]: random values on a cells×cells grid, bicubic-upsampled."""
    from PIL import Image
    out = np.empty((size, size, channels))
    for c in range(channels):
        low = rng.random((cells, cells)).astype(np.float32)
        out[..., c] = np.asarray(Image.fromarray(low, "F").resize((size, size), Image.BICUBIC))
    return np.clip(out, 0.0, 1.0)


def to_rgba8(rgb: np.ndarray, alpha=255) -> np.ndarray:
    h, w = rgb.shape[:2]
    out = np.full((h, w, 4), alpha, np.uint8)
    out[..., :rgb.shape[2]] = np.floor(np.clip(rgb, 0, 1) * 255 + 0.5)
    return out


def mr_image(rng, size: int) -> np.ndarray:
    """B (metallic) rises along u, G (roughness) falls along v, both with a little smooth noise;
    R is unrelated noise. B and G differ almost everywhere, so swapping them is visible."""
    u = (np.arange(size) + 0.5) / size
    noise = smooth_noise(rng, size, 5, 3)
    b = 0.08 + 0.84 * u[None, :] + 0.06 * (noise[..., 0] - 0.5)
    g = 0.95 - 0.8 * u[:, None] + 0.06 * (noise[..., 1] - 0.5)
    return to_rgba8(np.stack([noise[..., 2], g, b], -1))


def normal_image(rng, size: int, strength: float = 1.0) -> np.ndarray:
    """A tangent-space normal map of a smooth random height field (RGB = (n + 1)/2)."""
    h = smooth_noise(rng, size, 6, 1)[..., 0] * strength * size / 12.0
    gy, gx = np.gradient(h)
    n = np.stack([-gx, gy, np.ones_like(h)], -1)        # image rows run down: +y is up = -row
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    return to_rgba8((n + 1) / 2)


def textures_for(rng, size: int):
    base = Texture("base", to_rgba8(0.15 + 0.8 * smooth_noise(rng, size, 5, 3)), "repeat", "repeat", srgb=True)
    mr = Texture("mr", mr_image(rng, size), "clamp", "clamp", srgb=False)
    nrm = Texture("normal", normal_image(rng, size), "repeat", "repeat", srgb=False)
    occ_rgb = smooth_noise(rng, size, 4, 3)
    occ_rgb[..., 0] = 0.2 + 0.8 * occ_rgb[..., 0]
    occ = Texture("occlusion", to_rgba8(occ_rgb), "mirror", "mirror", srgb=False)
    emi = Texture("emissive", to_rgba8(smooth_noise(rng, size, 4, 3)), "clamp", "mirror", srgb=True)
    return [base, mr, nrm, occ, emi]


QUAD_POS = np.array([[-1, 1, 0], [1, 1, 0], [1, -1, 0], [-1, -1, 0]], np.float32)
QUAD_UV0 = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], np.float32)          # glTF: v runs down the image
QUAD_UV1 = np.array([[0.15, 0.9], [0.15, 0.05], [0.85, 0.05], [0.85, 0.9]], np.float32)
QUAD_TRIS = np.array([[0, 3, 2], [0, 2, 1]], np.int32)                     # counter-clockwise from +z
QUAD_COLORS = np.array([[1.0, 0.55, 0.3, 1.0], [0.45, 1.0, 0.8, 1.0], [0.9, 0.85, 0.25, 1.0],
                        [0.5, 0.7, 1.0, 1.0]], np.float32)
QUAD_TANGENTS = np.tile(np.array([[1, 0, 0, 1]], np.float32), (4, 1))      # +u = +x; B = +y = up the image


def quad_scene(material: Material, textures, colors=True, uv1=True, tangents=True) -> Scene:
    return Scene(QUAD_POS.copy(), np.tile([[0, 0, 1]], (4, 1)).astype(np.float32), QUAD_UV0.copy(), QUAD_TRIS.copy(),
                 np.zeros(2, np.int32), [material], list(textures),
                 colors=QUAD_COLORS.copy() if colors else None,
                 tangents=QUAD_TANGENTS.copy() if tangents else None,
                 extra_uvs=QUAD_UV1[None].copy() if uv1 else None)


FRONT = Camera.look_at((0.45, -0.6, 2.3), (0.0, 0.0, 0.0), (0, 1, 0), 55.0, near=0.1, far=20.0)
BACK = Camera.look_at((-0.5, 0.4, -2.3), (0.0, 0.0, 0.0), (0, 1, 0), 55.0, near=0.1, far=20.0)
ORTHO = Camera.orthographic((0.8, -0.9, 2.0), (0.0, 0.0, 0.0), (0, 1, 0), xmag=1.1, ymag=1.1, near=0.1, far=20.0)

FULL_MATERIAL = dict(
    name="full", base_color=(0.9, 0.95, 0.85, 1.0), metallic=0.9, roughness=0.85,
    base_color_texture=0, metallic_roughness_texture=1, normal_texture=2, normal_scale=0.8,
    occlusion_texture=3, occlusion_strength=0.7, emissive=(0.8, 0.5, 1.0), emissive_texture=4,
    emissive_strength=2.5,
    base_color_uv=UVTransform(0, (0.1, -0.2), 0.3, (1.5, 0.8)),
    metallic_roughness_uv=UVTransform(1),
    normal_uv=UVTransform(0, (0.0, 0.0), 0.0, (1.25, 1.25)),
    occlusion_uv=UVTransform(1, (0.3, 0.1), 0.0, (1.2, 1.2)),
    emissive_uv=UVTransform(0, (0.0, 0.0), 1.0, (1.0, 1.0)),
)


# -- comparison -----------------------------------------------------------------------------------
def code_errors(frame, ev, region) -> dict:
    """Per-pixel errors (1-D over `region`) of every material field, in G-buffer codes / degrees."""
    out = {}
    a_ref = linear_to_srgb8(ev["albedo"][region]).astype(int)
    a_got = linear_to_srgb8(frame.albedo[region]).astype(int)
    out["albedo"] = np.abs(a_ref - a_got).max(-1)
    out["specular_intensity"] = np.abs(ev["specular_intensity"][region] - frame.specular_intensity[region]) * 255
    lit = ~ev["unlit"][region]
    sp = np.abs(np.log2(ev["specular_power"][region]) - np.log2(frame.specular_power[region])) * 255 / SPEC_POWER_LOG2_MAX
    out["specular_power"] = np.where(lit, sp, 0.0)
    cosang = np.clip((ev["normal"][region] * frame.normal[region]).sum(-1)
                     / np.linalg.norm(frame.normal[region], axis=-1), -1, 1)
    out["normal"] = np.degrees(np.arccos(cosang))
    e_ref = linear_to_srgb8(ev["emissive"][region]).astype(int)
    e_got = linear_to_srgb8(frame.emissive[region]).astype(int)
    out["emissive"] = np.abs(e_ref - e_got).max(-1)
    out["occlusion"] = np.abs(ev["occlusion"][region] - frame.occlusion[region]) * 255
    return out


def describe(err: np.ndarray) -> str:
    return (f"n={err.size} max={err.max():.3f} p99={np.percentile(err, 99):.3f} "
            f"p50={np.median(err):.3f} mean={err.mean():.3f}")


def worst_pixel(err_full: np.ndarray, region, ev, frame, field: str) -> str:
    rows, cols = np.nonzero(region)
    k = int(np.argmax(err_full))
    y, x = rows[k], cols[k]
    return f"worst pixel (x={x}, y={y}): expected {np.round(ev[field][y, x], 5)}, got {np.round(getattr(frame, field)[y, x], 5)}"


def check_fields(frame, ev, region, bounds: dict):
    """bounds: field -> (max_error, p99_error). Fails naming the field, the statistics and the
    worst pixel."""
    errs = code_errors(frame, ev, region)
    problems = []
    for field, (max_err, p99_err) in bounds.items():
        e = errs[field]
        if e.max() > max_err or np.percentile(e, 99) > p99_err:
            problems.append(f"{field}: {describe(e)} (bounds: max {max_err}, p99 {p99_err}); "
                            + worst_pixel(e, region, ev, frame, field))
    assert not problems, "\n".join(problems)
    return errs


def interior(frame, ev=None):
    """Foreground pixels at least 1 px away from the background and the image border (the
    silhouettes; edges between triangles are kept: the reference evaluates the Frame's own
    triangle there, as the kernels do)."""
    fg = frame.triangle_id >= 0
    region = fg & ~ref.boundary_mask(np.where(fg, 0, -1), 1)
    if ev is not None:
        region &= ev["mask"]
    assert region.sum() > 200, "too few interior pixels"
    return region


TIGHT = {"albedo": (1, 1), "specular_intensity": (0.75, 0.6), "specular_power": (0.75, 0.6),
         "normal": (0.1, 0.1), "emissive": (1, 1), "occlusion": (0.75, 0.6)}
# minified synthetic textures against GL's exact-log2 LOD (see the module docstring)
MINIFIED = {"albedo": (4, 1), "specular_intensity": (4, 1), "specular_power": (4, 1),
            "normal": (0.5, 0.1), "emissive": (4, 1), "occlusion": (4, 1)}
# Khronos assets (see the module docstring); measured maxima in the tests' docstrings.
ASSET_TIGHT = {"albedo": (3, 1), "specular_intensity": (2, 0.6), "specular_power": (2.5, 0.6),
               "normal": (0.6, 0.1), "emissive": (2, 1), "occlusion": (1.5, 0.6)}
ASSET_GL = {"albedo": (8, 2), "specular_intensity": (8, 1.5), "specular_power": (10, 2),
            "normal": (2.5, 0.5), "emissive": (6, 3), "occlusion": (4, 1.5)}


def check_material(frame, scene, camera, region=None, fields=None, tight=None, loose=MINIFIED, **kw):
    """The Frame against the reference: within TIGHT of the reference with GL's exact log2 LOD
    or with the kernels' documented fast log2 (texture_vec.h) — whichever the kernels use, every
    pixel must then be within quantization — and always within `loose` of GL's. Returns the
    exact-LOD evaluation and the region (default: interior pixels)."""
    h, w = frame.triangle_id.shape
    ev = ref.evaluate(scene, camera, w, h, frame.triangle_id, log2="exact", **kw)
    region = interior(frame, ev) if region is None else region
    fields = fields or list(TIGHT)
    tight = tight or TIGHT
    check_fields(frame, ev, region, {k: loose[k] for k in fields})
    failures = []
    for log2 in ("exact", "fast"):
        evaluated = ev if log2 == "exact" else ref.evaluate(scene, camera, w, h, frame.triangle_id, log2=log2, **kw)
        try:
            check_fields(frame, evaluated, region, {k: tight[k] for k in fields})
            return ev, region
        except AssertionError as exc:
            failures.append(f"against the reference with {log2} log2 LOD:\n{exc}")
    raise AssertionError("\n".join(failures))

def reference_ids(scene, camera, w, h):
    from reference.raster import rasterize
    ids, _, _ = rasterize(scene, camera, w, h)
    return ids


def bump_height(x, y):
    """Height field on the quad and its gradient (three Gaussian bumps and a ripple)."""
    h = np.zeros_like(x)
    gx = np.zeros_like(x)
    gy = np.zeros_like(x)
    for (cx, cy, a, s) in ((-0.4, 0.3, 0.12, 0.25), (0.35, -0.2, -0.1, 0.3), (0.3, 0.5, 0.08, 0.18)):
        g = a * np.exp(-((x - cx) ** 2 + (y - cy) ** 2) / (2 * s * s))
        h += g
        gx += -g * (x - cx) / (s * s)
        gy += -g * (y - cy) / (s * s)
    h += 0.02 * np.sin(4 * x) * np.cos(3 * y)
    gx += 0.08 * np.cos(4 * x) * np.cos(3 * y)
    gy += -0.06 * np.sin(4 * x) * np.sin(3 * y)
    return h, gx, gy


def bump_normals(x, y):
    _, gx, gy = bump_height(x, y)
    n = np.stack([-gx, -gy, np.ones_like(gx)], -1)
    return n / np.linalg.norm(n, axis=-1, keepdims=True)


def bump_texture(size=128) -> Texture:
    """The analytic normals at the texel centres, encoded: texel (i, j) at u = (i+0.5)/size,
    v = (j+0.5)/size, which the quad maps to x = 2u - 1, y = 1 - 2v; tangent space = world
    (T = +x along +u, B = +y, N = +z)."""
    c = (np.arange(size) + 0.5) / size
    x, y = np.meshgrid(2 * c - 1, 1 - 2 * c)
    return Texture("bump", to_rgba8((bump_normals(x, y) + 1) / 2), "clamp", "clamp", srgb=False)


BUMP_CAMERA = Camera.look_at((0.3, -0.35, 2.4), (0.0, 0.0, 0.0), (0, 1, 0), 50.0, near=0.1, far=20.0)


def bump_scene(tangents=True):
    mat = Material(name="bump", base_color=(0.8, 0.8, 0.8, 1.0), metallic=0.0, roughness=0.5, normal_texture=0)
    return quad_scene(mat, [bump_texture()], colors=False, uv1=False, tangents=tangents)


def bump_errors(normals, ev, region):
    P = ev["position"][region]
    truth = bump_normals(P[:, 0], P[:, 1])
    n = normals[region] / np.linalg.norm(normals[region], axis=-1, keepdims=True)
    return np.degrees(np.arccos(np.clip((n * truth).sum(-1), -1, 1)))
