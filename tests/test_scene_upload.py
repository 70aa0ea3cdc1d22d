"""Incremental scene uploads (clrender/render/scene_upload.py): between animation frames only the posed
geometry (positions, normals, tangents, triangles, previous positions) is written into the existing
device buffers. Frames rendered that way are bit-identical to frames from a full upload, the texture
pool is not re-sent on a pose-only change, and anything else still rebuilds the upload."""
from __future__ import annotations

import copy

import numpy as np
import pytest

from gltf_files import primitive
from test_animation import cube, load_animated

import clrender
from clrender import Camera, Material
from clrender.render import scene_upload as scene_gpu
from clrender.scene.model import SceneError, Texture

S45 = np.sqrt(0.5)


def _images():
    y, x = np.mgrid[0:16, 0:16]
    checker = np.zeros((16, 16, 4), np.uint8)
    checker[..., 0] = np.where((x // 4 + y // 4) % 2, 230, 40)
    checker[..., 1], checker[..., 2], checker[..., 3] = 120, x * 15, 255
    normal = np.zeros((16, 16, 4), np.uint8)              # a bumpy tangent-space normal map
    normal[..., 0] = (128 + 80 * np.sin(x * 0.9)).astype(np.uint8)
    normal[..., 1] = (128 + 60 * np.cos(y * 0.7)).astype(np.uint8)
    normal[..., 2], normal[..., 3] = 220, 255
    return [checker, normal]


def animated_scene(tmp_path, generated_tangents: bool):
    """A normal-mapped textured quad that moves and turns, a cube that moves and is mirrored (STEP
    scale, negative x: winding flip) from t = 1, over a static ground; a shadowed sun and spot light."""
    anims = [{"channels": [{"sampler": k, "target": {"node": node, "path": path}}
                           for k, (node, path) in enumerate([(0, "translation"), (0, "rotation"),
                                                             (2, "translation"), (2, "scale")])],
              "samplers": [{"input": np.float32([0, 2]), "output": np.float32([[-1, 0, 0], [1, 0.5, 0]])},
                           {"input": np.float32([0, 2]),
                            "output": np.float32([[0, 0, 0, 1], [0, np.sin(0.4), 0, np.cos(0.4)]])},
                           {"input": np.float32([0, 2]), "output": np.float32([[1, 0, -1], [0, 0.5, -1]])},
                           {"input": np.float32([0, 1]), "output": np.float32([[1, 1, 1], [-1.3, 0.8, 1]]),
                            "interpolation": "STEP"}]}]
    nodes = [{"mesh": 0}, {"mesh": 1, "translation": [-4, -1, 4], "rotation": [-S45, 0, 0, S45], "scale": [8, 8, 1]},
             {"mesh": 2}]
    materials = [{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}, "normalTexture": {"index": 1},
                  "doubleSided": True}]
    scene = load_animated(tmp_path, anims, nodes=nodes, meshes=[[primitive(material=0)], [primitive()], [cube()]],
                          materials=materials, images=_images())
    assert scene.textures and scene.tangents is not None
    if generated_tangents:
        scene.tangents = None                   # generated at upload from the posed geometry
    scene.set_sun((-0.4, -1, -0.3), (2, 2, 2), shadow=True, shadow_map_size=512)
    scene.add_spot_light((0.5, 4, 2), (-0.1, -1, -0.5), (6, 6, 6), 12, 25, 40, shadow=True, shadow_map_size=256)
    scene.add_point_light((1, 1.5, 1), (1, 0.8, 0.6), 4)
    scene.camera = Camera.look_at((0.5, 2.5, 4.5), (0, 0, 0), fov_y_deg=55, near=0.1, far=40)
    return scene


def key(scene, renderer):
    return id(scene), renderer.device.info.id


def full_upload(scene, renderer):
    """Forget the scene's upload: the next render uploads everything again."""
    scene_gpu._UPLOADS.pop(key(scene, renderer), None)


AOVS = ("gbuffer", "color", "image", "shadow", "light_count", "ao", "depth", "normal", "albedo", "velocity",
        "triangle_id")

# (t, dt): motion, more motion, the cube mirrored, the same pose without dt (previous positions
# disappear), motion again (they appear), the same pose again (new arrays, same values).
STEPS = [(0.0, None), (0.3, 0.1), (0.7, 0.2), (1.2, 0.1), (1.2, None), (1.5, 0.25), (1.5, 0.25), (1.9, 0.3)]


@pytest.mark.parametrize("generated_tangents", [False, True], ids=["loaded-tangents", "generated-tangents"])
def test_animated_frames_match_full_uploads(tmp_path, device, generated_tangents):
    W, H = 96, 64
    incremental = animated_scene(tmp_path, generated_tangents)
    reference = copy.deepcopy(incremental)
    r_inc = clrender.Renderer(W, H, device=device.id)
    r_full = clrender.Renderer(W, H, device=device.id)      # its own shadow pass: nothing shared
    first = None
    for step, (t, dt) in enumerate(STEPS):
        prev_inc, prev_full = incremental.pose(t, dt), reference.pose(t, dt)
        assert (incremental.previous_positions is None) == (dt is None)
        a = r_inc.render(incremental, previous_camera=prev_inc)
        res = scene_gpu._UPLOADS[key(incremental, r_inc)][2]
        first = first or res
        assert res is first, f"step {step}: a pose-only change must update the upload in place"
        assert ("prev_positions" in res.buffers) == (dt is not None)
        full_upload(reference, r_full)
        b = r_full.render(reference, previous_camera=prev_full)
        for name in AOVS:
            np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=f"step {step} (t={t}): {name}")
        assert a.stats["shadow_maps"] == b.stats["shadow_maps"] > 1
        full = scene_gpu._UPLOADS[key(reference, r_full)][2]
        np.testing.assert_array_equal(res.values["scene_bounds"], full.values["scene_bounds"])
        for name in full.buffers:
            np.testing.assert_array_equal(res.buffers[name].get(), full.buffers[name].get(), err_msg=name)
        assert set(res.buffers) == set(full.buffers)
    assert (a.triangle_id >= 0).sum() > 1000


