"""Tiled light culling + deferred shading + tone mapping against truth clrender did not compute.

* tiled culling must change nothing: tiled == brute force for many light counts and tile sizes,
  with the hard cases (lights straddling tile borders, behind the camera, around the camera,
  grazing a tile's depth range, spot lights, hard-edged spots);
* shading == the float64 NumPy reference (tests/reference/shading.py) on the frame's own decoded
  G-buffer, so only float32-vs-float64 differences remain;
* attenuation is exactly zero from d = r on; tone mapping matches;
* light_count is conservative: per tile (many lights), and per light (each hard light rendered
  alone, so one light kept needlessly cannot hide another dropped), including a head-on wall where
  every culling test is tight (rim lights reaching one pixel across a tile border, lights reaching a
  surface by 0.5 % of r from in front / behind, spots whose rim ring barely reaches the wall).
  Lights near their reach limit contribute ~1e-7 of their color there, invisible in `color`: only
  `light_count` can show them.
"""
import numpy as np
import pytest

from helpers import SHADING_TOL
import clrender
from clrender import Camera, Material, Scene
from clrender.abi import structs
from reference import shading as ref
from reference.geometry import uv_sphere

AMBIENT = 0.05

# Geometry of the test room (world units): floor y = 0, back wall z = WALL_Z, a sphere on the floor.
FLOOR_X, FLOOR_Z = (-5.0, 5.0), (-7.0, 1.0)
WALL_Z, WALL_TOP = -7.0, 5.0
SPHERE_C, SPHERE_R = np.array([0.4, 1.0, -3.5]), 1.0


# -- scene construction -------------------------------------------------------------------------

def grid_quad(corner, edge_u, edge_v, n=4):
    """An n×n grid of quads from `corner` along two edges; front face (CCW) toward edge_u × edge_v."""
    corner, edge_u, edge_v = (np.asarray(v, np.float64) for v in (corner, edge_u, edge_v))
    s = np.linspace(0.0, 1.0, n + 1)
    uu, vv = np.meshgrid(s, s, indexing="ij")
    pos = corner + uu[..., None] * edge_u + vv[..., None] * edge_v
    idx = np.arange((n + 1) ** 2).reshape(n + 1, n + 1)
    a, b, c, d = idx[:-1, :-1], idx[1:, :-1], idx[1:, 1:], idx[:-1, 1:]
    faces = np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3), np.stack([a, c, d], -1).reshape(-1, 3)])
    normal = np.cross(edge_u, edge_v)
    normal /= np.linalg.norm(normal)
    return pos.reshape(-1, 3), faces, np.broadcast_to(normal, pos.reshape(-1, 3).shape)


def room_scene(with_sphere=True, with_wall=True) -> Scene:
    """Floor (+ back wall + sphere), three materials with non-trivial specular."""
    parts = [grid_quad((FLOOR_X[0], 0, FLOOR_Z[1]), (FLOOR_X[1] - FLOOR_X[0], 0, 0),
                       (0, 0, FLOOR_Z[0] - FLOOR_Z[1]))]                       # normal +y
    if with_wall:
        parts.append(grid_quad((FLOOR_X[0], 0, WALL_Z), (FLOOR_X[1] - FLOOR_X[0], 0, 0), (0, WALL_TOP, 0)))
    if with_sphere:
        parts.append(uv_sphere(radius=SPHERE_R, center=SPHERE_C))
    positions, faces, normals, mats = [], [], [], []
    base = 0
    for m, (p, f, n) in enumerate(parts):
        positions.append(p)
        normals.append(n)
        faces.append(np.asarray(f) + base)
        mats.append(np.full(len(f), m, np.int32))
        base += len(p)
    materials = [Material("floor", (0.8, 0.7, 0.6, 1.0), specular_intensity=0.3, specular_power=16.0),
                 Material("wall", (0.45, 0.55, 0.8, 1.0), specular_intensity=0.5, specular_power=4.0),
                 Material("sphere", (0.9, 0.25, 0.2, 1.0), specular_intensity=0.6, specular_power=48.0)]
    if not with_wall:
        materials[1], materials[2] = materials[2], materials[1]
    scene = Scene(np.concatenate(positions), np.concatenate(normals), np.zeros((base, 2), np.float32),
                  np.concatenate(faces), np.concatenate(mats), materials[: len(parts)])
    scene.ambient = AMBIENT
    return scene


