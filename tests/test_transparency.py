"""Transparency (docs/transparency.md) against the independent NumPy reference tests/reference/transparency.py.

* the reference itself on hand-computed cases (no device);
* A-buffer == reference on random soups (hypothesis) of overlapping transparent triangles (random
  alpha and colours, vertex normals varying across each triangle, single- and double-sided, some
  crossing the near plane) with opaque occluders, a back wall, point and spot lights:
  fragment_count exact, transmittance within 1e-5, color within COLOR_TOL of the frame's brightest
  reference value. The opaque colour under the layers is the float64 reference shading of the
  frame's own (opaque-only) G-buffer, whose triangle_id must equal the reference's opaque raster;
* lights reaching only a glass (every culling option), early stop, shadows cast by glass (ray-cast
  visibility), far plane and background, coplanar ties, alpha-0 texels, SSAO, fragment shading ==
  opaque shading (sun cascades, shadowed spot, texture), tile sizes, odd image sizes, reuse;
* order independence (shuffled transparent triangles: bit-identical), depth peeling (== A-buffer
  bit for bit with enough layers, == the reference truncated to N layers with fewer),
  max_fragments_per_pixel, screen door (the documented dither, every material pair), overflow
  (200 fragments per pixel; > 1M fragments; retries), opaque scenes unchanged by the transparency
  mode, refraction (the displaced lookup, clamping, back faces, face-on), the Khronos
  AlphaBlendModeTest scene, bad input.
"""
from __future__ import annotations

import os

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import clrender
from clrender import Camera, Material, Scene
from clrender.abi import structs
from clrender.scene.model import SceneError
from reference import shading as ref_shading
from reference import transparency as ref
from reference.raster import coverage_count, pixel_exact_camera, screen_to_world

# Fragments are shaded from unquantized float32 barycentrics, positions and normals and blended in
# float32; the reference is float64: 1e-4 of the brightest reference value of the frame, the shading
# tolerance of test_lighting.py (measured on PoCL: <= 3e-6; transmittance <= 5e-8).
COLOR_TOL = 1e-4
TRANSMITTANCE_TOL = 1e-5
SETTINGS = dict(derandomize=True, deadline=None, print_blob=True,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large,
                                       HealthCheck.function_scoped_fixture])

W, H = 64, 48
CAMERA = Camera.look_at((0.0, 0.0, 0.0), (0.0, 0.0, -1.0), fov_y_deg=60.0, near=0.1, far=50.0)
AMBIENT = 0.1
KHRONOS = os.path.join(os.path.dirname(__file__), "..", "..", "shared", "scenes", "khronos-AlphaBlendModeTest",
                       "AlphaBlendModeTest.gltf")


# -- scene construction --------------------------------------------------------------------------

def build_scene(parts, ambient=AMBIENT, lights=None, uvs=None, textures=()) -> Scene:
    """parts: (vertices (n, 3, 3), normals (n, 3, 3) or None for flat, Material); every triangle has
    its own three vertices, triangle ids follow the order of parts."""
    materials, pos, nrm, mat = [], [], [], []
    for verts, normals, material in parts:
        verts = np.asarray(verts, np.float64).reshape(-1, 3, 3)
        if normals is None:
            fn = np.cross(verts[:, 1] - verts[:, 0], verts[:, 2] - verts[:, 0])
            fn /= np.linalg.norm(fn, axis=-1, keepdims=True)
            normals = np.repeat(fn[:, None, :], 3, axis=1)
        if material not in materials:
            materials.append(material)
        pos.append(verts)
        nrm.append(np.asarray(normals, np.float64).reshape(-1, 3, 3))
        mat.append(np.full(len(verts), materials.index(material), np.int32))
    pos, nrm = np.concatenate(pos), np.concatenate(nrm)
    t = len(pos)
    uvs = np.zeros((3 * t, 2), np.float32) if uvs is None else uvs
    scene = Scene(pos.reshape(-1, 3), nrm.reshape(-1, 3), uvs, np.arange(3 * t, dtype=np.int32).reshape(-1, 3),
                  np.concatenate(mat), materials, textures=list(textures))
    scene.ambient = ambient
    if lights is not None:
        scene.lights = lights
    return scene


def quad(x0, x1, y0, y1, z):
    """Two CCW (camera-facing for a camera looking down -Z) triangles of an axis-aligned quad."""
    a, b, c, d = (x0, y0, z), (x1, y0, z), (x1, y1, z), (x0, y1, z)
    return np.array([[a, b, c], [a, c, d]], np.float64)


def point_lights(records) -> np.ndarray:
    out = np.zeros(len(records), structs.light_dtype)
    for i, (p, c, r) in enumerate(records):
        out[i]["position"], out[i]["color"], out[i]["radius"] = p, c, r
        out[i]["type"], out[i]["direction"] = structs.LIGHT_POINT, (0, 0, -1)
    return out


def wall(z=-12.0, material=None):
    m = material or Material("wall", (0.7, 0.7, 0.65, 1.0), specular_intensity=0.2, specular_power=8.0)
    return (quad(-12, 12, -9, 9, z), None, m)


def random_soup(seed: int, n_transparent=None, n_materials=None, crossing=False):
    """A back wall, 0-2 opaque occluders and 6-14 overlapping transparent triangles (2-5 BLEND
    materials: random colour, alpha 0.05..0.95 as base_color alpha or opacity, random specular,
    most double-sided), vertex normals perturbed per vertex, 3 point lights and a spot light.
    crossing: 2 more transparent triangles reaching behind the camera (near clipping)."""
    rng = np.random.default_rng(seed)
    tan = np.tan(np.radians(CAMERA.fov_y_deg) / 2)
    aspect = W / H

    def tri_at(depth_lo, depth_hi, size):
        d = rng.uniform(depth_lo, depth_hi)
        ndc = rng.uniform(-0.5, 0.5, 2)
        center = np.array([ndc[0] * d * tan * aspect, ndc[1] * d * tan, -d])
        offs = rng.normal(scale=size * d * tan, size=(3, 3))
        offs[:, 2] *= 0.6
        v = center + offs
        v[:, 2] = np.clip(v[:, 2], -11.0, -1.0)         # in front of the wall, far from the near plane
        return v

    def perturbed_normals(v):
        fn = np.cross(v[1] - v[0], v[2] - v[0])
        fn /= np.linalg.norm(fn)
        n = fn + rng.normal(scale=0.35, size=(3, 3))
        return n / np.linalg.norm(n, axis=-1, keepdims=True)

    parts = [wall()]
    occ = Material("occluder", (0.3, 0.5, 0.8, 1.0), specular_intensity=0.4, specular_power=16.0)
    for _ in range(int(rng.integers(0, 3))):
        v = tri_at(3.0, 8.0, 0.35)
        parts.append((v[None], perturbed_normals(v)[None], occ))
    nm = int(n_materials or rng.integers(2, 6))
    mats = []
    for k in range(nm):
        a = float(rng.uniform(0.05, 0.95))
        color = tuple(rng.uniform(0.1, 1.0, 3))
        kw = dict(specular_intensity=float(rng.uniform(0.0, 0.8)), specular_power=float(rng.uniform(2.0, 64.0)),
                  double_sided=bool(rng.random() < 0.75))
        if rng.random() < 0.5:
            mats.append(Material(f"glass{k}", (*color, a), alpha_mode="BLEND", **kw))
        else:
            mats.append(Material(f"glass{k}", (*color, 1.0), opacity=a, **kw))
    for _ in range(int(n_transparent or rng.integers(6, 15))):
        v = tri_at(2.0, 10.0, 0.7)
        parts.append((v[None], perturbed_normals(v)[None], mats[int(rng.integers(nm))]))
    if crossing:
        # two BLEND triangles reaching behind the camera: near-clipped into one or two prims each
        for k in range(2):
            a = rng.uniform((-1.5, -1.0, -3.0), (1.5, 1.0, -1.5))
            b = a + rng.uniform((-1.0, -1.0, -1.0), (1.0, 1.0, 0.0))
            c = np.array([rng.uniform(-0.5, 0.5), rng.uniform(-0.5, 0.5), rng.uniform(0.5, 2.0)])
            v = np.stack([a, b, c])
            parts.append((v[None], perturbed_normals(v)[None], mats[k % nm]))
    lights = point_lights([(rng.uniform((-3, -2, -6), (3, 2, -1)), rng.uniform(0.5, 2.0, 3), rng.uniform(6, 12))
                           for _ in range(3)])
    spot = point_lights([((rng.uniform(-2, 2), 3.0, -2.0), (1.5, 1.4, 1.2), 14.0)])
    spot["type"] = structs.LIGHT_SPOT
    d = np.array([rng.uniform(-0.3, 0.3), -1.0, -rng.uniform(0.5, 1.5)])
    spot["direction"] = d / np.linalg.norm(d)
    spot["cos_inner"], spot["cos_outer"] = np.cos(np.radians(20.0)), np.cos(np.radians(45.0))
    return build_scene(parts, lights=np.concatenate([lights, spot]))


def shuffled_transparent(scene: Scene, seed: int) -> tuple[Scene, np.ndarray]:
    """The scene with its BLEND triangles' rows permuted among themselves: (scene, old id of each new id)."""
    blend = ref.blend_mask(scene)
    idx = np.flatnonzero(blend)
    perm = np.arange(scene.triangle_count)
    perm[idx] = np.random.default_rng(seed).permutation(idx)
    return Scene(scene.positions, scene.normals, scene.uvs, scene.triangles[perm], scene.triangle_material[perm],
                 scene.materials, lights=scene.lights.copy(), ambient=scene.ambient), perm


# -- comparisons -----------------------------------------------------------------------------------

