"""glTF animation (clrender/scene/animation.py): node TRS channels sampled per the glTF 2.0 spec
(Appendix C) at hand-computed times, the world matrices of nested nodes, posing meshes / camera /
lights, the Khronos sample files, and renders of a posed scene (depth against a scene built from
the transformed vertices, velocity against the analytic reprojection)."""
from __future__ import annotations

import warnings

import numpy as np
import pytest

from clrender.errors import SceneError

from gltf_files import primitive, write_gltf
from helpers import shared_file

from clrender import Camera, Scene, load_scene
from clrender.scene.animation import Sampler, slerp, trs_matrix

S45 = np.sqrt(0.5)

# A unit cube centred at the origin, 8 shared vertices, outward counter-clockwise faces.
CUBE_POSITIONS = np.array([[x, y, z] for x in (-.5, .5) for y in (-.5, .5) for z in (-.5, .5)], np.float32)
CUBE_INDICES = np.array([0, 1, 3, 0, 3, 2, 4, 6, 7, 4, 7, 5, 0, 4, 5, 0, 5, 1, 2, 3, 7, 2, 7, 6,
                         0, 2, 6, 0, 6, 4, 1, 5, 7, 1, 7, 3], np.uint16)


def cube() -> dict:
    return primitive(CUBE_POSITIONS, CUBE_INDICES, normals=None, uvs=None)


def anim(node: int, path: str, times, values, interpolation: str = "LINEAR") -> dict:
    return {"channels": [{"sampler": 0, "target": {"node": node, "path": path}}],
            "samplers": [{"input": np.float32(times), "output": np.float32(values), "interpolation": interpolation}]}


def load_animated(tmp_path, animations, nodes=None, primitives=None, **kw) -> Scene:
    path = write_gltf(tmp_path / "anim.gltf", primitives or [cube()], nodes=nodes, animations=animations, **kw)
    with warnings.catch_warnings():
        warnings.simplefilter("error")          # an animated file of supported channels loads silently
        scene = load_scene(path)
    assert scene.animation is not None
    return scene


def translation_at(scene, t, node=0):
    return scene.animation.node_matrix(node, t)[:3, 3]


# -- interpolation -------------------------------------------------------------------------------------
def test_linear_translation_and_clamping(tmp_path):
    scene = load_animated(tmp_path, [anim(0, "translation", [0, 1, 2], [[0, 0, 0], [1, 2, 3], [1, 0, 0]])])
    assert scene.animation.duration == 2.0
    for t, expect in ((0.25, [0.25, 0.5, 0.75]), (1.0, [1, 2, 3]), (1.5, [1, 1, 1.5]),
                      (-1.0, [0, 0, 0]), (0.0, [0, 0, 0]), (2.0, [1, 0, 0]), (7.0, [1, 0, 0])):
        np.testing.assert_allclose(translation_at(scene, t), expect, atol=1e-6, err_msg=f"t={t}")


def test_step_holds_each_key_until_the_next(tmp_path):
    scene = load_animated(tmp_path, [anim(0, "scale", [1, 2, 3], [[1, 1, 1], [2, 3, 4], [5, 5, 5]], "STEP")])
    for t, expect in ((0.0, 1), (1.999, 1), (2.0, [2, 3, 4]), (2.5, [2, 3, 4]), (3.0, 5), (9.0, 5)):
        m = scene.animation.node_matrix(0, t)
        np.testing.assert_allclose(np.diag(m)[:3], np.broadcast_to(expect, 3), atol=1e-6, err_msg=f"t={t}")


def spec_slerp(q0, q1, t):
    """glTF 2.0 Appendix C, verbatim."""
    d = np.dot(q0, q1)
    a = np.arccos(abs(d))
    s = d / abs(d)
    return np.sin(a * (1 - t)) / np.sin(a) * q0 + s * np.sin(a * t) / np.sin(a) * q1


def test_slerp_matches_the_spec_formula():
    rng = np.random.default_rng(3)
    for _ in range(20):
        q0, q1 = (q / np.linalg.norm(q) for q in rng.normal(size=(2, 4)))
        for t in (0.0, 0.3, 0.5, 0.9, 1.0):
            np.testing.assert_allclose(slerp(q0, q1, t), spec_slerp(q0, q1, t), atol=1e-12)


