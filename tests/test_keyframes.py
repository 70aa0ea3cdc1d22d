"""TOML keyframe animation (clrender/scene/keyframes.py): camera keys, the camera orbit and light keys
against hand-computed values, absolute posing, the errors, and renders of a posed scene (depth
bit-identical to the same camera placed directly; velocity of a moving and of a fixed camera)."""
from __future__ import annotations

import math
import shutil
from pathlib import Path

import numpy as np
import pytest

from helpers import assert_scene_error

from clrender import Camera, load_scene
from clrender.abi import structs
from clrender.errors import SceneError
from clrender.scene.keyframes import KeyframeAnimation, LightKey, LightTrack

SCENES = Path(__file__).resolve().parent.parent / "scenes"

CAMERA_KEYS = """
[camera]
fov_y_deg = 45
near = 0.5
far = 50

[[camera.keys]]
time = 0.0
eye = [0, 4, 10]
target = [0, 1, 0]
fov_y_deg = 50

[[camera.keys]]
time = 2.0
eye = [4, 4, 6]
target = [1, 1, 0]
fov_y_deg = 40

[[camera.keys]]
time = 3.0
eye = [4, 6, 6]
target = [1, 1, 0]
"""

# (t, eye, target, fov): hand-computed (u = 0.25, 0.75 on the first segment, 0.5 on the second)
CAMERA_EXPECTED = [
    (-1.0, (0, 4, 10), (0, 1, 0), 50.0),
    (0.0, (0, 4, 10), (0, 1, 0), 50.0),
    (0.5, (1, 4, 9), (0.25, 1, 0), 47.5),
    (1.5, (3, 4, 7), (0.75, 1, 0), 42.5),
    (2.0, (4, 4, 6), (1, 1, 0), 40.0),
    (2.5, (4, 5, 6), (1, 1, 0), 42.5),
    (3.0, (4, 6, 6), (1, 1, 0), 45.0),
    (9.0, (4, 6, 6), (1, 1, 0), 45.0),
]


def write(tmp_path, text: str, mesh: bool = False) -> Path:
    path = tmp_path / "s.toml"
    if mesh:        # beside the TOML file: a scene reads only its own folder (or --allow-outside ones)
        for name in ("demo.gltf", "demo.bin", "checker.png", "leaf_mask.png"):
            shutil.copy(SCENES / name, tmp_path / name)
    path.write_text(('[[mesh]]\npath = "demo.gltf"\n' if mesh else "") + text)
    return path


def look_at(eye, target, fov, near=0.5, far=50.0) -> Camera:
    return Camera.look_at(eye, target, (0, 1, 0), fov, near, far)


# -- camera keys -----------------------------------------------------------------------------------------
def test_camera_keys_interpolate_linearly_and_clamp(tmp_path):
    scene = load_scene(write(tmp_path, CAMERA_KEYS))
    assert scene.animation.duration == 3.0
    assert scene.camera == look_at((0, 4, 10), (0, 1, 0), 50.0)        # loaded: posed at t = 0
    for t, eye, target, fov in CAMERA_EXPECTED:
        assert scene.pose(t) is None
        assert scene.camera == look_at(eye, target, fov), t


def test_previous_camera_is_the_camera_at_t_minus_dt(tmp_path):
    scene = load_scene(write(tmp_path, CAMERA_KEYS))
    previous = scene.pose(1.5, dt=1.0)
    assert previous == look_at((1, 4, 9), (0.25, 1, 0), 47.5)
    assert scene.camera == look_at((3, 4, 7), (0.75, 1, 0), 42.5)
    assert scene.pose(0.0, dt=0.5) == look_at((0, 4, 10), (0, 1, 0), 50.0)      # clamped before the first key


def test_single_key_is_a_fixed_camera_and_orthographic_keys(tmp_path):
    scene = load_scene(write(tmp_path, '[camera]\nprojection = "orthographic"\nxmag = 4\nymag = 3\n'
                                       '[[camera.keys]]\ntime = 1\neye = [0, 0, 5]\ntarget = [0, 0, 0]\n'))
    fixed = Camera.orthographic((0, 0, 5), (0, 0, 0), (0, 1, 0), 4, 3, 0.1, 100)
    assert scene.animation.duration == 1.0
    for t in (-3.0, 0.0, 1.0, 7.5):
        assert scene.pose(t, dt=0.25) == fixed and scene.camera == fixed


# -- orbit ----------------------------------------------------------------------------------------------
ORBIT = """
[camera]
fov_y_deg = 35

[camera.orbit]
center = [1, 2, 3]
radius = 4
height = 1.5
period = 8
"""