def expected(frame, scene, camera=CAMERA, layers=None, width=W, height=H, pixels=None, frags=None):
    """The reference blend over the reference shading of the frame's own opaque G-buffer, and a mask of
    the pixels the comparison is well defined on (no N·L ~ 0 specular switch, no T at the early stop)."""
    opaque, info = ref_shading.shade_frame(frame, camera, scene.lights, scene.ambient, details=True)
    out = ref.blend(scene, camera, width, height, opaque, layers=layers, pixels=pixels, frags=frags)
    fg = frame.triangle_id >= 0
    ok = ~out.ambiguous & ~(fg & (info["min_abs_ndotl"] < 1e-4) & (out.transmittance > 1e-3))
    return out, ok


def check_opaque_surface(frame, exp):
    """The G-buffer holds the opaque surfaces only: ids exactly the reference's opaque raster."""
    np.testing.assert_array_equal(frame.triangle_id, exp.fragments.opaque_id,
                                  err_msg="triangle_id must show the opaque surfaces only")


def assert_color_close(got, exp_color, ok, what, tol=COLOR_TOL):
    peak = float(np.abs(exp_color).max())
    assert peak > 0
    err = np.abs(got.astype(np.float64) - exp_color)
    err[~ok] = 0
    worst = np.unravel_index(np.argmax(err), err.shape)
    assert err.max() <= tol * peak, (
        f"{what}: max |color - reference| {err.max():.4g} at (y, x, c) {worst}: got {got[worst]:.6g}, "
        f"expected {exp_color[worst]:.6g} (brightest {peak:.4g}, tolerance {tol * peak:.3g}); "
        f"{int((err > tol * peak).any(-1).sum())} pixels over")
    return err.max() / peak


def assert_matches_reference(frame, scene, exp, ok, what, check_count=True, min_ok=0.97):
    check_opaque_surface(frame, exp)
    assert ok.mean() > min_ok, f"{what}: only {ok.mean():.1%} of pixels are comparable"
    if check_count:
        bad = frame.fragment_count != exp.fragment_count
        if bad.any():
            y, x = np.argwhere(bad)[0]
            pytest.fail(f"{what}: fragment_count differs at {int(bad.sum())} pixels, e.g. (y {y}, x {x}): "
                        f"got {frame.fragment_count[y, x]}, expected {exp.fragment_count[y, x]}")
    terr = np.abs(frame.transmittance.astype(np.float64) - exp.transmittance)
    terr[~ok] = 0
    worst = np.unravel_index(np.argmax(terr), terr.shape)
    assert terr.max() <= TRANSMITTANCE_TOL, (
        f"{what}: transmittance off by {terr.max():.3g} at (y, x) {worst}: got {frame.transmittance[worst]:.6g}, "
        f"expected {exp.transmittance[worst]:.6g} ({exp.fragment_count[worst]} fragments)")
    return assert_color_close(frame.color, exp.color, ok, what)


_FRAMES = {}


def render(make_renderer, device, key, scene, width=W, height=H, camera=CAMERA, **opts):
    full = (device.id, key, width, height, repr(sorted(opts.items())))
    if full not in _FRAMES:
        _FRAMES[full] = make_renderer(width, height, **opts).render(scene, camera)
    return _FRAMES[full]


# -- the reference on its own (no device) ---------------------------------------------------------

SIZE = 32
PX_CAM = pixel_exact_camera(far=50.0)


def screen_quad(x0, x1, y0, y1, depth):
    """World quad covering pixel rectangle [x0, x1) × [y0, y1) of a SIZE×SIZE pixel_exact_camera image
    (edges on pixel boundaries, so coverage is exact), facing the camera."""
    a, b = screen_to_world(x0, y1, SIZE, depth), screen_to_world(x1, y1, SIZE, depth)
    c, d = screen_to_world(x1, y0, SIZE, depth), screen_to_world(x0, y0, SIZE, depth)
    return np.array([[a, b, c], [a, c, d]], np.float64)


def hand_scene(front=None, back=None):
    white = Material("white wall", (1.0, 1.0, 1.0, 1.0), specular_intensity=0.0)
    parts = [(screen_quad(0, SIZE, 0, SIZE, 8.0), None, white)]
    for q in (front, back):
        if q is not None:
            parts.append(q)
    return build_scene(parts, ambient=0.5)


def test_reference_one_layer_ambient_only():
    red = Material("red", (1.0, 0.0, 0.0, 0.5), alpha_mode="BLEND", specular_intensity=0.0)
    scene = hand_scene((screen_quad(8, 24, 4, 20, 4.0), None, red))
    opaque = np.full((SIZE, SIZE, 3), 0.5)                     # white · ambient
    out = ref.blend(scene, PX_CAM, SIZE, SIZE, opaque)
    inside = np.zeros((SIZE, SIZE), bool)
    inside[4:20, 8:24] = True
    assert np.array_equal(out.fragment_count, inside.astype(np.int32))
    np.testing.assert_allclose(out.color[inside], np.broadcast_to([0.5 * 0.5 + 0.5 * 0.5, 0.25, 0.25], (inside.sum(), 3)))
    np.testing.assert_array_equal(out.color[~inside], opaque[~inside])
    np.testing.assert_allclose(out.transmittance, np.where(inside, 0.5, 1.0))
    assert np.isin(out.fragments.opaque_id, (0, 1)).all()                    # the wall's two triangles
    # opacity folds into alpha the same way
    red_op = Material("red", (1.0, 0.0, 0.0, 1.0), opacity=0.5, specular_intensity=0.0)
    out2 = ref.blend(hand_scene((screen_quad(8, 24, 4, 20, 4.0), None, red_op)), PX_CAM, SIZE, SIZE, opaque)
    np.testing.assert_array_equal(out2.color, out.color)
    # a layer behind the opaque wall is no fragment; nor one beyond far
    behind = ref.blend(hand_scene((screen_quad(8, 24, 4, 20, 9.0), None, red)), PX_CAM, SIZE, SIZE, opaque)
    assert behind.fragment_count.sum() == 0 and np.array_equal(behind.color, opaque)


def test_reference_two_layers_order_and_truncation():
    red = Material("red", (1.0, 0.0, 0.0, 0.5), alpha_mode="BLEND", specular_intensity=0.0)
    blue = Material("blue", (0.0, 0.0, 1.0, 0.25), alpha_mode="BLEND", specular_intensity=0.0)
    opaque = np.full((SIZE, SIZE, 3), 0.5)
    amb = 0.5
    # red in front (z 3) of blue (z 5); listed blue first so the id order is the opposite of depth
    scene = hand_scene((screen_quad(4, 20, 4, 20, 5.0), None, blue), (screen_quad(4, 20, 4, 20, 3.0), None, red))
    out = ref.blend(scene, PX_CAM, SIZE, SIZE, opaque)
    red_c, blue_c = np.array([1.0, 0, 0]) * amb, np.array([0, 0, 1.0]) * amb
    expect = 0.5 * red_c + 0.5 * 0.25 * blue_c + 0.5 * 0.75 * opaque[0, 0]
    np.testing.assert_allclose(out.color[10, 10], expect)
    assert out.fragment_count[10, 10] == 2 and out.shaded[10, 10] == 2
    np.testing.assert_allclose(out.transmittance[10, 10], 0.5 * 0.75)
    # swapped depths give a different colour: the order is by depth, not by id
    swapped = hand_scene((screen_quad(4, 20, 4, 20, 3.0), None, blue), (screen_quad(4, 20, 4, 20, 5.0), None, red))
    out_s = ref.blend(swapped, PX_CAM, SIZE, SIZE, opaque)
    np.testing.assert_allclose(out_s.color[10, 10], 0.25 * blue_c + 0.75 * 0.5 * red_c + 0.75 * 0.5 * opaque[0, 0])
    assert not np.allclose(out_s.color[10, 10], out.color[10, 10])
    # one layer: only the nearest, over the opaque colour; the count stays 2
    one = ref.blend(scene, PX_CAM, SIZE, SIZE, opaque, layers=1)
    np.testing.assert_allclose(one.color[10, 10], 0.5 * red_c + 0.5 * opaque[0, 0])
    assert one.fragment_count[10, 10] == 2 and one.shaded[10, 10] == 1
    # equal depths: the lower triangle id first (blue, ids 1-2, before red, ids 3-4)
    tie = hand_scene((screen_quad(4, 20, 4, 20, 4.0), None, blue), (screen_quad(4, 20, 4, 20, 4.0), None, red))
    out_t = ref.blend(tie, PX_CAM, SIZE, SIZE, opaque)
    np.testing.assert_allclose(out_t.color[10, 10], 0.25 * blue_c + 0.75 * 0.5 * red_c + 0.75 * 0.5 * opaque[0, 0])


