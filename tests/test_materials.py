"""glTF materials evaluated per pixel (docs/materials.md) against the NumPy (float64) reference
tests/reference/material.py on synthetic quads (Scene objects and glTF files written by
tests/reference/gltf_writer.py): every texture slot, texture transforms, vertex colours, normal
maps and their fallbacks, MASK from vertex alpha; emissive, unlit and occlusion in the shading.
Units and bounds of the comparisons: tests/materials_cases.py. The reference on its own:
test_materials_reference.py; Khronos samples: test_materials_khronos.py.
"""
from __future__ import annotations

import numpy as np
import pytest

from conftest import blinn_phong_renderer_fixture
from clrender import Camera, Material, Scene
from clrender.scene.model import UVTransform
from materials_cases import (BACK, BUMP_CAMERA, FRONT, FULL_MATERIAL, MINIFIED, ORTHO, QUAD_COLORS, QUAD_POS,
                             QUAD_TANGENTS, QUAD_TRIS, QUAD_UV0, QUAD_UV1, bump_errors, bump_scene, bump_texture,
                             check_fields, check_material, describe, interior, quad_scene, reference_ids,
                             textures_for)
from reference import material as ref
from reference.gltf_writer import CLAMP, MIRROR, REPEAT, write_gltf


# These tests check the report's Blinn-Phong mapping of metallic-roughness materials
# (docs/materials.md); the glTF BRDF of shading="auto" has its reference in tests/test_brdf.py.
make_renderer = blinn_phong_renderer_fixture()


@pytest.mark.parametrize("case", ["magnified-front", "magnified-back", "magnified-ortho", "minified-front"])
def test_textured_quad_matches_reference(make_renderer, case):
    """Every slot textured (base colour, MR, normal, occlusion, emissive), vertex colours,
    TEXCOORD_1 (MR and occlusion), a texture transform on four slots, wrap repeat / clamp /
    mirror: albedo, specular intensity and power, normal, emissive and occlusion per pixel
    (`check_material`, silhouettes excluded).
      * magnified (64² textures at 160², LOD 0 everywhere), front, back (the double-sided
        quad's normal negated) and orthographic: TIGHT; measured max 1 code albedo/emissive,
        0.51 code intensity/power/occlusion, 0.043°;
      * minified (512² textures at 96², LOD 2-4): TIGHT against the fast-log2 reference
        (measured max 1 / 0.51 code, 0.036°) and MINIFIED against GL's (measured max 3 codes
        albedo, 0.79 intensity, 0.14°; p99 1 code).
    The reference with the MR texture's G and B swapped fails the MINIFIED bounds of albedo,
    intensity and power (measured: off by up to 61, 41 and 200 codes)."""
    size, width, cam = {"magnified-front": (64, 160, FRONT), "magnified-back": (64, 160, BACK),
                        "magnified-ortho": (64, 160, ORTHO), "minified-front": (512, 96, FRONT)}[case]
    rng = np.random.default_rng(7)
    scene = quad_scene(Material(**FULL_MATERIAL), textures_for(rng, size))
    frame = make_renderer(width, width).render(scene, cam)
    ev, region = check_material(frame, scene, cam)
    assert np.array_equal(frame.triangle_id >= 0, ev["mask"])
    if case.startswith("magnified"):
        assert np.nanmax(ev["lod"][region]) == 0.0          # the case is what it claims
    else:
        assert np.nanmin(ev["lod"][region][:, 1]) > 1.5
    if case.endswith("back"):
        assert ev["backface"][region].all()

    for log2 in ("exact", "fast"):
        swapped = ref.evaluate(scene, cam, width, width, frame.triangle_id, mr_channels=("G", "B"), log2=log2)
        with pytest.raises(AssertionError) as info:
            check_fields(frame, swapped, region, {k: MINIFIED[k] for k in ("albedo", "specular_intensity",
                                                                           "specular_power")})
        msg = str(info.value)
        assert "albedo" in msg and "specular_intensity" in msg and "specular_power" in msg, msg


TRANSFORMS = {
    "offset": {"offset": [0.3, -0.15]},
    "rotation": {"rotation": 0.7},
    "scale": {"scale": [2.5, 0.6]},
    "all-texcoord1": {"offset": [-0.2, 0.1], "rotation": -1.1, "scale": [1.3, 1.7], "texCoord": 1},
}