@pytest.mark.parametrize("start_deg", [0.0, 90.0, -30.0])
def test_orbit_positions(tmp_path, start_deg):
    text = ORBIT + (f"start_deg = {start_deg}\n" if start_deg else "")
    scene = load_scene(write(tmp_path, text))
    assert scene.animation.duration == 8.0
    for t in (0.0, 2.0, 4.0, 6.0, 8.0, -2.0, 5.0):
        scene.pose(t)
        a = math.radians(start_deg) + 2 * math.pi * t / 8
        eye = (1 + 4 * math.sin(a), 3.5, 3 + 4 * math.cos(a))
        np.testing.assert_allclose(scene.camera.eye, eye, rtol=0, atol=1e-12, err_msg=f"t={t}")
        assert scene.camera.target == (1, 2, 3) and scene.camera.fov_y_deg == 35.0
        assert scene.camera.near == 0.1 and scene.camera.far == 100.0
    if start_deg == 0.0:        # t = 0, period/4, period/2, 3 period/4 by hand
        for t, eye in ((0.0, (1, 3.5, 7)), (2.0, (5, 3.5, 3)), (4.0, (1, 3.5, -1)), (6.0, (-3, 3.5, 3))):
            scene.pose(t)
            np.testing.assert_allclose(scene.camera.eye, eye, rtol=0, atol=1e-12)
    previous = scene.pose(2.0, dt=2.0)
    scene.pose(0.0)
    assert previous == scene.camera


# -- lights -------------------------------------------------------------------------------------------------
LIGHTS = """
[[light]]
type = "point"
position = [9, 9, 9]
color = [1, 1, 1]
radius = 2

[[light]]
type = "point"
color = [1.0, 0.5, 0.25]
intensity = 2
radius = 3
keys = [
    { time = 0, position = [0, 1, 0] },
    { time = 2, position = [2, 1, 4], intensity = 4 },
    { time = 4, position = [2, 3, 0], color = [0, 1, 0] },
]

[[light]]
type = "spot"
position = [0, 5, 0]
direction = [0, -1, 0]
color = [0.5, 0.5, 0.5]

[[light.keys]]
time = 1
color = [0.25, 0.25, 0.25]

[[light.keys]]
time = 3
position = [0, 5, 2]
"""


def test_light_keys(tmp_path):
    scene = load_scene(write(tmp_path, LIGHTS))
    assert scene.animation.duration == 4.0 and scene.camera is None
    static = scene.lights[0].copy()
    # (t, keyed point light position, its color, spot position, spot color); radius sqrt(256 * max color)
    for t, pos, color, spot_pos, spot_color in (
            (-1.0, (0, 1, 0), (2, 1, 0.5), (0, 5, 0), (0.25, 0.25, 0.25)),
            (0.0, (0, 1, 0), (2, 1, 0.5), (0, 5, 0), (0.25, 0.25, 0.25)),
            (1.0, (1, 1, 2), (3, 1.5, 0.75), (0, 5, 0), (0.25, 0.25, 0.25)),
            (2.0, (2, 1, 4), (4, 2, 1), (0, 5, 1), (0.375, 0.375, 0.375)),
            (3.0, (2, 2, 2), (2, 2, 0.5), (0, 5, 2), (0.5, 0.5, 0.5)),
            (10.0, (2, 3, 0), (0, 2, 0), (0, 5, 2), (0.5, 0.5, 0.5))):
        before = scene.lights
        assert scene.pose(t, dt=0.5) is None                   # no camera
        assert scene.lights is not before                       # replaced, not mutated
        lights = scene.lights
        assert lights[0] == static
        np.testing.assert_array_equal(lights["position"][1:], np.float32([pos, spot_pos]), err_msg=f"t={t}")
        np.testing.assert_array_equal(lights["color"][1:], np.float32([color, spot_color]), err_msg=f"t={t}")
        assert lights["radius"][1] == 3.0
        assert lights["radius"][2] == np.float32(math.sqrt(256 * spot_color[0]))   # auto radius follows color
        np.testing.assert_array_equal(lights["direction"][2], [0, -1, 0])


def test_light_position_from_keys_only_and_with_camera(tmp_path):
    text = ORBIT + '[[light]]\ntype = "point"\nradius = 1\nkeys = [{ time = 0, position = [0, 0, 0] }, ' \
                   '{ time = 16, position = [8, 0, -16] }]\n'
    scene = load_scene(write(tmp_path, text))
    assert scene.animation.duration == 16.0                 # the longest track
    previous = scene.pose(4.0, dt=2.0)
    np.testing.assert_array_equal(scene.lights["position"][0], [2, 0, -4])
    np.testing.assert_allclose(scene.camera.eye, (1, 3.5, -1), atol=1e-12)
    np.testing.assert_allclose(previous.eye, (5, 3.5, 3), atol=1e-12)