CAMERA = Camera.look_at((0.3, 2.0, 3.0), (0.0, 0.8, -3.0), fov_y_deg=55, near=0.1, far=30)


def light_array(records) -> np.ndarray:
    """records: dicts with position, radius, color, and for spots direction/inner/outer (degrees)."""
    out = np.zeros(len(records), structs.light_dtype)
    for i, r in enumerate(records):
        out[i]["position"] = r["position"]
        out[i]["radius"] = r["radius"]
        out[i]["color"] = r["color"]
        if "direction" in r:
            d = np.asarray(r["direction"], np.float64)
            out[i]["type"] = structs.LIGHT_SPOT
            out[i]["direction"] = d / np.linalg.norm(d)
            out[i]["cos_inner"] = np.cos(np.radians(r["inner"]))
            out[i]["cos_outer"] = np.cos(np.radians(r["outer"]))
        else:
            out[i]["type"] = structs.LIGHT_POINT
            out[i]["direction"] = (0, 0, -1)
    return out


def pixel_ray(camera, width, height, px, py):
    """Unit world direction through image point (px, py) (pixel units, not centers)."""
    right, up, back = camera.basis()
    t = np.tan(np.radians(camera.fov_y_deg) / 2)
    x, y = px / width * 2 - 1, 1 - py / height * 2
    d = -back + x * t * (width / height) * right + y * t * up
    return d / np.linalg.norm(d)


def first_hit(origin, direction, with_sphere=True, with_wall=True):
    """Nearest (point, normal) of the room along a ray (analytic), or None."""
    best = None
    cands = []
    if direction[1] < 0:
        t = -origin[1] / direction[1]
        p = origin + t * direction
        if FLOOR_X[0] <= p[0] <= FLOOR_X[1] and FLOOR_Z[0] <= p[2] <= FLOOR_Z[1]:
            cands.append((t, p, np.array([0.0, 1.0, 0.0])))
    if with_wall and direction[2] < 0:
        t = (WALL_Z - origin[2]) / direction[2]
        p = origin + t * direction
        if FLOOR_X[0] <= p[0] <= FLOOR_X[1] and 0 <= p[1] <= WALL_TOP:
            cands.append((t, p, np.array([0.0, 0.0, 1.0])))
    if with_sphere:
        oc = origin - SPHERE_C
        b = oc @ direction
        disc = b * b - (oc @ oc - SPHERE_R ** 2)
        if disc > 0:
            t = -b - np.sqrt(disc)
            if t > 0:
                p = origin + t * direction
                cands.append((t, p, (p - SPHERE_C) / SPHERE_R))
    for c in cands:
        if best is None or c[0] < best[0]:
            best = c
    return None if best is None else (best[1], best[2])


def rim_lights(camera, width, height, eps=0.004, r=3.0) -> list:
    """Lights whose center lies outside a tile's frustum and whose sphere reaches only the nearest
    pixel centers of that tile, by a hair (d = r·(1 - eps) at the first/last pixel column or row
    across a tile border common to 8/16/32-pixel tiles). Their light there is ~1e-7 of their color,
    so only `light_count` (conservative culling) can see them, which is the point: a culler whose
    tile planes are a pixel off, or whose sphere-plane test shrinks r by a few %, misses them."""
    eye = np.asarray(camera.eye, np.float64)
    bx, by = (64 if width > 64 else 32), 32
    recs = []
    # (boundary point, first pixel center across it), both along a row or a column
    cases = [((bx, 20.5), (bx + 0.5, 20.5)), ((bx, 20.5), (bx - 0.5, 20.5)),
             ((bx - 32.5, by), (bx - 32.5, by + 0.5)), ((bx - 32.5, by), (bx - 32.5, by - 0.5))]
    for (bpx, bpy), (qpx, qpy) in cases:
        b = first_hit(eye, pixel_ray(camera, width, height, bpx, bpy))
        q = first_hit(eye, pixel_ray(camera, width, height, qpx, qpy))
        if b is None or q is None or b[1][2] < 0.99 or q[1][2] < 0.99:       # both on the back wall
            continue
        u = (q[0] - b[0]) / np.linalg.norm(q[0] - b[0])
        center = q[0] - r * (1 - eps) * u + 1e-3 * q[1]
        recs.append(dict(position=center, radius=r, color=(0.5, 0.5, 0.5)))
    return recs


