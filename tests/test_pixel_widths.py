"""Pixels per work-item (CLRENDER_VEC: 1 on GPUs and Oclgrind, 8 or 16 on CPUs) must not change the
G-buffer or SSAO bits on one device: the same words as on every other implementation where the
kernels use only correctly rounded arithmetic. Intel's CPU runtime computes rsqrt() with other
roundings in its scalar and 16-wide builds than in its 8-wide one (and than PoCL), which moved
normal-mapped G-buffer normals by a 12-bit code; the kernels' RSQRT (kernels/vec.h) is 1/sqrt."""
import numpy as np

import clrender
from clrender.tools import check

# the G-buffer and what is computed from it with +, -, *, / and sqrt only; not the shading, whose
# library functions (pow, exp, sin, ...) may round differently at each width
EXACT_AOVS = ("triangle_id", "material_id", "depth", "normal", "albedo", "base_color", "metallic", "roughness",
              "emissive", "occlusion", "shading_model", "light_count", "ao")


def test_pixel_widths_compute_the_same_g_buffer(device, monkeypatch):
    cases = {name: (scene, camera) for name, scene, camera in check.default_cases(96, 64)}
    scene, camera = cases["materials"]         # normal maps, generated tangents: the RSQRT paths
    frames = {}
    for vec in ("1", "8", "16"):
        monkeypatch.setenv("CLRENDER_VEC", vec)
        frames[vec] = clrender.Renderer(96, 64, device=device.id, ssao=True).render(scene, camera)
    assert (frames["1"].triangle_id >= 0).mean() > 0.3
    for vec in ("8", "16"):
        for aov in EXACT_AOVS:
            np.testing.assert_array_equal(getattr(frames[vec], aov), getattr(frames["1"], aov),
                                          err_msg=f"{aov} at {vec} pixels per work-item")
