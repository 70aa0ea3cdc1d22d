"""The lit test room shared by the lighting tests (test_lighting.py, test_light_culling.py,
test_light_accumulation.py, test_orthographic.py, test_opencv_camera.py, test_variants.py): its
geometry and analytic ray caster, hard-case and random lights, a per-session frame cache and the
culling options."""
import numpy as np

from clrender import Camera, Material, Scene
from clrender.abi import structs
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


def sector_bounding_sphere(r, theta_deg):
    """(center distance along the axis, radius) of the smallest sphere around a spot's lit region (a
    spherical sector: distance <= r, angle <= theta): through apex and rim ring below 45 degrees,
    the rim ring's own sphere from 45 on."""
    c = np.cos(np.radians(theta_deg))
    if theta_deg < 45.0:
        return r / (2 * c), r / (2 * c)
    return r * c, r * np.sin(np.radians(theta_deg))


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