def special_lights(camera, width, height) -> list:
    """The hard cases for a tiled culler, most interesting first."""
    eye = np.asarray(camera.eye, np.float64)
    right, up, back = (np.asarray(v) for v in camera.basis())
    fwd = -back
    recs = [
        # the camera inside a light's radius (its sphere contains the eye: every tile plane test passes)
        dict(position=eye + 0.3 * fwd + 0.2 * right, radius=7.0, color=(0.35, 0.3, 0.25)),
    ]
    recs += rim_lights(camera, width, height)
    # lights centered on tile corners common to 8/16/32-pixel tiles, just above the surface
    corners = [(64, 32), (32, 64), (96, 32), (32, 32), (64, 64)]
    for k, (px, py) in enumerate(corners):
        if px >= width or py >= height:
            continue
        hit = first_hit(eye, pixel_ray(camera, width, height, px, py))
        if hit is None:
            continue
        p, n = hit
        if k % 2 == 0:
            recs.append(dict(position=p + 0.08 * n, radius=0.4, color=(2.0, 1.6, 1.0)))
        else:   # a narrow spot aimed at the corner point from 1 unit along the normal
            recs.append(dict(position=p + 1.0 * n, radius=1.6, color=(1.0, 2.0, 1.5),
                             direction=-n, inner=6.0, outer=11.0))
    # grazing a tile's depth range: a light in front of the wall whose radius barely reaches it
    # (by 0.5 %), one behind the wall reaching its front by as little, and one grazing the sphere's front
    r = 2.0
    recs.append(dict(position=(-1.5, 2.5, WALL_Z + 0.995 * r), radius=r, color=(8.0, 4.0, 2.0)))
    recs.append(dict(position=(1.5, 3.0, WALL_Z - 0.995 * r), radius=r, color=(8.0, 4.0, 2.0)))
    to_eye = (eye - SPHERE_C) / np.linalg.norm(eye - SPHERE_C)
    recs.append(dict(position=SPHERE_C + to_eye * (SPHERE_R + 0.995 * 1.0), radius=1.0, color=(6.0, 6.0, 2.0)))
    # behind the camera: one whose sphere reaches into the view (lights the near floor), one that does not
    recs.append(dict(position=eye + 1.0 * back - 0.8 * up, radius=4.0, color=(0.6, 0.7, 1.0)))
    recs.append(dict(position=eye + 2.5 * back, radius=0.8, color=(5.0, 5.0, 5.0)))
    # a flashlight from the eye, a wide spot on the floor, a hard-edged spot (inner == outer)
    recs.append(dict(position=eye, radius=12.0, color=(0.5, 0.5, 0.4), direction=fwd, inner=10.0, outer=18.0))
    recs.append(dict(position=(-2.0, 3.0, -2.0), radius=4.5, color=(1.2, 1.0, 0.8),
                     direction=(0.3, -1.0, -0.2), inner=25.0, outer=45.0))
    recs.append(dict(position=(2.5, 2.0, -5.0), radius=5.0, color=(0.8, 1.2, 0.8),
                     direction=(0.2, -1.0, 0.5), inner=20.0, outer=20.0))
    # just short of the sphere (lights nothing); in the depth gap between the sphere and the wall
    side = SPHERE_C + np.array([1.0, 0.6, 0.3]) / np.linalg.norm([1.0, 0.6, 0.3]) * (SPHERE_R + 0.4 * 1.02)
    recs.append(dict(position=side, radius=0.4, color=(3.0, 3.0, 3.0)))
    recs.append(dict(position=(0.4, 1.0, -5.6), radius=0.45, color=(4.0, 1.0, 1.0)))
    # a spot behind the wall pointing at it (lights its back: nothing visible) and a light under the floor
    recs.append(dict(position=(1.0, 2.0, WALL_Z - 0.5), radius=2.0, color=(3, 3, 3),
                     direction=(0, 0, 1), inner=30, outer=40))
    recs.append(dict(position=(-1.0, -0.3, -2.0), radius=1.0, color=(3, 3, 3)))
    return recs


