"""Tiled light culling against truth clrender did not compute (the room and its lights:
lighting_cases.py).

* tiled culling must change nothing: tiled == brute force for many light counts and tile sizes,
  with the hard cases (lights straddling tile borders, behind the camera, around the camera,
  grazing a tile's depth range, spot lights, hard-edged spots);
* light_count is conservative: per tile (many lights), and per light (each hard light rendered
  alone, so one light kept needlessly cannot hide another dropped), including a head-on wall where
  every culling test is tight (rim lights reaching one pixel across a tile border, lights reaching a
  surface by 0.5 % of r from in front / behind, spots whose rim ring barely reaches the wall).
  Lights near their reach limit contribute ~1e-7 of their color there, invisible in `color`: only
  `light_count` can show them.
"""
import numpy as np
import pytest

from clrender import Camera, Material, Scene
from lighting_cases import (AMBIENT, BRUTE, CAMERA, cull_opts, grid_quad, light_array, lit_scene, pixel_ray,
                            render, room_scene, sector_bounding_sphere, special_lights)
from reference import shading as ref


# Heavy light counts on the smallest image (100×72: partial tiles for every tile size).
CASES = [(0, 160, 120), (1, 160, 120), (17, 160, 120), (1024, 100, 72), (4096, 100, 72)]


def _tile_view(a, tile):
    """(ty, tx) of the value at each tile's first pixel, and whether a is constant per tile."""
    h, w = a.shape[:2]
    firsts = a[::tile, ::tile]
    rep = np.repeat(np.repeat(firsts, tile, 0), tile, 1)[:h, :w]
    return firsts, bool(np.array_equal(rep, a))


# -- tiled == brute force -----------------------------------------------------------------------

@pytest.mark.parametrize("tile", [8, 16, 32, "16+depth-mask"])
@pytest.mark.parametrize("count,width,height", CASES, ids=[f"{c}lights" for c, _, _ in CASES])
def test_tiled_equals_brute_force(make_renderer, device, count, width, height, tile):
    scene = lit_scene(count, width, height)
    brute = render(make_renderer, device, ("room", count), scene, CAMERA, width, height, **BRUTE)
    opts = cull_opts(tile)
    got = render(make_renderer, device, ("room", count), scene, CAMERA, width, height, **opts)
    assert got.color.shape == (height, width, 3) and got.color.dtype == np.float32
    fg = brute.triangle_id >= 0
    assert fg.mean() > 0.8
    assert np.isfinite(brute.color).all() and np.isfinite(got.color).all()
    peak = float(brute.color.max())
    assert peak > 0
    diff = np.abs(got.color.astype(np.float64) - brute.color)
    worst = np.unravel_index(np.argmax(diff), diff.shape)
    assert diff.max() <= 1e-4 * peak, (
        f"tiled (tile {tile}) vs brute force: max |diff| {diff.max():.3g} at pixel (y, x, c) {worst} "
        f"(brute {brute.color[worst]:.5g}, tiled {got.color[worst]:.5g}; light_count there "
        f"{got.light_count[worst[:2]]}), brightest {peak:.4g}")
    assert np.all(brute.light_count == count)
    assert got.stats["lights"] == count and brute.stats["lights"] == count
    if count:
        # the lights actually light something: the frame is not ambient-only
        ambient_only = brute.albedo * np.float32(AMBIENT)
        assert (brute.color[fg] > ambient_only[fg] * 1.01).any(-1).mean() > 0.2


# -- light_count is conservative ------------------------------------------------------------------

@pytest.mark.parametrize("tile", [8, 16, 32, "16+depth-mask"])
@pytest.mark.parametrize("count,width,height", [(17, 160, 120), (1024, 100, 72)], ids=["17lights", "1024lights"])
def test_light_count_is_conservative(make_renderer, device, count, width, height, tile):
    scene = lit_scene(count, width, height)
    frame = render(make_renderer, device, ("room", count), scene, CAMERA, width, height, **cull_opts(tile))
    tile = 16 if tile == "16+depth-mask" else tile
    assert frame.light_count.shape == (height, width) and frame.light_count.dtype == np.int32
    per_tile, constant = _tile_view(frame.light_count, tile)
    assert constant, "light_count must be one value per light tile"
    truth = ref.tile_light_truth(frame, CAMERA, scene.lights, tile)
    assert truth.max() > 0
    short = per_tile < truth
    if short.any():
        ty, tx = np.argwhere(short)[0]
        pytest.fail(f"{int(short.sum())} of {short.size} tiles ({tile}px) got fewer lights than reach them; "
                    f"e.g. tile (row {ty}, col {tx}): {per_tile[ty, tx]} assigned < {truth[ty, tx]} reaching")
    assert per_tile.max() <= count
    stats = frame.stats
    for key in ("lights", "light_cull_ms", "shade_ms", "lights_per_tile_avg", "lights_per_tile_max"):
        assert key in stats, f"stats lacks {key!r}"
    assert stats["lights_per_tile_max"] == per_tile.max()
    assert per_tile.min() - 1e-6 <= stats["lights_per_tile_avg"] <= per_tile.max() + 1e-6
    if count >= 1024:
        # culling culls: small random lights reach a small part of the view
        assert stats["lights_per_tile_avg"] < 0.25 * count


