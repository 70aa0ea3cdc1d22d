"""One subject (HDR environments, the host side) in one file: 528 lines.

HDR environments, the host side (clrender/scene/environment.py): OpenEXR and Radiance RGBE files,
validation, the direction convention's NumPy reference (`lookup`), the studio environment, and
how scenes, TOML files, load_scene's default and the CLI get one. Also: a glTF texture file that
is missing or unreadable is a warning, not an error. Nothing here renders but the last test."""
from __future__ import annotations

import math
import warnings
from pathlib import Path

import numpy as np
import pytest

from clrender.cli import app as cli
from clrender.scene.environment import (
    Environment, describe, directions_of_texels, load_environment, lookup, studio_environment)
from clrender.scene.environment_files import decode_rgbe, encode_rgbe, read_exr, read_rgbe, write_rgbe
from clrender.errors import SceneError
from clrender.loaders import load_scene
from clrender.scene.model import Scene
from gltf_files import primitive, write_gltf

SHARED_ENVIRONMENTS = Path(__file__).resolve().parents[2] / "shared" / "environments"

QUAD_OBJ = "v -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\nf 1 2 3\nf 1 3 4\n"


def write_exr(path, img, half=False):
    import OpenEXR
    dtype = np.float16 if half else np.float32
    channels = {c: np.ascontiguousarray(img[..., k], dtype=dtype) for k, c in enumerate("RGB")}
    OpenEXR.File({"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}, channels).write(str(path))
    return Path(path)


def scene_error(call, *words) -> str:
    """`call()` raises a one-line SceneError containing every word; returns the message."""
    with pytest.raises(SceneError) as info:
        call()
    msg = str(info.value)
    assert "\n" not in msg, msg
    for w in words:
        assert str(w) in msg, msg
    return msg


def random_image(seed, h=16, w=32, scale=8.0):
    return (np.random.default_rng(seed).random((h, w, 3)) * scale).astype(np.float32)


# -- OpenEXR -----------------------------------------------------------------------------------------------
def test_exr_float_round_trip_is_bit_exact(tmp_path):
    img = random_image(0)
    env = load_environment(write_exr(tmp_path / "f.exr", img))
    np.testing.assert_array_equal(read_exr(tmp_path / "f.exr"), img)
    assert env.pixels.dtype == np.float32 and env.pixels.shape == (16, 32, 3)
    np.testing.assert_array_equal(env.pixels, img)
    assert env.source == str(tmp_path / "f.exr")


def test_exr_half_round_trip(tmp_path):
    img = random_image(1)
    env = load_environment(write_exr(tmp_path / "h.exr", img, half=True))
    np.testing.assert_array_equal(env.pixels, img.astype(np.float16).astype(np.float32))   # HALF read exactly
    np.testing.assert_allclose(env.pixels, img, rtol=2 ** -11, atol=0)                       # half precision


def test_exr_missing_channel_and_garbage(tmp_path):
    import OpenEXR
    img = random_image(2)
    rg = tmp_path / "rg.exr"
    OpenEXR.File({"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage},
                 {"R": img[..., 0].copy(), "G": img[..., 1].copy()}).write(str(rg))
    scene_error(lambda: load_environment(rg), rg, "no B channel")
    garbage = tmp_path / "garbage.exr"
    garbage.write_bytes(b"not an exr file at all" * 20)
    scene_error(lambda: load_environment(garbage), garbage, "cannot read")


def test_exr_negative_pixels_clamp_and_nan_names_the_file(tmp_path):
    img = random_image(3) - 0.5                        # about 6% negative, as lossy compression leaves
    assert (img < 0).any()
    env = load_environment(write_exr(tmp_path / "neg.exr", img))
    np.testing.assert_array_equal(env.pixels, np.maximum(img, 0))
    img[2, 3, 1] = np.nan
    img[5, 7, :] = np.inf
    path = write_exr(tmp_path / "nan.exr", img)
    scene_error(lambda: load_environment(path), path, "2 of 512", "not finite")


def test_shared_exr_environment_when_present():
    path = SHARED_ENVIRONMENTS / "studio.exr"
    if not path.is_file():
        pytest.skip(f"{path} absent (the shared CC0 environments are test input only, not in the repository)")
    env = load_environment(path, intensity=0.5, rotation_deg=30)
    assert env.pixels.shape == (512, 1024, 3) and env.pixels.min() >= 0 and np.isfinite(env.pixels).all()
    assert (env.intensity, env.rotation_deg) == (0.5, 30.0)
    assert env.key == load_environment(str(path)).key


# -- Radiance RGBE -----------------------------------------------------------------------------------------
def wide_range_image(seed, h=16, w=32):
    rng = np.random.default_rng(seed)
    img = rng.random((h, w, 3)) * 10.0 ** rng.uniform(-3, 3, (h, w, 1))
    img[:3] = (2.0, 0.5, 0.25)                        # constant rows: runs in the RLE encoding
    img[4, :] = 0.0                                    # black: e = 0
    return img.astype(np.float32)


@pytest.mark.parametrize("rle", [True, False], ids=["rle", "flat"])
def test_rgbe_round_trip(tmp_path, rle):
    img = wide_range_image(4)
    path = write_rgbe(tmp_path / "e.hdr", img, rle=rle)
    data = path.read_bytes()
    marker = bytes((2, 2, 0, 32))
    assert (marker in data) == rle
    out = load_environment(path).pixels
    # RGBE keeps 8 mantissa bits of the pixel's largest channel: within max(r, g, b) / 256
    bound = img.max(axis=-1, keepdims=True) / 256 * (1 + 1e-6)
    assert (np.abs(out - img) <= bound).all(), np.abs(out - img).max()
    np.testing.assert_array_equal(out[4], 0.0)
    flat = encode_rgbe(img, rle=False)
    if rle:
        assert len(data) < len(flat)                  # the runs did compress
        np.testing.assert_array_equal(out, decode_rgbe(flat))     # same pixels either way


def test_rgbe_hand_made_files(tmp_path):
    header = b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\nEXPOSURE=4.0\n\n"
    # two flat pixels: (128, 64, 0, e=129) -> (c + 0.5) * 2^(129 - 136) = (c + 0.5) / 128; then e = 0 -> black
    two = tmp_path / "two.hdr"
    two.write_bytes(header + b"-Y 1 +X 2\n" + bytes([128, 64, 0, 129, 0, 0, 0, 0]))
    px = read_rgbe(two)
    assert px.shape == (1, 2, 3) and px.dtype == np.float32
    np.testing.assert_array_equal(px[0, 0], [128.5 / 128, 64.5 / 128, 0.5 / 128])    # EXPOSURE not applied
    np.testing.assert_array_equal(px[0, 1], [0, 0, 0])
    scene_error(lambda: load_environment(two), two, "not 2:1")
    # one RLE scanline of 8: R a run of 8 x 128, G 8 literal bytes 0..7, B a run of 0, E a run of 129
    rle = tmp_path / "rle.pic"
    rle.write_bytes(header + b"-Y 1 +X 8\n" + bytes([2, 2, 0, 8, 128 + 8, 128, 8, *range(8), 128 + 8, 0, 128 + 8, 129]))
    px = read_rgbe(rle)
    np.testing.assert_array_equal(px[0, :, 0], np.full(8, 128.5 / 128, np.float32))
    np.testing.assert_array_equal(px[0, :, 1], ((np.arange(8) + 0.5) / 128).astype(np.float32))
    np.testing.assert_array_equal(px[0, :, 2], np.full(8, 0.5 / 128, np.float32))


def test_rgbe_bad_files_name_the_file(tmp_path):
    flipped = tmp_path / "flipped.hdr"
    flipped.write_bytes(b"#?RADIANCE\n\n+Y 1 +X 2\n" + bytes(8))
    scene_error(lambda: load_environment(flipped), flipped, "orientation", "+Y 1 +X 2")
    xyz = tmp_path / "xyz.hdr"
    xyz.write_bytes(b"#?RADIANCE\nFORMAT=32-bit_rle_xyze\n\n-Y 1 +X 2\n" + bytes(8))
    scene_error(lambda: load_environment(xyz), xyz, "xyze")
    truncated = tmp_path / "truncated.hdr"
    truncated.write_bytes(encode_rgbe(wide_range_image(5))[:-40])
    scene_error(lambda: load_environment(truncated), truncated, "scanline")
    garbage = tmp_path / "garbage.hdr"
    garbage.write_bytes(b"\x89PNG\r\n\x1a\n" + bytes(100))
    scene_error(lambda: load_environment(garbage), garbage, "Radiance")
    overflow = tmp_path / "overflow.hdr"      # a run of 100 in a scanline of 8
    overflow.write_bytes(b"#?RADIANCE\n\n-Y 1 +X 8\n" + bytes([2, 2, 0, 8, 128 + 100, 1]) + bytes(40))
    scene_error(lambda: load_environment(overflow), overflow, "overflows")


# -- validation --------------------------------------------------------------------------------------------
def test_missing_unknown_and_bad_shapes(tmp_path):
    for name in ("missing.exr", "missing.hdr"):
        scene_error(lambda: load_environment(tmp_path / name), tmp_path / name, "not found")
    png = tmp_path / "sky.png"
    png.write_bytes(b"x")
    scene_error(lambda: load_environment(png), png, "unsupported", ".png")
    for shape in [(4, 4, 3), (8, 4, 3), (1, 2, 3), (4, 8, 4), (4, 8)]:
        scene_error(lambda: load_environment(np.ones(shape, np.float32)), "<array>")
    scene_error(lambda: load_environment(np.ones((4, 4, 3))), "not 2:1")
    square = write_rgbe(tmp_path / "square.hdr", np.ones((8, 8, 3)))
    scene_error(lambda: load_environment(square), square, "not 2:1")


def test_non_finite_pixels_count_and_negative_clamp():
    img = random_image(6, 8, 16)
    img[0, 0, 0] = np.nan
    img[3, 5] = (-np.inf, 0, 1)
    img[7, 15, 2] = np.inf
    scene_error(lambda: load_environment(img), "<array>", "3 of 128", "first at row 0, column 0")
    img = np.full((2, 4, 3), -0.25, np.float32)
    img[1, 2] = (1.0, -0.0, 2.0)
    env = Environment(img)
    np.testing.assert_array_equal(env.pixels, np.maximum(img, 0))
    assert not np.signbit(env.pixels).any()           # -0.0 becomes +0.0 (the key sees equal images)


@pytest.mark.parametrize("bad", [{"intensity": -1.0}, {"intensity": float("nan")}, {"intensity": float("inf")},
                                 {"rotation_deg": float("nan")}, {"rotation_deg": float("inf")},
                                 {"intensity": "2"}, {"background": "yes"}])
def test_bad_parameters_name_the_file(tmp_path, bad):
    path = write_rgbe(tmp_path / "ok.hdr", np.ones((4, 8, 3)))
    scene_error(lambda: load_environment(path, **bad), path)


def test_pixels_are_a_read_only_copy_and_key_identifies_them():
    img = random_image(7, 8, 16)
    env = load_environment(img, intensity=2, rotation_deg=-45, background=False)
    assert env.pixels.flags.c_contiguous and not env.pixels.flags.writeable
    with pytest.raises(ValueError):
        env.pixels[0, 0, 0] = 1.0
    img[0, 0, 0] += 1.0                                # the caller's array is not the environment's
    assert env.pixels[0, 0, 0] != img[0, 0, 0]
    assert (env.intensity, env.rotation_deg, env.background, env.source) == (2.0, -45.0, False, "<array>")
    assert len(env.key) == 64 and int(env.key, 16) >= 0
    same = load_environment(img.copy())
    assert same.key != env.key                        # one pixel differs
    img[0, 0, 0] -= 1.0
    again = Environment(img, 2, -45, False)
    assert again.key == env.key and again == env and hash(again) == hash(env)
    assert Environment(img).key == env.key            # the parameters are not in the key
    assert env.with_params(intensity=3).intensity == 3 and env.with_params(intensity=3).key == env.key
    assert env.with_params(intensity=3) != env
    assert load_environment(env, intensity=0.5).intensity == 0.5
    assert "16x8" in repr(env) and "intensity=2" in repr(env)
    import copy
    import pickle
    for twin in (pickle.loads(pickle.dumps(env)), copy.deepcopy(env)):
        assert twin == env and twin.key == env.key and not twin.pixels.flags.writeable


# -- the direction convention ------------------------------------------------------------------------------
def index_image(h, w):
    """Channel 0 = column index, channel 1 = row index, channel 2 = 1: bilinear lookups give back
    fractional texel coordinates."""
    img = np.zeros((h, w, 3), np.float32)
    img[..., 0] = np.arange(w)[None, :]
    img[..., 1] = np.arange(h)[:, None]
    img[..., 2] = 1.0
    return img


def test_lookup_hand_computed_directions():
    h, w = 4, 8
    img = index_image(h, w)
    # -Z: u = 0.5 -> x = 0.5 * 8 - 0.5 = 3.5 (the centre, between columns 3 and 4); horizon v = 0.5 -> row 1.5
    np.testing.assert_allclose(lookup(img, [[0, 0, -1]]), [[3.5, 1.5, 1]], atol=1e-12)
    # +X: u = 0.75 -> 5.5; -X: u = 0.25 -> 1.5
    np.testing.assert_allclose(lookup(img, [[1, 0, 0], [-1, 0, 0]])[:, :2], [[5.5, 1.5], [1.5, 1.5]], atol=1e-12)
    # +Z: u = 1 = 0 wraps: x = -0.5, halfway between the last column (7) and the first (0)
    np.testing.assert_allclose(lookup(img, [[0, 0, 1]])[0, :2], [3.5, 1.5], atol=1e-12)
    # +Y: v = 0 clamps to row 0; -Y: the last row
    np.testing.assert_allclose(lookup(img, [[0, 1, 0], [0, -1, 0]])[:, 1], [0, 3], atol=1e-12)
    # 45 degrees above -Z: v = 0.25 -> y = 1 - 0.5 = 0.5
    np.testing.assert_allclose(lookup(img, [[0, 1, -1]])[0, :2], [3.5, 0.5], atol=1e-12)
    # rotation R: the lookup at u + R / 360; 90 degrees moves -Z's u from 0.5 to 0.75 (+X's)
    np.testing.assert_allclose(lookup(img, [[0, 0, -1]], rotation_deg=90), lookup(img, [[1, 0, 0]]), atol=1e-12)
    np.testing.assert_allclose(lookup(img, [[1, 0, 0]], rotation_deg=-90), lookup(img, [[0, 0, -1]]), atol=1e-12)
    np.testing.assert_allclose(lookup(img, [[0, 0, -1]], rotation_deg=450), lookup(img, [[1, 0, 0]]), atol=1e-12)
    # direction length does not matter
    np.testing.assert_allclose(lookup(img, [[0, 3, -3]]), lookup(img, [[0, 1, -1]]), atol=1e-12)
    assert lookup(img, np.zeros((0, 3))).shape == (0, 3)


def test_directions_of_texels_hit_their_texels():
    h, w = 6, 12
    d = directions_of_texels(h, w)
    assert d.shape == (h, w, 3)
    np.testing.assert_allclose(np.linalg.norm(d, axis=-1), 1.0, atol=1e-12)
    assert (d[0, :, 1] > 0.96).all() and (d[-1, :, 1] < -0.96).all()       # row 0 up
    back = lookup(index_image(h, w), d.reshape(-1, 3)).reshape(h, w, 3)
    np.testing.assert_allclose(back[..., 0], np.arange(w)[None, :] + np.zeros((h, 1)), atol=1e-9)
    np.testing.assert_allclose(back[..., 1], np.arange(h)[:, None] + np.zeros((1, w)), atol=1e-9)
    # columns w/2 - 1 and w/2 straddle -Z; column 3w/4 - 1/2 would be +X
    mid = d[h // 2, w // 2 - 1] + d[h // 2, w // 2]
    assert abs(mid[0]) < 1e-12 and mid[2] < 0                                 # symmetric about -Z
    assert d[h // 2 - 1, 3 * w // 4, 0] > 0.9 and d[h // 2 - 1, w // 4, 0] < -0.9  # +X at 3/4, -X at 1/4


def test_lookup_matches_bilinear_by_hand_at_random_directions():
    h, w = 5, 10
    img = random_image(8, h, w)
    rng = np.random.default_rng(9)
    dirs = rng.normal(size=(200, 3))
    rot = 37.0
    got = lookup(img, dirs, rotation_deg=rot)
    for d, g in zip(dirs, got):
        x, y, z = d / np.linalg.norm(d)
        u = (0.5 + math.atan2(x, -z) / (2 * math.pi) + rot / 360) % 1.0
        v = math.acos(y) / math.pi
        fx, fy = u * w - 0.5, v * h - 0.5
        i0, j0 = math.floor(fx), math.floor(fy)
        ax, ay = fx - i0, fy - j0
        tex = lambda i, j: img[min(max(j, 0), h - 1), i % w].astype(np.float64)   # noqa: E731
        expect = ((1 - ax) * (1 - ay) * tex(i0, j0) + ax * (1 - ay) * tex(i0 + 1, j0)
                  + (1 - ax) * ay * tex(i0, j0 + 1) + ax * ay * tex(i0 + 1, j0 + 1))
        np.testing.assert_allclose(g, expect, rtol=1e-12, atol=1e-12)


# -- the studio environment --------------------------------------------------------------------------------
def irradiance_over_pi(img, normal) -> float:
    """E(n) / pi of a grey equirectangular image: sum of L max(0, n.d) dw over texels."""
    h, w = img.shape[:2]
    d = directions_of_texels(h, w)
    theta = (np.arange(h) + 0.5) / h * np.pi
    dw = (2 * np.pi / w) * (np.pi / h) * np.sin(theta)[:, None]
    cos = np.clip(d @ np.asarray(normal, np.float64), 0, None)
    return float((img[..., 0] * cos * dw).sum() / np.pi)


def test_studio_environment_numbers():
    img = studio_environment()
    assert img.shape == (256, 512, 3) and img.dtype == np.float32
    assert np.isfinite(img).all() and img.min() > 0
    np.testing.assert_array_equal(img[..., 0], img[..., 1])           # neutral grey
    np.testing.assert_array_equal(img[..., 0], img[..., 2])
    np.testing.assert_array_equal(img, studio_environment(256))        # deterministic
    # a uniform environment of radiance 1 integrates to E / pi = 1 (the integration itself)
    assert abs(irradiance_over_pi(np.ones((256, 512, 3)), (0, 1, 0)) - 1.0) < 1e-4
    up = irradiance_over_pi(img, (0, 1, 0))
    assert 0.8 <= up <= 1.5 and abs(up - 1.14) < 0.01, up              # the documented 1.14
    sides = {n: irradiance_over_pi(img, n) for n in [(1, 0, 0), (-1, 0, 0), (0, 0, 1), (0, 0, -1)]}
    assert all(e > 0.3 for e in sides.values()), sides
    assert abs(sides[(1, 0, 0)] - 0.60) < 0.01 and abs(sides[(0, 0, 1)] - 0.73) < 0.01, sides
    assert abs(sides[(1, 0, 0)] - sides[(-1, 0, 0)]) < 1e-6           # symmetric left/right
    assert irradiance_over_pi(img, (0, -1, 0)) < 0.3                   # the ground is darker
    # the sky is lighter than the ground; the key softbox above the front (+Z)
    sky, ground, key = lookup(img, [[0, 0.5, -1], [0, -0.5, -1], [0, 1, 1]])[:, 0]
    assert sky > 0.55 and ground < 0.2 and key == pytest.approx(5.0)
    small = studio_environment(16)
    assert small.shape == (16, 32, 3) and 0.8 <= irradiance_over_pi(small, (0, 1, 0)) <= 1.5
    env = load_environment("studio")
    assert env.source == "studio" and env.pixels.shape == (256, 512, 3)
    with pytest.raises(SceneError):
        studio_environment(1)


# -- scenes, TOML, load_scene ------------------------------------------------------------------------------
def test_scene_set_environment():
    scene = Scene.from_arrays([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]])
    assert scene.environment is None
    scene.settings["default_environment"] = True
    env = scene.set_environment("studio", intensity=2, rotation_deg=10, background=False)
    assert scene.environment is env and (env.intensity, env.rotation_deg, env.background) == (2, 10, False)
    assert "default_environment" not in scene.settings
    with pytest.raises(SceneError):
        scene.set_environment(np.ones((3, 3, 3)))
    assert scene.environment is env                  # a failed set keeps the environment
    assert scene.set_environment(None) is None and scene.environment is None


def toml_scene(tmp_path, table: str) -> Path:
    """A TOML scene of one OBJ quad and `table` (top-level keys first, as TOML needs)."""
    (tmp_path / "quad.obj").write_text(QUAD_OBJ)
    path = tmp_path / "s.toml"
    top = table.startswith("environment =")
    path.write_text((table if top else "") + '[[mesh]]\npath = "quad.obj"\n\n' + ("" if top else table))
    return path


def test_toml_environment_table(tmp_path):
    (tmp_path / "sky").mkdir()
    img = wide_range_image(10, 8, 16)
    write_rgbe(tmp_path / "sky" / "env.hdr", img)
    scene = load_scene(toml_scene(tmp_path, '[environment]\nsource = "sky/env.hdr"\nintensity = 2.5\n'
                                            'rotation = -30\nbackground = false\n'))
    env = scene.environment
    assert env.source == str(tmp_path / "sky" / "env.hdr")
    assert (env.intensity, env.rotation_deg, env.background) == (2.5, -30.0, False)
    np.testing.assert_array_equal(env.pixels, read_rgbe(tmp_path / "sky" / "env.hdr"))
    studio = load_scene(toml_scene(tmp_path, '[environment]\nsource = "studio"\n')).environment
    assert studio.source == "studio" and (studio.intensity, studio.rotation_deg, studio.background) == (1, 0, True)
    assert load_scene(toml_scene(tmp_path, "")).environment is None


@pytest.mark.parametrize("table, words", [
    ('[environment]\nsource = "studio"\nexposure = 2\n', ["unknown key 'exposure'", "[environment]"]),
    ('[environment]\nintensity = 2\n', ["needs 'source'"]),
    ('[environment]\nsource = "studio"\nintensity = -1\n', ["environment.intensity"]),
    ('[environment]\nsource = "studio"\nrotation = "left"\n', ["environment.rotation"]),
    ('[environment]\nsource = "studio"\nbackground = 1\n', ["environment.background"]),
    ('[environment]\nsource = "nowhere.exr"\n', ["nowhere.exr", "not found"]),
    ('environment = "studio"\n', ["[environment] must be a table"]),
])
def test_toml_environment_errors(tmp_path, table, words):
    path = toml_scene(tmp_path, table)
    scene_error(lambda: load_scene(path), path, *words)


def gltf_quad(tmp_path, name="q.gltf", **kw) -> Path:
    return write_gltf(tmp_path / name, **kw)


def point_light_doc(doc):
    doc["extensionsUsed"] = ["KHR_lights_punctual"]
    doc["extensions"] = {"KHR_lights_punctual": {"lights": [{"type": "point", "intensity": 5, "range": 4}]}}
    doc["nodes"].append({"translation": [0, 1, 1], "extensions": {"KHR_lights_punctual": {"light": 0}}})
    doc["scenes"][0]["nodes"].append(len(doc["nodes"]) - 1)


def directional_light_doc(doc):
    doc["extensionsUsed"] = ["KHR_lights_punctual"]
    doc["extensions"] = {"KHR_lights_punctual": {"lights": [{"type": "directional", "intensity": 3}]}}
    doc["nodes"].append({"extensions": {"KHR_lights_punctual": {"light": 0}}})
    doc["scenes"][0]["nodes"].append(len(doc["nodes"]) - 1)


def unused_light_doc(doc):                            # a light defined but placed on no node
    doc["extensionsUsed"] = ["KHR_lights_punctual"]
    doc["extensions"] = {"KHR_lights_punctual": {"lights": [{"type": "point", "intensity": 5}]}}


def test_load_scene_default_environment(tmp_path):
    lightless = load_scene(gltf_quad(tmp_path))
    assert lightless.environment is not None and lightless.environment.source == "studio"
    assert lightless.settings["default_environment"] is True
    assert describe(lightless.environment, True) == "studio (default: the file has no lights)"
    assert load_scene(gltf_quad(tmp_path, "u.gltf", edit=unused_light_doc)).environment.source == "studio"

    lit = load_scene(gltf_quad(tmp_path, "p.gltf", edit=point_light_doc))
    assert len(lit.lights) == 1 and lit.sun is None
    assert lit.environment is None and "default_environment" not in lit.settings
    sun = load_scene(gltf_quad(tmp_path, "d.gltf", edit=directional_light_doc))
    assert sun.sun is not None and sun.environment is None
    assert load_scene(gltf_quad(tmp_path), default_environment=False).environment is None

    (tmp_path / "quad.obj").write_text(QUAD_OBJ)
    assert load_scene(tmp_path / "quad.obj").environment is None              # OBJ: ambient only, as before
    toml = tmp_path / "g.toml"
    toml.write_text('[[mesh]]\npath = "q.gltf"\n')
    scene = load_scene(toml)
    assert scene.environment is None and "default_environment" not in scene.settings


# -- glTF texture files: a warning, not an error -----------------------------------------------------------
def test_gltf_missing_or_unreadable_texture_warns(tmp_path):
    red, green = np.zeros((2, 2, 4), np.uint8), np.zeros((2, 2, 4), np.uint8)
    red[..., 0] = red[..., 3] = 255
    green[..., 1] = green[..., 3] = 255
    materials = [{"name": "lost", "pbrMetallicRoughness": {"baseColorFactor": [1, 0.5, 0.25, 1],
                                                           "baseColorTexture": {"index": 0},
                                                           "metallicRoughnessTexture": {"index": 2}},
                  "normalTexture": {"index": 0}},       # image 0 again, as linear data: one warning
                 {"name": "kept", "pbrMetallicRoughness": {"baseColorTexture": {"index": 1}}}]
    path = write_gltf(tmp_path / "t.gltf", primitives=[primitive(material=0), primitive(material=1)],
                      materials=materials, images=[red, green, red])
    (tmp_path / "t_image0.png").unlink()                       # missing
    (tmp_path / "t_image2.png").write_bytes(b"not a png")      # unreadable
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        scene = load_scene(path)
    messages = [str(w.message) for w in caught if "texture" in str(w.message) or "image" in str(w.message)]
    assert len(messages) == 2, messages
    assert all("\n" not in m and "t.gltf" in m and "'lost'" in m for m in messages), messages
    assert any("t_image0.png" in m and "not found" in m and "normalTexture" in m for m in messages), messages
    assert any("t_image2.png" in m and "cannot decode" in m for m in messages), messages
    lost, kept = scene.materials[:2]
    assert lost.base_color_texture == lost.metallic_roughness_texture == lost.normal_texture == -1
    assert lost.base_color == (1.0, 0.5, 0.25, 1.0)            # the factors stay
    assert len(scene.textures) == 1 and kept.base_color_texture == 0     # renumbered
    np.testing.assert_array_equal(scene.textures[0].rgba, green)


# -- the command line --------------------------------------------------------------------------------------
def parse(*extra):
    return cli.build_parser().parse_args(cli._join_vector_options(["render", "s.gltf", "-o", "o.png", *extra]))


def test_cli_environment_flags_parse():
    args = parse("--environment", "sky.exr", "--environment-intensity", "2.5", "--environment-rotation", "-90")
    assert (args.environment, args.environment_intensity, args.environment_rotation) == ("sky.exr", 2.5, -90.0)
    args = parse()
    assert (args.environment, args.environment_intensity, args.environment_rotation) == (None, None, None)
    for bad in (["--environment-intensity", "-1"], ["--environment-intensity", "nan"],
                ["--environment-rotation", "inf"], ["--environment-rotation", "left"]):
        with pytest.raises(cli.CLIError) as info:
            parse(*bad)
        assert bad[0] in str(info.value) and info.value.code == 2


def test_cli_environment_applied_to_scenes(tmp_path):
    write_rgbe(tmp_path / "env.hdr", np.ones((4, 8, 3)))
    lightless = lambda: load_scene(gltf_quad(tmp_path))            # noqa: E731  (studio by default)

    scene = lightless()
    cli.apply_environment(scene, parse("--environment", "none"), cli.environment_option(parse("--environment", "none")))
    assert scene.environment is None and cli.describe_environment(scene) == "none"

    args = parse("--environment", str(tmp_path / "env.hdr"), "--environment-intensity", "3")
    env = cli.environment_option(args)
    scene = lightless()
    cli.apply_environment(scene, args, env)
    assert scene.environment is env and env.intensity == 3
    assert cli.describe_environment(scene) == f"{tmp_path / 'env.hdr'} (intensity 3)"

    scene = lightless()
    assert cli.describe_environment(scene) == "studio (default: the file has no lights)"
    args = parse("--environment-rotation", "45")
    cli.apply_environment(scene, args, cli.environment_option(args))
    assert scene.environment.rotation_deg == 45 and scene.environment.source == "studio"
    assert cli.describe_environment(scene) == "studio (default: the file has no lights, rotation 45 deg)"

    lit = load_scene(gltf_quad(tmp_path, "p.gltf", edit=point_light_doc))
    args = parse("--environment-intensity", "2")
    with pytest.raises(cli.CLIError, match="--environment-intensity.*no environment"):
        cli.apply_environment(lit, args, cli.environment_option(args))
    with pytest.raises(cli.CLIError, match="--environment-intensity"):
        cli.environment_option(parse("--environment", "none", "--environment-intensity", "2"))


def test_cli_environment_errors_are_one_line(tmp_path, capsys):
    scene = gltf_quad(tmp_path)
    missing = tmp_path / "nowhere.exr"
    assert cli.main(["render", str(scene), "-o", str(tmp_path / "x.png"), "--environment", str(missing)]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("clrender: error: --environment") and "nowhere.exr" in err[0], err
    assert cli.main(["render", str(scene), "-o", str(tmp_path / "out"), "--frames", "0:1",
                     "--environment", "studio"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--environment" in err[0] and "--frames" in err[0], err
    assert not (tmp_path / "x.png").exists()


def test_cli_render_with_environment_none(tmp_path, device, capsys):
    """End to end: a lightless glTF with --environment none renders as before environments (the
    ambient term), and the per-scene line says which environment it had."""
    out = tmp_path / "q.png"
    rc = cli.main(["render", str(gltf_quad(tmp_path)), "-o", str(out), "--width", "32", "--height", "24",
                   "--device", device.id, "--environment", "none"])
    err = capsys.readouterr().err
    assert rc == 0, err
    assert out.is_file() and "environment: none" in err, err
