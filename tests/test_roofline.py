"""bench/roofline.py and roofline_ops.py: the micro-kernels really copy and really compute
(against NumPy), the instruction-count parser attributes launches to passes, and the bytes model
of a tiny frame is the sum of the buffers it names."""
from __future__ import annotations

import numpy as np
import pytest

from bench import roofline, roofline_ops


@pytest.fixture(scope="module")
def probe(device):
    from clrender.device.core import Device
    return roofline.Probe(Device.get(device.id))


def test_copy_kernel_copies(probe):
    src = np.random.default_rng(3).standard_normal(4 * 5000).astype(np.float32)
    assert np.array_equal(probe.copy(src), src)


@pytest.mark.parametrize("kind", ["fma", "mul_add"])
def test_fma_chains_match_numpy(probe, kind):
    """The chains' result depends on every step: a kernel that skipped or folded them would not
    match (mul_add may round twice per step: a tolerance of a few ulps)."""
    items, iters = 96, 37
    out = probe.fma(items, iters, kind)
    ref = roofline.fma_reference(items, iters)
    np.testing.assert_allclose(out, ref, rtol=2e-6)
    assert not np.allclose(out, roofline.fma_reference(items, iters - 1), rtol=2e-6)


OCLGRIND_TEXT = """\
Instructions executed for kernel 'chunk_cull':
              10 - fadd
               4 - call _Z12get_local_idj()
Instructions executed for kernel 'fill':
               2 - store global (4 bytes)
Instructions executed for kernel 'chunk_cull':
               1 - fadd
Instructions executed for kernel 'setup_count':
             100 - fmul
              20 - call _Z4sqrtf(float)
              30 - add
               7 - load global (4 bytes)
               6 - br
               5 - call edge_test()
               4 - call _Z3minii()
Instructions executed for kernel 'scan_blocks':
               5 - add
Instructions executed for kernel 'tonemap_image':
               9 - add
Instructions executed for kernel 'scan_blocks':
               9 - add
Instructions executed for kernel 'shade':
              40 - fadd
               3 - call _Z10atomic_addPU3AS1Vii(int*, int)
               2 - store global (12 bytes)
"""


def test_inst_counts_go_to_the_last_frames_passes():
    passes = roofline_ops.per_pass_counts(roofline_ops.parse_inst_counts(OCLGRIND_TEXT))
    assert passes == {"setup": {"chunks": {"float": 1, "int": 5},
                                "triangles": {"float": 120, "int": 34, "load": 7, "free": 11}},
                      "shade": {"pixels": {"float": 40, "atomic": 3, "store": 2}}}


def test_ops_scale_per_unit_and_shade_per_light_pair():
    small = {"pixels": 100, "triangles": 10, "chunks": 1, "light_pairs": 0}
    runs = {"0": {"counts": small, "passes": {"setup": {"triangles": {"float": 50}},
                                              "shade": {"pixels": {"float": 300}}}},
            "8": {"counts": {**small, "light_pairs": 40}, "passes": {"shade": {"pixels": {"float": 700}}}}}
    big = {"pixels": 1000, "triangles": 10, "chunks": 1, "light_pairs": 1000}
    assert roofline_ops.ops_model(runs, 0, big) == {"setup": {"float": 50.0}, "shade": {"float": 3000.0}}
    # 3 per pixel + (700 - 300) / 40 = 10 per light pair
    assert roofline_ops.ops_model(runs, 8, big)["shade"]["float"] == pytest.approx(3 * 1000 + 10 * 1000)


def test_bytes_model_is_the_sum_of_the_frames_buffers(device):
    import clrender
    from clrender.abi import structs
    from lighting_cases import CAMERA, light_array, random_lights, room_scene
    w, h = 64, 48
    scene = room_scene()
    scene.lights = light_array(random_lights(5, seed=2))
    r = clrender.Renderer(w, h, device=device.id)
    frame = r.render(scene, CAMERA)
    res = r._scene_resources(scene)
    counts = roofline.frame_counts(r, res, frame.stats)
    model = {p: sum(t.values()) for p, t in roofline.bytes_model(r, res, counts).items()}
    px, prim = w * h, structs.prim_dtype.itemsize
    vis = r.pipeline.raster.vis_prim.get()
    visible = np.unique(vis[vis >= 0]).size
    assert 0 < visible == counts["visible_prims"] <= frame.stats["prims"]
    nv = len(scene.positions)                   # positions, normals, uvs (+ tangents, when the scene has them)
    vertex = (12 + 12 + 8) * nv + res.buffers["tangents"].nbytes
    assert res.buffers["positions"].nbytes == 12 * nv and res.buffers["uvs"].nbytes == 8 * nv
    lc = r.pipeline.light_cull
    light_tiles = lc.tiles_x * lc.tiles_y
    entries = int(lc.counts.get()[:light_tiles].sum())
    assert model["gbuffer"] == 8 * px + int(visible * (prim + 16 + 3 * vertex / nv)) + 4 * 6 * px
    assert model["light_cull"] == 4 * px + res["lights"].nbytes + 8 * light_tiles + 4 * entries
    assert model["shade"] == 16 * px + 8 * light_tiles + 4 * entries + res["lights"].nbytes + 4 * visible + 24 * px
    tiles = r.pipeline.binning.tiles_x * r.pipeline.binning.tiles_y
    assert model["binning"] == prim * frame.stats["prims"] + 8 * tiles + 4 * frame.stats["tile_entries"]
    assert model["raster"] == model["binning"] + 8 * px
