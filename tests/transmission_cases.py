"""Scenes for the see-through material tests (test_transmission.py, the Oclgrind tier, `clrender check`):
transmissive glTF materials, pixel-aligned quads and slabs, and opaque unlit backgrounds whose colour
varies per pixel (noise texture, checkerboard, a linear ramp for measuring lookup offsets).

Two cameras over SIZE x SIZE images: PX_CAM (reference.raster.pixel_exact_camera: fov 90°, a quad's
pixel-rectangle edges land exactly on pixel boundaries) and ORTHO (orthographic, 16 pixels per world
unit, every view ray along -Z: normal incidence on a face-on surface at every pixel).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import numpy as np

from clrender import Camera, Material, Scene, Texture
from clrender.scene.model import SceneObject
from reference.raster import coverage_count, pixel_exact_camera, screen_to_world

SIZE = 64
PX_CAM = pixel_exact_camera(far=50.0)
ORTHO_HALF = 2.0                       # world units: the ortho view spans [-2, 2]² (16 px per unit)
ORTHO = Camera.orthographic((0.0, 0.0, 0.0), (0.0, 0.0, -1.0), xmag=ORTHO_HALF, ymag=ORTHO_HALF, near=0.1, far=50.0)
QUAD_UV = np.array([[[0, 1], [1, 1], [1, 0]], [[0, 1], [1, 0], [0, 0]]], np.float64)   # matches *_quad corners


def glass(name="glass", base=(0.9, 0.6, 0.3), alpha=1.0, metallic=0.0, roughness=0.0, transmission=1.0,
          **kw) -> Material:
    """A transmissive glTF metallic-roughness material (IOR 1.5 unless given)."""
    return Material.from_metallic_roughness(name, (*base, alpha), metallic, roughness, transmission=transmission, **kw)


def unlit(name, rgb=(1.0, 1.0, 1.0), **kw) -> Material:
    return Material(name, (*rgb, 1.0), unlit=True, **kw)


@dataclass
class Part:
    verts: np.ndarray                   # (n, 3, 3) world
    material: Material
    uvs: Optional[np.ndarray] = None    # (n, 3, 2)
    colors: Optional[np.ndarray] = None  # (n, 3, 4) linear vertex colours
    normals: Optional[np.ndarray] = None  # (n, 3, 3); None: the face normal
    mesh: str = "mesh"


def assemble(parts, textures=(), ambient=0.0, volume_scale=None) -> Scene:
    """One Scene from parts (triangle ids follow the order); each distinct `mesh` name is an object
    (volume_scale: {mesh: scale} for SceneObject.volume_scale)."""
    materials, meshes = [], []
    pos, nrm, uvs, cols, mat, mesh = [], [], [], [], [], []
    for p in parts:
        v = np.asarray(p.verts, np.float64).reshape(-1, 3, 3)
        if p.normals is None:
            fn = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
            fn /= np.linalg.norm(fn, axis=-1, keepdims=True)
            n = np.repeat(fn[:, None], 3, axis=1)
        else:
            n = np.asarray(p.normals, np.float64).reshape(-1, 3, 3)
        if p.material not in materials:
            materials.append(p.material)
        if p.mesh not in meshes:
            meshes.append(p.mesh)
        pos.append(v)
        nrm.append(n)
        uvs.append(np.zeros((len(v), 3, 2)) if p.uvs is None else np.asarray(p.uvs, np.float64).reshape(-1, 3, 2))
        cols.append(np.ones((len(v), 3, 4)) if p.colors is None else np.asarray(p.colors, np.float64).reshape(-1, 3, 4))
        mat.append(np.full(len(v), materials.index(p.material), np.int32))
        mesh.append(np.full(len(v), meshes.index(p.mesh), np.int32))
    pos, t = np.concatenate(pos), sum(len(v) for v in pos)
    scales = volume_scale or {}
    objects = [SceneObject(m, m, m, volume_scale=scales.get(m, 1.0)) for m in meshes]
    any_color = any(p.colors is not None for p in parts)
    scene = Scene(pos.reshape(-1, 3), np.concatenate(nrm).reshape(-1, 3), np.concatenate(uvs).reshape(-1, 2),
                  np.arange(3 * t, dtype=np.int32).reshape(-1, 3), np.concatenate(mat), materials,
                  textures=list(textures), mesh_names=meshes, triangle_mesh=np.concatenate(mesh), objects=objects,
                  colors=np.concatenate(cols).reshape(-1, 4) if any_color else None)
    scene.ambient = ambient
    return scene


# -- geometry: pixel rectangles -> world quads -------------------------------------------------------

def px_quad(x0, x1, y0, y1, depth):
    """PX_CAM: the world quad at view depth `depth` covering pixels [x0, x1) × [y0, y1), facing the camera."""
    a, b = screen_to_world(x0, y1, SIZE, depth), screen_to_world(x1, y1, SIZE, depth)
    c, d = screen_to_world(x1, y0, SIZE, depth), screen_to_world(x0, y0, SIZE, depth)
    return np.array([[a, b, c], [a, c, d]], np.float64)


def ortho_xy(px, py):
    """ORTHO: world (x, y) of screen position (px, py) (pixels, y down)."""
    px, py = np.asarray(px, np.float64), np.asarray(py, np.float64)
    return (px / SIZE * 2 - 1) * ORTHO_HALF, (1 - py / SIZE * 2) * ORTHO_HALF


def ortho_quad(x0, x1, y0, y1, z):
    """ORTHO: the quad at world z covering pixels [x0, x1) × [y0, y1), facing the camera (+Z)."""
    (wx0, wx1), (wy1, wy0) = ortho_xy([x0, x1], [0, 0])[0], ortho_xy([0, 0], [y1, y0])[1]
    a, b, c, d = (wx0, wy1, z), (wx1, wy1, z), (wx1, wy0, z), (wx0, wy0, z)
    return np.array([[a, b, c], [a, c, d]], np.float64)


def back_facing(quad):
    """The same quad wound the other way (its face normal points away from the camera)."""
    return np.asarray(quad)[:, ::-1].copy()


def turned(quad, angle_deg, center, axis="y"):
    """The quad turned by angle_deg about the vertical ("y") or horizontal ("x") axis through `center`."""
    t = np.radians(angle_deg)
    c, s = np.cos(t), np.sin(t)
    rot = np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]]) if axis == "y" else np.array([[1, 0, 0], [0, c, -s], [0, s, c]])
    c = np.asarray(center, np.float64)
    return (np.asarray(quad) - c) @ rot.T + c


def slab(front, thickness, material, mesh="slab"):
    """A slab's two large faces: `front` (camera-facing) and its copy `thickness` behind along the front's
    normal, wound the other way (the volume's exit). Its sides are seen edge-on and left out."""
    n = np.cross(front[0, 1] - front[0, 0], front[0, 2] - front[0, 0])
    back = back_facing(front - thickness * n / np.linalg.norm(n))
    return [Part(front, material, mesh=mesh), Part(back, material, mesh=mesh)]


# -- backgrounds (unlit: the colour is the texture / vertex colour, independent of lights) -----------

def noise_texture(seed, size=SIZE) -> Texture:
    rng = np.random.default_rng(seed)
    rgba = rng.integers(30, 256, (size, size, 4), dtype=np.uint8)
    rgba[..., 3] = 255
    return Texture("noise", rgba, wrap_s="clamp", wrap_t="clamp")


def noise_background(quad, texture_index=0, mesh="background") -> Part:
    """An opaque unlit quad showing texture `texture_index` (the per-pixel varied background)."""
    return Part(quad, unlit("background", base_color_texture=texture_index), uvs=QUAD_UV, mesh=mesh)


def checker_background(cell, depth, light=(0.9, 0.8, 0.7), dark=(0.1, 0.15, 0.2)) -> list:
    """PX_CAM: a checkerboard of `cell`-pixel squares at `depth` (light squares just in front of a dark wall)."""
    parts = [Part(px_quad(0, SIZE, 0, SIZE, depth + 0.5), unlit("dark", dark), mesh="background")]
    m = unlit("light", light)
    for i in range(SIZE // cell):
        for j in range(SIZE // cell):
            if (i + j) % 2 == 0:
                parts.append(Part(px_quad(i * cell, (i + 1) * cell, j * cell, (j + 1) * cell, depth), m,
                                  mesh="background"))
    return parts


RAMP = (0.05, 0.95)        # the ramp's colour at the image's left and right edges


def ramp_background(z, axis="x") -> Part:
    """ORTHO: an unlit quad over the whole image whose colour (every channel) rises linearly with pixel x
    (or y, downwards) (vertex colours, screen-linear under an orthographic camera) from RAMP[0] to RAMP[1]:
    0.014 a pixel, more than an 8-bit sRGB code anywhere, so the stored (quantized) row still rises."""
    q = ortho_quad(0, SIZE, 0, SIZE, z)
    lo, hi = RAMP
    xs = (q[..., 0] / ORTHO_HALF + 1) / 2 if axis == "x" else (1 - q[..., 1] / ORTHO_HALF) / 2   # 0 .. 1
    colors = np.concatenate([np.repeat((lo + (hi - lo) * xs)[..., None], 3, -1), np.ones(q.shape[:2] + (1,))], -1)
    return Part(q, unlit("ramp"), colors=colors, mesh="background")


def invert_row(row, value):
    """Continuous pixel x (pixel i's centre at i) where the linear interpolation of an increasing row of
    values (the opaque image's row, as the lookup interpolates it) takes `value`."""
    row = np.asarray(row, np.float64)
    assert np.all(np.diff(row) > 0), "the ramp row must rise at every pixel"
    i = np.clip(np.searchsorted(row, value) - 1, 0, len(row) - 2)
    return i + (np.asarray(value, np.float64) - row[i]) / (row[i + 1] - row[i])


# -- per-pixel geometry of a plane ------------------------------------------------------------------

def plane_pixels(scene_part: Part, camera, width=SIZE, height=SIZE):
    """(covered (H, W) bool, P (H, W, 3), n (H, W, 3) facing the viewer, v (H, W, 3), nv (H, W)) of a planar
    part: coverage by the raster reference, P the pixel ray's float64 intersection with the plane."""
    from reference import shading
    v0 = np.asarray(scene_part.verts, np.float64).reshape(-1, 3, 3)
    n = np.cross(v0[0, 1] - v0[0, 0], v0[0, 2] - v0[0, 0])
    n /= np.linalg.norm(n)
    only = assemble([Part(v0, Material("plane"))])
    covered = coverage_count(only, camera, width, height) > 0
    o, d = shading.pixel_origins(camera, width, height), shading.pixel_directions(camera, width, height)
    s = ((v0[0, 0] - o) @ n) / (d @ n)
    P = o + s[..., None] * d
    v = shading.view_vectors(P, camera)
    nf = np.where(((v @ n) < 0)[..., None], -n, n)
    return covered, P, nf, v, np.sum(nf * v, -1)


# -- overlapping see-through soups (order independence, `clrender check`) ---------------------------

SOUP_W, SOUP_H = 64, 48
SOUP_CAM = Camera.look_at((0.0, 0.0, 0.0), (0.0, 0.0, -1.0), fov_y_deg=60.0, near=0.1, far=50.0)


def see_through_soup(seed, n=12, width=SOUP_W, height=SOUP_H) -> Scene:
    """A lit opaque glTF wall and `n` overlapping triangles (vertex normals perturbed per vertex) drawn from
    5 see-through materials: thin glass (roughness 0), a rough volume with attenuation, a dispersive volume
    (a textured thickness), a metallic BLEND glaze and a transmissive BLEND film; point lights and a sun."""
    rng = np.random.default_rng(seed)
    tan = np.tan(np.radians(SOUP_CAM.fov_y_deg) / 2)
    mats = [glass("thin", base=(0.9, 0.7, 0.5)),
            glass("smoky", base=(0.8, 0.85, 0.9), roughness=0.45, thickness=0.6, attenuation_color=(0.4, 0.6, 0.9),
                  attenuation_distance=0.8, double_sided=False),
            glass("prism", base=(0.95, 0.95, 0.95), roughness=0.1, ior=1.7, thickness=0.4, dispersion=1.5,
                  thickness_texture=0),
            Material.from_metallic_roughness("glaze", (0.3, 0.7, 0.45, 0.55), 0.3, 0.5, alpha_mode="BLEND"),
            glass("film", base=(0.6, 0.9, 0.7), alpha=0.7, alpha_mode="BLEND", roughness=0.2, transmission=0.8)]
    wall = Material.from_metallic_roughness("wall", (0.7, 0.7, 0.65, 1.0), 0.0, 0.8)
    a, b, c, d = (-12, -9, -12), (12, -9, -12), (12, 9, -12), (-12, 9, -12)
    parts = [Part(np.array([[a, b, c], [a, c, d]], np.float64), wall, uvs=QUAD_UV * 3)]
    for k in range(n):
        d = rng.uniform(2.0, 10.0)
        ndc = rng.uniform(-0.5, 0.5, 2)
        center = np.array([ndc[0] * d * tan * width / height, ndc[1] * d * tan, -d])
        offs = rng.normal(scale=0.6 * d * tan, size=(3, 3))
        offs[:, 2] *= 0.6
        v = center + offs
        v[:, 2] = np.clip(v[:, 2], -11.0, -1.0)
        fn = np.cross(v[1] - v[0], v[2] - v[0])
        fn /= np.linalg.norm(fn)
        nv = fn + rng.normal(scale=0.3, size=(3, 3))
        parts.append(Part(v[None], mats[k % len(mats)], uvs=rng.uniform(0, 1, (1, 3, 2)),
                          normals=(nv / np.linalg.norm(nv, axis=-1, keepdims=True))[None]))
    thickness = Texture("thickness", rng.integers(0, 256, (8, 8, 4), dtype=np.uint8), srgb=False)
    scene = assemble(parts, textures=[thickness], ambient=0.1)
    for _ in range(3):
        scene.add_point_light(rng.uniform((-3, -2, -6), (3, 2, -1)), rng.uniform(0.5, 2.0, 3), rng.uniform(6, 12))
    scene.set_sun((0.3, -0.5, -0.8), (1.2, 1.1, 1.0), shadow=False)
    return scene


def shuffled(scene: Scene, seed: int) -> Scene:
    """The scene with its triangles' rows permuted (seeded); materials, meshes and objects follow them."""
    perm = np.random.default_rng(seed).permutation(scene.triangle_count)
    return Scene(scene.positions, scene.normals, scene.uvs, scene.triangles[perm], scene.triangle_material[perm],
                 scene.materials, textures=scene.textures, mesh_names=scene.mesh_names,
                 triangle_mesh=scene.triangle_mesh[perm], objects=scene.objects, lights=scene.lights.copy(),
                 ambient=scene.ambient, sun=scene.sun, colors=scene.colors)