def test_reference_early_stop_and_lighting():
    """T < 1e-4 stops before the next fragment; a lit fragment follows the shading reference."""
    opaque = np.zeros((SIZE, SIZE, 3))
    dense = Material("dense", (0.2, 0.4, 0.6, 0.999), alpha_mode="BLEND", specular_intensity=0.0)
    extra = Material("extra", (1.0, 1.0, 1.0, 0.5), alpha_mode="BLEND", specular_intensity=0.0)
    scene = hand_scene((screen_quad(0, 8, 0, 8, 2.0), None, dense), (screen_quad(0, 8, 0, 8, 3.0), None, extra))
    out = ref.blend(scene, PX_CAM, SIZE, SIZE, opaque)
    assert out.fragment_count[2, 2] == 2 and out.shaded[2, 2] == 2           # T = 1e-3 >= 1e-4: no stop yet
    dense2 = Material("dense", (0.2, 0.4, 0.6, 0.99999), alpha_mode="BLEND", specular_intensity=0.0)
    scene2 = hand_scene((screen_quad(0, 8, 0, 8, 2.0), None, dense2), (screen_quad(0, 8, 0, 8, 3.0), None, extra))
    out2 = ref.blend(scene2, PX_CAM, SIZE, SIZE, opaque)
    assert out2.fragment_count[2, 2] == 2 and out2.shaded[2, 2] == 1         # T = 1e-5 < 1e-4: stop
    np.testing.assert_allclose(out2.transmittance[2, 2], 1e-5, rtol=1e-6)
    np.testing.assert_allclose(out2.color[2, 2], 0.99999 * 0.5 * np.array([0.2, 0.4, 0.6]))
    # one lit layer: the same model as reference/shading.py on a head-on pixel
    lights = point_lights([((0.0, 0.0, -1.0), (1.0, 1.0, 1.0), 4.0)])
    glass = Material("glass", (0.5, 0.5, 0.5, 0.5), alpha_mode="BLEND", specular_intensity=0.5, specular_power=8.0)
    scene = hand_scene((screen_quad(0, SIZE, 0, SIZE, 2.0), None, glass))
    scene.lights = lights
    out = ref.blend(scene, PX_CAM, SIZE, SIZE, opaque)
    one = lambda v: np.asarray(v, np.float64).reshape((1, 1) + np.shape(v))
    # pixel (15, 15): its centre is at screen (15.5, 15.5), view depth 2
    d = ref_shading.pixel_directions(PX_CAM, SIZE, SIZE)[15, 15]
    # a 1x1 image looking along that ray: its depth is measured along the unit ray
    fields = dict(normal=one([0, 0, 1]), albedo=one([0.5, 0.5, 0.5]), specular_intensity=one(0.5),
                  specular_power=one(8.0), depth=one(2.0 * np.linalg.norm(d)), triangle_id=np.zeros((1, 1), np.int32))
    cam1 = Camera.look_at((0, 0, 0), d, fov_y_deg=90, near=0.1, far=50)
    c = ref_shading.shade(**fields, camera=cam1, lights=lights, ambient=0.5)[0, 0]
    np.testing.assert_allclose(out.color[15, 15], 0.5 * c, rtol=1e-6)
    assert c[0] > 0.5 * 0.5 * 1.2, "the light adds to the ambient term"


def test_reference_interpolates_normals_and_flips_back_faces():
    """A double-sided quad seen from behind is lit on its visible side; normals interpolate."""
    opaque = np.zeros((SIZE, SIZE, 3))
    light = point_lights([((0.0, 0.0, -1.0), (1.0, 1.0, 1.0), 10.0)])
    m = Material("glass", (1.0, 1.0, 1.0, 0.5), alpha_mode="BLEND", specular_intensity=0.0)
    q = screen_quad(0, SIZE, 0, SIZE, 3.0)
    front = hand_scene((q, None, m))
    back = hand_scene((q[:, ::-1].copy(), -np.full((2, 3, 3), (0.0, 0.0, 1.0)), m))   # reversed winding and normals
    front.lights = back.lights = light
    a = ref.blend(front, PX_CAM, SIZE, SIZE, opaque)
    b = ref.blend(back, PX_CAM, SIZE, SIZE, opaque)
    assert b.fragments.backface.all() and not a.fragments.backface.any()
    np.testing.assert_allclose(a.color, b.color, rtol=1e-6)       # float32 depths round per winding
    assert a.color.max() > 0.2
    # normals tilting across the quad: a smooth gradient, not a flat one
    tilted = np.array([[[-0.5, 0, 1], [0.5, 0, 1], [0.5, 0, 1]], [[-0.5, 0, 1], [0.5, 0, 1], [-0.5, 0, 1]]])
    c = ref.blend(hand_scene((q, tilted / np.linalg.norm(tilted, axis=-1, keepdims=True), m)), PX_CAM, SIZE,
                  SIZE, opaque, lights=point_lights([((-3.0, 0.0, -3.0), (1.0, 1.0, 1.0), 10.0)]))
    # by hand: on a face-on quad the perspective-correct weights are affine in the screen position
    lp = np.array([-3.0, 0.0, -3.0])
    for x in (1, 9, 16, 23, 30):
        u = (x + 0.5) / SIZE
        n = np.array([-0.5 + u, 0.0, 1.0])
        n /= np.linalg.norm(n)
        P = screen_to_world(x + 0.5, 16.5, SIZE, 3.0).astype(np.float64)
        lv = lp - P
        d = np.linalg.norm(lv)
        diffuse = (1 - (d / 10.0) ** 2) ** 3 * max(n @ lv / d, 0.0)
        np.testing.assert_allclose(c.color[16, x], 0.5 * (0.5 + diffuse), rtol=1e-5)
    assert c.color[16, 1, 0] > c.color[16, 16, 0] + 0.05


# -- A-buffer against the reference -----------------------------------------------------------------

@settings(max_examples=20, **SETTINGS)
@given(seed=st.integers(0, 2**31 - 1), crossing=st.booleans())
def test_abuffer_matches_reference(make_renderer, seed, crossing):
    scene = random_soup(seed, crossing=crossing)
    frame = make_renderer(W, H).render(scene, CAMERA)
    exp, ok = expected(frame, scene)
    assert exp.fragment_count.sum() > 0
    assert_matches_reference(frame, scene, exp, ok, f"soup {seed} (crossing the near plane: {crossing})")


def test_near_clipped_transparent_triangles(make_renderer, device):
    """Transparent triangles crossing the near plane: their pieces' fragments (barycentrics carried
    by the clip) match the reference."""
    hits = 0
    for seed in (1, 2, 5):
        scene = random_soup(seed, crossing=True)
        frame = make_renderer(W, H).render(scene, CAMERA)
        exp, ok = expected(frame, scene)
        clipped = np.zeros((H, W), bool)
        clipped[exp.fragments.row[exp.fragments.clipped], exp.fragments.col[exp.fragments.clipped]] = True
        hits += int(clipped.sum())
        assert_matches_reference(frame, scene, exp, ok, f"soup {seed} with near-clipped layers")
    assert hits > 200, "the crossing triangles must put clipped fragments on screen"


def test_reference_barycentrics_agree():
    """The reference's barycentrics (contract edge functions) agree with ray casting against the
    unsnapped triangles up to the 1/256-pixel snapping, for whole and near-clipped triangles."""
    scene = random_soup(4, crossing=True)
    fr = ref.fragments(scene, CAMERA, W, H)
    assert len(fr) > 500 and fr.clipped.sum() > 100
    eye = np.asarray(CAMERA.eye, np.float64)
    dirs = ref_shading.pixel_directions(CAMERA, W, H)
    world = scene.positions.astype(np.float64)
    worst = 0.0
    for t in np.unique(fr.tri):
        sel = fr.tri == t
        ray = ref._ray_barycentrics(world[scene.triangles[t]], eye, dirs[fr.row[sel], fr.col[sel]])
        worst = max(worst, float(np.abs(ray - fr.bary[sel]).max()))
        assert (fr.bary[sel] > -1e-3).all() and np.allclose(fr.bary[sel].sum(-1), 1.0)
    assert worst < 2e-3, worst


def test_light_reaching_only_a_transparent_surface(make_renderer, device):
    """A small light in front of a transparent quad, far from the wall: light culling must take the
    fragments' depths into each tile's range (docs/transparency.md), with every culling option."""
    glass = Material("glass", (0.9, 0.9, 0.9, 1.0), opacity=0.6, specular_intensity=0.5, specular_power=16.0)
    scene = build_scene([wall(-20.0), (quad(-2, 2, -1.5, 1.5, -3.0), None, glass)],
                        lights=point_lights([((0.7, 0.3, -2.4), (3.0, 2.0, 1.0), 1.2),
                                             ((-0.9, -0.5, -2.7), (1.0, 2.0, 3.0), 0.8)]))
    frames = {}
    for opts in (dict(light_culling="brute_force"), dict(light_tile_size=8), dict(light_tile_size=16),
                 dict(light_tile_size=32), dict(light_tile_size=16, light_depth_mask=True)):
        frame = make_renderer(W, H, **opts).render(scene, CAMERA)
        exp, ok = expected(frame, scene)
        lit = exp.color.max(-1) > 1.5 * (np.asarray(glass.base_color[:3]).max() * AMBIENT)
        assert lit.sum() > 30, "the lights must visibly light the glass"
        assert_matches_reference(frame, scene, exp, ok, f"lights on glass only, {opts}")
        frames[repr(opts)] = frame
    base = frames[repr(dict(light_culling="brute_force"))]
    for k, f in frames.items():
        np.testing.assert_allclose(f.color, base.color, rtol=0, atol=1e-5 * base.color.max(), err_msg=k)


def test_early_stop(make_renderer, device):
    """Behind T < 1e-4 nothing is shaded: the 3rd layer (alpha 0.5) of a pixel whose first two leave
    T = 2.5e-5 changes neither colour nor transmittance; fragment_count still counts it."""
    size = SIZE
    dense = Material("dense", (0.2, 0.4, 0.6, 0.995), alpha_mode="BLEND", specular_intensity=0.0)
    bright = Material("bright", (1.0, 1.0, 1.0, 0.5), alpha_mode="BLEND", specular_intensity=0.0)
    parts = [(screen_quad(0, size, 0, size, 12.0), None, Material("wall", (1.0, 1.0, 1.0, 1.0)))]
    parts += [(screen_quad(4, 28, 4, 28, 3.0), None, dense), (screen_quad(4, 28, 4, 28, 4.0), None, dense),
              (screen_quad(0, 32, 0, 32, 5.0), None, bright)]
    scene = build_scene(parts, ambient=40.0)
    for opts in (dict(), dict(transparency="depth_peeling", peel_layers=3)):
        frame = make_renderer(size, size, **opts).render(scene, PX_CAM)
        exp, ok = expected(frame, scene, camera=PX_CAM, width=size, height=size)
        inner = np.zeros((size, size), bool)
        inner[4:28, 4:28] = True
        assert np.all(exp.fragment_count[inner] == 3) and np.all(exp.shaded[inner] == 2)
        np.testing.assert_array_equal(frame.fragment_count, exp.fragment_count)
        np.testing.assert_allclose(frame.transmittance[inner], 0.005 ** 2, rtol=1e-3,
                                   err_msg=f"{opts}: T must stop at the 2nd layer (1.25e-5 means the 3rd was blended)")
        np.testing.assert_allclose(frame.transmittance[~inner], 0.5)
        assert_matches_reference(frame, scene, exp, ok, f"early stop {opts}")