def quad_gltf(tmp_path, rng, material_extra=None, slot_ext=None, color_format="u2", tangents=True,
              images=None, name="quad.gltf"):
    """The quad as a glTF file: base colour, MR, normal, occlusion, emissive textures (64²), the
    given KHR_texture_transform on every textureInfo, COLOR_0 and TEXCOORD_1."""
    imgs = images if images is not None else [t.rgba for t in textures_for(rng, 64)]
    samplers = [{"wrapS": REPEAT, "wrapT": REPEAT}, {"wrapS": CLAMP, "wrapT": CLAMP},
                {"wrapS": MIRROR, "wrapT": MIRROR}, {"wrapS": CLAMP, "wrapT": MIRROR}]
    textures = [{"source": 0, "sampler": 0}, {"source": 1, "sampler": 1}, {"source": 2, "sampler": 0},
                {"source": 3, "sampler": 2}, {"source": 4, "sampler": 3}]

    def info(index, **kw):
        d = {"index": index, **kw}
        if slot_ext:
            d["extensions"] = {"KHR_texture_transform": dict(slot_ext)}
        return d

    material = {
        "name": "quad",
        "pbrMetallicRoughness": {"baseColorFactor": [0.9, 0.95, 0.85, 1.0], "baseColorTexture": info(0),
                                 "metallicFactor": 0.9, "roughnessFactor": 0.85,
                                 "metallicRoughnessTexture": info(1)},
        "normalTexture": info(2, scale=0.8), "occlusionTexture": info(3, strength=0.7),
        "emissiveTexture": info(4), "emissiveFactor": [0.8, 0.5, 1.0], "doubleSided": True,
        **(material_extra or {}),
    }
    used = ["KHR_texture_transform"] if slot_ext else []
    for k in (material_extra or {}).get("extensions", {}):
        used.append(k)
    return write_gltf(tmp_path / name, QUAD_POS, QUAD_TRIS, normals=np.tile([[0, 0, 1]], (4, 1)), uvs=QUAD_UV0,
                      uvs1=QUAD_UV1, colors=QUAD_COLORS, color_format=color_format,
                      tangents=QUAD_TANGENTS if tangents else None, material=material, images=imgs,
                      samplers=samplers, textures=textures, extensions_used=used)


@pytest.mark.parametrize("kind", list(TRANSFORMS))
def test_gltf_texture_transform_matches_reference(make_renderer, tmp_path, kind):
    """A synthetic glTF quad, every textureInfo with a known KHR_texture_transform (offset,
    rotation, scale, or all three with a texCoord override to TEXCOORD_1), normalized-ushort
    COLOR_0: the loaded scene holds exactly those transforms, colours and TEXCOORD_1, and the
    Frame matches the reference per pixel (`check_material`: measured max 1 code albedo and
    emissive, 0.54 code intensity, 0.044° against the fast-log2 reference; the scale and
    texCoord cases minify, against GL's log2: max 4 codes albedo, 1.3 intensity, 0.13°).
    A reference that ignores the base colour's transform must fail the albedo bound."""
    from clrender import load_scene
    rng = np.random.default_rng(11)
    ext = TRANSFORMS[kind]
    path = quad_gltf(tmp_path, rng, slot_ext=ext)
    scene = load_scene(path)
    expected = UVTransform(ext.get("texCoord", 0), tuple(ext.get("offset", (0, 0))), ext.get("rotation", 0.0),
                           tuple(ext.get("scale", (1, 1))))
    mat = scene.materials[0]
    for slot in ref.SLOTS:
        got = getattr(mat, f"{slot}_uv")
        assert got == expected, f"{slot}: loaded {got}, file says {expected}"
    assert mat.metallic == pytest.approx(0.9) and mat.roughness == pytest.approx(0.85)
    np.testing.assert_allclose(scene.colors, QUAD_COLORS, atol=0.5 / 65535)
    np.testing.assert_array_equal(scene.extra_uvs[0], QUAD_UV1)

    frame = make_renderer(128, 128).render(scene, FRONT)
    ev, region = check_material(frame, scene, FRONT)

    untransformed = scene.materials[0]
    from dataclasses import replace
    scene.materials[0] = replace(untransformed, base_color_uv=UVTransform(0))
    ignored = ref.evaluate(scene, FRONT, 128, 128, frame.triangle_id)
    with pytest.raises(AssertionError, match="albedo"):
        check_fields(frame, ignored, region, {"albedo": MINIFIED["albedo"]})