@pytest.mark.parametrize("negate", [False, True])
def test_linear_rotation_is_the_shortest_slerp(tmp_path, negate):
    """0 -> 90 degrees about z; the second key negated (the same rotation) gives the same path."""
    q1 = np.array([0, 0, S45, S45]) * (-1 if negate else 1)
    scene = load_animated(tmp_path, [anim(0, "rotation", [0, 2], [[0, 0, 0, 1], q1])])
    for t, deg in ((0.5, 22.5), (1.0, 45.0), (1.5, 67.5), (3.0, 90.0)):
        c, s = np.cos(np.radians(deg)), np.sin(np.radians(deg))
        np.testing.assert_allclose(scene.animation.node_matrix(0, t)[:3, :3], [[c, -s, 0], [s, c, 0], [0, 0, 1]],
                                   atol=1e-6, err_msg=f"t={t}")


def test_cubicspline_with_known_tangents(tmp_path):
    """Keys at t = 0 and 2 (td = 2): x from 0 to 1 with out-tangent 1 (m0 = 2), y from 0 to 1
    with in-tangent 4 (m1 = 8), z constant 2. Hermite basis at u = 1/2: h00 = 1/2, h10 = 1/8,
    h01 = 1/2, h11 = -1/8; at u = 1/4: h00 = 0.84375, h10 = 0.140625, h01 = 0.15625, h11 = -0.046875."""
    values = [[9, 9, 9], [0, 0, 2], [1, 0, 0],       # key 0: in-tangent (unused), value, out-tangent
              [0, 4, 0], [1, 1, 2], [9, 9, 9]]       # key 1: in-tangent, value, out-tangent (unused)
    scene = load_animated(tmp_path, [anim(0, "translation", [0, 2], values, "CUBICSPLINE")])
    for t, expect in ((1.0, [0.125 * 2 + 0.5, 0.5 - 0.125 * 8, 2]),          # 0.75, -0.5, 2
                      (0.5, [0.140625 * 2 + 0.15625, 0.15625 - 0.046875 * 8, 2]),   # 0.4375, -0.21875
                      (-1.0, [0, 0, 2]), (2.0, [1, 1, 2]), (5.0, [1, 1, 2])):
        np.testing.assert_allclose(translation_at(scene, t), expect, atol=1e-6, err_msg=f"t={t}")


def test_cubicspline_rotation_is_normalized():
    """Hermite of two unit quaternions with zero tangents is not unit at u = 1/2: the result is."""
    q0, q1 = np.array([0, 0, 0, 1.0]), np.array([0, 0, 1.0, 0])
    z = np.zeros(4)
    s = Sampler(np.array([0.0, 1.0]), np.array([z, q0, z, z, q1, z]), "CUBICSPLINE")
    q = s.sample(0.5, rotation=True)
    np.testing.assert_allclose(q, [0, 0, S45, S45], atol=1e-12)


# -- hierarchy and posing ---------------------------------------------------------------------------------
def quad_nodes():
    """Node 0: animated parent (translation 0 -> (0, 2, 0), rotation 0 -> 90 degrees about z over
    t in [0, 1]); node 1: its static child at (1, 0, 0) holding the unit quad."""
    nodes = [{"children": [1]}, {"mesh": 0, "translation": [1, 0, 0]}]
    anims = [{"channels": [{"sampler": 0, "target": {"node": 0, "path": "translation"}},
                           {"sampler": 1, "target": {"node": 0, "path": "rotation"}}],
              "samplers": [{"input": np.float32([0, 1]), "output": np.float32([[0, 0, 0], [0, 2, 0]])},
                           {"input": np.float32([0, 1]), "output": np.float32([[0, 0, 0, 1], [0, 0, S45, S45]])}]}]
    return nodes, anims


def test_nested_nodes_world_matrix_and_posed_vertices(tmp_path):
    nodes, anims = quad_nodes()
    scene = load_animated(tmp_path, anims, nodes=nodes, primitives=[primitive()])
    np.testing.assert_allclose(scene.positions[:, :2], [[1, 0], [2, 0], [2, 1], [1, 1]], atol=1e-6)  # rest
    expect_world = np.array([[0, -1, 0, 0], [1, 0, 0, 3], [0, 0, 1, 0], [0, 0, 0, 1]])  # T(0,2,0) Rz90 T(1,0,0)
    np.testing.assert_allclose(scene.animation.node_matrix(1, 1.0), expect_world, atol=1e-6)
    np.testing.assert_allclose(scene.animation.node_matrix(1, 0.5),
                               trs_matrix([0, 1, 0], [0, 0, np.sin(np.pi / 8), np.cos(np.pi / 8)]) @
                               trs_matrix([1, 0, 0]), atol=1e-6)
    assert scene.pose(1.0) is None
    # quad corners (0,0), (1,0), (1,1), (0,1) -> child (x+1, y) -> Rz90 (-y, x+1) -> + (0, 2)
    np.testing.assert_allclose(scene.positions, [[0, 3, 0], [0, 4, 0], [-1, 4, 0], [-1, 3, 0]], atol=1e-6)
    np.testing.assert_allclose(scene.normals, np.tile([0, 0, 1], (4, 1)), atol=1e-6)
    assert scene.previous_positions is None                 # no dt: no motion
    scene.pose(0.0)                                         # posing is absolute: back to rest
    np.testing.assert_allclose(scene.positions[:, :2], [[1, 0], [2, 0], [2, 1], [1, 1]], atol=1e-6)
    scene.pose(1.0, dt=0.5)                                 # previous = the pose at 0.5
    prev = (scene.animation.node_matrix(1, 0.5) @ np.c_[[[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]],
                                                        np.ones(4)].T).T[:, :3]
    np.testing.assert_allclose(scene.previous_positions, prev, atol=1e-6)


