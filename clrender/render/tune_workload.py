"""The autotune's workload (render/autotune.py): a seeded scene whose screen statistics are Sponza's at
1280x720 (bench.common's camera), scaled to the tune's smaller frame, so that what is fastest on it is
what is fastest on real scenes.

Measured on Sponza (2026-11-28): 0.23 triangles in the frustum per pixel; their screen areas spread
log-normally (10/50/90/99th percentiles 0.05 / 1.3 / 19 / 250 px); 13 % of the triangles are
alpha-masked (foliage, chains), the rest single-sided; detail comes in meshes (neighbouring small
triangles), with some wall-sized triangles behind it. Each of these moves the ranking: a soup of
larger, scattered, unmasked triangles (the first workload) rated VEC 16 0.83-0.87 of VEC 8 where
Sponza is 1.03-1.11 (masked triangles sample their texture per pixel in the raster, lane by lane),
and tile 16 better than it is.
"""
from __future__ import annotations

import numpy as np

TRIANGLES_PER_PIXEL = 0.25
MEDIAN_AREA_PX = 1.3
AREA_SIGMA = 2.1                 # ln-space: the 90th percentile ~19 px, the 99th ~180 px
MESH_TRIANGLES = 64              # triangles per patch of neighbouring detail
MASKED_FRACTION = 0.13
WALLS = 25                       # triangles of ~10 % of the frame each
FOV_Y_DEG = 60.0


def _triangles(rng, size, n: int, area_px: np.ndarray, per_patch: int) -> np.ndarray:
    """(n, 3, 3) world-space triangles in patches of `per_patch` sharing a depth and a screen spot,
    each of about area_px[patch] pixels, in front of a camera at the origin looking down -z."""
    w, h = size
    t = np.tan(np.radians(FOV_Y_DEG) / 2)
    patches = -(-n // per_patch)
    depth = np.repeat(np.exp(rng.uniform(np.log(1.5), np.log(40.0), patches)), per_patch)[:n]
    area = np.repeat(area_px[:patches], per_patch)[:n]
    px_per_unit = h / (2 * depth * t)
    edge = np.sqrt(2 * area) / px_per_unit
    radius = np.sqrt(per_patch * area / np.pi) / px_per_unit      # the patch's triangles tile a disc
    x = np.repeat(rng.uniform(-1.05, 1.05, patches), per_patch)[:n] * depth * t * (w / h)
    y = np.repeat(rng.uniform(-1.05, 1.05, patches), per_patch)[:n] * depth * t
    angle = rng.uniform(0, 2 * np.pi, n)
    r = radius * np.sqrt(rng.uniform(0, 1, n))
    centres = np.stack([x + r * np.cos(angle), y + r * np.sin(angle), -depth], 1)
    return centres[:, None, :] + rng.normal(size=(n, 3, 3)) * (edge / 1.2)[:, None, None]


def workload(size=(640, 360), seed: int = 40):
    """(Scene, Camera) for a frame of `size`: see the module's doc for what it reproduces."""
    from clrender.scene.camera import Camera
    from clrender.scene.material import Material
    from clrender.scene.model import Scene, Texture
    rng = np.random.default_rng(seed)
    w, h = size
    n = int(TRIANGLES_PER_PIXEL * w * h)
    detail = _triangles(rng, size, n, np.exp(rng.normal(np.log(MEDIAN_AREA_PX), AREA_SIGMA, n)), MESH_TRIANGLES)
    walls = _triangles(rng, size, WALLS, np.full(WALLS, 0.1 * w * h), 1)
    positions = np.concatenate([detail, walls]).reshape(-1, 3).astype(np.float32)
    triangles = np.arange(len(positions), dtype=np.int64).reshape(-1, 3)
    masked = rng.uniform(size=len(triangles)) < MASKED_FRACTION
    alpha = np.where(rng.uniform(size=(64, 64)) < 0.6, 255, 0).astype(np.uint8)
    leaves = Texture("tune-leaves", np.dstack([np.full((64, 64, 3), 200, np.uint8), alpha]))
    materials = [Material(name="tune-solid", double_sided=False),
                 Material(name="tune-leaves", base_color_texture=0, alpha_mode="MASK")]
    plain = Scene.from_arrays(positions, triangles)                 # (its vertex normals)
    uvs = rng.uniform(0, 4, (len(positions), 2)).astype(np.float32)
    scene = Scene(plain.positions, plain.normals, uvs, plain.triangles, masked.astype(np.int32), materials,
                  textures=[leaves], source="<autotune workload>")
    return scene, Camera.look_at((0, 0, 0), (0, 0, -1), fov_y_deg=FOV_Y_DEG, near=0.1, far=60.0)