@pytest.mark.parametrize("color_format", ["f4", "u1", "f4-vec3"])
def test_gltf_vertex_colour_formats(make_renderer, tmp_path, color_format):
    """COLOR_0 as float VEC4, normalized ubyte VEC4 and float VEC3 (alpha 1) is loaded as
    written and multiplies the base colour: albedo per pixel (`check_material`, measured max 1
    code)."""
    from clrender import load_scene
    rng = np.random.default_rng(5)
    scene = load_scene(quad_gltf(tmp_path, rng, color_format=color_format))
    expected = QUAD_COLORS.copy()
    if color_format == "f4-vec3":
        expected[:, 3] = 1
    np.testing.assert_allclose(scene.colors, expected, atol=0.5 / 255 + 1e-7)
    frame = make_renderer(128, 128).render(scene, FRONT)
    check_material(frame, scene, FRONT, fields=["albedo"])


@pytest.mark.parametrize("source", ["scene-tangents", "gltf-generated-tangents"])
def test_analytic_bump_normals(make_renderer, tmp_path, source):
    """A normal map encoding a known height field (three Gaussian bumps and a ripple, slopes up
    to ~20°) on a flat quad: Frame.normal within 2° of the analytic normal at every pixel but
    the silhouette's, with the scene's tangents or with tangents generated for a glTF file
    without TANGENT. Measured max 0.33° (8-bit texels, bilinear); the flat normal is 5.8° off
    at the median, and a flipped green channel > 4° at the 90th percentile
    (test_reference_analytic_bump)."""
    if source == "scene-tangents":
        scene = bump_scene()
    else:
        from clrender import load_scene
        tex = bump_texture()
        material = {"pbrMetallicRoughness": {"baseColorFactor": [0.8, 0.8, 0.8, 1], "metallicFactor": 0.0,
                                             "roughnessFactor": 0.5},
                    "normalTexture": {"index": 0}, "doubleSided": True}
        path = write_gltf(tmp_path / "bump.gltf", QUAD_POS, QUAD_TRIS, normals=np.tile([[0, 0, 1]], (4, 1)),
                          uvs=QUAD_UV0, material=material, images=[tex.rgba],
                          samplers=[{"wrapS": CLAMP, "wrapT": CLAMP}])
        scene = load_scene(path)
    frame = make_renderer(128, 128).render(scene, BUMP_CAMERA)
    ev = ref.evaluate(scene, BUMP_CAMERA, 128, 128, frame.triangle_id)
    region = interior(frame, ev)
    err = bump_errors(frame.normal, ev, region)
    assert err.max() < 2.0, describe(err)
    # and the flat quad's normal is far from it (the map is actually applied)
    flat = bump_errors(np.broadcast_to([0.0, 0.0, 1.0], frame.normal.shape), ev, region)
    assert np.percentile(flat, 75) > 5.0, describe(flat)


@pytest.mark.parametrize("case", ["zero-vertex-normals", "tangent-parallel-to-normal", "zero-tangent"])
def test_degenerate_normal_and_tangent_fallbacks(make_renderer, case):
    """docs/materials.md step 4: a zero interpolated vertex normal falls back to the geometric
    normal; a tangent that is zero or parallel to N leaves the normal map unapplied. The bump
    quad seen from the front: Frame.normal = (0, 0, 1) within 0.1° on interior pixels, as the
    reference says; the BACK view of the zero-normal case gives (0, 0, -1)."""
    scene = bump_scene()
    if case == "zero-vertex-normals":
        scene.normals = np.zeros_like(scene.normals)
        scene.materials = [Material(name="plain", base_color=(0.8, 0.8, 0.8, 1.0), metallic=0.0, roughness=0.5)]
    elif case == "tangent-parallel-to-normal":
        scene.tangents = np.tile(np.array([[0, 0, 1, 1]], np.float32), (4, 1))
    else:
        scene.tangents = np.tile(np.array([[0, 0, 0, 1]], np.float32), (4, 1))
    cams = [(BUMP_CAMERA, 1.0)] + ([(BACK, -1.0)] if case == "zero-vertex-normals" else [])
    for cam, sign in cams:
        frame = make_renderer(128, 128).render(scene, cam)
        ev, region = check_material(frame, scene, cam, fields=["normal"])
        np.testing.assert_allclose(ev["normal"][region], np.broadcast_to([0, 0, sign], (region.sum(), 3)), atol=1e-9)