def test_transparent_layers_cast_shadows(make_renderer, device):
    """A shadowed spot at the eye: the front glass is lit, the glass behind it and the wall lie in its
    (full) shadow, elsewhere lit; fragments against the reference with ray-cast visibility."""
    from reference.shadow_rays import occluded
    size = 64
    cam = pixel_exact_camera(far=50.0)
    front = Material("front", (0.9, 0.8, 0.3, 1.0), opacity=0.4, specular_intensity=0.3, specular_power=8.0)
    back = Material("back", (0.3, 0.8, 0.9, 1.0), opacity=0.5, specular_intensity=0.3, specular_power=8.0)
    sq = lambda x0, x1, y0, y1, d: np.array([[screen_to_world(x0, y1, size, d), screen_to_world(x1, y1, size, d),
                                             screen_to_world(x1, y0, size, d)],
                                            [screen_to_world(x0, y1, size, d), screen_to_world(x1, y0, size, d),
                                             screen_to_world(x0, y0, size, d)]], np.float64)
    parts = [(sq(0, size, 0, size, 12.0), None, Material("wall", (0.8, 0.8, 0.8, 1.0), specular_intensity=0.1)),
             (sq(20, 44, 20, 44, 4.0), None, front), (sq(8, 56, 8, 56, 8.0), None, back)]
    scene = build_scene(parts, ambient=0.05)
    scene.add_spot_light((0.0, 0.0, 0.0), (0.0, 0.0, -1.0), (30.0, 30.0, 30.0), 40.0, 50.0, 60.0, shadow=True,
                         shadow_map_size=512)
    scene.add_point_light((2.0, 1.0, -6.0), (0.5, 0.5, 0.5), 10.0)
    frame = make_renderer(size, size).render(scene, cam)
    assert frame.shadow.shape == (size, size, 1)
    vis_opaque = frame.shadow[..., 0].astype(np.float64)
    behind_front = np.zeros((size, size), bool)
    behind_front[20:44, 20:44] = True
    assert vis_opaque[behind_front].max() < 0.05, "transparent surfaces cast full shadows on the wall"
    assert vis_opaque[2, 2] > 0.95

    def light_visibility(points, i):
        if i != 0:
            return np.ones(len(points))
        v = -points                                      # the spot sits at the origin
        dist = np.linalg.norm(v, axis=1)
        dirs = v / dist[:, None]
        return (~occluded(scene, points + 1e-3 * dirs, dirs, dist - 2e-3)).astype(np.float64)

    # the opaque colour with the frame's own visibility for the spot (as the G-buffer, taken as given)
    lights = scene.lights
    sh = lambda ls: ref_shading.shade_frame(frame, cam, ls, scene.ambient)
    opaque = sh(lights[1:]) + vis_opaque[..., None] * (sh(lights[:1]) - sh(lights[:0]))
    exp = ref.blend(scene, cam, size, size, opaque, light_visibility=light_visibility)
    edge = np.zeros((size, size), bool)                 # PCF and the map's texels blur 2 pixels around
    edge[18:46, 18:46] = True
    edge[22:42, 22:42] = False
    ok = ~edge & ~exp.ambiguous
    assert np.all(exp.fragment_count[behind_front] == 2)
    assert_matches_reference(frame, scene, exp, ok, "shadowed spot through two glass layers", min_ok=0.88)
    # and the back glass really is darker behind the front one than beside it (not just the reference)
    no_shadow = ref.blend(scene, cam, size, size, opaque)
    assert np.abs(no_shadow.color - exp.color)[behind_front].max() > 0.05 * exp.color.max()


def test_far_plane_and_background(make_renderer, device):
    """A glass tilted through the far plane over the background (no opaque surface: opaque depth
    +inf, colour 0): fragments stop at z <= far; over nothing the colour is the layers' alone."""
    cam = Camera.look_at((0.0, 0.0, 0.0), (0.0, 0.0, -1.0), fov_y_deg=60.0, near=0.1, far=9.0)
    t = np.radians(60.0)
    rot = np.array([[np.cos(t), 0, np.sin(t)], [0, 1, 0], [-np.sin(t), 0, np.cos(t)]])
    q = quad(-6, 6, -3, 3, 0.0) @ rot.T + np.array([0.0, 0.0, -8.0])
    glass = Material("glass", (0.3, 0.9, 0.6, 1.0), opacity=0.7, specular_intensity=0.3, specular_power=10.0)
    scene = build_scene([(quad(-20, -8, -8, 8, -6.0), None, Material("post")), (q, None, glass)],
                        lights=point_lights([((0.0, 2.0, -6.0), (2.0, 2.0, 2.0), 8.0)]))
    frame = make_renderer(W, H).render(scene, cam)
    exp, ok = expected(frame, scene, camera=cam)
    beyond = (frame.triangle_id < 0) & (exp.fragment_count == 0)
    layered = (frame.triangle_id < 0) & (exp.fragment_count > 0)
    assert layered.sum() > 200 and beyond.sum() > 100
    # the far plane cuts the glass: some of its pixels lie beyond it (the reference raster says where)
    assert_matches_reference(frame, scene, exp, ok, "glass through the far plane")
    assert np.all(frame.color[beyond] == 0) and np.all(frame.transmittance[beyond] == 1.0)
    assert frame.color[layered].min() > 0


def test_coplanar_layers_tie_order(make_renderer, device):
    """Exactly coplanar layers (the same vertices): ordered by triangle id, then prim; depth peeling
    peels them one by one and equals the A-buffer."""
    size = SIZE
    mats = [Material(f"c{k}", (*np.eye(3)[k % 3] * 0.8 + 0.1, 1.0), opacity=0.3 + 0.2 * k, specular_intensity=0.0)
            for k in range(3)]
    base = screen_quad(4, 28, 4, 28, 5.0)
    parts = [(screen_quad(0, size, 0, size, 12.0), None, Material("wall", (1.0, 1.0, 1.0, 1.0)))]
    parts += [(base, None, mats[k]) for k in (2, 0, 1)]           # ids 2-3 / 4-5 / 6-7: materials 2, 0, 1
    scene = build_scene(parts, ambient=1.0)
    abuf = make_renderer(size, size).render(scene, PX_CAM)
    exp, ok = expected(abuf, scene, camera=PX_CAM, width=size, height=size)
    assert (exp.fragment_count == 3).sum() == 24 * 24
    assert_matches_reference(abuf, scene, exp, ok, "coplanar layers")
    # the same layers listed in another order blend in that order (ties go to the lower id)
    other = build_scene(parts[:1] + [(base, None, mats[k]) for k in (0, 1, 2)], ambient=1.0)
    f2 = make_renderer(size, size).render(other, PX_CAM)
    exp2, ok2 = expected(f2, other, camera=PX_CAM, width=size, height=size)
    assert_matches_reference(f2, other, exp2, ok2, "coplanar layers, other order")
    assert np.abs(exp2.color - exp.color).max() > 0.05, "the tie order must matter in this scene"
    peeled = make_renderer(size, size, transparency="depth_peeling", peel_layers=3).render(scene, PX_CAM)
    np.testing.assert_array_equal(peeled.color, abuf.color, err_msg="coplanar fragments must peel one by one")
    np.testing.assert_array_equal(peeled.transmittance, abuf.transmittance)


def test_coplanar_with_opaque_is_not_in_front(make_renderer, device):
    """A glass with the opaque wall's own vertices has the same depths: not strictly in front, no fragment."""
    size = SIZE
    wall_q = screen_quad(0, size, 0, size, 8.0)
    glass = Material("glass", (1.0, 0.0, 0.0, 1.0), opacity=0.5)
    scene = build_scene([(wall_q, None, Material("wall")), (wall_q.copy(), None, glass),
                         (screen_quad(8, 24, 8, 24, 6.0), None, glass)])
    frame = make_renderer(size, size).render(scene, PX_CAM)
    exp, ok = expected(frame, scene, camera=PX_CAM, width=size, height=size)
    inner = np.zeros((size, size), bool)
    inner[8:24, 8:24] = True
    assert np.array_equal(exp.fragment_count, inner.astype(np.int32))
    assert_matches_reference(frame, scene, exp, ok, "glass coplanar with the wall")