def test_posing_is_absolute(tmp_path):
    scene = load_scene(write(tmp_path, CAMERA_KEYS + LIGHTS))
    times = [2.5, 0.5, 3.7, -1.0, 1.25, 2.5, 9.0, 0.5]
    results = {}
    for t in times:
        previous = scene.pose(t, dt=0.3)
        state = (scene.camera, previous, scene.lights.tobytes())
        assert results.setdefault(t, state) == state, t
    fresh = load_scene(write(tmp_path, CAMERA_KEYS + LIGHTS))
    for t in sorted(results, reverse=True):
        previous = fresh.pose(t, dt=0.3)
        assert (fresh.camera, previous, fresh.lights.tobytes()) == results[t]


def test_composes_with_a_base_animation():
    class Base:
        duration = 7.0
        calls = []

        def pose(self, scene, t, dt=None):
            self.calls.append((t, dt))
            return "base-previous"

    class Holder:
        camera = None
        lights = np.zeros(1, structs.light_dtype)

    track = LightTrack(0, (LightKey(0.0, (0.0, 0.0, 0.0), (1.0, 1.0, 1.0)),
                           LightKey(2.0, (2.0, 0.0, 0.0), (1.0, 1.0, 1.0))))
    anim = KeyframeAnimation(None, [track], "x.toml", base=Base())
    holder = Holder()
    assert anim.duration == 7.0
    assert anim.pose(holder, 1.0, 0.5) == "base-previous" and Base.calls == [(1.0, 0.5)]
    np.testing.assert_array_equal(holder.lights["position"][0], [1, 0, 0])
    with pytest.raises(SceneError, match="finite"):
        anim.pose(holder, float("nan"))


def test_static_toml_scene_has_no_animation():
    assert load_scene(SCENES / "demo.toml").animation is None


def test_orbit_example_scene():
    scene = load_scene(SCENES / "orbit.toml")
    assert scene.animation.duration == 12.0
    assert scene.camera == Camera.look_at((0, 4, 9.5), (0, 1, 0), (0, 1, 0), 50, 0.1, 100)
    previous = scene.pose(3.0, dt=3.0)
    np.testing.assert_allclose(scene.camera.eye, (9.5, 4, 0), atol=1e-12)
    assert previous == Camera.look_at((0, 4, 9.5), (0, 1, 0), (0, 1, 0), 50, 0.1, 100)
    np.testing.assert_allclose(scene.lights["position"][0], (0, 2.2, 1.1), atol=1e-6)
    np.testing.assert_allclose(scene.lights["color"][0], np.float32([1, 0.72, 0.45]) * 3.5, rtol=1e-6)
    assert scene.triangle_count > 0 and scene.settings["render"] == {"width": 960, "height": 540}


# -- errors ---------------------------------------------------------------------------------------------------
KEY = '[[camera.keys]]\ntime = {t}\neye = [0, 0, 5]\ntarget = [0, 0, 0]\n'