def test_vertex_alpha_feeds_mask(make_renderer):
    """Base alpha = factor × texture × COLOR_0 alpha decides MASK coverage: with vertex alpha
    running 0 → 1 across the quad and cutoff 0.5, a pixel whose reference alpha is above
    0.5 + 0.01 is covered and one below 0.5 − 0.01 is not (ids of the covered pixels from the
    reference rasterizer run on the same quad made OPAQUE)."""
    from dataclasses import replace
    mat = Material(name="masked", base_color=(0.9, 0.9, 0.9, 1.0), metallic=0.0, roughness=0.5,
                   alpha_mode="MASK", alpha_cutoff=0.5)
    scene = quad_scene(mat, [], uv1=False, tangents=False)
    colors = scene.colors.copy()
    colors[:, 3] = [0.0, 1.0, 1.0, 0.0]                  # alpha rises with x
    scene.colors = colors
    frame = make_renderer(128, 128).render(scene, FRONT)
    opaque = quad_scene(replace(mat, alpha_mode="OPAQUE"), [], uv1=False, tangents=False)
    opaque.colors = colors
    ids = reference_ids(opaque, FRONT, 128, 128)
    ev = ref.evaluate(opaque, FRONT, 128, 128, ids)
    near_edge = ref.boundary_mask(np.where(ids >= 0, 0, -1), 1)
    above = ev["mask"] & (ev["alpha"] > 0.51) & ~near_edge
    below = ev["mask"] & (ev["alpha"] < 0.49) & ~near_edge
    assert above.sum() > 500 and below.sum() > 500
    assert (frame.triangle_id[above] >= 0).all(), "pixels with alpha above the cutoff were discarded"
    assert (frame.triangle_id[below] < 0).all(), "pixels with alpha below the cutoff were kept"


# -- shading: emissive, unlit, occlusion ----------------------------------------------------------
CORNER_CAMERA = Camera.look_at((1.6, 1.3, 2.6), (0.0, -0.3, 0.0), (0, 1, 0), 55.0, near=0.1, far=20.0)


def corner_scene(floor: Material, textures) -> Scene:
    """The textured quad as a floor (y = -1) and a plain wall (z = -1) behind it: SSAO darkens
    the corner, the sun (when set) shadows part of the floor."""
    pos = np.concatenate([QUAD_POS[:, [0, 2, 1]] * [1, 1, -1] + [0, -1, 0],   # floor: x, z from the quad
                          QUAD_POS + [0, 0, -1]]).astype(np.float32)
    nrm = np.array([[0, 1, 0]] * 4 + [[0, 0, 1]] * 4, np.float32)
    uv = np.concatenate([QUAD_UV0, QUAD_UV0])
    tris = np.concatenate([QUAD_TRIS[:, [0, 2, 1]], QUAD_TRIS + 4]).astype(np.int32)
    # floor winding: counter-clockwise seen from +y
    p = pos[tris[0]]
    if np.cross(p[1] - p[0], p[2] - p[0])[1] < 0:
        tris[:2] = tris[:2][:, [0, 2, 1]]
    wall = Material(name="wall", base_color=(0.7, 0.7, 0.7, 1.0), metallic=0.0, roughness=0.7)
    colors = np.concatenate([QUAD_COLORS, np.ones((4, 4), np.float32)])
    tangents = np.tile(np.array([[1, 0, 0, 1]], np.float32), (8, 1))
    return Scene(pos, nrm, uv, tris, np.array([0, 0, 1, 1], np.int32), [floor, wall], list(textures),
                 colors=colors, tangents=tangents, extra_uvs=np.concatenate([QUAD_UV1, QUAD_UV0])[None])


def frame_fields(frame, ev) -> dict:
    """The reference's geometry (positions, view vectors, unlit flags, strengths) with the
    Frame's decoded G-buffer material fields: shading then differs from the kernels only by
    float32 arithmetic."""
    out = dict(ev)
    for name in ("albedo", "specular_intensity", "specular_power", "normal", "emissive", "occlusion"):
        out[name] = getattr(frame, name).astype(np.float64)
    return out


