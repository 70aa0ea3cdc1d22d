"""The AOV table (clrender/abi/aovs.py) is the one list of a frame's outputs: every row has its
Frame accessor, readback source, preview and EXR channels, the CLI offers exactly its rows, and a
rendered Frame's arrays have the dtypes and shapes it states, with values a small scene predicts."""
from __future__ import annotations

import math
import subprocess
import sys
from dataclasses import replace
from functools import cached_property

import numpy as np
import pytest

from clrender.abi import aovs
from clrender.abi.gbuffer import FIELDS


def table_problems(table) -> list[str]:
    """What a row lacks: a Frame accessor, a device source or fill (buffer rows), a G-buffer field
    (gbuffer rows), a preview that outputs/previews.py draws, EXR channels that fit its channels."""
    from clrender.outputs.previews import DRAW
    from clrender.render.frame import Frame
    from clrender.render.readback import _device_sources

    class Res(dict):
        def __missing__(self, key):
            return 1                                   # shadow_planes: 1, any buffer: a token
    config = type("Config", (), {"ssao": True, "edge_aa": True})()
    sources = _device_sources(config, Res(), True, object())
    problems = []
    for row in table:
        where = f"AOV {row.name!r}"
        if not isinstance(getattr(Frame, row.name, None), (cached_property, property)):
            problems.append(f"{where}: no Frame accessor")
        if row.source not in aovs.SOURCES:
            problems.append(f"{where}: unknown source {row.source!r}")
        if row.source == "buffer" and row.name not in sources:
            problems.append(f"{where}: no device source in clrender/render/readback.py")
        if row.source == "gbuffer" and row.field not in FIELDS:
            problems.append(f"{where}: no G-buffer field {row.field!r}")
        if row.preview not in aovs.PREVIEWS or row.preview not in DRAW:
            problems.append(f"{where}: no preview {row.preview!r}")
        if row.exr is not None and row.exr not in ("", "#"):
            fits = len(row.exr) == (1 if row.channels == 1 else row.channels)
            if not fits:
                problems.append(f"{where}: EXR channels {row.exr!r} for {row.channels} channels")
        if row.exr in ("", "#") and (row.exr == "#") != (row.channels == aovs.VARIABLE):
            problems.append(f"{where}: EXR channels {row.exr!r} for {row.channels} channels")
        if row.exr is None and not row.integer:
            problems.append(f"{where}: a float AOV left out of the EXR")
        np.dtype(row.dtype)
    return problems


def test_every_row_is_complete():
    assert table_problems(aovs.TABLE) == []
    assert len(set(aovs.NAMES)) == len(aovs.TABLE)


def test_the_check_fails_on_an_incomplete_row():
    """Self-check: a row added without its Frame accessor, preview or EXR channels is reported."""
    extra = aovs.AOV("sparkle", "float32", 3, "buffer", "glitter", "XY", "a new output")
    problems = table_problems(aovs.TABLE + (extra,))
    assert any("no Frame accessor" in p for p in problems)
    assert any("no device source" in p for p in problems)
    assert any("no preview" in p for p in problems)
    assert any("EXR channels 'XY'" in p for p in problems)
    no_field = replace(aovs.AOVS["velocity"], name="velocity", field="speed")
    assert any("no G-buffer field" in p for p in table_problems((no_field,)))


def test_writers_and_cli_read_the_table():
    from clrender.cli import app as cli
    from clrender.outputs import aov_io
    from clrender.render.frame import Frame
    assert Frame.AOV_NAMES == aovs.NAMES
    assert cli.AOVS == aovs.WRITTEN == tuple(n for n in aovs.NAMES if n != "image")
    assert set(aov_io.INT_AOVS) == {"triangle_id", "object_id", "material_id", "fragment_count", "edges",
                                    "shading_model"}
    assert list(aov_io.exr_channels("normal", np.zeros((2, 2, 3)))) == ["normal.X", "normal.Y", "normal.Z"]
    assert list(aov_io.exr_channels("shadow", np.zeros((2, 2, 2)))) == ["shadow.0", "shadow.1"]
    assert aov_io.exr_channels("shadow", np.zeros((2, 2, 0))) == {}           # no shadowed light
    assert list(aov_io.exr_channels("depth", np.zeros((2, 2)))) == ["depth.Z"]
    assert list(aov_io.exr_channels("ao", np.zeros((2, 2)))) == ["ao"]
    assert aov_io.exr_layers(None, ["object_id", "depth", "image", "ao"]) == ["color", "depth", "ao"]
    with pytest.raises(ValueError, match="no preview"):
        aov_io.preview("sparkle", np.zeros((2, 2)), np.zeros((2, 2), bool))


def test_cli_parser_imports_no_opencl():
    code = "import clrender.cli.parser, sys; assert 'pyopencl' not in sys.modules, 'pyopencl imported'"
    subprocess.run([sys.executable, "-c", code], check=True)


