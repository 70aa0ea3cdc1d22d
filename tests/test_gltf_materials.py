"""One subject (glTF materials and vertex attributes at the loader level) in one file: 514 lines.

glTF materials and vertex attributes at the loader level (issue 13; docs/materials.md).

Every glTF 2.0 material property (+ KHR_materials_emissive_strength, KHR_materials_unlit,
KHR_texture_transform) into `Material`, texture sRGB flags, COLOR_0 / TEXCOORD_n / TANGENT into
`Scene.colors / extra_uvs / tangents`, tangent generation (clrender.scene.tangents) against exact
expectations and against the tangents sample files were exported with, one warning per file and
unsupported feature, and the errors bad input gets. Files are written by tests/gltf_files.py;
expectations are computed here from the arrays the test wrote. No rendering.
"""
from __future__ import annotations

import math
import os
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

from conftest import blinn_phong_renderer_fixture

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

from gltf_files import QUAD_INDICES, QUAD_NORMALS, QUAD_POSITIONS, QUAD_UVS, primitive, write_gltf  # noqa: E402

from clrender.loaders import load_scene  # noqa: E402
from clrender.scene.model import Material, SceneError, UVTransform  # noqa: E402
from clrender.scene.tangents import generate_tangents  # noqa: E402


# These tests check the report's Blinn-Phong mapping of metallic-roughness materials
# (docs/materials.md); the glTF BRDF of shading="auto" has its reference in tests/test_brdf.py.
make_renderer = blinn_phong_renderer_fixture()


SHARED = Path(__file__).resolve().parents[1].parent / "shared" / "scenes"


def image(seed: int, h: int = 4, w: int = 8) -> np.ndarray:
    return np.random.default_rng(seed).integers(0, 256, (h, w, 4), dtype=np.uint8)