def test_alpha_zero_texels_are_fragments(make_renderer, device):
    """Alpha does not decide whether a fragment exists: a texture whose left half has alpha 0 gives
    fragments over the whole quad, contributing nothing (T = 1) on that half."""
    from clrender import Texture
    size = SIZE
    rgba = np.full((8, 8, 4), 255, np.uint8)
    rgba[:, :4, 3] = 0
    rgba[:, 4:, 3] = 128
    q = screen_quad(8, 24, 8, 24, 4.0)
    uv = np.array([[[0, 1], [1, 1], [1, 0]], [[0, 1], [1, 0], [0, 0]]], np.float32)   # matches screen_quad's corners
    parts = [(screen_quad(0, size, 0, size, 8.0), None, Material("wall")),
             (q, None, Material("decal", (1.0, 1.0, 1.0, 1.0), base_color_texture=0, alpha_mode="BLEND"))]
    scene = build_scene(parts, uvs=np.concatenate([np.zeros((6, 2)), uv.reshape(-1, 2)]),
                        textures=[Texture("half", rgba, wrap_s="clamp", wrap_t="clamp")])
    frame = make_renderer(size, size).render(scene, PX_CAM)
    inner = np.zeros((size, size), bool)
    inner[8:24, 8:24] = True
    np.testing.assert_array_equal(frame.fragment_count, inner.astype(np.int32))
    left, right = inner.copy(), inner.copy()
    left[:, 14:] = False                       # texel columns 0-3 (away from the bilinear seam)
    right[:, :18] = False
    np.testing.assert_array_equal(frame.transmittance[left], 1.0)
    np.testing.assert_allclose(frame.transmittance[right], 1.0 - 128 / 255, atol=2e-3)
    np.testing.assert_array_equal(frame.transmittance[~inner], 1.0)


def test_ssao_does_not_apply_to_fragments(make_renderer, device):
    """With SSAO the opaque colour carries ao, the fragments do not (ambient · albedo)."""
    scene = random_soup(3, n_transparent=8)
    scene.ambient = 0.4                                         # a visible ambient term
    frame = make_renderer(W, H, ssao=True, ssao_radius=3.0).render(scene, CAMERA)
    assert frame.ao.min() < 0.9, "the scene must be occluded somewhere"
    opaque, info = ref_shading.shade_frame(frame, CAMERA, scene.lights, scene.ambient, details=True)
    opaque -= frame.albedo * (np.float32(scene.ambient) * (1.0 - frame.ao.astype(np.float64)))[..., None]
    exp = ref.blend(scene, CAMERA, W, H, opaque)
    fg = frame.triangle_id >= 0
    ok = ~exp.ambiguous & ~(fg & (info["min_abs_ndotl"] < 1e-4) & (exp.transmittance > 1e-3))
    assert_matches_reference(frame, scene, exp, ok, "SSAO on")


def textured_sphere(center, radius, n_lat=12, n_lon=24):
    """(positions, faces, normals, uvs) of a UV sphere, counter-clockwise seen from outside."""
    lat = np.linspace(0, np.pi, n_lat + 1)
    lon = np.linspace(0, 2 * np.pi, n_lon + 1)
    la, lo = np.meshgrid(lat, lon, indexing="ij")
    normals = np.stack([np.sin(la) * np.cos(lo), np.cos(la), -np.sin(la) * np.sin(lo)], -1).reshape(-1, 3)
    uvs = np.stack([lo / (2 * np.pi), la / np.pi], -1).reshape(-1, 2)
    idx = np.arange((n_lat + 1) * (n_lon + 1)).reshape(n_lat + 1, n_lon + 1)
    a, b, c, d = idx[:-1, :-1], idx[:-1, 1:], idx[1:, :-1], idx[1:, 1:]
    faces = np.concatenate([np.stack([a, c, b], -1).reshape(-1, 3), np.stack([b, c, d], -1).reshape(-1, 3)])
    return normals * radius + np.asarray(center), faces, normals, uvs


def lit_sphere_scene(opacity):
    """A textured single-sided sphere (opacity: BLEND when < 1) over nothing, an opaque box that
    shadows part of it from the sun, a shadowed sun (cascades), a shadowed spot and point lights."""
    from clrender import Texture
    rng = np.random.default_rng(2)
    rgba = np.full((16, 16, 4), 255, np.uint8)
    rgba[..., :3] = np.where(((np.arange(16)[:, None] // 4 + np.arange(16)[None, :] // 4) % 2)[..., None] == 1,
                             rng.integers(120, 255, 3), rng.integers(20, 120, 3))
    sp, sf, sn, su = textured_sphere((0.0, 0.0, -5.0), 1.6)
    box_p = np.array([[x, y, z] for x in (-2.6, -1.6) for y in (2.0, 2.6) for z in (-5.5, -4.5)], np.float64)
    box_f = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1], [2, 3, 7], [2, 7, 6],
                      [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])
    positions = np.concatenate([sp, box_p])
    normals = np.concatenate([sn, box_p / np.linalg.norm(box_p, axis=1, keepdims=True)])
    uvs = np.concatenate([su, np.zeros((len(box_p), 2))])
    faces = np.concatenate([sf, box_f + len(sp)])
    mats = [Material("glass", (1.0, 0.9, 0.8, 1.0), base_color_texture=0, specular_intensity=0.5,
                     specular_power=24.0, double_sided=False, opacity=opacity),
            Material("box", (0.6, 0.6, 0.6, 1.0))]
    scene = Scene(positions, normals, uvs, faces, np.r_[np.zeros(len(sf), np.int32), np.ones(12, np.int32)], mats,
                  textures=[Texture("checker", rgba)])
    scene.ambient = 0.15
    scene.set_sun((0.6, -1.0, -0.2), (1.2, 1.1, 1.0), shadow=True, shadow_map_size=512)
    scene.add_spot_light((2.5, 1.5, -2.0), (-2.5, -1.5, -3.0), (4.0, 3.0, 2.0), 10.0, 15.0, 30.0, shadow=True,
                         shadow_map_size=512)
    scene.add_point_light((-1.5, -1.0, -2.5), (0.6, 0.8, 1.5), 5.0)
    return scene


def test_fragment_shading_matches_opaque_shading(make_renderer, device):
    """A fragment is lit by the same code as an opaque pixel (sun and its cascades, shadowed spot,
    point light, texture, specular): a 50 % glass sphere over nothing shows 0.5 × the colour of the
    same sphere opaque, up to the G-buffer's quantization of the opaque one (normals, albedo)."""
    glass = make_renderer(W, H).render(lit_sphere_scene(0.5), CAMERA)
    solid = make_renderer(W, H).render(lit_sphere_scene(1.0), CAMERA)
    n_sphere = 2 * 12 * 24
    on = np.isin(solid.triangle_id, np.arange(n_sphere))
    assert on.sum() > 300 and np.all(glass.fragment_count[on] == 1)
    np.testing.assert_array_equal(glass.triangle_id[on], -1)
    np.testing.assert_allclose(glass.transmittance[on], 0.5, rtol=1e-6)
    assert glass.shadow.shape[-1] == solid.shadow.shape[-1] >= 2
    # the sun's and the spot's shadows reach the sphere (so both lookups are exercised)
    assert (solid.shadow[on] < 0.5).any(axis=0).all(), "sun and spot must each shadow part of the sphere"
    peak = float(solid.color[on].max())
    err = np.abs(2.0 * glass.color[on].astype(np.float64) - solid.color[on]).max(-1)
    assert np.median(err) < 2e-3 * peak, f"median |2·glass - opaque| {np.median(err):.3g} (peak {peak:.3g})"
    assert np.mean(err < 1e-2 * peak) > 0.97, (
        f"{np.mean(err >= 1e-2 * peak):.1%} of sphere pixels differ by more than 1 % of the peak "
        f"(worst {err.max():.3g}): fragments are not lit like opaque pixels")


def test_tile_sizes_change_nothing(make_renderer, device):
    """The raster tile size (8/16/32) changes neither the fragment lists' content nor their order."""
    scene = random_soup(11, n_transparent=12)
    frames = [make_renderer(W, H, tile_size=t).render(scene, CAMERA) for t in (8, 16, 32)]
    for f in frames[1:]:
        np.testing.assert_array_equal(f.fragment_count, frames[0].fragment_count)
        np.testing.assert_array_equal(f.color, frames[0].color)
        np.testing.assert_array_equal(f.transmittance, frames[0].transmittance)
    peeled = [make_renderer(W, H, tile_size=t, transparency="depth_peeling", peel_layers=2).render(scene, CAMERA)
              for t in (8, 32)]
    np.testing.assert_array_equal(peeled[0].color, peeled[1].color)


@pytest.mark.parametrize("size", [(37, 29), (61, 45)])
def test_odd_image_sizes(make_renderer, device, size):
    """Partial raster, light and resolve tiles at the image's right and bottom edges."""
    w, h = size
    for seed in (5, 6):
        scene = random_soup(seed, n_transparent=12)
        for opts in (dict(), dict(transparency="depth_peeling", peel_layers=3)):
            frame = make_renderer(w, h, light_tile_size=16, **opts).render(scene, CAMERA)
            exp, ok = expected(frame, scene, width=w, height=h, layers=opts.get("peel_layers"))
            assert_matches_reference(frame, scene, exp, ok, f"{w}x{h}, soup {seed}, {opts}")


def test_renderer_reuse_across_scenes(device):
    """One renderer: a transparent scene, an opaque one, the transparent one again: nothing leaks
    between frames (fragment lists, transmittance, grown buffers)."""
    r = clrender.Renderer(W, H, device=device.id)
    soup = random_soup(3, n_transparent=12)
    first = r.render(soup, CAMERA)
    opaque = build_scene([wall()], lights=soup.lights)
    plain = r.render(opaque, CAMERA)
    assert np.all(plain.fragment_count == 0) and np.all(plain.transmittance == 1.0)
    fresh = clrender.Renderer(W, H, device=device.id).render(opaque, CAMERA)
    np.testing.assert_array_equal(plain.color, fresh.color)
    again = r.render(soup, CAMERA)
    np.testing.assert_array_equal(again.color, first.color)
    np.testing.assert_array_equal(again.fragment_count, first.fragment_count)
    np.testing.assert_array_equal(again.transmittance, first.transmittance)