def random_lights(count, seed) -> list:
    """Points and spots (a quarter, some hard-edged) in a box around the room, the camera and beyond."""
    rng = np.random.default_rng(seed)
    recs = []
    for _ in range(count):
        rec = dict(position=rng.uniform((-5.5, -0.3, -8.0), (5.5, 4.5, 5.0)),
                   radius=float(rng.uniform(0.3, 2.0)), color=rng.uniform(0.05, 1.0, 3))
        if rng.random() < 0.25:
            inner = float(rng.uniform(3.0, 40.0))
            outer = inner if rng.random() < 0.2 else min(inner + float(rng.uniform(1.0, 30.0)), 85.0)
            rec.update(direction=rng.normal(size=3), inner=inner, outer=outer)
        recs.append(rec)
    return recs


def lit_scene(count, width, height, seed=7):
    """The room with exactly `count` lights: the special cases first, then random ones."""
    scene = room_scene()
    recs = special_lights(CAMERA, width, height)[:count]
    recs += random_lights(count - len(recs), seed)
    scene.lights = light_array(recs)
    assert len(scene.lights) == count
    return scene


# -- rendering with a per-session cache (render() is deterministic) -----------------------------

_FRAMES = {}


def render(make_renderer, device, key, scene, camera, width, height, **opts):
    full = (device.id, key, width, height, repr(sorted(opts.items())))
    if full not in _FRAMES:
        _FRAMES[full] = make_renderer(width, height, **opts).render(scene, camera)
    return _FRAMES[full]


BRUTE = dict(light_culling="brute_force", tonemap="reinhard")


def tiled(tile):
    return dict(light_culling="tiled", light_tile_size=tile, tonemap="reinhard")


def cull_opts(tile):
    """tile: a light tile size, or "16+depth-mask" (16-pixel tiles with the 2.5D depth mask)."""
    return tiled(16) | {"light_depth_mask": True} if tile == "16+depth-mask" else tiled(tile)


# Heavy light counts on the smallest image (100×72: partial tiles for every tile size).
CASES = [(0, 160, 120), (1, 160, 120), (17, 160, 120), (1024, 100, 72), (4096, 100, 72)]


def _tile_view(a, tile):
    """(ty, tx) of the value at each tile's first pixel, and whether a is constant per tile."""
    h, w = a.shape[:2]
    firsts = a[::tile, ::tile]
    rep = np.repeat(np.repeat(firsts, tile, 0), tile, 1)[:h, :w]
    return firsts, bool(np.array_equal(rep, a))


# -- pure-NumPy checks of the reference itself ---------------------------------------------------

