"""Scenes and comparisons shared by the transparency tests (test_transparency*.py, test_screen_door.py,
test_refraction.py): scene construction from parts, random soups of overlapping transparent triangles,
and the comparison of a frame with the independent NumPy reference tests/reference/transparency.py.
"""
from __future__ import annotations

import numpy as np
import pytest

from clrender import Camera, Material, Scene
from clrender.abi import structs
from reference import shading as ref_shading
from reference import transparency as ref
from reference.raster import pixel_exact_camera, screen_to_world

# Fragments are shaded from unquantized float32 barycentrics, positions and normals and blended in
# float32; the reference is float64: 1e-4 of the brightest reference value of the frame, the shading
# tolerance of test_lighting.py (measured on PoCL: <= 3e-6; transmittance <= 5e-8).
COLOR_TOL = 1e-4
TRANSMITTANCE_TOL = 1e-5

W, H = 64, 48
CAMERA = Camera.look_at((0.0, 0.0, 0.0), (0.0, 0.0, -1.0), fov_y_deg=60.0, near=0.1, far=50.0)
AMBIENT = 0.1


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


# -- pixel-exact quads (a SIZE x SIZE pixel_exact_camera image) ---------------------------------

SIZE = 32
PX_CAM = pixel_exact_camera(far=50.0)


def screen_quad(x0, x1, y0, y1, depth):
    """World quad covering pixel rectangle [x0, x1) × [y0, y1) of a SIZE×SIZE pixel_exact_camera image
    (edges on pixel boundaries, so coverage is exact), facing the camera."""
    a, b = screen_to_world(x0, y1, SIZE, depth), screen_to_world(x1, y1, SIZE, depth)
    c, d = screen_to_world(x1, y0, SIZE, depth), screen_to_world(x0, y0, SIZE, depth)
    return np.array([[a, b, c], [a, c, d]], np.float64)