SEEDS = (3, 11, 2024)


@pytest.mark.parametrize("seed", SEEDS)
def test_abuffer_is_not_black(make_renderer, device, seed):
    """Whatever the reference says: where transparent layers are, the frame shows them."""
    scene = random_soup(seed, n_transparent=8)
    frame = render(make_renderer, device, ("soup", seed), scene)
    exp, ok = expected(frame, scene)
    layered = exp.fragment_count > 0
    assert layered.mean() > 0.1, "the soup must cover a good part of the frame"
    assert np.all(frame.fragment_count[layered] > 0), "fragment_count must be non-zero where layers are"
    assert np.all(frame.transmittance[layered] < 1.0), "layers with alpha >= 0.05 must absorb"
    assert frame.color[layered].max() > 0.05
    # the layers change the colour: compared with the opaque colour alone
    opaque = ref_shading.shade_frame(frame, CAMERA, scene.lights, scene.ambient)
    change = np.abs(frame.color.astype(np.float64) - opaque).max(-1)
    expect_change = np.abs(exp.color - opaque).max(-1)
    visible = layered & (expect_change > 0.02 * exp.color.max())
    assert visible.sum() > 50
    assert np.all(change[visible] > 0.5 * expect_change[visible]), "transparent layers missing from the colour"
    # the image is the tone-mapped blend
    diff = np.abs(frame.image.astype(int) - ref_shading.tonemap(frame.color, "reinhard").astype(int))
    assert diff.max() <= 1 and frame.image[layered].max() > 20


@pytest.mark.parametrize("seed", SEEDS)
def test_order_independence(make_renderer, device, seed):
    scene = random_soup(seed, n_transparent=10)
    base = render(make_renderer, device, ("soup10", seed), scene)
    assert base.fragment_count.max() >= 2
    for k in range(2):
        shuffled, perm = shuffled_transparent(scene, seed + 100 * k)
        assert not np.array_equal(perm, np.arange(len(perm)))
        got = make_renderer(W, H).render(shuffled, CAMERA)
        np.testing.assert_array_equal(got.color, base.color, err_msg="shuffling transparent triangles changed color")
        np.testing.assert_array_equal(got.transmittance, base.transmittance)
        np.testing.assert_array_equal(got.fragment_count, base.fragment_count)
        np.testing.assert_array_equal(got.gbuffer, base.gbuffer)


@pytest.mark.parametrize("seed", SEEDS)
def test_depth_peeling(make_renderer, device, seed):
    scene = random_soup(seed, n_transparent=10)
    abuf = render(make_renderer, device, ("soup10", seed), scene)
    n_max = int(abuf.fragment_count.max())
    assert n_max >= 3, "the soup needs pixels with several layers"
    full = render(make_renderer, device, ("soup10", seed), scene, transparency="depth_peeling", peel_layers=n_max)
    np.testing.assert_array_equal(full.color, abuf.color, err_msg=f"{n_max} peels must equal the A-buffer bit for bit")
    np.testing.assert_array_equal(full.transmittance, abuf.transmittance)
    np.testing.assert_array_equal(full.fragment_count, abuf.fragment_count)
    np.testing.assert_array_equal(full.gbuffer, abuf.gbuffer)
    more = render(make_renderer, device, ("soup10", seed), scene, transparency="depth_peeling", peel_layers=64)
    np.testing.assert_array_equal(more.color, abuf.color)
    for n in (1, 2):
        few = render(make_renderer, device, ("soup10", seed), scene, transparency="depth_peeling", peel_layers=n)
        exp, ok = expected(few, scene, layers=n)
        assert_matches_reference(few, scene, exp, ok, f"soup {seed}, {n} peels")
        assert (exp.fragment_count > n).sum() > 20
        deeper = exp.fragment_count > n
        assert np.abs(few.color - abuf.color)[deeper].max() > 1e-3 * abuf.color.max(), \
            f"{n} peels must differ from the full A-buffer where pixels have more layers"


@pytest.mark.parametrize("seed", SEEDS[:2])
def test_max_fragments_per_pixel(make_renderer, device, seed):
    scene = random_soup(seed, n_transparent=10)
    abuf = render(make_renderer, device, ("soup10", seed), scene)
    n_max = int(abuf.fragment_count.max())
    assert n_max >= 3
    for k in (1, n_max - 1):
        capped = render(make_renderer, device, ("soup10", seed), scene, max_fragments_per_pixel=k)
        exp, ok = expected(capped, scene, layers=k)
        assert_matches_reference(capped, scene, exp, ok, f"soup {seed}, max_fragments_per_pixel={k}")
        dropped = int(np.maximum(exp.fragment_count.astype(np.int64) - k, 0).sum())
        assert dropped > 0
        assert capped.stats.get("fragments_dropped") == dropped, (
            f"stats['fragments_dropped'] = {capped.stats.get('fragments_dropped')!r}, expected {dropped}")
    uncapped = render(make_renderer, device, ("soup10", seed), scene, max_fragments_per_pixel=64)
    np.testing.assert_array_equal(uncapped.color, abuf.color)
    assert uncapped.stats.get("fragments_dropped", 0) == 0 and abuf.stats.get("fragments_dropped", 0) == 0


# -- overflow: long lists and retries ---------------------------------------------------------------

def test_200_fragments_per_pixel(device):
    """200 stacked layers over a region (in random id order): the long-list sort stays exact."""
    size = 32
    rng = np.random.default_rng(7)
    depths = 2.0 + 0.03 * rng.permutation(200)                # distinct depths, ids in random depth order
    parts = [(screen_quad(0, size, 0, size, 12.0), None,
              Material("wall", (0.8, 0.8, 0.8, 1.0), specular_intensity=0.3, specular_power=8.0))]
    mats = [Material(f"film{k}", (*rng.uniform(0.1, 1.0, 3), float(rng.uniform(0.01, 0.03))), alpha_mode="BLEND",
                     specular_intensity=0.3, specular_power=12.0) for k in range(8)]
    for k, d in enumerate(depths):
        parts.append((screen_quad(6, 26, 4, 28, d), None, mats[k % len(mats)]))
    scene = build_scene(parts, lights=point_lights([((1.0, 0.5, -1.0), (2.0, 1.8, 1.5), 20.0)]))
    renderer = clrender.Renderer(size, size, device=device.id)
    frame = renderer.render(scene, PX_CAM)
    exp, ok = expected(frame, scene, camera=PX_CAM, width=size, height=size)
    assert exp.fragment_count.max() == 200 and (exp.fragment_count == 200).sum() == 20 * 24
    assert exp.transmittance.min() > 1e-3, "every layer must count (no early stop)"
    assert_matches_reference(frame, scene, exp, ok, "200 layers")
    assert frame.stats.get("retries", 0) >= 1, "a fresh renderer's A-buffer must grow (retry) for 96000 fragments"
    again = renderer.render(scene, PX_CAM)                    # the grown buffer: no retry, the same bits
    assert again.stats.get("retries", 0) == 0
    np.testing.assert_array_equal(again.color, frame.color)
    np.testing.assert_array_equal(again.transmittance, frame.transmittance)
    peeled = clrender.Renderer(size, size, device=device.id, transparency="depth_peeling",
                               peel_layers=3).render(scene, PX_CAM)
    exp3, ok3 = expected(peeled, scene, camera=PX_CAM, width=size, height=size, layers=3)
    assert_matches_reference(peeled, scene, exp3, ok3, "200 layers, 3 peels")


def test_more_than_a_million_fragments(device):
    """256x256 with 20 full-screen layers (1,310,720 fragments): exact counts, colour analytic."""
    size, n = 256, 20
    rng = np.random.default_rng(11)
    depths = 2.0 + 0.25 * rng.permutation(n)
    amb = 0.25
    wall_m = Material("wall", (0.6, 0.7, 0.8, 1.0), specular_intensity=0.0)
    mats = [Material(f"layer{k}", (*rng.uniform(0.1, 1.0, 3), float(rng.uniform(0.1, 0.25))), alpha_mode="BLEND",
                     specular_intensity=0.0) for k in range(n)]
    big = lambda d: np.array([[[-2 * d, -2 * d, -d], [2 * d, -2 * d, -d], [2 * d, 2 * d, -d]],
                              [[-2 * d, -2 * d, -d], [2 * d, 2 * d, -d], [-2 * d, 2 * d, -d]]])
    parts = [(big(10.0), None, wall_m)] + [(big(d), None, mats[k]) for k, d in enumerate(depths)]
    scene = build_scene(parts, ambient=amb)
    frame = clrender.Renderer(size, size, device=device.id).render(scene, PX_CAM)
    assert (frame.fragment_count == n).all(), f"fragment_count: {np.unique(frame.fragment_count)} (expected all {n})"
    # analytic: layers front to back, ambient only
    acc, T = np.zeros(3), 1.0
    for k in np.argsort(depths):
        a = mats[k].base_color[3]
        acc += T * a * np.asarray(mats[k].base_color[:3]) * np.float32(amb)
        T *= 1 - a
    # the wall's colour comes from the G-buffer's (8-bit sRGB) albedo: ambient · decoded albedo
    assert np.all(frame.albedo == frame.albedo[0, 0])
    expect = acc + T * frame.albedo[0, 0].astype(np.float64) * np.float32(amb)
    assert T > 1e-3
    np.testing.assert_allclose(frame.color.reshape(-1, 3), np.broadcast_to(expect, (size * size, 3)),
                               rtol=0, atol=COLOR_TOL * expect.max())
    np.testing.assert_allclose(frame.transmittance, T, rtol=0, atol=TRANSMITTANCE_TOL)
    assert frame.stats.get("retries", 0) >= 1
    # and the reference on a subsample of pixels
    pixels = np.zeros((size, size), bool)
    pixels[::37, ::23] = True
    exp, ok = expected(frame, scene, camera=PX_CAM, width=size, height=size, pixels=pixels)
    assert (exp.fragment_count == n).all()
    err = np.abs(frame.color[pixels].astype(np.float64) - exp.color[pixels])
    assert err.max() <= COLOR_TOL * expect.max()


