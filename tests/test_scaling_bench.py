"""bench/scaling.py's instances axis (bench/big_scene.py): the grid layout of the scene's copies and
the per-pass growth arithmetic."""
import numpy as np
import pytest

from bench.big_scene import grid_offsets, pass_growth, replicate
from bench.scaling import points
from clrender.scene import Scene


def _scene():
    """Two triangles over four vertices, extent (2, 1, 3)."""
    pos = np.array([[0, 0, 0], [2, 0, 0], [0, 1, 3], [2, 1, 3]], np.float32)
    return Scene(positions=pos, normals=np.tile(np.float32([0, 1, 0]), (4, 1)), uvs=np.zeros((4, 2), np.float32),
                 triangles=np.array([[0, 1, 2], [1, 3, 2]], np.int32), triangle_material=np.zeros(2, np.int32))


@pytest.mark.parametrize("copies, cols", [(1, 1), (2, 2), (4, 2), (5, 3), (16, 4), (17, 5), (40, 7)])
def test_grid_offsets_fill_rows_of_ceil_sqrt_columns(copies, cols):
    off = grid_offsets(copies, (2.5, 9.0, 3.25))
    want = [[k % cols * 2.5, 0.0, k // cols * 3.25] for k in range(copies)]      # independent: exact in float32
    assert off.dtype == np.float32 and off.shape == (copies, 3)
    assert off.tolist() == want
    assert len({tuple(o) for o in off.tolist()}) == copies                      # no two copies in one place


def test_grid_offsets_refuse_no_copies():
    with pytest.raises(ValueError):
        grid_offsets(0, (1, 1, 1))


def test_replicate_on_a_grid_moves_each_copy_and_keeps_the_rest():
    s = _scene()
    lo, hi = s.bounds().astype(np.float64)
    g = replicate(s, 4, grid_offsets(4, hi - lo))
    assert g.triangle_count == 4 * s.triangle_count and len(g.positions) == 16
    for k, (dx, dz) in enumerate([(0, 0), (2, 0), (0, 3), (2, 3)]):
        np.testing.assert_array_equal(g.positions[4 * k: 4 * k + 4], s.positions + np.float32([dx, 0, dz]))
        np.testing.assert_array_equal(g.triangles[2 * k: 2 * k + 2], s.triangles + 4 * k)
    np.testing.assert_array_equal(g.bounds(), [[0, 0, 0], [4, 1, 6]])           # touching, not overlapping
    stacked = replicate(s, 4)                                                   # the triangles axis: in place
    np.testing.assert_array_equal(stacked.bounds(), s.bounds())
    with pytest.raises(ValueError):
        replicate(s, 4, grid_offsets(3, hi - lo))


def test_points_of_the_instances_axis():
    got = points(["instances"], (1, 4, 16, 40))
    assert [x for _, x, _ in got] == [1, 4, 16, 40]
    assert all(s["grid"] and s["size"] == (1280, 720) and s["lights"] == 256 for _, _, s in got)
    assert 40 * 262087 > 10_000_000                                             # Sponza x40: a 10M-triangle scene


def test_pass_growth_is_ms_per_million_triangles_between_rendered_points():
    def entry(x, tris, setup, shade):
        return {"x": x, "triangles": tris, "clrender": {
            "pass_ms": {"setup_ms": setup, "shade_ms": shade}, "passes_ms": setup + shade,
            "render_wall_ms": setup + shade + 1, "user_frame_ms": setup + shade + 2}}
    failed = {"x": 8, "triangles": 8_000_000, "clrender": {"error": "DeviceMemoryError"}}
    g = pass_growth([entry(1, 1_000_000, 10, 50), failed, entry(4, 4_000_000, 40, 53)])
    assert len(g) == 1 and (g[0]["from"], g[0]["to"]) == (1, 4)
    assert g[0]["ms_per_million_triangles"] == {"setup_ms": 10.0, "shade_ms": 1.0, "passes_ms": 11.0,
                                               "render_wall_ms": 11.0, "user_frame_ms": 11.0}

