"""The transparency reference (tests/reference/transparency.py) on hand-computed cases (no device):
one layer, two layers (order by depth, truncation, ties by id), the early stop and lighting, normals
interpolated and back faces flipped.
"""
from __future__ import annotations

import numpy as np

from clrender import Camera, Material
from reference import shading as ref_shading
from reference import transparency as ref
from reference.raster import screen_to_world
from transparency_cases import PX_CAM, SIZE, build_scene, point_lights, screen_quad


def hand_scene(front=None, back=None):
    white = Material("white wall", (1.0, 1.0, 1.0, 1.0), specular_intensity=0.0)
    parts = [(screen_quad(0, SIZE, 0, SIZE, 8.0), None, white)]
    for q in (front, back):
        if q is not None:
            parts.append(q)
    return build_scene(parts, ambient=0.5)


def test_reference_one_layer_ambient_only():
    red = Material("red", (1.0, 0.0, 0.0, 0.5), alpha_mode="BLEND", specular_intensity=0.0)
    scene = hand_scene((screen_quad(8, 24, 4, 20, 4.0), None, red))
    opaque = np.full((SIZE, SIZE, 3), 0.5)                     # white · ambient
    out = ref.blend(scene, PX_CAM, SIZE, SIZE, opaque)
    inside = np.zeros((SIZE, SIZE), bool)
    inside[4:20, 8:24] = True
    assert np.array_equal(out.fragment_count, inside.astype(np.int32))
    np.testing.assert_allclose(out.color[inside], np.broadcast_to([0.5 * 0.5 + 0.5 * 0.5, 0.25, 0.25], (inside.sum(), 3)))
    np.testing.assert_array_equal(out.color[~inside], opaque[~inside])
    np.testing.assert_allclose(out.transmittance, np.where(inside, 0.5, 1.0))
    assert np.isin(out.fragments.opaque_id, (0, 1)).all()                    # the wall's two triangles
    # opacity folds into alpha the same way
    red_op = Material("red", (1.0, 0.0, 0.0, 1.0), opacity=0.5, specular_intensity=0.0)
    out2 = ref.blend(hand_scene((screen_quad(8, 24, 4, 20, 4.0), None, red_op)), PX_CAM, SIZE, SIZE, opaque)
    np.testing.assert_array_equal(out2.color, out.color)
    # a layer behind the opaque wall is no fragment; nor one beyond far
    behind = ref.blend(hand_scene((screen_quad(8, 24, 4, 20, 9.0), None, red)), PX_CAM, SIZE, SIZE, opaque)
    assert behind.fragment_count.sum() == 0 and np.array_equal(behind.color, opaque)


def test_reference_two_layers_order_and_truncation():
    red = Material("red", (1.0, 0.0, 0.0, 0.5), alpha_mode="BLEND", specular_intensity=0.0)
    blue = Material("blue", (0.0, 0.0, 1.0, 0.25), alpha_mode="BLEND", specular_intensity=0.0)
    opaque = np.full((SIZE, SIZE, 3), 0.5)
    amb = 0.5
    # red in front (z 3) of blue (z 5); listed blue first so the id order is the opposite of depth
    scene = hand_scene((screen_quad(4, 20, 4, 20, 5.0), None, blue), (screen_quad(4, 20, 4, 20, 3.0), None, red))
    out = ref.blend(scene, PX_CAM, SIZE, SIZE, opaque)
    red_c, blue_c = np.array([1.0, 0, 0]) * amb, np.array([0, 0, 1.0]) * amb
    expect = 0.5 * red_c + 0.5 * 0.25 * blue_c + 0.5 * 0.75 * opaque[0, 0]
    np.testing.assert_allclose(out.color[10, 10], expect)
    assert out.fragment_count[10, 10] == 2 and out.shaded[10, 10] == 2
    np.testing.assert_allclose(out.transmittance[10, 10], 0.5 * 0.75)
    # swapped depths give a different colour: the order is by depth, not by id
    swapped = hand_scene((screen_quad(4, 20, 4, 20, 3.0), None, blue), (screen_quad(4, 20, 4, 20, 5.0), None, red))
    out_s = ref.blend(swapped, PX_CAM, SIZE, SIZE, opaque)
    np.testing.assert_allclose(out_s.color[10, 10], 0.25 * blue_c + 0.75 * 0.5 * red_c + 0.75 * 0.5 * opaque[0, 0])
    assert not np.allclose(out_s.color[10, 10], out.color[10, 10])
    # one layer: only the nearest, over the opaque colour; the count stays 2
    one = ref.blend(scene, PX_CAM, SIZE, SIZE, opaque, layers=1)
    np.testing.assert_allclose(one.color[10, 10], 0.5 * red_c + 0.5 * opaque[0, 0])
    assert one.fragment_count[10, 10] == 2 and one.shaded[10, 10] == 1
    # equal depths: the lower triangle id first (blue, ids 1-2, before red, ids 3-4)
    tie = hand_scene((screen_quad(4, 20, 4, 20, 4.0), None, blue), (screen_quad(4, 20, 4, 20, 4.0), None, red))
    out_t = ref.blend(tie, PX_CAM, SIZE, SIZE, opaque)
    np.testing.assert_allclose(out_t.color[10, 10], 0.25 * blue_c + 0.75 * 0.5 * red_c + 0.75 * 0.5 * opaque[0, 0])