# -- a rendered frame against the table and against what the scene predicts --------------------
W, H = 64, 48
FOV_Y, EYE_Z, FAR = 45.0, 5.0, 20.0
LEFT, RIGHT = (-2.0, -0.5), (0.5, 2.0)       # two quads at z = 0, x ranges; y in [-1, 1]
KD = {"red": (0.8, 0.1, 0.1), "blue": (0.1, 0.1, 0.8)}


@pytest.fixture(scope="module")
def two_quads(tmp_path_factory):
    from clrender.loaders import load_scene
    folder = tmp_path_factory.mktemp("aov_table")
    (folder / "q.mtl").write_text("".join(f"newmtl {n}\nKd {r} {g} {b}\n" for n, (r, g, b) in KD.items()))
    lines, base = ["mtllib q.mtl"], 1
    for name, (x0, x1), mtl in (("left", LEFT, "red"), ("right", RIGHT, "blue")):
        lines += [f"o {name}", f"v {x0} -1 0", f"v {x1} -1 0", f"v {x1} 1 0", f"v {x0} 1 0", f"usemtl {mtl}",
                  f"f {base} {base + 1} {base + 2}", f"f {base} {base + 2} {base + 3}"]
        base += 4
    (folder / "q.obj").write_text("\n".join(lines) + "\n")
    scene = load_scene(folder / "q.obj")
    scene.set_sun((0.2, -0.3, -1.0), (1.0, 1.0, 1.0), shadow=True, shadow_map_size=256)   # one shadow plane
    return scene


def _pixel(x: float, y: float) -> tuple[int, int]:
    """The (row, column) whose centre ray meets z = 0 nearest (x, y) (the camera at z = EYE_Z looking -z)."""
    tan_y = math.tan(math.radians(FOV_Y) / 2)
    tan_x = tan_y * W / H
    col = int((x / (EYE_Z * tan_x) + 1) / 2 * W)
    row = int((1 - y / (EYE_Z * tan_y)) / 2 * H)
    return row, col


def test_frame_arrays_match_the_table_and_the_scene(two_quads, make_renderer):
    from clrender import Camera
    cam = Camera.look_at((0.0, 0.0, EYE_Z), (0.0, 0.0, 0.0), fov_y_deg=FOV_Y, near=0.5, far=FAR)
    frame = make_renderer(W, H, shading="blinn_phong").render(two_quads, cam)
    k = frame.shadow.shape[-1]
    assert k == 1, "the sun's shadow plane"
    for row in aovs.TABLE:
        a = np.asarray(frame.aov(row.name))
        assert a.dtype == np.dtype(row.dtype), row.name
        assert a.shape == row.shape(H, W, k), row.name

    left, right, gap = _pixel(-1.25, 0.3), _pixel(1.25, 0.3), _pixel(0.0, 1.8)
    names = [m.name for m in two_quads.materials]
    assert frame.object_id[left] == 0 and frame.object_id[right] == 1 and frame.object_id[gap] == -1
    assert names[frame.material_id[left]] == "red" and names[frame.material_id[right]] == "blue"
    assert frame.material_id[gap] == -1
    assert frame.triangle_id[left] in (0, 1) and frame.triangle_id[right] in (2, 3) and frame.triangle_id[gap] == -1
    assert frame.shading_model[left] == 0 and frame.shading_model[gap] == -1
    np.testing.assert_allclose(frame.depth[left], EYE_Z, rtol=1e-5)
    np.testing.assert_allclose(frame.linear_depth[right], EYE_Z / FAR, rtol=1e-5)
    assert np.isinf(frame.depth[gap])
    np.testing.assert_allclose(frame.normal[left], (0, 0, 1), atol=2e-3)
    assert (frame.normal[gap] == 0).all()
    r, c = left
    tan_y = math.tan(math.radians(FOV_Y) / 2)
    expect = (((c + 0.5) * 2 / W - 1) * tan_y * W / H * EYE_Z, (1 - (r + 0.5) * 2 / H) * tan_y * EYE_Z, 0.0)
    np.testing.assert_allclose(frame.position[left], expect, atol=1e-4)
    assert np.isnan(frame.position[gap]).all()
    np.testing.assert_allclose(frame.albedo[left], KD["red"], atol=0.01)        # 8-bit sRGB in the G-buffer
    np.testing.assert_allclose(frame.albedo[right], KD["blue"], atol=0.01)
    assert (frame.velocity == 0).all()                                        # no previous camera
    assert frame.color[left][0] > frame.color[left][2] and frame.image[right][2] > frame.image[right][0]
    assert (frame.ao == 1).all() and (frame.transmittance == 1).all()          # no SSAO, no BLEND surface
    assert (frame.fragment_count == 0).all() and (frame.edges == 0).all()
    assert frame.light_count.min() >= 0

    background = frame.triangle_id < 0
    for row in aovs.TABLE:                   # every row's preview draws, as the CLI's .png would
        picture = frame.preview(row.name)
        assert picture.dtype == np.uint8 and picture.shape == (H, W, 3), row.name
    assert (frame.preview("object_id")[background] == 0).all()