def test_reference_shading_hand_computed():
    cam = Camera.look_at((0, 0, 0), (0, 0, -1), fov_y_deg=90)
    one = lambda v: np.asarray(v, np.float32).reshape((1, 1) + np.shape(v))
    fields = dict(normal=one([0, 0, 1]), albedo=one([0.5, 0.5, 0.5]), specular_intensity=one(0.5),
                  specular_power=one(8.0), depth=one(2.0), triangle_id=np.zeros((1, 1), np.int32))
    # P = (0, 0, -2); light 1 away at (0, .6, .8) from P: A = (1 - 1/4)^3, N·L = .8, (N·H)^2 = .9
    point = light_array([dict(position=(0, 0.6, -1.2), radius=2.0, color=(1, 1, 1))])
    got = ref.shade(**fields, camera=cam, lights=point, ambient=0.1)
    a = 0.75 ** 3
    expect = 0.5 * (0.1 + a * 0.8) + a * 0.5 * 0.9 ** 4
    np.testing.assert_allclose(got[0, 0], expect, rtol=1e-6)
    # the same light as a spot: dot(-L, (0,-1,0)) = 0.6, t = (0.6 - 0.5)/(0.7 - 0.5) = 0.5, S = 0.25
    spot = point.copy()
    spot["type"], spot["direction"] = structs.LIGHT_SPOT, (0, -1, 0)
    spot["cos_outer"], spot["cos_inner"] = 0.5, 0.7
    got = ref.shade(**fields, camera=cam, lights=spot, ambient=0.1)
    expect = 0.5 * (0.1 + 0.25 * a * 0.8) + 0.25 * a * 0.5 * 0.9 ** 4
    np.testing.assert_allclose(got[0, 0], expect, rtol=1e-6)
    # beyond the radius: ambient only; background: 0
    far = point.copy()
    far["radius"] = 1.0
    np.testing.assert_allclose(ref.shade(**fields, camera=cam, lights=far, ambient=0.1)[0, 0], 0.05)
    fields["triangle_id"] = np.full((1, 1), -1, np.int32)
    assert np.all(ref.shade(**fields, camera=cam, lights=point, ambient=0.1) == 0)


def test_reference_tonemap_curves():
    c = np.array([0.0, 1.0, 3.0])
    np.testing.assert_allclose(ref.tonemap_curve(c, "reinhard"), [0.0, 0.5, 0.75])
    np.testing.assert_allclose(ref.tonemap_curve(c, "reinhard", 2.0), [0.0, 2 / 3, 6 / 7])
    np.testing.assert_allclose(ref.tonemap_curve(c[:2], "aces"), [0.0, 2.54 / 3.16])
    assert ref.tonemap_curve(np.array([100.0]), "aces")[0] == 1.0
    assert ref.tonemap(np.array([1.0]), "reinhard")[0] == 188        # sRGB(0.5) = 0.7354 -> 187.5 -> 188


def test_room_lights_hit_what_they_aim_at():
    """The analytic ray caster that places the special lights agrees with itself (no device)."""
    recs = special_lights(CAMERA, 160, 120)
    assert len(recs) >= 17
    eye = np.asarray(CAMERA.eye)
    assert np.linalg.norm(recs[0]["position"] - eye) < recs[0]["radius"]   # camera inside
    for px, py in [(64, 32), (32, 64), (96, 32)]:
        assert first_hit(eye, pixel_ray(CAMERA, 160, 120, px, py)) is not None
    for w, h in [(160, 120), (100, 72)]:
        assert len(rim_lights(CAMERA, w, h)) == 4, "every rim light lands on the back wall"


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


def sector_bounding_sphere(r, theta_deg):
    """(center distance along the axis, radius) of the smallest sphere around a spot's lit region (a
    spherical sector: distance <= r, angle <= theta): through apex and rim ring below 45 degrees,
    the rim ring's own sphere from 45 on."""
    c = np.cos(np.radians(theta_deg))
    if theta_deg < 45.0:
        return r / (2 * c), r / (2 * c)
    return r * c, r * np.sin(np.radians(theta_deg))


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


# -- shading equals the NumPy reference ----------------------------------------------------------

def reference_scene_lights():
    return light_array([
        dict(position=(0.4, 2.6, -2.6), radius=3.5, color=(1.5, 1.4, 1.2)),           # over the sphere
        dict(position=(-2.0, 0.6, -2.0), radius=3.0, color=(0.4, 0.8, 1.6)),          # low, grazes the floor
        dict(position=(2.0, 1.5, -6.0), radius=3.0, color=(1.2, 0.6, 0.3)),           # near the wall
        dict(position=(-1.0, 3.0, -1.0), radius=6.0, color=(1.0, 1.0, 0.9),           # spot onto the sphere
             direction=SPHERE_C - (-1.0, 3.0, -1.0), inner=10.0, outer=20.0),
        dict(position=(1.8, 2.5, 0.0), radius=5.0, color=(0.9, 1.3, 0.9),             # spot onto the floor
             direction=(-0.2, -1.0, -0.5), inner=15.0, outer=30.0),
        # just behind the wall (N·L < 0 on it, while N·H > 0 with its broad specular): no specular there
        dict(position=(-0.5, 2.0, WALL_Z - 0.3), radius=3.0, color=(1.0, 1.0, 1.0)),
    ])