HEAD_ON_CAM = Camera.look_at((0.0, 0.0, 0.0), (0.0, 0.0, -1.0), fov_y_deg=50, near=0.1, far=30)
HEAD_ON_Z, NEAR_Z = -5.0, -3.0       # a wall facing the camera, a smaller quad in front of it
NEAR_PX = 100.3                      # the near quad covers pixels x, y > NEAR_PX (of 128): mid-tile edges


def head_on_plane(camera, size, z):
    eye = np.asarray(camera.eye, np.float64)

    def at(px, py):
        d = pixel_ray(camera, size, size, px, py)
        return eye + d * (z - eye[2]) / d[2]
    return at


def head_on_scene(camera, size) -> Scene:
    wall_pos, wall_faces, wall_n = grid_quad((-6, -6, HEAD_ON_Z), (12, 0, 0), (0, 12, 0))
    corner = head_on_plane(camera, size, NEAR_Z)(NEAR_PX, NEAR_PX)       # top-left of the near quad
    near_pos, near_faces, near_n = grid_quad((corner[0], corner[1] - 6, NEAR_Z), (6, 0, 0), (0, 6, 0), n=2)
    scene = Scene(np.concatenate([wall_pos, near_pos]), np.concatenate([wall_n, near_n]),
                  np.zeros((len(wall_pos) + len(near_pos), 2)),
                  np.concatenate([wall_faces, near_faces + len(wall_pos)]),
                  np.zeros(len(wall_faces) + len(near_faces), np.int32),
                  [Material("wall", (0.6, 0.6, 0.6, 1.0), specular_intensity=0.2, specular_power=16.0)])
    scene.ambient = AMBIENT
    scene.lights = light_array(head_on_lights(camera, size))
    return scene