@pytest.mark.parametrize("text, words", [
    (KEY.format(t=1) + KEY.format(t=1), ["camera.keys", "strictly increasing"]),
    (KEY.format(t=2) + KEY.format(t=1), ["camera.keys", "strictly increasing"]),
    (KEY.format(t="nan"), ["camera.keys[0].time", "finite"]),
    (KEY.format(t="inf"), ["camera.keys[0].time", "finite"]),
    ('[[camera.keys]]\ntime = 0\neye = [0, 5]\ntarget = [0, 0, 0]\n', ["camera.keys[0].eye", "3 numbers"]),
    ('[[camera.keys]]\ntime = 0\neye = [0, 0, 5]\ntarget = [0, inf, 0]\n', ["camera.keys[0].target", "finite"]),
    ('[[camera.keys]]\ntime = 0\neye = [0, 0, 5]\n', ["camera.keys[0]", "target"]),
    ('[[camera.keys]]\neye = [0, 0, 5]\ntarget = [0, 0, 0]\n', ["camera.keys[0]", "time"]),
    (KEY.format(t=0) + "fov = 40\n", ["camera.keys[0]", "'fov'"]),
    (KEY.format(t=0) + "fov_y_deg = 200\n", ["camera.keys[0]", "fov_y_deg"]),
    ('[[camera.keys]]\ntime = 0\neye = [0, 0, 5]\ntarget = [0, 0, 5]\n', ["camera.keys[0]", "coincide"]),
    ('[camera]\nprojection = "orthographic"\nxmag = 1\nymag = 1\n' + KEY.format(t=0) + "fov_y_deg = 30\n",
     ["camera.keys[0]", "perspective"]),
    ('[camera]\neye = [0, 0, 1]\n' + KEY.format(t=0), ["eye", "camera.keys"]),
    ('[camera]\nkeys = []\n', ["camera.keys", "non-empty"]),
    ('[camera]\nkeys = [1, 2]\n', ["camera.keys[0]", "table"]),
    (ORBIT + KEY.format(t=0), ["camera.keys", "camera.orbit", "not both"]),
    (ORBIT.replace("radius = 4", "radius = 0"), ["camera.orbit.radius", "> 0"]),
    (ORBIT.replace("radius = 4", "radius = -1"), ["camera.orbit.radius", "> 0"]),
    (ORBIT.replace("period = 8", "period = 0"), ["camera.orbit.period", "> 0"]),
    (ORBIT.replace("period = 8", "period = -8"), ["camera.orbit.period", "> 0"]),
    (ORBIT.replace("period = 8", "period = nan"), ["camera.orbit.period", "finite"]),
    (ORBIT.replace("center = [1, 2, 3]", "center = [1, 2]"), ["camera.orbit.center", "3 numbers"]),
    (ORBIT.replace("center = [1, 2, 3]", ""), ["[camera.orbit]", "center"]),
    (ORBIT + "speed = 2\n", ["[camera.orbit]", "'speed'"]),
    (ORBIT.replace("height = 1.5", "height = true"), ["camera.orbit.height", "finite number"]),
    ('[[light]]\ntype = "point"\nkeys = [{ time = 1, position = [0, 0, 0] }, { time = 0, position = [1, 0, 0] }]\n',
     ["light[0].keys", "strictly increasing"]),
    ('[[light]]\ntype = "point"\nkeys = [{ time = 0, position = [0, 0] }]\n', ["light[0].keys[0].position", "3 numbers"]),
    ('[[light]]\ntype = "point"\nkeys = [{ time = 0, position = [0, 0, nan] }]\n', ["light[0].keys[0].position", "finite"]),
    ('[[light]]\ntype = "point"\nkeys = [{ time = 0, position = [0, 0, 0] }, { time = 1 }]\n',
     ["light[0].keys[1]", "position"]),
    ('[[light]]\ntype = "point"\nposition = [0, 0, 0]\nkeys = [{ time = 0, radius = 3 }]\n',
     ["light[0].keys[0]", "'radius'"]),
    ('[[light]]\ntype = "point"\nposition = [0, 0, 0]\nkeys = [{ time = 0, intensity = -1 }]\n',
     ["light[0].keys[0]", "non-negative"]),
    ('[[light]]\ntype = "directional"\ndirection = [0, -1, 0]\nkeys = [{ time = 0 }]\n', ["light[0]", "'keys'"]),
])
def test_keyframe_errors(tmp_path, text, words):
    msg = assert_scene_error(write(tmp_path, text), words)
    assert "\n" not in msg


def test_degenerate_camera_between_keys_is_a_scene_error(tmp_path):
    # eye passes through the target at t = 1
    scene = load_scene(write(tmp_path, '[[camera.keys]]\ntime = 0\neye = [0, 0, 1]\ntarget = [0, 0, 0]\n'
                                       '[[camera.keys]]\ntime = 2\neye = [0, 0, -1]\ntarget = [0, 0, 0]\n'))
    with pytest.raises(SceneError, match=r"s\.toml.*t=1"):
        scene.pose(1.0)


# -- renders ---------------------------------------------------------------------------------------------------
def test_posed_render_matches_the_camera_placed_directly(tmp_path, make_renderer):
    scene = load_scene(write(tmp_path, CAMERA_KEYS, mesh=True))
    renderer = make_renderer(64, 48)
    for t, eye, target, fov in ((0.5, (1, 4, 9), (0.25, 1, 0), 47.5), (2.5, (4, 5, 6), (1, 1, 0), 42.5)):
        previous = scene.pose(t, dt=1 / 24)
        got = renderer.render(scene, scene.camera, previous_camera=previous, time=t)
        want = renderer.render(scene, look_at(eye, target, fov), time=t)
        assert np.isfinite(want.depth).sum() > 500
        np.testing.assert_array_equal(got.depth, want.depth)
        np.testing.assert_array_equal(got.triangle_id, want.triangle_id)
        moving = np.abs(got.velocity[np.isfinite(got.depth)]).max()
        assert moving > 0.5, moving                      # the camera moves over dt


def test_fixed_camera_has_zero_velocity(tmp_path, make_renderer):
    scene = load_scene(write(tmp_path, KEY.format(t=0).replace("[0, 0, 5]", "[0, 4, 10]").replace(
        "[0, 0, 0]", "[0, 1, 0]"), mesh=True))
    previous = scene.pose(1.0, dt=0.5)
    assert previous == scene.camera
    frame = make_renderer(64, 48).render(scene, scene.camera, previous_camera=previous, time=1.0)
    assert np.isfinite(frame.depth).sum() > 500
    still = np.abs(frame.velocity).max()
    assert still == 0.0, still          # nothing moved: the pipeline skips the reprojection
