"""Picking (clrender.viewer.pick): what a rendered frame shows under a pixel.

Truth: the test writes the glTF (two boxes under a group, a floor, a BLEND pane in front) and keeps
its own table of every world-space triangle in load order (traversal order, primitives, faces) with
the names it gave it; each picked pixel's camera ray through the pixel centre is cast against every
triangle in float64 (Möller–Trumbore). The nearest hit gives the triangle and its names; the nearest
opaque hit gives the position and z-depth (the G-buffer's surface: a BLEND fragment has no depth of
its own). Pixels are drawn (fixed seed) where the reference's answer is the same over the 3x3
neighbourhood, away from edges, where the rasterizer and the ray agree on the triangle.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from clrender import Camera
from clrender.loaders import load_scene
from clrender.viewer.pick import OUTLINE, TINT, Pick, highlight, pick, pick_markdown
from gltf_files import primitive, write_gltf
from test_scene_cameras import quat, trs

W, H = 64, 48
EYE, TARGET, FOV = (0.0, 1.5, 6.0), (0.0, 0.0, 0.0), 45.0
CAMERA = Camera.look_at(EYE, TARGET, (0, 1, 0), FOV, near=0.5, far=20.0)
# The rasterizer snaps vertices to 1/256 pixel (docs/raster_contract.md §3), about 4e-4 world units at
# depth 6 here, and interpolates depth in float32: measured 1.6e-4 (position) and 2.4e-5 (relative
# depth) at most on PoCL. The tolerances leave some room and still catch a 2e-4 relative error.
SCENE_SIZE = 8.0                            # about the scene's diagonal
POSITION_TOL = 5e-5 * SCENE_SIZE
DEPTH_RTOL = 1e-4


def box(half: float):
    """24 vertices (4 per side, outward normals), 12 counter-clockwise triangles, sides in the
    order +X, -X, +Y, -Y, +Z, -Z."""
    pos, nrm, idx = [], [], []
    for axis in range(3):
        for sign in (1.0, -1.0):
            n = np.zeros(3)
            n[axis] = sign
            u, v = np.roll(np.eye(3), 1, 0)[axis], np.roll(np.eye(3), 2, 0)[axis]     # u x v = +axis
            if sign < 0:
                u, v = v, u
            c = n * half
            base = len(pos)
            pos += [c + half * (a * u + b * v) for a, b in ((-1, -1), (1, -1), (1, 1), (-1, 1))]
            nrm += [n] * 4
            idx += [[base, base + 1, base + 2], [base, base + 2, base + 3]]
    return np.array(pos, np.float32), np.array(nrm, np.float32), np.array(idx, np.uint32)


def quad(corners):
    pos = np.array(corners, np.float32)
    n = np.cross(pos[1] - pos[0], pos[2] - pos[0])
    return pos, np.tile((n / np.linalg.norm(n)).astype(np.float32), (4, 1)), np.array([[0, 1, 2], [0, 2, 3]],
                                                                                      np.uint32)


MATERIALS = [{"name": n, "doubleSided": True, "pbrMetallicRoughness": {"baseColorFactor": c}}
             for n, c in (("red", [0.8, 0.1, 0.1, 1]), ("green", [0.1, 0.8, 0.1, 1]), ("blue", [0.1, 0.1, 0.8, 1]),
                          ("floor_grey", [0.5, 0.5, 0.5, 1]), ("glass*pane", [0.6, 0.8, 1.0, 0.4]))]
MATERIALS[4]["alphaMode"] = "BLEND"
BOX = box(0.6)
FLOOR = quad([(-3, -0.8, 2.5), (3, -0.8, 2.5), (3, -0.8, -2.5), (-3, -0.8, -2.5)])
PANE = quad([(0, 0, 0), (1.4, 0, 0), (1.4, 1.2, 0), (0, 1.2, 0)])
# node name, path, world matrix, [(mesh name, (positions, normals, faces), material)] per primitive;
# the file's traversal order: Group (no mesh), BoxA, BoxB, Floor, Pane
DRAWN = [
    ("BoxA", "Group/BoxA", trs((-1.2, 0.0, 0.0)), [("BoxA/mesh0", BOX, 0)]),
    ("BoxB", "Group/BoxB", trs((1.2, 0.2, -0.5), quat((0, 1, 0), 30)),
     [("BoxB/mesh1/0", (BOX[0], BOX[1], BOX[2][:6]), 1), ("BoxB/mesh1/1", (BOX[0], BOX[1], BOX[2][6:]), 2)]),
    ("Floor", "Floor", np.eye(4), [("Floor/mesh2", FLOOR, 3)]),
    ("Pane", "Pane", trs((-1.6, 0.1, 1.2)), [("Pane/mesh3", PANE, 4)]),
]


def write_scene(path):
    meshes = [[primitive(p, f, material=m, normals=n, uvs=None) for _, (p, n, f), m in prims]
              for _, _, _, prims in DRAWN]
    nodes = [{"name": "Group", "children": [1, 2]},
             {"name": "BoxA", "mesh": 0, "translation": [-1.2, 0.0, 0.0]},
             {"name": "BoxB", "mesh": 1, "translation": [1.2, 0.2, -0.5], "rotation": quat((0, 1, 0), 30)},
             {"name": "Floor", "mesh": 2},
             {"name": "Pane", "mesh": 3, "translation": [-1.6, 0.1, 1.2]}]
    return write_gltf(path, meshes=meshes, nodes=nodes, materials=MATERIALS)


def reference_table():
    """World-space triangles (T, 3, 3) float64 in load order and, per triangle, (object index,
    object name, path, material index, mesh name, face)."""
    tris, rows = [], []
    for k, (name, path, m, prims) in enumerate(DRAWN):
        for mesh, (pos, _, faces), mat in prims:
            world = pos.astype(np.float64) @ m[:3, :3].T + m[:3, 3]
            tris.append(world[faces.astype(np.int64)])
            rows += [(k, name, path, mat, mesh, f) for f in range(len(faces))]
    return np.concatenate(tris), rows


def pixel_rays():
    """(H, W, 3) ray directions through the pixel centres, scaled so that the component along the
    optical axis is 1 (the ray parameter is then the z-depth)."""
    eye, target = np.array(EYE), np.array(TARGET)
    f = (target - eye) / np.linalg.norm(target - eye)
    r = np.cross(f, [0.0, 1.0, 0.0])
    r /= np.linalg.norm(r)
    u = np.cross(r, f)
    ty = math.tan(math.radians(FOV) / 2)
    tx = ty * W / H
    x = ((np.arange(W) + 0.5) / W * 2 - 1) * tx
    y = (1 - (np.arange(H) + 0.5) / H * 2) * ty
    return f + x[None, :, None] * r + y[:, None, None] * u


def ray_hits(directions, tris):
    """Möller–Trumbore, float64, both faces: (N, T) ray parameter, inf where the ray misses."""
    o = np.array(EYE)
    e1, e2 = tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]
    p = np.cross(directions[:, None, :], e2[None])
    det = np.einsum("ntk,tk->nt", p, e1)
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / det
        s = o - tris[:, 0]
        u = np.einsum("ntk,tk->nt", p, s) * inv
        q = np.cross(s, e1)
        v = np.einsum("nk,tk->nt", directions, q) * inv
        t = np.einsum("tk,tk->t", e2, q)[None] * inv
    hit = (np.abs(det) > 1e-12) & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 0)
    return np.where(hit, t, np.inf)


@pytest.fixture(scope="module")
def picked(tmp_path_factory, make_renderer):
    scene = load_scene(write_scene(tmp_path_factory.mktemp("pick") / "pick.gltf"), default_environment=False)
    frame = make_renderer(W, H).render(scene, CAMERA)
    tris, rows = reference_table()
    dirs = pixel_rays().reshape(-1, 3)
    t = ray_hits(dirs, tris)
    opaque = np.array([MATERIALS[r[3]].get("alphaMode") != "BLEND" for r in rows])
    nearest = np.where(np.isfinite(t.min(1)), t.argmin(1), -1).reshape(H, W)
    t_opaque = np.where(opaque[None], t, np.inf)
    behind = np.where(np.isfinite(t_opaque.min(1)), t_opaque.argmin(1), -1).reshape(H, W)
    return scene, frame, tris, rows, dirs.reshape(H, W, 3), nearest, behind, t_opaque.min(1).reshape(H, W)


def interior(ids: np.ndarray) -> np.ndarray:
    """Pixels (not on the border) whose 3x3 neighbourhood has their id."""
    ok = np.zeros(ids.shape, bool)
    ok[1:-1, 1:-1] = True
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            ok[1:-1, 1:-1] &= ids[1 + dy:H - 1 + dy, 1 + dx:W - 1 + dx] == ids[1:-1, 1:-1]
    return ok


def test_scene_is_the_reference_table(picked):
    scene, _, tris, rows, *_ = picked
    np.testing.assert_allclose(scene.positions[scene.triangles], tris, rtol=0, atol=1e-6)
    assert [o.name for o in scene.objects] == [d[0] for d in DRAWN]


def test_pick_matches_the_ray_cast_reference(picked):
    scene, frame, tris, rows, dirs, nearest, behind, depth = picked
    ok = interior(nearest) & interior(behind)
    transparent_ref = (nearest >= 0) & (nearest != behind)
    # one group per (object or background, transparent): each must be present, up to 8 pixels from each
    key = np.where(nearest >= 0, np.array([r[0] for r in rows])[np.maximum(nearest, 0)], -1) * 2 + transparent_ref
    key = np.where(transparent_ref & (behind < 0), 100, key)    # the pane over the background
    rng = np.random.default_rng(39)
    groups = {}
    for k in np.unique(key[ok]):
        ys, xs = np.nonzero(ok & (key == k))
        chosen = rng.choice(len(ys), min(8, len(ys)), replace=False)
        groups[int(k)] = list(zip(ys[chosen].tolist(), xs[chosen].tolist()))
    # background, BoxA, BoxB, Floor, Pane over BoxA, over the floor or background
    assert {-2, 0, 2, 4, 7, 100} <= set(groups), sorted(groups)
    for y, x in (yx for g in groups.values() for yx in g):
        p = pick(frame, scene, x, y)
        tri = int(nearest[y, x])
        if tri < 0:
            assert p is None, (x, y)
            continue
        k, name, path, mat, mesh, face = rows[tri]
        assert (p.x, p.y, p.triangle, p.object_id, p.object_name, p.object_path) == (x, y, tri, k, name, path)
        assert (p.material_id, p.material_name, p.mesh, p.face) == (
            scene.materials.index(next(m for m in scene.materials if m.name == MATERIALS[mat]["name"])),
            MATERIALS[mat]["name"], mesh, face)
        assert p.transparent == bool(transparent_ref[y, x]) == (MATERIALS[mat].get("alphaMode") == "BLEND")
        if behind[y, x] < 0:                 # a BLEND pane over the background: no depth behind it
            assert math.isinf(p.depth) and np.isnan(p.position).all()
            continue
        z = depth[y, x]
        assert p.depth == pytest.approx(z, rel=DEPTH_RTOL), (x, y)
        np.testing.assert_allclose(p.position, np.array(EYE) + z * dirs[y, x], rtol=0, atol=POSITION_TOL,
                                   err_msg=f"pixel {(x, y)}")
        assert isinstance(p.depth, float) and all(isinstance(v, float) for v in p.position)


def test_pick_outside_the_frame_and_markdown(picked):
    scene, frame, *_ = picked
    for x, y in ((-1, 0), (W, 0), (0, H), (3, -2)):
        with pytest.raises(ValueError, match=rf"pixel \({x}, {y}\) is outside the {W}x{H} frame"):
            pick(frame, scene, x, y)
    with pytest.raises(ValueError, match="integer pixel index"):
        pick(frame, scene, 1.5, 2)
    assert pick_markdown(None) == "background"
    p = Pick(3, 4, 1, "Box_B", "Group/Box_B", 4, "glass*pane", "Box_B/mesh1/0", 17, 5, (1.0, -2.5, 0.125), 6.5,
             True)
    text = pick_markdown(p)
    for part in (r"**Box\_B** (object 1) at pixel (3, 4)", r"path: Group/Box\_B", r"material: glass\*pane (material 4)",
                 r"mesh: Box\_B/mesh1/0, face 5 (triangle 17)", "position: (1, -2.5, 0.125)", "depth: 6.5",
                 "transparent"):
        assert part in text, (part, text)
    over_background = pick_markdown(Pick(0, 0, 0, "a", "a", 0, "m", "a/m", 0, 0, (math.nan,) * 3, math.inf, True))
    assert "background behind the transparent surface" in over_background and "- depth:" not in over_background


def test_highlight_tints_inside_and_outlines_outside():
    rng = np.random.default_rng(7)
    image = rng.integers(0, 256, (5, 6, 3), dtype=np.uint8)
    before = image.copy()
    mask = np.zeros((5, 6), bool)
    mask[1:3, 1:3] = True          # a 2x2 block
    mask[4, 5] = True              # a corner pixel: its ring stops at the border
    out = highlight(image, mask)
    assert out.dtype == np.uint8 and out.shape == image.shape and out is not image
    np.testing.assert_array_equal(image, before)
    ring = {(y, x) for y in range(0, 4) for x in range(0, 4)} - {(1, 1), (1, 2), (2, 1), (2, 2)}
    ring |= {(3, 4), (3, 5), (4, 4)}
    for y in range(5):
        for x in range(6):
            if mask[y, x]:
                want = (image[y, x].astype(int) + np.array(TINT)) // 2
            elif (y, x) in ring:
                want = np.array(OUTLINE)
            else:
                want = image[y, x]
            np.testing.assert_array_equal(out[y, x], want, err_msg=str((y, x)))
    np.testing.assert_array_equal(highlight(image, np.zeros((5, 6), bool)), image)
    with pytest.raises(ValueError, match="mask must be"):
        highlight(image, np.zeros((5, 5), bool))
    with pytest.raises(ValueError, match="image must be"):
        highlight(image.astype(np.float32), mask)
