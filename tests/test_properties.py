"""Property-based tests (hypothesis, derandomized, bounded) on random triangle soups and light sets.

Extends test_raster.py::test_random_soup_matches_reference (triangle ids exact, depth rtol 1e-6,
same soups) to every G-buffer field, and checks invariances no single example pins down:

  * G-buffer == NumPy reference: ids exact, depth rtol 1e-6, normal within NORMAL_TOL of the face
    normal (flipped for visible back faces), albedo within 1 sRGB code, specular intensity within
    half a unorm8 step, specular power within one log2unorm8 step;
  * tiled shading == brute force within 1e-5 of the brightest pixel (exact on PoCL; the tolerance
    leaves GPU compilers room to contract differently), and brute force == the float64 shading
    reference (tests/reference/shading.py) within 2e-4 of the brightest pixel (measured <= 6e-5);
  * shuffling the scene's triangle order (and its vertex order) changes nothing: ids map through the
    permutation, depth/normals/albedo bit-identical, color identical;
  * tile_size 8/16/32 and light_tile_size 8/16/32 change nothing: G-buffer bit-identical, color
    within 1e-5 of the brightest pixel (exact on PoCL).

Examples (per device): 20 G-buffer soups, 15 light sets, 12 shuffles, 12 tile-size pairs; 5-10 s.
"""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from helpers import SHADING_TOL_RANDOM
from clrender import Camera, Material, Scene
from clrender.abi import structs
from clrender.abi.gbuffer import linear_to_srgb8
from clrender.scene.geometry import vertex_normals
from reference import shading as ref_shading
from reference.raster import rasterize
from test_raster import make_soup, soups

NORMAL_TOL = 2e-3          # octahedral 2×12-bit: |decoded - n| <= ~1.1e-3 (measured 8e-4)
SETTINGS = dict(derandomize=True, deadline=None, print_blob=True,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large,
                                       HealthCheck.function_scoped_fixture])


def with_random_materials(scene: Scene, rng) -> Scene:
    """The scene with 6 random materials (some single-sided) assigned at random to its triangles."""
    mats = [Material(f"m{k}", (*rng.uniform(0, 1, 3), 1.0), specular_intensity=float(rng.uniform(0, 1)),
                     specular_power=float(np.exp(rng.uniform(0, np.log(2048)))), double_sided=bool(k % 3))
            for k in range(6)]
    tri_mat = rng.integers(0, len(mats), scene.triangle_count).astype(np.int32)
    return Scene(scene.positions, scene.normals, scene.uvs, scene.triangles, tri_mat, mats)


def face_normals(scene: Scene) -> np.ndarray:
    p = scene.positions.astype(np.float64)[scene.triangles]
    with np.errstate(all="ignore"):
        n = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
        return n / np.linalg.norm(n, axis=1, keepdims=True)


@settings(max_examples=20, **SETTINGS)
@given(params=soups())
def test_gbuffer_fields_match_reference(make_renderer, params):
    from helpers import reach_the_raster_guard
    with pytest.MonkeyPatch.context() as mp:     # the soup holds non-finite vertices on purpose
        reach_the_raster_guard(mp)
        _gbuffer_fields_match_reference(make_renderer, params)