def test_shading_matches_reference(make_renderer, device):
    w, h = 128, 96
    scene = room_scene()
    scene.lights = reference_scene_lights()
    frame = render(make_renderer, device, "reference", scene, CAMERA, w, h, **tiled(16))
    fg = frame.triangle_id >= 0
    assert fg.mean() > 0.8
    expect, info = ref.shade_frame(frame, CAMERA, scene.lights, AMBIENT, details=True)
    # the reference's depth reading is right: floor pixels reconstruct onto y = 0
    floor = np.isin(frame.triangle_id, np.arange(2 * 16))
    assert floor.sum() > 1000 and np.abs(info["positions"][floor][:, 1]).max() < 1e-3
    assert np.all(frame.color[~fg] == 0), "background must be black"
    # The specular term jumps at N·L = 0 (model), so pixels where some light sits at N·L ~ 0 are ambiguous.
    ok = fg & (info["min_abs_ndotl"] > 1e-4)
    assert ok.sum() > 0.95 * fg.sum()
    assert info["specular"][ok].max() > 0.2, "the scene must exercise the specular term"
    peak = float(expect.max())
    err = np.abs(frame.color.astype(np.float64) - expect)
    err[~ok] = 0
    worst = np.unravel_index(np.argmax(err), err.shape)
    assert err.max() <= SHADING_TOL * peak, (
        f"max |color - reference| {err.max():.4g} at (y, x, c) {worst}: got {frame.color[worst]:.5g}, "
        f"expected {expect[worst]:.5g} (brightest {peak:.4g}); mean error {err[ok].mean():.3g}")


def test_lights_brighten_the_frame(make_renderer, device):
    """A black (or ambient-only) frame must fail, whatever the reference says."""
    w, h = 128, 96
    scene = room_scene()
    scene.lights = reference_scene_lights()
    frame = render(make_renderer, device, "reference", scene, CAMERA, w, h, **tiled(16))
    fg = frame.triangle_id >= 0
    ambient_only = frame.albedo * np.float32(AMBIENT)
    # where the lights are: pixels within half a radius of some light (and facing it) are well lit
    P = ref.world_positions(frame.depth, CAMERA)
    P[~fg] = 0.0
    near = np.zeros(fg.shape, bool)
    for light in scene.lights:
        if light["type"] == structs.LIGHT_POINT:
            lv = light["position"].astype(np.float64) - P
            d = np.linalg.norm(lv, axis=-1)
            facing = (frame.normal * lv).sum(-1) > 0.3 * d
            near |= fg & (d < 0.5 * light["radius"]) & facing
    assert near.sum() > 100
    assert np.all(frame.color[near].sum(-1) > 2 * ambient_only[near].sum(-1))
    assert np.all(frame.color[fg] >= ambient_only[fg] * (1 - 1e-6))
    assert frame.image[fg].mean() > 40 and frame.image[near].min() > 0


# -- attenuation reaches exactly zero at the radius ------------------------------------------------

FLOOR_CAM = Camera.look_at((0.0, 4.0, 2.0), (0.0, 0.0, -2.5), fov_y_deg=60, near=0.1, far=30)