def test_emissive_added_and_unaffected_by_lights_shadow_and_ssao(make_renderer):
    """colour = albedo·(ambient·ssao·ao + Σdiffuse) + Σspecular + e·strength, the emission
    outside every factor: with a shadowing sun, a point light and SSAO on, the Frame's colour
    equals the reference shading of its own decoded G-buffer, SSAO and sun visibility (relative
    1e-4 + 1e-5 absolute) on a floor with > 30 SSAO-darkened (ao < 0.8) and > 30 shadowed pixels,
    so an emission scaled by either fails; with no light and ambient 0 the colour is e·strength
    alone; tripling the strength adds exactly 2·e·strength. The emissive and occlusion planes
    against the material reference: `check_material` on the floor (measured max 1 code / 0.52)."""
    rng = np.random.default_rng(21)
    texs = textures_for(rng, 64)
    floor = Material(**{**FULL_MATERIAL, "emissive_strength": 1.5})
    scene = corner_scene(floor, texs)
    scene.set_sun((0.3, -1.0, 0.6), (1.2, 1.1, 1.0), shadow=True, shadow_map_size=512)
    scene.add_point_light((0.6, -0.4, 0.9), (2.0, 1.5, 1.0), 3.0)
    scene.ambient = 0.3
    r = make_renderer(128, 128, ssao=True, ssao_radius=0.6)
    frame = r.render(scene, CORNER_CAMERA)
    ev = ref.evaluate(scene, CORNER_CAMERA, 128, 128, frame.triangle_id)
    region = interior(frame, ev)
    floor_px = region & (ev["material"] == 0)
    check_material(frame, scene, CORNER_CAMERA, region=floor_px, fields=["emissive", "occlusion"])
    assert (frame.ao[floor_px] < 0.8).sum() > 30, "the scene needs SSAO-darkened floor pixels"
    sun_vis = frame.shadow[..., 0]
    assert (sun_vis[floor_px] < 0.5).sum() > 30, "the scene needs shadowed floor pixels"
    expected = ref.lit(frame_fields(frame, ev), scene, ssao=frame.ao, sun_visibility=sun_vis)
    fg = frame.triangle_id >= 0
    np.testing.assert_allclose(frame.color[fg], expected[fg], rtol=1e-4, atol=1e-5)

    dark = Scene(scene.positions, scene.normals, scene.uvs, scene.triangles, scene.triangle_material,
                 scene.materials, scene.textures, colors=scene.colors, tangents=scene.tangents,
                 extra_uvs=scene.extra_uvs, ambient=0.0)
    f_dark = r.render(dark, CORNER_CAMERA)
    e = f_dark.emissive.astype(np.float64) * 1.5
    np.testing.assert_allclose(f_dark.color[floor_px], e[floor_px], rtol=1e-5, atol=1e-6)
    from dataclasses import replace
    dark.materials = [replace(floor, emissive_strength=4.5), scene.materials[1]]
    f3 = r.render(dark, CORNER_CAMERA)
    np.testing.assert_allclose(f3.color[floor_px] - f_dark.color[floor_px], 2 * e[floor_px], rtol=1e-5, atol=1e-6)


def test_unlit_is_base_colour_whatever_the_lights(make_renderer):
    """KHR_materials_unlit: colour = albedo (the G-buffer's base colour) exactly, identical with
    and without lights, SSAO and shadow; albedo = factor × texture × vertex colour and specular
    intensity 0 against the reference (`check_material`, interior floor pixels)."""
    rng = np.random.default_rng(23)
    texs = textures_for(rng, 64)
    floor = Material(**{**FULL_MATERIAL, "unlit": True, "emissive_strength": 0.0})
    scene = corner_scene(floor, texs)
    scene.set_sun((0.3, -1.0, 0.6), (1.2, 1.1, 1.0), shadow=True, shadow_map_size=512)
    scene.add_point_light((0.6, -0.4, 0.9), (2.0, 1.5, 1.0), 3.0)
    r = make_renderer(128, 128, ssao=True, ssao_radius=0.6)
    frame = r.render(scene, CORNER_CAMERA)
    ev = ref.evaluate(scene, CORNER_CAMERA, 128, 128, frame.triangle_id)
    floor_px = interior(frame, ev) & (ev["material"] == 0)
    check_material(frame, scene, CORNER_CAMERA, region=floor_px, fields=["albedo", "specular_intensity"])
    np.testing.assert_allclose(frame.color[floor_px], frame.albedo[floor_px], rtol=1e-6, atol=0)
    scene.lights = scene.lights[:0]
    scene.sun = None
    scene.ambient = 0.0
    dark = r.render(scene, CORNER_CAMERA)
    np.testing.assert_array_equal(dark.color[floor_px], frame.color[floor_px])