def test_reference_early_stop_and_lighting():
    """T < 1e-4 stops before the next fragment; a lit fragment follows the shading reference."""
    opaque = np.zeros((SIZE, SIZE, 3))
    dense = Material("dense", (0.2, 0.4, 0.6, 0.999), alpha_mode="BLEND", specular_intensity=0.0)
    extra = Material("extra", (1.0, 1.0, 1.0, 0.5), alpha_mode="BLEND", specular_intensity=0.0)
    scene = hand_scene((screen_quad(0, 8, 0, 8, 2.0), None, dense), (screen_quad(0, 8, 0, 8, 3.0), None, extra))
    out = ref.blend(scene, PX_CAM, SIZE, SIZE, opaque)
    assert out.fragment_count[2, 2] == 2 and out.shaded[2, 2] == 2           # T = 1e-3 >= 1e-4: no stop yet
    dense2 = Material("dense", (0.2, 0.4, 0.6, 0.99999), alpha_mode="BLEND", specular_intensity=0.0)
    scene2 = hand_scene((screen_quad(0, 8, 0, 8, 2.0), None, dense2), (screen_quad(0, 8, 0, 8, 3.0), None, extra))
    out2 = ref.blend(scene2, PX_CAM, SIZE, SIZE, opaque)
    assert out2.fragment_count[2, 2] == 2 and out2.shaded[2, 2] == 1         # T = 1e-5 < 1e-4: stop
    np.testing.assert_allclose(out2.transmittance[2, 2], 1e-5, rtol=1e-6)
    np.testing.assert_allclose(out2.color[2, 2], 0.99999 * 0.5 * np.array([0.2, 0.4, 0.6]))
    # one lit layer: the same model as reference/shading.py on a head-on pixel
    lights = point_lights([((0.0, 0.0, -1.0), (1.0, 1.0, 1.0), 4.0)])
    glass = Material("glass", (0.5, 0.5, 0.5, 0.5), alpha_mode="BLEND", specular_intensity=0.5, specular_power=8.0)
    scene = hand_scene((screen_quad(0, SIZE, 0, SIZE, 2.0), None, glass))
    scene.lights = lights
    out = ref.blend(scene, PX_CAM, SIZE, SIZE, opaque)
    one = lambda v: np.asarray(v, np.float64).reshape((1, 1) + np.shape(v))
    # pixel (15, 15): its centre is at screen (15.5, 15.5), view depth 2
    d = ref_shading.pixel_directions(PX_CAM, SIZE, SIZE)[15, 15]
    # a 1x1 image looking along that ray: its depth is measured along the unit ray
    fields = dict(normal=one([0, 0, 1]), albedo=one([0.5, 0.5, 0.5]), specular_intensity=one(0.5),
                  specular_power=one(8.0), depth=one(2.0 * np.linalg.norm(d)), triangle_id=np.zeros((1, 1), np.int32))
    cam1 = Camera.look_at((0, 0, 0), d, fov_y_deg=90, near=0.1, far=50)
    c = ref_shading.shade(**fields, camera=cam1, lights=lights, ambient=0.5)[0, 0]
    np.testing.assert_allclose(out.color[15, 15], 0.5 * c, rtol=1e-6)
    assert c[0] > 0.5 * 0.5 * 1.2, "the light adds to the ambient term"


def test_reference_interpolates_normals_and_flips_back_faces():
    """A double-sided quad seen from behind is lit on its visible side; normals interpolate."""
    opaque = np.zeros((SIZE, SIZE, 3))
    light = point_lights([((0.0, 0.0, -1.0), (1.0, 1.0, 1.0), 10.0)])
    m = Material("glass", (1.0, 1.0, 1.0, 0.5), alpha_mode="BLEND", specular_intensity=0.0)
    q = screen_quad(0, SIZE, 0, SIZE, 3.0)
    front = hand_scene((q, None, m))
    back = hand_scene((q[:, ::-1].copy(), -np.full((2, 3, 3), (0.0, 0.0, 1.0)), m))   # reversed winding and normals
    front.lights = back.lights = light
    a = ref.blend(front, PX_CAM, SIZE, SIZE, opaque)
    b = ref.blend(back, PX_CAM, SIZE, SIZE, opaque)
    assert b.fragments.backface.all() and not a.fragments.backface.any()
    np.testing.assert_allclose(a.color, b.color, rtol=1e-6)       # float32 depths round per winding
    assert a.color.max() > 0.2
    # normals tilting across the quad: a smooth gradient, not a flat one
    tilted = np.array([[[-0.5, 0, 1], [0.5, 0, 1], [0.5, 0, 1]], [[-0.5, 0, 1], [0.5, 0, 1], [-0.5, 0, 1]]])
    c = ref.blend(hand_scene((q, tilted / np.linalg.norm(tilted, axis=-1, keepdims=True), m)), PX_CAM, SIZE,
                  SIZE, opaque, lights=point_lights([((-3.0, 0.0, -3.0), (1.0, 1.0, 1.0), 10.0)]))
    # by hand: on a face-on quad the perspective-correct weights are affine in the screen position
    lp = np.array([-3.0, 0.0, -3.0])
    for x in (1, 9, 16, 23, 30):
        u = (x + 0.5) / SIZE
        n = np.array([-0.5 + u, 0.0, 1.0])
        n /= np.linalg.norm(n)
        P = screen_to_world(x + 0.5, 16.5, SIZE, 3.0).astype(np.float64)
        lv = lp - P
        d = np.linalg.norm(lv)
        diffuse = (1 - (d / 10.0) ** 2) ** 3 * max(n @ lv / d, 0.0)
        np.testing.assert_allclose(c.color[16, x], 0.5 * (0.5 + diffuse), rtol=1e-5)
    assert c.color[16, 1, 0] > c.color[16, 16, 0] + 0.05