def test_pose_keeps_the_texture_pool_and_a_material_change_rebuilds_it(tmp_path, make_renderer):
    renderer = make_renderer(48, 32)
    scene = animated_scene(tmp_path, generated_tangents=False)
    scene.pose(0.2, 0.1)
    res = scene_gpu.upload(scene, renderer.device)
    kept = {name: res.buffers[name] for name in ("texels", "tex_infos", "tex_levels", "materials", "uvs",
                                                 "tri_material", "colors", "srgb_lut")}
    positions = res.buffers["positions"]
    bounds = res.values["scene_bounds"]
    for t in (0.5, 1.1, 1.7):
        scene.pose(t, 0.1)
        assert scene_gpu.needs_upload(scene, renderer.device)
        assert scene_gpu.upload(scene, renderer.device) is res
        assert not scene_gpu.needs_upload(scene, renderer.device)
        for name, buf in kept.items():
            assert res.buffers[name] is buf, f"{name} was re-uploaded on a pose-only change"
        # Rewritten in place (same device memory), under a new Array object: caches keyed by
        # buffer identity (the shadow pass's kept maps) see the change.
        assert res.buffers["positions"] is not positions
        assert res.buffers["positions"].data.int_ptr == positions.data.int_ptr
        np.testing.assert_array_equal(res.buffers["positions"].get().reshape(-1, 3), scene.positions)
        np.testing.assert_array_equal(res.values["scene_bounds"], scene.bounds())
        positions = res.buffers["positions"]
    assert not np.array_equal(bounds, res.values["scene_bounds"])

    scene.textures = list(scene.textures)             # a new list of the same textures: still the same pool
    assert scene_gpu.upload(scene, renderer.device) is res and res.buffers["texels"] is kept["texels"]

    scene.materials = scene.materials + [Material(base_color=(0.2, 0.9, 0.3, 1))]
    rebuilt = scene_gpu.upload(scene, renderer.device)
    assert rebuilt is not res and rebuilt.buffers["texels"] is not kept["texels"]
    assert rebuilt.buffers["materials"].size == len(scene.materials)

    red = np.zeros((4, 4, 4), np.uint8)
    red[..., 0], red[..., 3] = 255, 255
    scene.textures = [Texture("red", red)] + scene.textures[1:]
    again = scene_gpu.upload(scene, renderer.device)
    assert again is not rebuilt and again.buffers["texels"] is not rebuilt.buffers["texels"]
    np.testing.assert_array_equal(again.buffers["texels"].get()[:16], red.view(np.uint32).reshape(-1))

    scene.uvs = scene.uvs.copy()                      # not posed geometry: a full upload
    assert scene_gpu.upload(scene, renderer.device) is not again


def test_pose_only_updates_are_validated(tmp_path, make_renderer):
    renderer = make_renderer(48, 32)
    scene = animated_scene(tmp_path, generated_tangents=False)
    scene.pose(0.2, 0.1)
    res = scene_gpu.upload(scene, renderer.device)
    good = scene.triangles
    bad = good.copy()
    bad[3, 1] = len(scene.positions)
    scene.triangles = bad
    with pytest.raises(SceneError, match="out of range"):
        scene_gpu.upload(scene, renderer.device)
    bad = good.copy()
    bad[0, 0] = -1
    scene.triangles = bad
    with pytest.raises(SceneError, match="out of range"):
        scene_gpu.upload(scene, renderer.device)
    scene.triangles = good
    tangents = scene.tangents.copy()
    tangents[2, 0] = np.nan
    scene.tangents = tangents
    with pytest.raises(SceneError, match="tangents must be finite"):
        scene_gpu.upload(scene, renderer.device)
    scene.tangents = tangents[:, :3].copy()           # another shape: the full upload's validation
    with pytest.raises(SceneError, match="tangents"):
        scene_gpu.upload(scene, renderer.device)
    scene.tangents = None
    scene.previous_positions = np.zeros((5, 3), np.float32)
    with pytest.raises(SceneError, match="previous_positions"):
        scene_gpu.upload(scene, renderer.device)
    scene.previous_positions = None
    assert scene_gpu.upload(scene, renderer.device) is not res      # tangents gone: rebuilt