# -- screen door ------------------------------------------------------------------------------------

def screen_door_scene(alpha):
    """A wall (material 0) and a 48x32-pixel quad (material 1, opacity alpha) at depth 4; 64x48, fov 90."""
    size_w, size_h = 64, 48
    cam = Camera.look_at((0, 0, 0), (0, 0, -1), fov_y_deg=90.0, near=0.1, far=50)
    tan_y, tan_x = 1.0, size_w / size_h

    def at(px, py, d):
        return ((px / size_w * 2 - 1) * tan_x * d, (1 - py / size_h * 2) * tan_y * d, -d)

    x0, x1, y0, y1 = 8, 56, 8, 40
    a, b, c, e = at(x0, y1, 4), at(x1, y1, 4), at(x1, y0, 4), at(x0, y0, 4)
    q = np.array([[a, b, c], [a, c, e]], np.float64)
    glass = Material("glass", (1.0, 0.2, 0.2, 1.0), opacity=alpha)
    scene = build_scene([(quad(-40, 40, -30, 30, -10.0), None, Material("wall", (0.5, 0.5, 0.5, 1.0))),
                         (q, None, glass)])
    return scene, cam, size_w, size_h


@pytest.mark.parametrize("alpha", [0.25, 0.5, 0.75, 0.3])
def test_screen_door_fraction(make_renderer, device, alpha):
    scene, cam, w, h = screen_door_scene(alpha)
    frame = make_renderer(w, h, transparency="screen_door").render(scene, cam)
    quad_ids = np.flatnonzero(ref.blend_mask(scene))
    covered = coverage_count(Scene(scene.positions, scene.normals, scene.uvs, scene.triangles[quad_ids],
                                   np.zeros(len(quad_ids), np.int32), [Material()]), cam, w, h) > 0
    assert covered.sum() == 48 * 32
    kept = np.isin(frame.triangle_id, quad_ids)
    assert not (kept & ~covered).any()
    frac = kept[covered].mean()
    assert abs(frac - alpha) <= 1 / 16, f"screen door alpha {alpha}: {frac:.3f} of the quad's pixels kept"
    assert (frame.triangle_id[covered & ~kept] >= 0).all(), "the wall shows through the dropped pixels"
    # every 4x4 block keeps the same number of pixels (an ordered dither, not noise)
    blocks = kept[8:40, 8:56].reshape(8, 4, 12, 4).sum(axis=(1, 3))
    assert blocks.min() == blocks.max(), f"pixels kept per 4x4 block: {np.unique(blocks)}"
    assert np.all(frame.fragment_count == 0) and np.all(frame.transmittance == 1.0)
    # exactly the documented dither (the glass is material 1)
    np.testing.assert_array_equal(kept[covered], screen_door_mask(alpha, 1, h, w)[covered])
    # kept pixels are shaded as opaque surfaces of the glass colour
    np.testing.assert_allclose(frame.albedo[kept], np.broadcast_to((1.0, 0.2, 0.2), (kept.sum(), 3)), atol=0.01)


BAYER4 = np.array([[0, 8, 2, 10], [12, 4, 14, 6], [3, 11, 1, 9], [15, 7, 13, 5]])


def screen_door_mask(alpha, material, h, w):
    """docs/transparency.md: kept where alpha >= (r + 0.5)/16, r = (bayer4x4[(y + 2(m & 1)) & 3][x & 3] + m) & 15."""
    y, x = np.mgrid[0:h, 0:w]
    r = (BAYER4[(y + 2 * (material & 1)) & 3, x & 3] + material) & 15
    return np.float32(alpha) >= (r + 0.5) / 16


def overlapping_quads(make_renderer, m_front, m_back, alpha):
    """Two overlapping quads (materials m_front in front, m_back behind; materials 0..11 all of opacity
    alpha, the wall 12) in screen-door mode: (triangle_id, overlap mask), the overlap 16x32 pixels."""
    cam = Camera.look_at((0, 0, 0), (0, 0, -1), fov_y_deg=90.0, near=0.1, far=50)
    mats = [Material(f"m{k}", (k / 12, 0.5, 0.2, 1.0), opacity=alpha) for k in range(12)]
    mats.append(Material("wall", (0.5, 0.5, 0.5, 1.0)))
    front = quad(-3, 1, -2, 2, -3.0)                            # pixels x 8..40, y 8..40
    back = quad(-1, 3, -2, 2, -5.0)
    back[..., :2] *= 5.0 / 3.0                                  # pixels x 24..56, y 8..40
    verts = np.concatenate([quad(-40, 40, -30, 30, -10.0), front, back])
    scene = Scene(verts.reshape(-1, 3), np.tile([0.0, 0.0, 1.0], (18, 1)), np.zeros((18, 2)),
                  np.arange(18).reshape(-1, 3), np.array([12, 12, m_front, m_front, m_back, m_back]), mats)
    frame = make_renderer(64, 48, transparency="screen_door").render(scene, cam)
    overlap = np.zeros((48, 64), bool)
    overlap[8:40, 24:40] = True
    return frame.triangle_id, overlap


@pytest.mark.parametrize("materials", [(1, 2), (1, 3), (2, 5)])
def test_screen_door_overlapping_layers(make_renderer, device, materials):
    """Two overlapping 50 % quads of different materials: both show in the overlap, each where the
    documented dither keeps it."""
    ids, overlap = overlapping_quads(make_renderer, *materials, 0.5)
    in_front = np.isin(ids[overlap], (2, 3)).mean()
    in_back = np.isin(ids[overlap], (4, 5)).mean()
    assert in_front > 0.3, f"front quad (material {materials[0]}) kept at {in_front:.2f} of the overlap"
    assert in_back > 0.1, (f"back quad (material {materials[1]}) vanishes from the overlap ({in_back:.2f} of its "
                           f"pixels): both layers picked the same stipple pixels")
    keep_front = screen_door_mask(0.5, materials[0], 48, 64)
    keep_back = screen_door_mask(0.5, materials[1], 48, 64)
    expect = np.where(keep_front, 2, np.where(keep_back, 4, -1))
    got = np.where(np.isin(ids, (2, 3)), 2, np.where(np.isin(ids, (4, 5)), 4, -1))
    np.testing.assert_array_equal(got[overlap], expect[overlap])


def test_screen_door_every_material_pair(make_renderer, device):
    """docs/transparency.md: over every pair of materials 0..11 and alpha 1/4, 1/2, 3/4, the back
    layer shows in at least 1/16 of the overlap (and the front keeps round(16·alpha)/16 of it)."""
    worst = {}
    for alpha in (0.25, 0.5, 0.75):
        for a in range(12):
            for b in range(12):
                if a == b:
                    continue
                ids, overlap = overlapping_quads(make_renderer, a, b, alpha)
                front = np.isin(ids[overlap], (2, 3)).mean()
                back = np.isin(ids[overlap], (4, 5)).mean()
                assert front == alpha, f"materials {a}/{b}, alpha {alpha}: front keeps {front}"
                worst[alpha] = min(worst.get(alpha, 1.0), back)
                assert back >= 1 / 16, (f"alpha {alpha}: the back layer (material {b}) shows in {back:.3f} of the "
                                        f"overlap behind material {a}")
    assert min(worst.values()) >= 1 / 16


# -- opaque scenes are unchanged -------------------------------------------------------------------------

def test_opaque_scene_identical_in_every_mode(make_renderer, device):
    rng = np.random.default_rng(5)
    parts = [wall()]
    for k in range(6):
        m = Material(f"opaque{k}", (*rng.uniform(0.2, 1.0, 3), 1.0), specular_intensity=0.3, specular_power=16.0)
        v = rng.uniform((-3, -2, -9), (3, 2, -3), (2, 3, 3))
        parts.append((v, None, m))
    # MASK materials stay opaque too
    parts.append((quad(-1, 1, -1, 1, -4.0), None, Material("mask", (0.9, 0.9, 0.1, 1.0), alpha_mode="MASK")))
    scene = build_scene(parts, lights=point_lights([((0.0, 1.0, -2.0), (2.0, 2.0, 2.0), 9.0)]))
    frames = {mode: make_renderer(W, H, transparency=mode).render(scene, CAMERA)
              for mode in ("abuffer", "depth_peeling", "screen_door")}
    base = frames["abuffer"]
    assert (base.triangle_id >= 0).all() and base.color.max() > 0.1
    for mode, f in frames.items():
        np.testing.assert_array_equal(f.color, base.color, err_msg=mode)
        np.testing.assert_array_equal(f.gbuffer, base.gbuffer, err_msg=mode)
        np.testing.assert_array_equal(f.image, base.image, err_msg=mode)
        assert np.all(f.fragment_count == 0) and np.all(f.transmittance == 1.0), mode
        assert f.stats.get("transparent", 0) == 0
        launched = [k for k in f.stats if k.endswith("_ms") and k.split("_")[0] in ("fragments", "abuffer", "peel",
                                                                                    "composite")]
        assert not launched, f"{mode}: an opaque scene launched transparency kernels: {launched}"


# -- refraction ---------------------------------------------------------------------------------------