def test_camera_and_lights_follow_their_nodes(tmp_path):
    nodes = [{"mesh": 0, "translation": [0, 0, -5]},
             {"camera": 0},
             {"extensions": {"KHR_lights_punctual": {"light": 0}}},
             {"extensions": {"KHR_lights_punctual": {"light": 1}}, "rotation": [-S45, 0, 0, S45]}]
    anims = [anim(1, "translation", [0, 1], [[0, 0, 0], [2, 0, 0]]),
             anim(2, "translation", [0, 1], [[0, 1, 0], [0, 3, 0]]),
             anim(3, "rotation", [0, 1], [[-S45, 0, 0, S45], [0, 0, 0, 1]])]
    lights = {"lights": [{"type": "point", "range": 5}, {"type": "spot", "range": 5}]}
    scene = load_animated(tmp_path, anims, nodes=nodes, primitives=[primitive()],
                          cameras=[{"type": "perspective", "perspective": {"yfov": 0.8, "znear": 0.1, "zfar": 50}}],
                          extensionsUsed=["KHR_lights_punctual"], extensions={"KHR_lights_punctual": lights})
    np.testing.assert_allclose(scene.lights["direction"][1], [0, -1, 0], atol=1e-6)      # rest: -Z turned down
    previous = scene.pose(0.5, dt=0.25)
    np.testing.assert_allclose(scene.camera.eye, [1, 0, 0], atol=1e-6)
    np.testing.assert_allclose(np.subtract(scene.camera.target, scene.camera.eye), [0, 0, -1], atol=1e-6)
    assert scene.camera.fov_y_deg == pytest.approx(np.degrees(0.8)) and scene.camera.far == 50
    np.testing.assert_allclose(previous.eye, [0.5, 0, 0], atol=1e-6)
    np.testing.assert_allclose(scene.lights["position"][0], [0, 2, 0], atol=1e-6)
    np.testing.assert_allclose(scene.lights["direction"][1], [0, -S45, -S45], atol=1e-6)   # 45 degrees down


def test_weight_channels_need_morph_targets(tmp_path):
    """A `weights` channel on a node whose mesh has no morph targets: a SceneError naming the node
    (clrender.scene.deform poses real ones: tests/test_skinning.py)."""
    weights = {"channels": [{"sampler": 0, "target": {"node": 0, "path": "weights"}}],
               "samplers": [{"input": np.float32([0, 1]), "output": np.float32([0, 1])}]}
    path = write_gltf(tmp_path / "w.gltf", animations=[weights])
    with pytest.raises(SceneError, match="node 0, whose mesh has no morph targets"):
        load_scene(path)


def test_static_files_have_no_animation(tmp_path):
    scene = load_scene(write_gltf(tmp_path / "s.gltf"))
    assert scene.animation is None and scene.pose(1.0) is None


@pytest.mark.parametrize("rel", ["khronos-AnimatedCube/AnimatedCube.gltf", "khronos-BoxAnimated/BoxAnimated.gltf",
                                 "khronos-InterpolationTest/InterpolationTest.gltf"])
def test_khronos_samples_load_and_pose(rel):
    scene = load_scene(shared_file(rel))
    assert scene.animation is not None and scene.animation.duration > 0 and scene.animation.meshes
    rest = scene.positions.copy()
    for t in np.linspace(-0.5, scene.animation.duration + 0.5, 9):
        scene.pose(t, dt=1 / 24)
        assert np.isfinite(scene.positions).all() and np.isfinite(scene.normals).all()
    scene.pose(scene.animation.duration / 3)
    assert not np.allclose(scene.positions, rest, atol=1e-4), "the animation must move something"