def load_quietly(path):
    """Load, failing on any warning."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        return load_scene(path)


# -- materials ------------------------------------------------------------------------------------------
FULL_MATERIAL = {
    "name": "full",
    "pbrMetallicRoughness": {
        "baseColorFactor": [0.5, 0.25, 1.0, 0.75],
        "baseColorTexture": {"index": 0},
        "metallicFactor": 0.3, "roughnessFactor": 0.6,
        "metallicRoughnessTexture": {"index": 1, "texCoord": 1},
    },
    "normalTexture": {"index": 2, "scale": -0.5, "texCoord": 1},
    "occlusionTexture": {"index": 3, "strength": 0.25,
                         "extensions": {"KHR_texture_transform": {"offset": [0.5, -0.25], "rotation": 0.75,
                                                                  "scale": [2.0, 3.0], "texCoord": 1}}},
    "emissiveFactor": [1.0, 0.5, 0.0],
    "emissiveTexture": {"index": 4, "extensions": {"KHR_texture_transform": {"scale": [0.5, 0.5]}}},
    "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": 7.5}},
    "alphaMode": "MASK", "alphaCutoff": 0.3, "doubleSided": True,
}


def test_every_material_property(tmp_path):
    """Factors, textures, texCoord and KHR_texture_transform (its texCoord wins) of every slot; one
    image read as colour (sRGB) and as data (linear) becomes two textures; same image + sampler +
    colour space is shared."""
    imgs = [image(0), image(1)]
    samplers = [{"wrapS": 33071, "wrapT": 33648}]
    textures = [{"source": 0, "sampler": 0},   # 0 base colour (sRGB)
                {"source": 0, "sampler": 0},   # 1 metallic-roughness: same image + sampler, linear
                {"source": 1},                 # 2 normal (linear)
                {"source": 1},                 # 3 occlusion: same as 2
                {"source": 0, "sampler": 0}]   # 4 emissive: same as 0 (sRGB)
    unlit = {"name": "flat", "extensions": {"KHR_materials_unlit": {}},
             "pbrMetallicRoughness": {"baseColorFactor": [0.1, 0.2, 0.3, 1.0]}}
    prims = [primitive(material=0, TEXCOORD_1=QUAD_UVS[::-1].copy()), primitive(material=1), primitive(material=2)]
    path = write_gltf(tmp_path / "full.gltf", prims, [FULL_MATERIAL, unlit, {}], images=imgs, textures=textures,
                      samplers=samplers,
                      extensionsUsed=["KHR_texture_transform", "KHR_materials_emissive_strength", "KHR_materials_unlit"])
    scene = load_quietly(path)
    full, flat, plain = scene.materials
    assert isinstance(full, Material)
    assert full.name == "full" and full.base_color == (0.5, 0.25, 1.0, 0.75)
    assert (full.metallic, full.roughness) == pytest.approx((0.3, 0.6))
    assert (full.normal_scale, full.occlusion_strength) == (-0.5, 0.25)
    assert full.emissive == (1.0, 0.5, 0.0) and full.emissive_strength == 7.5 and not full.unlit
    assert (full.alpha_mode, full.alpha_cutoff, full.double_sided) == ("MASK", pytest.approx(0.3), True)
    # the Blinn-Phong fields follow the mapping of the factors
    ref = Material.from_metallic_roughness("x", (0.5, 0.25, 1.0, 0.75), 0.3, 0.6)
    assert (full.specular_intensity, full.specular_power) == (ref.specular_intensity, ref.specular_power)

    # textures: (image, wrap, sRGB) -> one Texture each
    tex = {slot: scene.textures[getattr(full, f"{slot}_texture")]
           for slot in ("base_color", "metallic_roughness", "normal", "occlusion", "emissive")}
    assert len(scene.textures) == 3
    assert tex["base_color"] is tex["emissive"] and tex["base_color"].srgb
    assert tex["metallic_roughness"] is not tex["base_color"] and not tex["metallic_roughness"].srgb
    assert tex["normal"] is tex["occlusion"] and not tex["normal"].srgb
    np.testing.assert_array_equal(tex["base_color"].rgba, imgs[0])
    np.testing.assert_array_equal(tex["metallic_roughness"].rgba, imgs[0])
    np.testing.assert_array_equal(tex["normal"].rgba, imgs[1])
    assert (tex["metallic_roughness"].wrap_s, tex["metallic_roughness"].wrap_t) == ("clamp", "mirror")
    assert (tex["normal"].wrap_s, tex["normal"].wrap_t) == ("repeat", "repeat")

    # where each slot reads its coordinates
    assert full.base_color_uv == UVTransform()
    assert full.metallic_roughness_uv == UVTransform(texcoord=1)
    assert full.normal_uv == UVTransform(texcoord=1)
    assert full.occlusion_uv == UVTransform(1, (0.5, -0.25), 0.75, (2.0, 3.0))
    assert full.emissive_uv == UVTransform(0, (0.0, 0.0), 0.0, (0.5, 0.5))
    # KHR_texture_transform: uv' = T R S uv, R = [[cos, sin], [-sin, cos]]
    c, s = math.cos(0.75), math.sin(0.75)
    uv = np.array([0.3, 0.7])
    want = np.array([[c, s], [-s, c]]) @ (uv * [2.0, 3.0]) + [0.5, -0.25]
    m = full.occlusion_uv.matrix()
    np.testing.assert_allclose(m[:, :2] @ uv + m[:, 2], want, rtol=1e-12)

    # KHR_materials_unlit
    assert flat.unlit and flat.base_color == (0.1, 0.2, 0.3, 1.0)
    # glTF defaults
    assert (plain.metallic, plain.roughness, plain.normal_scale, plain.occlusion_strength) == (1.0, 1.0, 1.0, 1.0)
    assert (plain.emissive, plain.emissive_strength, plain.unlit, plain.double_sided) == ((0, 0, 0), 1.0, False, False)
    assert all(getattr(plain, f"{s}_texture") == -1 for s in ("base_color", "metallic_roughness", "normal",
                                                                 "occlusion", "emissive"))
    assert scene.triangle_material.tolist() == [0, 0, 1, 1, 2, 2]


# -- vertex attributes --------------------------------------------------------------------------------------
def test_vertex_colors(tmp_path):
    """COLOR_0: VEC3 float (alpha 1), VEC4 normalized unsigned byte and short (c / 255, c / 65535);
    a primitive without COLOR_0 gets white when another has colours; no COLOR_0 at all: None."""
    rng = np.random.default_rng(3)
    c3 = rng.random((4, 3), dtype=np.float32)
    c8 = rng.integers(0, 256, (4, 4), dtype=np.uint8)
    c16 = rng.integers(0, 65536, (4, 4), dtype=np.uint16)
    c8[0, 0], c16[0, 0] = 255, 65535
    prims = [primitive(COLOR_0=c3), primitive(COLOR_0=c8), primitive(), primitive(COLOR_0=c16)]
    scene = load_quietly(write_gltf(tmp_path / "c.gltf", prims))
    assert scene.colors.dtype == np.float32 and scene.colors.shape == (16, 4)
    np.testing.assert_array_equal(scene.colors[0:4], np.concatenate([c3, np.ones((4, 1), np.float32)], 1))
    np.testing.assert_array_equal(scene.colors[4:8], c8.astype(np.float32) / np.float32(255))
    np.testing.assert_array_equal(scene.colors[8:12], np.ones((4, 4), np.float32))
    np.testing.assert_array_equal(scene.colors[12:16], c16.astype(np.float32) / np.float32(65535))
    assert scene.colors[4, 0] == scene.colors[12, 0] == 1.0
    assert load_quietly(write_gltf(tmp_path / "none.gltf")).colors is None


def test_extra_uv_sets(tmp_path):
    """TEXCOORD_n, n >= 1 -> extra_uvs[n - 1] (K = the most any primitive has; missing sets are
    zeros); TEXCOORD_0 stays Scene.uvs; no TEXCOORD_1 anywhere: None."""
    rng = np.random.default_rng(4)
    uv1 = rng.random((4, 2), dtype=np.float32) * 4 - 2
    uv2 = rng.integers(0, 65536, (4, 2), dtype=np.uint16)
    prims = [primitive(TEXCOORD_1=uv1), primitive(), primitive(TEXCOORD_1=uv1[::-1].copy(), TEXCOORD_2=uv2)]
    scene = load_quietly(write_gltf(tmp_path / "uv.gltf", prims))
    assert scene.extra_uvs.shape == (2, 12, 2) and scene.uv_set_count == 3
    np.testing.assert_array_equal(scene.uvs, np.tile(QUAD_UVS, (3, 1)))
    np.testing.assert_array_equal(scene.extra_uvs[0], np.concatenate([uv1, np.zeros((4, 2)), uv1[::-1]]))
    np.testing.assert_array_equal(scene.extra_uvs[1, :8], 0)
    np.testing.assert_array_equal(scene.extra_uvs[1, 8:], uv2.astype(np.float32) / np.float32(65535))
    np.testing.assert_array_equal(scene.uv_set(2), scene.extra_uvs[1])
    assert load_quietly(write_gltf(tmp_path / "one.gltf")).extra_uvs is None


def quat(axis, deg):
    axis = np.asarray(axis, np.float64) / np.linalg.norm(axis)
    h = math.radians(deg) / 2
    return [*(axis * math.sin(h)), math.cos(h)]


def test_tangents_to_world_space(tmp_path):
    """TANGENT xyz by the node's 3x3 (renormalized), w times the sign of its determinant: a
    mirroring node flips w. Pieces without TANGENT and without a normal map: (0, 0, 0, 1).
    TANGENT without NORMAL is ignored (spec)."""
    t = np.array([[1, 0, 0, 1], [0.6, 0.8, 0, -1], [0, 1, 0, 1], [1, 1, 0, 1]], np.float32)
    t[3, :3] /= np.linalg.norm(t[3, :3])
    rot = quat([0, 0, 1], 90)
    nodes = [{"mesh": 0, "rotation": rot, "scale": [2, 1, 1]},  # stretch along local x, then rotate
             {"mesh": 0, "scale": [-1, 1, 1]},                  # mirror
             {"mesh": 1}]
    meshes = [[primitive(TANGENT=t)], [primitive()]]
    scene = load_quietly(write_gltf(tmp_path / "t.gltf", nodes=nodes, meshes=meshes))
    assert scene.tangents.shape == (12, 4) and scene.tangents.dtype == np.float32
    a = np.array([[0, -1, 0], [1, 0, 0], [0, 0, 1]], np.float64) @ np.diag([2.0, 1, 1])
    want = t[:, :3] @ a.T
    want /= np.linalg.norm(want, axis=1, keepdims=True)
    np.testing.assert_allclose(scene.tangents[0:4, :3], want, atol=1e-6)
    np.testing.assert_array_equal(scene.tangents[0:4, 3], t[:, 3])
    mirrored = t[:, :3] * [-1, 1, 1]
    np.testing.assert_allclose(scene.tangents[4:8, :3], mirrored, atol=1e-7)
    np.testing.assert_array_equal(scene.tangents[4:8, 3], -t[:, 3])
    np.testing.assert_array_equal(scene.tangents[8:12], np.tile([0, 0, 0, 1], (4, 1)))
    # TANGENT without NORMAL is ignored; nothing else needs tangents: None
    no_normal = write_gltf(tmp_path / "nn.gltf", [primitive(normals=None, TANGENT=t)])
    assert load_quietly(no_normal).tangents is None
    assert load_quietly(write_gltf(tmp_path / "plain.gltf")).tangents is None


def test_normal_map_without_tangent_generates_them(tmp_path):
    """A primitive whose material has a normalTexture but no TANGENT gets generate_tangents of its
    world-space positions and normals and of the uv set the normal map reads (here TEXCOORD_1,
    through KHR_texture_transform's texCoord); a mirroring node flips w."""
    uv1 = np.array([[1, 1], [0, 1], [0, 0], [1, 0]], np.float32)     # u runs along -X: mirrored
    mats = [{"normalTexture": {"index": 0, "extensions": {"KHR_texture_transform": {"texCoord": 1}}}}]
    nodes = [{"mesh": 0, "translation": [3, 0, 0]}, {"mesh": 0, "scale": [-1, 1, 1]}]
    path = write_gltf(tmp_path / "n.gltf", [primitive(material=0, TEXCOORD_1=uv1)], mats, images=[image(5)],
                      nodes=nodes, extensionsUsed=["KHR_texture_transform"])
    scene = load_quietly(path)
    assert scene.triangle_mesh.tolist() == [0, 0, 1, 1] and len(scene.mesh_names) == 2
    first = generate_tangents(scene.positions[:4], scene.normals[:4], uv1, QUAD_INDICES.reshape(-1, 3))
    np.testing.assert_array_equal(scene.tangents[:4], first)
    np.testing.assert_allclose(first, np.tile([-1, 0, 0, -1], (4, 1)), atol=1e-7)
    # mirrored in x: the tangent (along -u) is +X in world space and the frame is right-handed again
    np.testing.assert_allclose(scene.tangents[4:], np.tile([1, 0, 0, 1], (4, 1)), atol=1e-7)


# -- tangent generation ----------------------------------------------------------------------------------
QUAD_TRIS = QUAD_INDICES.reshape(-1, 3)


@pytest.mark.parametrize("uv, tangent", [
    (QUAD_UVS, [1, 0, 0, 1]),                                     # upright image: T = +X, right-handed
    (QUAD_UVS * [-1, 1] + [1, 0], [-1, 0, 0, -1]),                 # mirrored in u
    (QUAD_UVS * [1, -1] + [0, 1], [1, 0, 0, -1]),                  # mirrored in v (upside down)
    (1 - QUAD_UVS, [-1, 0, 0, 1]),                                 # rotated 180 degrees: no mirror
    (QUAD_UVS[:, ::-1], [0, -1, 0, -1]),                           # u along -Y, v along -X: transposed
])
def test_flat_quad_tangent_is_dp_du(uv, tangent):
    """On a flat quad with an affine uv mapping T = dP/du exactly, and w = +1 exactly when the
    image is not mirrored (glTF: B = cross(N, T) w points up the image, along -dP/dv)."""
    got = generate_tangents(QUAD_POSITIONS, QUAD_NORMALS, np.asarray(uv, np.float32), QUAD_TRIS)
    np.testing.assert_array_equal(got, np.tile(np.float32(tangent), (4, 1)))


def test_tilted_quad_with_skewed_uvs():
    """A quad in a tilted plane with a skewed (non-orthogonal), scaled uv mapping: T is dP/du
    normalized (it lies in the plane, so Gram-Schmidt leaves it), w from the bitangent dP/dv."""
    rng = np.random.default_rng(7)
    a, b = rng.normal(size=3), rng.normal(size=3)             # dP/du, dP/dv
    uv = np.array([[0.1, 0.2], [2.1, 0.2], [2.1, 1.7], [0.1, 1.7]])
    p = 5.0 + (uv[:, :1] * a + uv[:, 1:] * b)
    n = np.cross(b, a)                                          # normal that makes the mapping upright
    n /= np.linalg.norm(n)
    tris = np.array([[0, 1, 2], [0, 2, 3]])
    got = generate_tangents(p, np.tile(n, (4, 1)), uv, tris)
    np.testing.assert_allclose(got[:, :3], np.tile(a / np.linalg.norm(a), (4, 1)), atol=1e-6)
    np.testing.assert_array_equal(got[:, 3], 1.0)
    flipped = generate_tangents(p, np.tile(-n, (4, 1)), uv, tris[:, ::-1])   # seen from the other side
    np.testing.assert_array_equal(flipped[:, 3], -1.0)


def test_tangent_accumulation_is_angle_weighted():
    """A vertex shared by a 90-degree corner (T = +X) and a 45-degree corner (T = +Y) gets
    normalize(pi/2 X + pi/4 Y) (area weighting, both areas 1/2, would give 45 degrees)."""
    p = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 1, 0], [-1, 1, 0]], np.float64)
    n = np.tile([0.0, 0.0, 1.0], (5, 1))
    # triangle A (0, 1, 2): u = x, v = -y; triangle B (0, 3, 4): u = y, v = x (vertex 3 = 2, other uv)
    uv = np.array([[0, 0], [1, 0], [0, -1], [1, 0], [1, -1]], np.float64)
    got = generate_tangents(p, n, uv, np.array([[0, 1, 2], [0, 3, 4]]))
    want = np.array([math.pi / 2, math.pi / 4, 0.0])
    np.testing.assert_allclose(got[0, :3], want / np.linalg.norm(want), atol=1e-6)
    # Gram-Schmidt: a tilted vertex normal gets a tangent perpendicular to it
    n2 = n.copy()
    n2[0] = np.array([0.3, 0.0, 1.0]) / np.linalg.norm([0.3, 0.0, 1.0])
    got = generate_tangents(p, n2, uv, np.array([[0, 1, 2], [0, 3, 4]]))
    assert abs(np.dot(got[0, :3], n2[0])) < 1e-6 and np.linalg.norm(got[0, :3]) == pytest.approx(1, abs=1e-6)