@pytest.mark.parametrize("culling", ["tiled", "brute_force"])
def test_attenuation_is_exactly_zero_beyond_radius(make_renderer, device, culling):
    w, h = 128, 96
    r = 2.0
    scene = room_scene(with_sphere=False, with_wall=False)
    center = np.array([0.3, 0.0, -2.5])
    scene.lights = light_array([dict(position=center + (0, 0.4 * r, 0), radius=r, color=(3.0, 2.5, 2.0))])
    opts = dict(light_culling=culling, tonemap="aces")
    frame = render(make_renderer, device, "disk", scene, FLOOR_CAM, w, h, **opts)
    fg = frame.triangle_id >= 0
    assert fg.mean() > 0.7
    P = ref.world_positions(frame.depth, FLOOR_CAM)
    P[~fg] = np.nan
    d = np.linalg.norm(P - scene.lights["position"][0].astype(np.float64), axis=-1)
    outside, inside = fg & ~(d <= r * (1 + 1e-4)), fg & (d < 0.9 * r)
    assert outside.sum() > 1000 and inside.sum() > 500
    ambient_only = frame.albedo * np.float32(AMBIENT)
    bad = outside & (frame.color != ambient_only).any(-1)
    assert not bad.any(), (f"{int(bad.sum())} pixels beyond the radius are lit, e.g. d/r = "
                           f"{(d[bad] / r).min():.6f}: color {frame.color[bad][0]} vs ambient·albedo "
                           f"{ambient_only[bad][0]}")
    assert np.all(frame.color[inside] > ambient_only[inside])
    # a light r (+ a little) above the floor reaches nothing at all
    scene.lights = light_array([dict(position=center + (0, r * 1.001, 0), radius=r, color=(50.0, 50.0, 50.0))])
    frame = make_renderer(w, h, **opts).render(scene, FLOOR_CAM)
    expect = frame.albedo * np.float32(AMBIENT)
    expect[~fg] = 0
    assert np.array_equal(frame.color, expect)


@pytest.mark.parametrize("culling", ["tiled", "brute_force"])
def test_no_lights_is_ambient_times_albedo(make_renderer, device, culling):
    w, h = 96, 64
    scene = room_scene()
    assert len(scene.lights) == 0
    frame = make_renderer(w, h, light_culling=culling, tonemap="reinhard").render(scene, CAMERA)
    fg = frame.triangle_id >= 0
    assert fg.mean() > 0.8
    expect = frame.albedo * np.float32(AMBIENT)
    expect[~fg] = 0
    assert np.array_equal(frame.color, expect)
    assert np.all(frame.light_count == 0)
    assert frame.stats["lights"] == 0


# -- tone mapping -------------------------------------------------------------------------------

@pytest.mark.parametrize("operator,exposure", [("reinhard", 1.0), ("reinhard", 0.6), ("aces", 1.0),
                                               ("aces", 1.7)])
def test_tonemap_matches_reference(make_renderer, device, operator, exposure):
    w, h = 128, 96
    scene = room_scene()
    lights = reference_scene_lights()
    lights["color"] *= 3.0                          # HDR: plenty of pixels above 1
    scene.lights = lights
    frame = render(make_renderer, device, "hdr", scene, CAMERA, w, h,
                   light_culling="tiled", tonemap=operator, exposure=exposure)
    assert frame.image.shape == (h, w, 3) and frame.image.dtype == np.uint8
    assert (frame.color > 1).any(-1).mean() > 0.05, "the frame must have HDR values to map"
    expect = ref.tonemap(frame.color, operator, exposure)
    diff = np.abs(frame.image.astype(int) - expect.astype(int))
    worst = np.unravel_index(np.argmax(diff), diff.shape)
    assert diff.max() <= 1, (f"{operator} exposure {exposure}: image off by {diff.max()} codes at {worst} "
                             f"(color {frame.color[worst]:.5g}: got {frame.image[worst]}, expected {expect[worst]})")
    # ±1 only where float32 rounding lands on the other side of a code boundary: rare
    assert (diff == 0).mean() > 0.99, f"{operator} exposure {exposure}: {(diff != 0).mean():.1%} of codes differ"
    assert len(np.unique(frame.image)) > 100
    # exposure and operator act on the image only: color is the same linear HDR radiance
    base = render(make_renderer, device, "hdr", scene, CAMERA, w, h,
                  light_culling="tiled", tonemap="reinhard", exposure=1.0)
    np.testing.assert_array_equal(frame.color, base.color)
    if (operator, exposure) != ("reinhard", 1.0):
        assert (frame.image != base.image).mean() > 0.3, "the tone map settings must change the image"


def test_unknown_options_are_rejected(device):
    with pytest.raises(ValueError, match="filmic"):
        clrender.Renderer(16, 16, device=device.id, tonemap="filmic")
    with pytest.raises(ValueError, match="clustered"):
        clrender.Renderer(16, 16, device=device.id, light_culling="clustered")