def _gbuffer_fields_match_reference(make_renderer, params):
    size = params[0]
    scene, cam = make_soup(*params)
    scene = with_random_materials(scene, np.random.default_rng(params[2]))
    ids, depth, _ = rasterize(scene, cam, *size)
    frame = make_renderer(*size).render(scene, camera=cam)
    assert np.array_equal(frame.triangle_id, ids), f"{(frame.triangle_id != ids).sum()} ids differ"
    fg = ids >= 0
    np.testing.assert_allclose(frame.depth[fg], depth[fg], rtol=1e-6, atol=0)
    if not fg.any():
        return
    t = ids[fg]
    # Flat triangles (separate vertices): the normal is the face normal, facing the eye.
    n = face_normals(scene)[t]
    p0 = scene.positions.astype(np.float64)[scene.triangles[t, 0]]
    facing = np.einsum("ij,ij->i", n, np.asarray(cam.eye) - p0)
    n *= np.sign(facing)[:, None]
    clear = np.abs(facing) > 1e-6 * np.linalg.norm(np.asarray(cam.eye) - p0, axis=1)
    err = np.linalg.norm(frame.normal[fg] - n, axis=1)[clear]
    assert err.max() <= NORMAL_TOL, f"normal off by {err.max():.3g}"
    mats = scene.materials
    m = scene.triangle_material[t]
    color = np.array([mt.base_color[:3] for mt in mats])[m]
    code = np.abs(linear_to_srgb8(frame.albedo[fg]).astype(int) - linear_to_srgb8(color).astype(int))
    assert code.max() <= 1, "albedo off by more than one sRGB code"
    spec = np.array([mt.specular_intensity for mt in mats])[m]
    assert np.abs(frame.specular_intensity[fg] - spec).max() <= 0.5 / 255 + 1e-6
    power = np.array([mt.specular_power for mt in mats])[m]
    step = 2.0 ** (11 / 255) - 1           # one log2unorm8 code, relative
    assert np.abs(frame.specular_power[fg] / power - 1).max() <= step


# -- lights -------------------------------------------------------------------------------------------
@st.composite
def light_sets(draw):
    return dict(seed=draw(st.integers(0, 2**32 - 1)), count=draw(st.sampled_from([0, 1, 7, 60, 300])),
                spot_fraction=draw(st.sampled_from([0.0, 0.3, 1.0])),
                radius=draw(st.sampled_from([(0.2, 1.0), (0.5, 4.0), (3.0, 12.0)])),
                tile=draw(st.sampled_from([8, 16, 32])), depth_mask=draw(st.booleans()),
                size=draw(st.sampled_from([(64, 48), (97, 61), (40, 40)])))


def lit_soup(p):
    """A soup of 150 triangles in front of a fixed camera plus random point and spot lights around it."""
    rng = np.random.default_rng(p["seed"])
    n = 150
    cam = Camera.look_at((0.0, 1.0, 6.0), (0.0, 0.0, 0.0), (0, 1, 0), 60.0, near=0.1, far=40.0)
    centers = rng.uniform((-4, -2, -4), (4, 3, 2), (n, 1, 3))
    tris = centers + rng.normal(size=(n, 3, 3)) * np.exp(rng.uniform(np.log(0.1), np.log(1.5), (n, 1, 1)))
    positions = tris.reshape(-1, 3)
    faces = np.arange(3 * n).reshape(-1, 3)
    scene = with_random_materials(Scene(positions, vertex_normals(positions, faces),
                                        np.zeros((3 * n, 2)), faces, np.zeros(n, np.int32)), rng)
    c = p["count"]
    lights = np.zeros(c, structs.light_dtype)
    lights["position"] = rng.uniform((-5, -3, -5), (5, 4, 7), (c, 3))      # some around / behind the camera
    lights["radius"] = rng.uniform(*p["radius"], c)
    lights["color"] = rng.uniform(0.05, 1.5, (c, 3))
    lights["direction"] = (0, 0, -1)
    spot = rng.random(c) < p["spot_fraction"]
    d = rng.normal(size=(c, 3))
    lights["direction"][spot] = d[spot] / np.linalg.norm(d[spot], axis=1, keepdims=True)
    outer = rng.uniform(5, 80, c)
    inner = np.where(rng.random(c) < 0.2, outer, outer * rng.uniform(0, 1, c))
    lights["type"][spot] = structs.LIGHT_SPOT
    lights["cos_outer"][spot] = np.cos(np.radians(outer[spot]))
    lights["cos_inner"][spot] = np.cos(np.radians(inner[spot]))
    scene.lights = lights
    scene.ambient = 0.05
    return scene, cam