def test_degenerate_input_never_gives_nan():
    """Zero-area uvs, collinear or NaN positions, zero or NaN normals, unused vertices: a unit
    tangent perpendicular to the (fallback) normal, w = 1, and never NaN."""
    p = np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0], [0, 1, 0], [np.nan, 0, 0], [5, 5, 5], [1, 1, 0]])
    n = np.array([[0, 0, 1], [0, 0, 0], [np.nan, 0, 1], [1, 0, 0], [0, 0, 1], [0, 1, 0], [0, 0, 1]])
    uv = np.array([[0, 0], [0, 0], [0, 0], [1, 1], [0, 1], [0, 0], [np.inf, 0]])
    tris = np.array([[0, 1, 2], [0, 1, 3], [0, 4, 3], [0, 3, 6], [1, 1, 1]])
    got = generate_tangents(p, n, uv, tris)
    assert np.isfinite(got).all()
    np.testing.assert_allclose(np.linalg.norm(got[:, :3], axis=1), 1.0, atol=1e-6)
    assert set(np.unique(got[:, 3])) <= {-1.0, 1.0}
    unit_n = np.array([[0, 0, 1], [0, 0, 1], [0, 0, 1], [1, 0, 0], [0, 0, 1], [0, 1, 0], [0, 0, 1]])
    assert np.abs(np.einsum("ij,ij->i", got[:, :3], unit_n)).max() < 1e-6
    assert generate_tangents(np.zeros((0, 3)), np.zeros((0, 3)), np.zeros((0, 2)), np.zeros((0, 3))).shape == (0, 4)