def test_animated_cube_rotation_matches_the_spec_slerp():
    """AnimatedCube: one LINEAR rotation channel; the node's matrix at 0.3 s is the spec's slerp of its keys."""
    import json
    path = shared_file("khronos-AnimatedCube/AnimatedCube.gltf")
    scene = load_scene(path)
    ch = scene.animation.channels[0]
    times, values = ch.sampler.times, ch.sampler.values
    k = int(np.searchsorted(times, 0.3, side="right")) - 1
    q = spec_slerp(values[k], values[k + 1], (0.3 - times[k]) / (times[k + 1] - times[k]))
    np.testing.assert_allclose(scene.animation.node_matrix(ch.node, 0.3), trs_matrix(rotation=q), atol=1e-9)
    assert json.loads(path.read_text())["animations"][0]["samplers"][0].get("interpolation", "LINEAR") == "LINEAR"


# -- renders ---------------------------------------------------------------------------------------------
def test_posed_cube_depth_matches_a_scene_of_transformed_vertices(tmp_path, make_renderer):
    anims = [{"channels": [{"sampler": 0, "target": {"node": 0, "path": "translation"}},
                           {"sampler": 1, "target": {"node": 0, "path": "rotation"}}],
              "samplers": [{"input": np.float32([0, 1]), "output": np.float32([[0, 0, 0], [0.6, 0.2, -0.5]])},
                           {"input": np.float32([0, 1]),
                            "output": np.float32([[0, 0, 0, 1], [0.3, 0.5, 0.2, 0.78]])}]}]
    nodes = [{"mesh": 0, "translation": [0.1, 0, 0], "scale": [1, 1.2, 1]}]
    scene = load_animated(tmp_path, anims, nodes=nodes)
    camera = Camera.look_at((0.5, 1.2, 3.0), (0, 0, 0), fov_y_deg=45, near=0.1, far=20)
    t = 0.7
    scene.pose(t)
    q1 = np.array([0.3, 0.5, 0.2, 0.78], np.float32).astype(np.float64)
    q = spec_slerp(np.array([0, 0, 0, 1.0]), q1 / np.linalg.norm(q1), t)
    world = trs_matrix(t * np.float32([0.6, 0.2, -0.5]).astype(np.float64), q, [1, 1.2, 1])
    expected = CUBE_POSITIONS.astype(np.float64) @ world[:3, :3].T + world[:3, 3]
    direct = Scene.from_arrays(expected, CUBE_INDICES.reshape(-1, 3).astype(np.int64))
    renderer = make_renderer(64, 48)
    got, want = renderer.render(scene, camera).depth, renderer.render(direct, camera).depth
    covered = np.isfinite(want)
    assert covered.sum() > 300
    agree = np.isclose(got, want, rtol=1e-6, atol=0)
    assert agree[covered].all(), np.abs(got - want)[covered].max()


def test_translating_quad_velocity_is_the_analytic_reprojection(tmp_path, make_renderer):
    """A camera-facing quad moving +x at 1 unit/s: posed at t with dt, the velocity AOV is the
    pixel displacement of its motion over dt (constant over the quad: it stays at one depth)."""
    W, H, dt = 64, 48, 0.25
    quad = primitive(np.float32([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]]))
    scene = load_animated(tmp_path, [anim(0, "translation", [0, 2], [[-0.5, 0, -4], [1.5, 0, -4]])],
                          primitives=[quad])
    camera = Camera.look_at((0, 0, 0), (0, 0, -1), fov_y_deg=50, near=0.1, far=20)
    previous = scene.pose(0.8, dt=dt)
    assert previous is None or previous == scene.camera
    frame = make_renderer(W, H).render(scene, camera)

    def pixel(p):
        clip = camera.view_projection(W, H) @ np.append(p, 1.0)
        ndc = clip[:2] / clip[3]
        return np.array([(ndc[0] + 1) / 2 * W, (1 - ndc[1]) / 2 * H])

    now = np.array([0.3, 0.0, -4.0])
    expect = pixel(now) - pixel(now - [dt, 0, 0])
    assert 2 < expect[0] < 6 and abs(expect[1]) < 1e-9
    mask = frame.triangle_id >= 0
    interior = mask.copy()
    for axis in (0, 1):
        for shift in (-1, 1):
            interior &= np.roll(mask, shift, axis)
    assert interior.sum() > 200
    err = np.abs(frame.velocity[interior] - expect)
    assert err.max() < 0.05, err.max()