def refraction_scene(tilt_deg, strength):
    """A striped opaque wall (4-pixel stripes) and a 50 % quad in front of it, turned about the y axis."""
    stripes = []
    light_m, dark_m = Material("light", (0.9, 0.9, 0.9, 1.0), specular_intensity=0.0), \
        Material("dark", (0.05, 0.1, 0.3, 1.0), specular_intensity=0.0)
    # pixel_exact_camera, square image: view x at depth 10 maps to pixel (x/10 + 1)/2·size
    size = 48
    for k in range(size // 4):
        x0, x1 = (8 * k / size * 2 - 1) * 10, ((8 * k + 4) / size * 2 - 1) * 10
        stripes.append((quad(x0, x1, -12, 12, -10.0), None, light_m))
        x2 = ((8 * k + 8) / size * 2 - 1) * 10
        stripes.append((quad(x1, x2, -12, 12, -10.0), None, dark_m))
    t = np.radians(tilt_deg)
    rot = np.array([[np.cos(t), 0, np.sin(t)], [0, 1, 0], [-np.sin(t), 0, np.cos(t)]])
    q = quad(-1.8, 1.8, -1.8, 1.8, 0.0) @ rot.T + np.array([0, 0, -4.0])
    glass = Material("glass", (0.3, 0.8, 0.4, 1.0), opacity=0.5, specular_intensity=0.0, refraction=strength)
    scene = build_scene(stripes + [(q, None, glass)], ambient=0.5)
    normal = rot @ np.array([0.0, 0.0, 1.0])
    return scene, normal, size


@pytest.mark.parametrize("strength", [0.08, 1.0])
def test_refraction_displaces_the_opaque_image(make_renderer, device, strength):
    """The opaque colour read behind each glass pixel is the opaque image's near p + s·height·(n_x, -n_y)
    (clamped to the image: strength 1 reaches 27 pixels); depth peeling composites the same way."""
    scene, normal, size = refraction_scene(35.0, strength)
    cam = pixel_exact_camera(far=50.0)
    plain = make_renderer(size, size).render(scene, cam)
    bent = make_renderer(size, size, refraction=True).render(scene, cam)
    layered = plain.fragment_count > 0
    assert layered.sum() > 200
    np.testing.assert_array_equal(bent.fragment_count, plain.fragment_count)
    np.testing.assert_array_equal(bent.transmittance, plain.transmittance)
    np.testing.assert_array_equal(bent.color[~layered], plain.color[~layered])
    changed = np.abs(bent.color - plain.color).max(-1) > 1e-3
    assert changed[layered].mean() > 0.3, "refraction must change the colour behind a tilted quad"
    # the opaque colour read behind each pixel: (bent - plain)/T + opaque(p) = opaque(p + offset)
    n_glass = int(ref.blend_mask(scene).sum())
    opaque_only = Scene(scene.positions, scene.normals, scene.uvs, scene.triangles[:-n_glass],
                        scene.triangle_material[:-n_glass], scene.materials, ambient=scene.ambient)
    O = make_renderer(size, size).render(opaque_only, cam).color.astype(np.float64)
    T = plain.transmittance.astype(np.float64)[..., None]
    looked_up = (bent.color - plain.color) / T + O
    right, up, back = (np.asarray(v) for v in cam.basis())
    n = normal if normal @ back > 0 else -normal                # facing the camera
    dx, dy = strength * size * (n @ right), -strength * size * (n @ up)
    assert abs(dx) > 2.0
    bad = []
    for y, x in np.argwhere(layered):
        tx, ty = np.clip(x + dx, 0, size - 1), np.clip(y + dy, 0, size - 1)
        xs = slice(max(int(np.floor(tx)) - 1, 0), min(int(np.ceil(tx)) + 2, size))
        ys = slice(max(int(np.floor(ty)) - 1, 0), min(int(np.ceil(ty)) + 2, size))
        lo, hi = O[ys, xs].reshape(-1, 3).min(0), O[ys, xs].reshape(-1, 3).max(0)
        v = looked_up[y, x]
        if np.any(v < lo - 1e-4) or np.any(v > hi + 1e-4):
            bad.append((y, x, v, lo, hi))
    assert not bad, (f"{len(bad)} of {layered.sum()} pixels read an opaque colour not found near p + "
                     f"({dx:.2f}, {dy:.2f}) px, e.g. (y, x, read, min, max) {bad[0]}")
    peeled = make_renderer(size, size, refraction=True, transparency="depth_peeling", peel_layers=2).render(scene, cam)
    np.testing.assert_array_equal(peeled.color, bent.color)
    # seen from behind (reversed winding, double-sided): the normal faces the camera, the same offset
    n_tri = scene.triangle_count
    flipped_tris = scene.triangles.copy()
    flipped_tris[n_tri - n_glass:] = flipped_tris[n_tri - n_glass:, ::-1]
    flipped_normals = scene.normals.copy()
    flipped_normals[scene.triangles[n_tri - n_glass:].ravel()] *= -1
    flipped = Scene(scene.positions, flipped_normals, scene.uvs, flipped_tris, scene.triangle_material,
                    scene.materials, ambient=scene.ambient)
    assert ref.fragments(flipped, cam, size, size).backface.all()
    back = make_renderer(size, size, refraction=True).render(flipped, cam)
    np.testing.assert_array_equal(back.fragment_count, bent.fragment_count)
    np.testing.assert_allclose(back.color, bent.color, rtol=0, atol=1e-5 * bent.color.max())


def test_refraction_face_on_changes_nothing(make_renderer, device):
    scene, _, size = refraction_scene(0.0, 0.08)
    cam = pixel_exact_camera(far=50.0)
    plain = make_renderer(size, size).render(scene, cam)
    bent = make_renderer(size, size, refraction=True).render(scene, cam)
    assert (plain.fragment_count > 0).sum() > 200
    np.testing.assert_allclose(bent.color, plain.color, rtol=0, atol=1e-6 * plain.color.max())
    # and strength 0 (the default) changes nothing even when tilted
    scene0, _, _ = refraction_scene(35.0, 0.0)
    a = make_renderer(size, size).render(scene0, cam)
    b = make_renderer(size, size, refraction=True).render(scene0, cam)
    np.testing.assert_array_equal(a.color, b.color)


# -- the Khronos AlphaBlendModeTest scene -------------------------------------------------------------------

def test_khronos_alpha_blend_mode(make_renderer, device):
    if not os.path.exists(KHRONOS):
        pytest.skip(f"Khronos AlphaBlendModeTest not found at {os.path.normpath(KHRONOS)} (../shared/scenes)")
    scene = clrender.load_scene(KHRONOS)
    cam = scene.default_camera()
    w, h = 96, 64
    frame = make_renderer(w, h).render(scene, cam)
    blend_tri = ref.blend_mask(scene)
    mask_tri = np.array([scene.materials[m].alpha_mode == "MASK" for m in scene.triangle_material])
    assert blend_tri.sum() > 0 and mask_tri.sum() > 0
    assert frame.stats.get("transparent") == int(blend_tri.sum())
    # BLEND triangles are not in the G-buffer
    assert not np.isin(frame.triangle_id, np.flatnonzero(blend_tri)).any()
    # their coverage (reference raster on the BLEND triangles alone, plain double-sided materials)
    sub = np.flatnonzero(blend_tri)
    plain = [Material(f"p{k}", double_sided=m.double_sided) for k, m in enumerate(scene.materials)]
    covered = coverage_count(Scene(scene.positions, scene.normals, scene.uvs, scene.triangles[sub],
                                   scene.triangle_material[sub], plain), cam, w, h)
    assert (covered > 0).sum() > 50
    fc = frame.fragment_count
    assert np.all(fc <= covered), "fragments only where BLEND triangles cover"
    assert (fc[covered > 0] >= 1).mean() > 0.9, "the BLEND quads lie in front of the bed: fragments there"
    with_frag = fc > 0
    assert np.all(frame.transmittance[~with_frag] == 1.0)
    assert np.all(frame.transmittance <= 1.0) and np.all(frame.transmittance >= 0.0)
    assert (frame.transmittance[with_frag] < 1.0).mean() > 0.5, "BLEND quads absorb where their texture has alpha"
    # MASK quads are opaque: their ids show where alpha >= cutoff, and they make no fragments
    for m in np.unique(scene.triangle_material[mask_tri]):
        ids = np.flatnonzero(scene.triangle_material == m)
        shown = np.isin(frame.triangle_id, ids)
        assert shown.sum() > 10, f"MASK material {scene.materials[m].name} never shows"
        assert np.all(fc[shown & (covered == 0)] == 0)
    assert np.isfinite(frame.color).all() and frame.color.max() > 0


# -- bad input ---------------------------------------------------------------------------------------------

@pytest.mark.parametrize("value", [float("nan"), -0.1, 1.5, float("inf")])
def test_bad_opacity_is_a_scene_error(value):
    with pytest.raises(SceneError, match="frosted"):
        Material("frosted", (1, 1, 1, 1), opacity=value)


def test_mask_with_opacity_is_a_scene_error():
    with pytest.raises(SceneError, match="leaf"):
        Material("leaf", (1, 1, 1, 1), alpha_mode="MASK", opacity=0.5)


@pytest.mark.parametrize("value", [float("nan"), -0.5])
def test_bad_refraction_is_a_scene_error(value):
    with pytest.raises(SceneError, match="prism"):
        Material("prism", (1, 1, 1, 1), opacity=0.5, refraction=value)


@pytest.mark.parametrize("option,value", [("transparency", "weighted_oit"), ("peel_layers", 0), ("peel_layers", 65),
                                          ("peel_layers", 2.0), ("max_fragments_per_pixel", -1),
                                          ("refraction", 1)])
def test_bad_transparency_options(option, value):
    from clrender.render.renderer import RenderConfig
    with pytest.raises(ValueError, match=option):
        RenderConfig.from_options(**{option: value})