@settings(max_examples=15, **SETTINGS)
@given(p=light_sets())
def test_tiled_shading_equals_brute_force_and_reference(make_renderer, p):
    scene, cam = lit_soup(p)
    w, h = p["size"]
    brute = make_renderer(w, h, light_culling="brute_force").render(scene, camera=cam)
    tiled = make_renderer(w, h, light_tile_size=p["tile"], light_depth_mask=p["depth_mask"]).render(scene, camera=cam)
    assert np.array_equal(tiled.gbuffer, brute.gbuffer)
    peak = max(float(brute.color.max()), 1e-6)
    diff = np.abs(tiled.color.astype(np.float64) - brute.color)
    assert diff.max() <= 1e-5 * peak, f"tiled vs brute force: {diff.max():.3g} (peak {peak:.3g})"
    expect, info = ref_shading.shade_frame(brute, cam, scene.lights, scene.ambient, details=True)
    ok = info["min_abs_ndotl"] > 1e-4          # the specular term jumps at N·L = 0 (see test_lighting.py)
    err = np.abs(brute.color.astype(np.float64) - expect)[ok]
    assert err.size == 0 or err.max() <= SHADING_TOL_RANDOM * max(float(expect.max()), 1e-6), f"vs reference: {err.max():.3g}"
    fg = brute.triangle_id >= 0
    assert fg.mean() > 0.2
    if p["count"] >= 60 and p["radius"][0] >= 0.5:       # a black or ambient-only frame must fail
        assert (brute.color[fg] > 1.01 * scene.ambient * brute.albedo[fg]).any(-1).mean() > 0.2


# -- invariances --------------------------------------------------------------------------------------
def shuffled(scene: Scene, rng) -> tuple[Scene, np.ndarray]:
    """(the scene with triangles and vertices in random order, perm): new triangle j is old perm[j]."""
    perm = rng.permutation(scene.triangle_count)
    vperm = rng.permutation(len(scene.positions))          # new vertex k is old vperm[k]
    inverse = np.empty_like(vperm)
    inverse[vperm] = np.arange(len(vperm))
    out = Scene(scene.positions[vperm], scene.normals[vperm], scene.uvs[vperm], inverse[scene.triangles[perm]],
                scene.triangle_material[perm], scene.materials)
    out.lights, out.ambient = scene.lights, scene.ambient
    return out, perm


@settings(max_examples=12, **SETTINGS)
@given(p=light_sets())
def test_triangle_order_does_not_matter(make_renderer, p):
    scene, cam = lit_soup(p)
    w, h = p["size"]
    r = make_renderer(w, h, light_tile_size=p["tile"])
    a = r.render(scene, camera=cam)
    other, perm = shuffled(scene, np.random.default_rng(p["seed"] + 1))
    b = r.render(other, camera=cam)
    fg = a.triangle_id >= 0
    assert np.array_equal(b.triangle_id >= 0, fg)
    assert np.array_equal(perm[b.triangle_id[fg]], a.triangle_id[fg]), "ids must map through the permutation"
    for plane in range(4):                               # everything but the triangle id plane
        assert np.array_equal(a.gbuffer[plane], b.gbuffer[plane]), f"G-buffer plane {plane} differs"
    assert np.array_equal(a.color, b.color) and np.array_equal(a.light_count, b.light_count)
    for key in ("invalid", "culled_near", "degenerate", "culled_backface", "prims", "tile_entries"):
        assert a.stats[key] == b.stats[key], key


@settings(max_examples=12, **SETTINGS)
@given(p=light_sets(), tile=st.sampled_from([8, 16, 32]))
def test_tile_sizes_do_not_matter(make_renderer, p, tile):
    scene, cam = lit_soup(p)
    w, h = p["size"]
    base = make_renderer(w, h, tile_size=8, light_tile_size=32).render(scene, camera=cam)
    other = make_renderer(w, h, tile_size=tile, light_tile_size=p["tile"]).render(scene, camera=cam)
    assert np.array_equal(other.gbuffer, base.gbuffer), "the G-buffer must not depend on the tile sizes"
    peak = max(float(base.color.max()), 1e-6)
    diff = np.abs(other.color.astype(np.float64) - base.color).max()
    assert diff <= 1e-5 * peak, f"tile {tile} / light tile {p['tile']}: color differs by {diff:.3g}"