def compare_with_file_tangents(path: Path, meshes=None):
    """Regenerate the TANGENT of every primitive of `path` (that has TANGENT, NORMAL, TEXCOORD_0)
    from its own local data. Returns (angles in degrees between the generated tangent and the
    file's made orthogonal to the normal, whether w agrees) over the vertices that have a tangent
    frame at all (a triangle with non-zero uv area and a file tangent not parallel to N), and the
    number of vertices left out."""
    from clrender.loaders.gltf.document import load_document

    doc = load_document(path)
    angles, agree, left_out = [], [], 0
    for mi, mesh in enumerate(doc.json["meshes"]):
        if meshes is not None and not meshes(mesh.get("name", "")):
            continue
        for prim in mesh["primitives"]:
            a = prim["attributes"]
            if not {"TANGENT", "NORMAL", "TEXCOORD_0"} <= set(a):
                continue
            p, n, uv = (doc.accessor(a[k]).astype(np.float64) for k in ("POSITION", "NORMAL", "TEXCOORD_0"))
            idx = doc.accessor(prim["indices"]).reshape(-1, 3).astype(np.int64) if "indices" in prim \
                else np.arange(len(p)).reshape(-1, 3)
            ref = doc.accessor(a["TANGENT"]).astype(np.float64)
            got = generate_tangents(p, n, uv, idx).astype(np.float64)
            d1, d2 = uv[idx[:, 1]] - uv[idx[:, 0]], uv[idx[:, 2]] - uv[idx[:, 0]]
            det = d1[:, 0] * d2[:, 1] - d2[:, 0] * d1[:, 1]
            framed = np.zeros(len(p), bool)
            framed[idx[np.abs(det) > 1e-12 * np.abs(np.concatenate([d1, d2], 1)).max(1) ** 2].ravel()] = True
            n = n / np.linalg.norm(n, axis=1, keepdims=True)
            t = ref[:, :3] - n * np.einsum("ij,ij->i", n, ref[:, :3])[:, None]
            length = np.linalg.norm(t, axis=1)
            used = np.zeros(len(p), bool)
            used[idx.ravel()] = True
            keep = used & framed & (length > 1e-3)
            left_out += int((used & ~keep).sum())
            t = t[keep] / length[keep, None]
            angles.append(np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", t, got[keep, :3]), -1, 1))))
            agree.append(np.sign(ref[keep, 3]) == got[keep, 3])
    return np.concatenate(angles), np.concatenate(agree), left_out


def shared_scene(rel: str) -> Path:
    path = SHARED / rel
    if not path.is_file():
        pytest.skip(f"shared test scene {path} is not available (needs ../shared/scenes next to the repository)")
    return path


# (file, mesh filter, vertices compared, left out, median, p95, max angle bounds in degrees, w agreement)
# The numbers measured are in clrender/scene/tangents.py's docstring; the bounds sit just above them.
MIKK_FILES = [
    # Khronos Blender exporter (MikkTSpace): exact up to float rounding
    ("khronos-AlphaBlendModeTest/AlphaBlendModeTest.gltf", None, 137, 0, 0.001, 0.02, 0.02, 1.0),
    ("khronos-VertexColorTest/VertexColorTest.gltf", None, 56, 16, 0.001, 0.001, 0.001, 52 / 56),
    # UnityGLTF: Unity's MikkTSpace; the TextMeshPro text meshes carry a constant hand-set tangent
    ("lights-punctual-AnimateAllTheThings/24_animation_pointer.gltf", lambda name: "TMP" not in name,
     8757, 0, 0.01, 1.5, 62.0, 8749 / 8757),
    # VKTS exporter: per-face tangents, not MikkTSpace, and w = +1 everywhere (see tangents.py)
    ("khronos-Suzanne/Suzanne.gltf", None, 11808, 0, 3.8, 18.0, 65.0, 0.0),
    ("khronos-AnimatedCube/AnimatedCube.gltf", None, 36, 0, 0.001, 0.001, 0.001, 0.0),
]


@pytest.mark.parametrize("rel, meshes, count, left_out, median, p95, worst, w_agree", MIKK_FILES,
                         ids=[f[0].split("/")[1] for f in MIKK_FILES])
def test_mikktspace_agreement(rel, meshes, count, left_out, median, p95, worst, w_agree):
    angles, agree, skipped = compare_with_file_tangents(shared_scene(rel), meshes)
    assert (len(angles), skipped) == (count, left_out)
    assert np.median(angles) <= median and np.percentile(angles, 95) <= p95 and angles.max() <= worst
    assert agree.mean() == pytest.approx(w_agree, abs=1e-9)


# -- unsupported features ------------------------------------------------------------------------------------
def weights_animation() -> dict:
    """An animation of node 0's morph target weights (one target)."""
    return {"channels": [{"sampler": 0, "target": {"node": 0, "path": "weights"}}],
            "samplers": [{"input": np.float32([0, 1]), "output": np.float32([0, 1])}]}


def test_one_warning_per_file_and_feature(tmp_path):
    """Unknown extensions (in extensionsUsed, on materials, on nodes), point/line and fan primitives,
    COLOR_1, nearest magnification: each used twice, each warned exactly once naming the file and the
    feature; the triangles still load. Skins, morph targets and animated weights (supported) do not warn."""
    joints = np.zeros((4, 4), np.uint8)
    weights = np.tile(np.float32([1, 0, 0, 0]), (4, 1))
    morph = [{"POSITION": np.zeros((4, 3), np.float32)}]
    prims = [primitive(material=0, JOINTS_0=joints, WEIGHTS_0=weights, targets=morph, COLOR_1=QUAD_NORMALS),
             primitive(material=1, JOINTS_0=joints, WEIGHTS_0=weights, targets=morph, COLOR_1=QUAD_NORMALS),
             primitive(mode=0), primitive(mode=1), primitive(mode=6), primitive(mode=6)]
    mats = [{"extensions": {"KHR_materials_volume_scatter": {}, "KHR_materials_unlit": {}},
             "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}},
            {"extensions": {"KHR_materials_volume_scatter": {}, "VENDOR_thing": {}},
             "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}]
    nodes = [{"mesh": 0, "skin": 0, "extensions": {"EXT_node_magic": {}}}, {"mesh": 0, "skin": 0}]
    path = write_gltf(tmp_path / "features.gltf", prims, mats, images=[image(1)], nodes=nodes,
                      samplers=[{"magFilter": 9728}], textures=[{"source": 0, "sampler": 0}],
                      skins=[{"joints": [0]}], animations=[weights_animation(), weights_animation()],
                      extensionsUsed=["KHR_materials_volume_scatter", "KHR_materials_unlit", "VENDOR_thing",
                                      "EXT_node_magic", "KHR_animation_pointer"])
    with warnings.catch_warnings(record=True) as record:
        warnings.simplefilter("always")
        scene = load_scene(path)
    messages = [str(w.message) for w in record]
    features = ["KHR_materials_volume_scatter", "VENDOR_thing", "EXT_node_magic",
                "KHR_animation_pointer", "point and line primitives", "TRIANGLE_FAN", "COLOR_1", "magFilter NEAREST"]
    for feature in features:
        hits = [m for m in messages if feature in m]
        assert len(hits) == 1, (feature, messages)
        assert hits[0].startswith(str(path)), hits[0]
    assert len(messages) == len(features), messages
    assert all(issubclass(w.category, UserWarning) for w in record)
    assert not any("KHR_materials_unlit" in m or "skin" in m or "morph" in m for m in messages)    # supported
    assert scene.triangle_count == 2 * 2 * 2 and scene.materials[0].unlit


def test_supported_extensions_do_not_warn(tmp_path):
    mats = [{"extensions": {"KHR_materials_unlit": {}, "KHR_materials_emissive_strength": {"emissiveStrength": 2}},
             "emissiveFactor": [1, 1, 1],
             "pbrMetallicRoughness": {"baseColorTexture": {
                 "index": 0, "extensions": {"KHR_texture_transform": {"rotation": 1.0}}}}}]
    used = ["KHR_materials_unlit", "KHR_materials_emissive_strength", "KHR_texture_transform"]
    path = write_gltf(tmp_path / "ok.gltf", [primitive(material=0)], mats, images=[image(2)],
                      extensionsUsed=used, extensionsRequired=used)
    m = load_quietly(path).materials[0]
    assert m.unlit and m.emissive_strength == 2.0 and m.base_color_uv.rotation == 1.0


@pytest.mark.parametrize("required", [["VENDOR_mesh_compression"], ["KHR_materials_unlit", "VENDOR_required"]])
def test_required_unknown_extension_fails(tmp_path, required):
    path = write_gltf(tmp_path / "req.gltf", extensionsUsed=required, extensionsRequired=required)
    with pytest.raises(SceneError, match=r"req\.gltf") as info:
        load_scene(path)
    assert required[-1] in str(info.value) and "extensionsRequired" in str(info.value)
    assert "KHR_materials_unlit" not in str(info.value).split("(")[0]     # the supported one is not blamed


# -- bad input ---------------------------------------------------------------------------------------------
def _with_material(material, **prim_kw):
    return dict(primitives=[primitive(material=0, **prim_kw)], materials=[dict(material, name="bad")],
                images=[image(3)])


BAD = {
    "normal texture index": (_with_material({"normalTexture": {"index": 5}}),
                             ["material 0 ('bad') normalTexture", "textures[5]", "does not exist"]),
    "emissive texture index": (_with_material({"emissiveTexture": {"index": -1}}), ["emissiveTexture", "textures[-1]"]),
    "texCoord set missing": (_with_material({"occlusionTexture": {"index": 0, "texCoord": 2}}),
                             ["primitive 0", "material 0 ('bad')", "occlusionTexture", "TEXCOORD_2",
                              "does not have", "TEXCOORD_0"]),
    "transform texCoord set missing": (
        _with_material({"pbrMetallicRoughness": {"metallicRoughnessTexture": {
            "index": 0, "extensions": {"KHR_texture_transform": {"texCoord": 1}}}}}),
        ["material 0 ('bad')", "pbrMetallicRoughness.metallicRoughnessTexture", "TEXCOORD_1"]),
    "texture without TEXCOORD_0": (_with_material({"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}},
                                                  uvs=None), ["baseColorTexture", "TEXCOORD_0", "none"]),
    "transform offset": (_with_material({"normalTexture": {"index": 0, "extensions": {
        "KHR_texture_transform": {"offset": [1]}}}}), ["normalTexture", "offset", "2 numbers"]),
    "occlusion strength": (_with_material({"occlusionTexture": {"index": 0, "strength": 2}}),
                           ["occlusionTexture.strength", "2"]),
    "metallic factor": (_with_material({"pbrMetallicRoughness": {"metallicFactor": 1.5}}),
                        ["material 0 ('bad')", "metallic", "1.5"]),
    "emissive factor": (_with_material({"emissiveFactor": [2, 0, 0]}), ["material 0 ('bad')", "emissive"]),
    "emissive strength": (_with_material({"extensions": {"KHR_materials_emissive_strength": {
        "emissiveStrength": -1}}}), ["material 0 ('bad')", "emissive_strength", "-1"]),
    "COLOR_0 VEC2": (dict(primitives=[primitive(COLOR_0=np.zeros((4, 2), np.float32))]),
                     ["primitive 0", "COLOR_0", "VEC3 or VEC4", "got VEC2"]),
    "COLOR_0 signed": (dict(primitives=[primitive(COLOR_0=np.zeros((4, 4), np.int8))]),
                       ["COLOR_0", "normalized UNSIGNED_BYTE", "got VEC4 of normalized BYTE"]),
    "COLOR_0 count": (dict(primitives=[primitive(COLOR_0=np.zeros((3, 4), np.float32))]),
                      ["COLOR_0", "3 entries", "POSITION has 4"]),
    "COLOR_0 NaN": (dict(primitives=[primitive(COLOR_0=np.full((4, 4), np.nan, np.float32))]),
                    ["COLOR_0", "non-finite"]),
    "TANGENT VEC3": (dict(primitives=[primitive(TANGENT=np.zeros((4, 3), np.float32))]), ["TANGENT", "VEC4"]),
    "TANGENT NaN": (dict(primitives=[primitive(TANGENT=np.full((4, 4), np.nan, np.float32))]),
                    ["TANGENT", "non-finite"]),
    "TEXCOORD_1 VEC3": (dict(primitives=[primitive(TEXCOORD_1=np.zeros((4, 3), np.float32))]),
                        ["TEXCOORD_1", "VEC2"]),
}


@pytest.mark.parametrize("name", list(BAD))
def test_bad_input_names_file_and_element(tmp_path, name):
    kw, words = BAD[name]
    path = write_gltf(tmp_path / "bad.gltf", **kw)
    with pytest.raises(SceneError) as info:
        load_scene(path)
    msg = str(info.value)
    assert msg.startswith(str(path)), msg
    for word in words:
        assert word in msg, (word, msg)


# -- TOML scenes keep the new attributes -------------------------------------------------------------------
def test_toml_concatenation_keeps_colors_tangents_uvs_and_texture_slots(tmp_path):
    """A TOML scene of an OBJ and a glTF: vertex colours, tangents and uv sets concatenate (the OBJ
    gets the defaults), every texture slot is re-indexed, and a mirroring transform flips w."""
    import imageio.v3 as iio

    iio.imwrite(tmp_path / "t.png", image(7))
    (tmp_path / "a.mtl").write_text("newmtl m\nmap_Kd t.png\n")
    (tmp_path / "a.obj").write_text("mtllib a.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl m\nf 1 2 3\n")
    t = np.tile(np.float32([1, 0, 0, 1]), (4, 1))
    c = np.tile(np.float32([0.5, 0.25, 0.125, 1.0]), (4, 1))
    mats = [{"normalTexture": {"index": 0}, "occlusionTexture": {"index": 1},
             "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}]
    write_gltf(tmp_path / "g.gltf", [primitive(material=0, TANGENT=t, COLOR_0=c, TEXCOORD_1=QUAD_UVS)], mats,
               images=[image(8), image(9)])
    (tmp_path / "s.toml").write_text('[[mesh]]\npath = "a.obj"\n[[mesh]]\npath = "g.gltf"\n'
                                     'transform = { scale = [-1, 1, 1] }\n')
    gltf = load_quietly(tmp_path / "g.gltf")
    scene = load_quietly(tmp_path / "s.toml")
    np.testing.assert_array_equal(scene.colors, np.concatenate([np.ones((3, 4)), c]))
    np.testing.assert_array_equal(scene.tangents, np.concatenate([np.tile([0, 0, 0, 1], (3, 1)),
                                                                  np.tile([-1, 0, 0, -1], (4, 1))]))
    np.testing.assert_array_equal(scene.extra_uvs, np.concatenate([np.zeros((1, 3, 2)), QUAD_UVS[None]], 1))
    m, g = scene.materials[-1], gltf.materials[0]
    assert (m.base_color_texture, m.normal_texture, m.occlusion_texture) == \
        (g.base_color_texture + 1, g.normal_texture + 1, g.occlusion_texture + 1)   # after the OBJ's texture
    assert [t.srgb for t in gltf.textures] == [True, False, False]
    assert scene.textures[1:] == gltf.textures or all(
        np.array_equal(a.rgba, b.rgba) and a.srgb == b.srgb for a, b in zip(scene.textures[1:], gltf.textures))
    assert scene.materials[0].base_color_texture == 0