def test_occlusion_multiplies_ambient_with_ssao(make_renderer):
    """With no lights: colour = albedo·ambient·occlusion·ssao (relative 1e-4), the occlusion plane
    = 1 + strength·(tex.R − 1) (TEXCOORD_1, offset and scale, mirror wrap; `check_material`); with
    a point light the direct term is not occluded (colour = the reference shading of the
    Frame's G-buffer). Interior pixels."""
    rng = np.random.default_rng(29)
    texs = textures_for(rng, 64)
    floor = Material(**{**FULL_MATERIAL, "emissive": (0.0, 0.0, 0.0), "emissive_texture": -1})
    scene = corner_scene(floor, texs)
    scene.ambient = 0.4
    r = make_renderer(128, 128, ssao=True, ssao_radius=0.6)
    frame = r.render(scene, CORNER_CAMERA)
    ev = ref.evaluate(scene, CORNER_CAMERA, 128, 128, frame.triangle_id)
    floor_px = interior(frame, ev) & (ev["material"] == 0)
    check_material(frame, scene, CORNER_CAMERA, region=floor_px, fields=["occlusion"])
    assert np.ptp(frame.occlusion[floor_px]) > 0.3
    expected = frame.albedo * (np.float32(0.4) * frame.occlusion * frame.ao)[..., None]
    fg = frame.triangle_id >= 0
    np.testing.assert_allclose(frame.color[fg], expected[fg], rtol=1e-4, atol=1e-6)
    scene.add_point_light((0.6, -0.4, 0.9), (2.0, 1.5, 1.0), 3.0)
    lit_frame = r.render(scene, CORNER_CAMERA)
    expected = ref.lit(frame_fields(lit_frame, ev), scene, ssao=lit_frame.ao)
    np.testing.assert_allclose(lit_frame.color[fg], expected[fg], rtol=1e-4, atol=1e-5)


@pytest.mark.parametrize("extension", ["KHR_materials_unlit", "KHR_materials_emissive_strength"])
def test_gltf_unlit_and_emissive_strength(make_renderer, tmp_path, extension):
    """The two material extensions read from a synthetic glTF file: unlit gives colour = albedo
    (= the reference's base colour within 1 code) under a point light; emissive strength 3
    gives, with no light and ambient 0, colour = 3·e, e = the emissive plane = the reference's
    emissive factor × texture (`check_material`: interior pixels)."""
    from clrender import load_scene
    rng = np.random.default_rng(31)
    ext = {"KHR_materials_unlit": {}} if extension == "KHR_materials_unlit" else \
        {"KHR_materials_emissive_strength": {"emissiveStrength": 3.0}}
    scene = load_scene(quad_gltf(tmp_path, rng, material_extra={"extensions": ext}), default_environment=False)
    mat = scene.materials[0]
    scene.lights = scene.lights[:0]
    if extension == "KHR_materials_unlit":
        assert mat.unlit
        scene.add_point_light((0.3, 0.2, 1.0), (3.0, 3.0, 3.0), 5.0)
    else:
        assert mat.emissive_strength == 3.0 and not mat.unlit
        scene.ambient = 0.0
    frame = make_renderer(128, 128).render(scene, FRONT)
    ev, region = check_material(frame, scene, FRONT, fields=["albedo", "emissive"])
    if extension == "KHR_materials_unlit":
        np.testing.assert_allclose(frame.color[region], frame.albedo[region], rtol=1e-6, atol=0)
    else:
        np.testing.assert_allclose(frame.color[region], 3.0 * frame.emissive[region], rtol=1e-5, atol=1e-6)
        assert frame.emissive[region].max() > 0.2
