"""Screen-door transparency (docs/transparency.md): the kept fraction, exactly the documented 4x4
dither per material, and overlapping layers of every material pair.
"""
from __future__ import annotations

import numpy as np
import pytest

from clrender import Camera, Material, Scene
from reference import transparency as ref
from reference.raster import coverage_count
from transparency_cases import build_scene, quad


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