def head_on_lights(camera, size) -> list:
    """Lights that make a culler's every test tight, for a camera looking straight at a wall (its view
    depth is the same at every pixel, and tile planes through the image center are perpendicular
    to it): rim lights reaching one pixel column/row across a tile border by 0.3 % of r, lights
    whose sphere reaches a surface from in front / from behind by 0.5 % of r (a tile's min and max
    depth, also in tiles holding both the wall and the near quad: the depth mask), and spots whose
    cone rim is what reaches the wall (the cone's bounding sphere)."""
    wall, near = head_on_plane(camera, size, HEAD_ON_Z), head_on_plane(camera, size, NEAR_Z)
    n = np.array([0.0, 0.0, 1.0])
    recs = []
    r, eps = 4.0, 0.003           # big r: half a pixel is ~0.5 % of r, so a 1 % looser plane test shows
    for b in (size // 2, size // 4, 3 * size // 4):
        for along in (0.3 * size + 0.5, 0.7 * size + 0.5):
            for side in (+0.5, -0.5):          # the first pixel across the border, either way
                for vertical in (True, False):
                    bp, qp = ((b, along), (b + side, along)) if vertical else ((along, b), (along, b + side))
                    bw, qw = wall(*bp), wall(*qp)
                    u = (qw - bw) / np.linalg.norm(qw - bw)
                    recs.append(dict(position=qw - r * (1 - eps) * u, radius=r, color=(0.2, 0.2, 0.2)))
    r = 0.8
    for plane, (px, py) in [(wall, (20.5, 20.5)), (wall, (0.6 * size, 0.3 * size)), (wall, (80.5, 90.5)),
                            (wall, (98.5, 110.5)), (wall, (110.5, 98.5)),       # beside the near quad
                            (near, (110.5, 102.5)), (near, (102.5, 120.5))]:
        q = plane(px, py)
        recs.append(dict(position=q + 0.995 * r * n, radius=r, color=(1.0, 1.0, 1.0)))    # in front
        recs.append(dict(position=q - 0.995 * r * n, radius=r, color=(1.0, 1.0, 1.0)))    # behind
    r = 1.5
    for k, theta in enumerate((20.0, 40.0, 60.0)):
        for tilt in (0.0, 25.0):
            q = wall(size * (0.2 + 0.25 * k) + 0.5, size * (0.3 if tilt else 0.6) + 0.5)
            t = np.radians(tilt)
            d = np.array([np.sin(t), 0.0, -np.cos(t)])
            h = 0.99 * r * np.cos(np.radians(theta) + t)     # the cone's far rim reaches, at 0.99 r
            recs.append(dict(position=q - d * h / np.cos(t), radius=r, color=(1.0, 0.8, 0.6), direction=d,
                             inner=theta - 5.0, outer=theta))
    # Spots turned so that the point of their rim ring (distance r, angle = outer) where the sector's
    # smallest bounding sphere is tangent faces the wall, which cuts that sphere 1.5 % deep: only a
    # sliver of the cone near its ring reaches the wall, so a looser-than-exact cone bound shows.
    r, eps = 3.0, 0.015
    for theta, (px, py) in [(20.0, (30.5, 100.5)), (40.0, (60.5, 100.5)), (60.0, (90.5, 20.5)),
                            (75.0, (20.5, 60.5))]:
        c_along, radius = sector_bounding_sphere(r, theta)
        tr = np.radians(theta)
        m = np.array([r * np.cos(tr) - c_along, r * np.sin(tr)]) / radius    # ring normal in (axis, side)
        phi = np.arctan2(m[1], m[0])
        d = np.array([-np.sin(phi), 0.0, -np.cos(phi)])                      # so that the ring normal is -z
        q = wall(px, py)
        center = np.array([q[0], q[1], HEAD_ON_Z + radius * (1 - eps)])
        recs.append(dict(position=center - c_along * d, radius=r, color=(1.0, 0.9, 0.7), direction=d,
                         inner=theta - 5.0, outer=theta))
    return recs


def missed_tiles_per_light(make_renderer, scene, camera, width, height, tile):
    """Render each light alone: {light index: tiles (row, col) it reaches but was not assigned to}.

    With one light, `light_count >= truth` per tile is a set check; with many, one light a culler
    keeps needlessly would hide another it drops."""
    opts, tsize = cull_opts(tile), (16 if tile == "16+depth-mask" else tile)
    renderer = make_renderer(width, height, **opts)
    lights = scene.lights.copy()
    missed = {}
    try:
        for i in range(len(lights)):
            scene.lights = lights[i:i + 1]
            frame = renderer.render(scene, camera)
            truth = ref.tile_light_truth(frame, camera, scene.lights, tsize)
            short = np.argwhere(frame.light_count[::tsize, ::tsize] < truth)
            if len(short):
                missed[i] = [tuple(map(int, t)) for t in short]
    finally:
        scene.lights = lights
    return missed


def _describe(missed, lights):
    return "; ".join(f"light {i} (type {int(lights[i]['type'])}, at {np.round(lights[i]['position'], 3).tolist()}, "
                     f"r {float(lights[i]['radius']):.3g}): tiles {t[:4]}{'...' if len(t) > 4 else ''}"
                     for i, t in list(missed.items())[:6])


@pytest.mark.parametrize("tile", [8, 16, 32, "16+depth-mask"])
def test_each_hard_light_reaches_its_tiles_room(make_renderer, device, tile):
    w, h = 160, 120
    scene = room_scene()
    scene.lights = light_array(special_lights(CAMERA, w, h))
    missed = missed_tiles_per_light(make_renderer, scene, CAMERA, w, h, tile)
    assert not missed, f"tile {tile}: lights dropped from tiles they reach: {_describe(missed, scene.lights)}"


@pytest.mark.parametrize("tile", [8, 16, 32, "16+depth-mask"])
def test_light_count_is_conservative_head_on(make_renderer, device, tile):
    size = 128
    scene = head_on_scene(HEAD_ON_CAM, size)
    frame = render(make_renderer, device, "head_on", scene, HEAD_ON_CAM, size, size, **cull_opts(tile))
    assert (frame.triangle_id >= 0).all()
    near = frame.depth < 4
    assert 200 < near.sum() < 1500 and near[-1, -1] and not near[0, 0]
    reach = ref.light_reach_mask(ref.world_positions(frame.depth, HEAD_ON_CAM), scene.lights)
    lost = np.flatnonzero(~reach.any(axis=(1, 2)))
    assert not len(lost), f"lights {lost.tolist()} reach no pixel (so they test nothing)"
    brute = render(make_renderer, device, "head_on", scene, HEAD_ON_CAM, size, size, **BRUTE)
    assert np.abs(frame.color - brute.color).max() <= 1e-4 * brute.color.max()
    missed = missed_tiles_per_light(make_renderer, scene, HEAD_ON_CAM, size, size, tile)
    assert not missed, f"tile {tile}: lights dropped from tiles they reach: {_describe(missed, scene.lights)}"
