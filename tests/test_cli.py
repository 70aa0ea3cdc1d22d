"""The command line (`clrender render | devices | info`), called in-process through `main()`,
and once as `python -m clrender` to check the entry point."""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from clrender.outputs import aov_io
from clrender.cli import app as cli
from helpers import record_render_configs

REPO = Path(__file__).resolve().parent.parent

try:
    import clrender.loaders  # noqa: F401
    _LOADERS_MISSING = None
except ImportError as exc:                                  # being written elsewhere
    _LOADERS_MISSING = f"clrender.loaders cannot be imported ({exc})"

needs_loaders = pytest.mark.skipif(_LOADERS_MISSING is not None, reason=_LOADERS_MISSING or "")

W, H = 64, 48
EYE, TARGET, FOV = (0.0, 0.0, 3.0), (0.0, 0.0, 0.0), 50.0
CAMERA_ARGS = ["--camera-eye", "0,0,3", "--camera-target", "0,0,0", "--fov", "50"]
ALL_AOVS = ["depth", "normal", "albedo", "triangle_id", "velocity"]

# A 2x2 square in the z=0 plane, facing +Z: two triangles, no material (white, double-sided).
QUAD_OBJ = """\
v -1 -1 0
v 1 -1 0
v 1 1 0
v -1 1 0
f 1 2 3
f 1 3 4
"""


def _error_line(capsys) -> str:
    """stderr must be exactly one `clrender: error: ...` line, without a traceback."""
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("clrender: error: "), err
    assert "Traceback" not in err
    return lines[0]


@pytest.fixture
def quad(tmp_path) -> Path:
    path = tmp_path / "quad.obj"
    path.write_text(QUAD_OBJ)
    return path


@pytest.fixture(autouse=True)
def _no_debug(monkeypatch):
    monkeypatch.delenv(cli.ENV_DEBUG, raising=False)


def _have_devices() -> bool:
    from clrender.device.core import list_devices
    return bool(list_devices())


# -- devices ------------------------------------------------------------------------------------------
def test_devices_table_and_json(capsys):
    if not _have_devices():
        pytest.skip("no OpenCL device")
    assert cli.main(["devices"]) == 0
    table = capsys.readouterr().out
    assert "KERNELS" in table and "0:0" in table

    assert cli.main(["devices", "--json"]) == 0
    records = json.loads(capsys.readouterr().out)
    assert len(records) >= 1
    assert sum(r["default"] for r in records) <= 1
    for r in records:
        assert {"id", "platform", "name", "label", "default", "kernels", "kernels_error"} <= set(r)
        assert r["kernels"] in ("ok", "failed")
        assert (r["kernels_error"] is None) == (r["kernels"] == "ok")
        # the capabilities.summary() limits
        assert {"type", "compute_units", "max_work_group_size", "local_mem_bytes", "global_mem_bytes",
                "int64_atomics"} <= set(r)


def test_python_m_clrender_devices():
    if not _have_devices():
        pytest.skip("no OpenCL device")
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(REPO), os.environ.get("PYTHONPATH", "")]))
    env.pop(cli.ENV_DEBUG, None)
    proc = subprocess.run([sys.executable, "-m", "clrender", "devices", "--json"], cwd=REPO, env=env,
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert len(json.loads(proc.stdout)) >= 1


# -- render -------------------------------------------------------------------------------------------
@needs_loaders
def test_render_png(quad, tmp_path, device, capsys):
    import imageio.v3 as iio

    out = tmp_path / "out" / "quad.png"
    rc = cli.main(["render", str(quad), "-o", str(out), "--width", str(W), "--height", str(H),
                   "--device", device.id, *CAMERA_ARGS])
    assert rc == 0, capsys.readouterr().err
    err = capsys.readouterr().err
    assert f"[1/1] {quad} -> {out}" in err and "2 triangles" in err and "passes (ms):" in err
    img = iio.imread(out)
    assert img.shape[:2] == (H, W)
    assert img.max() > 0, "image is all black"
    # No lights: the white material shows the ambient term, tone-mapped (grey, not black).
    from clrender.abi.gbuffer import linear_to_srgb8
    ambient = 0.03
    expect = int(linear_to_srgb8(np.float32(ambient / (1 + ambient))))
    assert (np.abs(img[H // 2, W // 2, :3].astype(int) - expect) <= 1).all(), img[H // 2, W // 2]
    assert (img[0, 0, :3] == 0).all(), "the corner is background"


@needs_loaders
def test_render_aovs_match_library(quad, tmp_path, device, capsys):
    import imageio.v3 as iio

    import clrender

    out = tmp_path / "q.png"
    rc = cli.main(["render", str(quad), "-o", str(out), "--width", str(W), "--height", str(H),
                   "--device", device.id, "--aov", ",".join(ALL_AOVS), "--quiet", *CAMERA_ARGS])
    assert rc == 0, capsys.readouterr().err
    assert capsys.readouterr().err == "", "--quiet prints nothing"

    camera = clrender.Camera.look_at(EYE, TARGET, fov_y_deg=FOV)
    frame = clrender.Renderer(W, H, device=device.id).render(clrender.load_scene(quad), camera)

    ids = np.load(tmp_path / "q.triangle_id.npy")
    assert ids.dtype == frame.triangle_id.dtype
    np.testing.assert_array_equal(ids, frame.triangle_id)
    assert set(np.unique(ids).tolist()) == {-1, 0, 1}

    depth = np.load(tmp_path / "q.depth.npy")
    fg = frame.triangle_id >= 0
    assert np.isinf(depth[~fg]).all()
    np.testing.assert_allclose(depth[fg], frame.depth[fg], rtol=1e-5)
    np.testing.assert_array_equal(np.load(tmp_path / "q.albedo.npy"), frame.albedo)

    exr = [p for p in tmp_path.iterdir() if p.suffix == ".exr"]
    for aov in ALL_AOVS:
        data = np.load(tmp_path / f"q.{aov}.npy")
        assert data.shape[:2] == (H, W)
        preview = iio.imread(tmp_path / f"q.{aov}.png")
        assert preview.shape[:2] == (H, W) and preview.dtype == np.uint8
    # EXR only with --exr (one multi-layer file per frame; tests/test_outputs.py)
    assert exr == []

    ids_png = iio.imread(tmp_path / "q.triangle_id.png")
    assert (ids_png[~fg] == 0).all() and (ids_png[fg].max(-1) > 0).all()
    depth_png = iio.imread(tmp_path / "q.depth.png")
    assert (depth_png[~fg] == 0).all() and (depth_png[fg] > 0).all()


@needs_loaders
def test_render_batch_directory_and_pattern(tmp_path, device, capsys):
    import imageio.v3 as iio

    for name in ("a", "b"):
        (tmp_path / f"{name}.obj").write_text(QUAD_OBJ)
    scenes = [str(tmp_path / "a.obj"), str(tmp_path / "b.obj")]
    common = ["--width", "32", "--height", "24", "--device", device.id, *CAMERA_ARGS]

    assert cli.main(["render", *scenes, "-o", str(tmp_path / "dir"), *common]) == 0
    err = capsys.readouterr().err
    assert "[1/2]" in err and "[2/2]" in err
    for name in ("a", "b"):
        assert iio.imread(tmp_path / "dir" / f"{name}.png").shape[:2] == (24, 32)

    assert cli.main(["render", *scenes, "-o", str(tmp_path / "pat" / "{name}_x.jpg"), "-q", *common]) == 0
    assert sorted(p.name for p in (tmp_path / "pat").iterdir()) == ["a_x.jpg", "b_x.jpg"]


@needs_loaders
def test_render_refuses_to_write_an_output_twice(tmp_path, capsys):
    for sub in ("one", "two"):
        (tmp_path / sub).mkdir()
        (tmp_path / sub / "box.obj").write_text(QUAD_OBJ)
    scenes = [str(tmp_path / "one" / "box.obj"), str(tmp_path / "two" / "box.obj")]
    out = tmp_path / "out"
    assert cli.main(["render", *scenes, "-o", str(out), "--width", "16", "--height", "16"]) != 0
    assert "box.png" in _error_line(capsys)
    assert not out.exists(), "nothing is rendered when outputs collide"

    # several scenes into one file
    assert cli.main(["render", *scenes, "-o", str(tmp_path / "one.png")]) != 0
    assert "{name}" in _error_line(capsys)


@needs_loaders
def test_render_size_from_scene_settings(quad, tmp_path, device, capsys):
    import imageio.v3 as iio

    toml = tmp_path / "scene.toml"
    toml.write_text(f'[[mesh]]\npath = "{quad.name}"\n\n[camera]\neye = [0, 0, 3]\ntarget = [0, 0, 0]\n\n'
                    f'[render]\nwidth = 40\nheight = 30\n')
    out = tmp_path / "s.png"
    assert cli.main(["render", str(toml), "-o", str(out), "--device", device.id, "-q"]) == 0
    assert iio.imread(out).shape[:2] == (30, 40)
    # one side given: the other keeps the scene's aspect ratio
    assert cli.main(["render", str(toml), "-o", str(out), "--device", device.id, "-q", "--width", "20"]) == 0
    assert iio.imread(out).shape[:2] == (15, 20)


@needs_loaders
def test_transparency_options_reach_the_config(quad, tmp_path, device, capsys, monkeypatch):
    """--transparency/--peel-layers/--max-fragments-per-pixel/--refraction become the RenderConfig
    fields of the same names; without them the config keeps its defaults."""
    from clrender.render import renderer as renderer_module

    seen = record_render_configs(monkeypatch)
    common = [str(quad), "--width", "16", "--height", "12", "--device", device.id, "-q", *CAMERA_ARGS]
    assert cli.main(["render", *common, "-o", str(tmp_path / "a.png"), "--transparency", "depth_peeling",
                     "--peel-layers", "8", "--max-fragments-per-pixel", "3", "--refraction"]) == 0, \
        capsys.readouterr().err
    assert cli.main(["render", *common, "-o", str(tmp_path / "b.png"), "--transparency", "screen_door",
                     "--max-fragments-per-pixel", "0"]) == 0, capsys.readouterr().err
    assert cli.main(["render", *common, "-o", str(tmp_path / "c.png")]) == 0, capsys.readouterr().err
    assert len(seen) == 3
    fields = lambda c: (c.transparency, c.peel_layers, c.max_fragments_per_pixel, c.refraction)  # noqa: E731
    assert fields(seen[0]) == ("depth_peeling", 8, 3, True)
    assert fields(seen[1]) == ("screen_door", 4, 0, False)
    default = renderer_module.RenderConfig()
    assert fields(seen[2]) == fields(default) == ("abuffer", 4, 0, False)


@needs_loaders
def test_render_fragment_count_and_transmittance_aovs(quad, tmp_path, device, capsys):
    """--aov fragment_count,transmittance: .npy with the Frame's dtypes and (H, W) shape, .png
    previews, no .exr without --exr. The quad is opaque, so
    there are no fragments: count 0 and transmittance 1 everywhere (docs/transparency.md)."""
    import imageio.v3 as iio

    out = tmp_path / "t.png"
    rc = cli.main(["render", str(quad), "-o", str(out), "--width", str(W), "--height", str(H),
                   "--device", device.id, "--aov", "fragment_count,transmittance", "-q", *CAMERA_ARGS])
    assert rc == 0, capsys.readouterr().err
    count = np.load(tmp_path / "t.fragment_count.npy")
    trans = np.load(tmp_path / "t.transmittance.npy")
    assert (count.dtype, count.shape) == (np.int32, (H, W))
    assert (trans.dtype, trans.shape) == (np.float32, (H, W))
    assert (count == 0).all() and (trans == 1).all()
    heat, grey = iio.imread(tmp_path / "t.fragment_count.png"), iio.imread(tmp_path / "t.transmittance.png")
    assert heat.shape == (H, W, 3) and heat.dtype == np.uint8 and (heat == 0).all()
    assert grey.shape == (H, W) and grey.dtype == np.uint8 and (grey == 255).all()
    assert not (tmp_path / "t.fragment_count.exr").exists()
    assert not (tmp_path / "t.transmittance.exr").exists()      # EXR only with --exr (test_outputs.py)
    assert "fragment_count" in aov_io.INT_AOVS and "transmittance" not in aov_io.INT_AOVS


# -- errors -------------------------------------------------------------------------------------------
def test_missing_scene_is_one_line(tmp_path, capsys):
    missing = tmp_path / "missing.obj"
    assert cli.main(["render", str(missing), "-o", str(tmp_path / "x.png")]) != 0
    assert "missing.obj" in _error_line(capsys)
    assert cli.main(["info", str(missing)]) != 0
    assert "missing.obj" in _error_line(capsys)
    assert not (tmp_path / "x.png").exists()


@needs_loaders
def test_bad_scene_is_one_line(tmp_path, capsys):
    bad = tmp_path / "bad.toml"
    bad.write_text("[[mesh]]\npath = 3\n")
    assert cli.main(["info", str(bad)]) != 0
    assert "bad.toml" in _error_line(capsys)
    unsupported = tmp_path / "scene.xyz"
    unsupported.write_text("")
    assert cli.main(["render", str(unsupported), "-o", str(tmp_path / "x.png")]) != 0
    assert "unsupported" in _error_line(capsys)


def test_unknown_aov_is_an_error(quad, tmp_path, capsys):
    assert cli.main(["render", str(quad), "-o", str(tmp_path / "x.png"), "--aov", "depth,bogus"]) != 0
    line = _error_line(capsys)
    assert "bogus" in line and "triangle_id" in line


@pytest.mark.parametrize("option", [["--width", "0"], ["--height", "-3"], ["--fov", "180"],
                                    ["--camera-eye", "1,2"], ["--camera-target", "a,b,c"], ["--tile-size", "12"]])
def test_bad_option_values(quad, tmp_path, capsys, option):
    assert cli.main(["render", str(quad), "-o", str(tmp_path / "x.png"), *option]) != 0
    assert option[0] in _error_line(capsys)


def test_bad_transparency_values_are_one_line(quad, tmp_path, capsys):
    base = ["render", str(quad), "-o", str(tmp_path / "x.png")]
    assert cli.main([*base, "--transparency", "glass"]) == 2
    line = _error_line(capsys)
    assert "--transparency" in line and "'glass'" in line
    assert all(v in line for v in ("abuffer", "depth_peeling", "screen_door")), line
    for option, words in ((["--peel-layers", "65"], ["64", "65"]), (["--peel-layers", "0"], ["'0'"]),
                          (["--peel-layers", "two"], ["'two'"]),
                          (["--max-fragments-per-pixel", "-1"], ["'-1'", ">= 0"]),
                          (["--max-fragments-per-pixel", "1.5"], ["'1.5'"])):
        assert cli.main([*base, *option]) != 0
        line = _error_line(capsys)
        assert option[0] in line and all(w in line for w in words), line
    assert cli.main([*base, "--refraction", "yes"]) == 2          # a flag takes no value
    _error_line(capsys)
    assert not (tmp_path / "x.png").exists()


def test_bad_output_type(quad, tmp_path, capsys):
    assert cli.main(["render", str(quad), "-o", str(tmp_path / "x.tga")]) != 0
    assert ".tga" in _error_line(capsys)


def test_unknown_device_is_one_line(quad, tmp_path, capsys):
    if not _have_devices():
        pytest.skip("no OpenCL device")
    rc = cli.main(["render", str(quad), "-o", str(tmp_path / "x.png"), "--device", "no-such-device-xyz"])
    assert rc != 0
    assert "no-such-device-xyz" in _error_line(capsys)


def test_usage_errors(capsys):
    assert cli.main([]) == 2
    _error_line(capsys)
    assert cli.main(["frobnicate"]) == 2
    _error_line(capsys)
    assert cli.main(["--help"]) == 0
    assert "render" in capsys.readouterr().out


def test_debug_env_shows_the_exception(tmp_path, monkeypatch):
    monkeypatch.setenv(cli.ENV_DEBUG, "1")
    with pytest.raises(Exception, match="missing.obj"):
        cli.main(["info", str(tmp_path / "missing.obj")])


# -- info ---------------------------------------------------------------------------------------------
@needs_loaders
def test_info_json(quad, tmp_path, capsys):
    assert cli.main(["info", str(quad), "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["triangles"] == 2 and info["vertices"] == 4
    assert info["meshes"] >= 1
    assert info["materials"] == 1
    assert info["alpha_masked_materials"] == 0 and info["single_sided_materials"] == 0
    assert info["textures"] == 0 and info["texture_sizes"] == []
    assert info["bounds_min"] == [-1.0, -1.0, 0.0] and info["bounds_max"] == [1.0, 1.0, 0.0]
    assert info["camera"] is None

    toml = tmp_path / "scene.toml"
    toml.write_text(f'[[mesh]]\npath = "{quad.name}"\n\n[camera]\neye = [0, 1, 5]\ntarget = [0, 0, 0]\n'
                    f'fov_y_deg = 40\n\n[render]\nwidth = 40\nheight = 30\n')
    assert cli.main(["info", str(toml), "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["camera"] == {"eye": [0.0, 1.0, 5.0], "target": [0.0, 0.0, 0.0], "fov_y_deg": 40.0}
    assert info["settings"]["render"] == {"width": 40, "height": 30}

    assert cli.main(["info", str(toml)]) == 0
    text = capsys.readouterr().out
    assert "triangles" in text and "fov 40 deg" in text


@needs_loaders
def test_info_counts_transparent_materials(quad, tmp_path, capsys):
    """`info` reports BLEND materials next to the alpha-masked ones: here glass by a [[material]]
    table (both meshes) and the second mesh's leaf by its opacity."""
    quad.with_suffix(".mtl").write_text("newmtl glass\nKd 1 1 1\nnewmtl leaf\nKd 0 1 0\n")
    quad.write_text("mtllib quad.mtl\nusemtl glass\n" + QUAD_OBJ.replace("f 1 3 4", "usemtl leaf\nf 1 3 4"))
    assert cli.main(["info", str(quad), "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert (info["materials"], info["transparent_materials"], info["alpha_masked_materials"]) == (2, 0, 0)
    toml = tmp_path / "scene.toml"
    toml.write_text(f'[[mesh]]\npath = "{quad.name}"\n[[mesh]]\npath = "{quad.name}"\nopacity = 0.5\n'
                    f'[[material]]\nname = "gl*"\nalpha_mode = "BLEND"\n')
    assert cli.main(["info", str(toml), "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert (info["materials"], info["transparent_materials"], info["alpha_masked_materials"]) == (4, 3, 0)
    assert cli.main(["info", str(toml)]) == 0
    assert "4 (0 alpha-masked, 3 transparent, 0 single-sided)" in capsys.readouterr().out


# -- previews (NumPy only) ----------------------------------------------------------------------------
def test_previews():
    ids = np.array([[-1, 0, 1], [7, 7, -1]], np.int32)
    bg = ids < 0
    colors = aov_io.preview("triangle_id", ids, bg)
    assert colors.shape == (2, 3, 3) and colors.dtype == np.uint8
    assert (colors[bg] == 0).all() and (colors[~bg].max(-1) > 0).all()
    assert (colors[1, 0] == colors[1, 1]).all() and not (colors[0, 1] == colors[0, 2]).all()
    np.testing.assert_array_equal(colors, aov_io.preview("triangle_id", ids, bg))   # stable

    depth = np.array([[np.inf, 1.0, 2.0], [3.0, 3.0, np.inf]], np.float32)
    gray = aov_io.preview("depth", depth, bg)
    assert (gray[bg] == 0).all() and gray[0, 1] == 255 and 0 < gray[1, 0] < gray[0, 2] < gray[0, 1]

    still = aov_io.preview("velocity", np.zeros((2, 3, 2), np.float32), bg)
    assert (still == 0).all()
    moving = aov_io.preview("velocity", np.array([[[1, 0], [-1, 0], [0, 1]]] * 2, np.float32), bg)
    assert len({tuple(c) for c in moving[0]}) == 3

    normal = aov_io.preview("normal", np.array([[[0, 0, 1]] * 3] * 2, np.float32), bg)
    assert (normal[bg] == 0).all() and (normal[0, 1] == (128, 128, 255)).all()

    counts = np.array([[0, 1, 2], [4, 4, 0]], np.int32)
    heat = aov_io.preview("fragment_count", counts, bg)
    assert heat.shape == (2, 3, 3) and heat.dtype == np.uint8
    assert (heat[0, 0] == 0).all() and (heat[1, 0] == 255).all()            # none: black; the most: white
    assert heat[0, 1].sum() < heat[0, 2].sum() < heat[1, 0].sum()
    np.testing.assert_array_equal(heat, aov_io.preview("light_count", counts, bg))
    trans = aov_io.preview("transmittance", np.array([[1, 0.5, 0], [0.25, 1, 1]], np.float32), bg)
    assert trans.dtype == np.uint8 and trans.tolist() == [[255, 128, 0], [64, 255, 255]]


@needs_loaders
def test_batch_keeps_going_past_a_bad_scene(quad, tmp_path, device, capsys):
    bad = tmp_path / "bad.toml"
    bad.write_text("[[mesh]]\npath = 3\n")
    out = tmp_path / "out"
    rc = cli.main(["render", str(bad), str(quad), "-o", str(out), "--width", "16", "--height", "16",
                   "--device", device.id, "-q"])
    assert rc != 0
    err = capsys.readouterr().err.strip().splitlines()
    assert any("bad.toml" in line for line in err) and "1 of 2 scenes failed" in err[-1]
    assert (out / "quad.png").exists(), "the good scene is still rendered"


@needs_loaders
def test_post_options_from_flags_and_toml(quad, tmp_path, device, capsys, monkeypatch):
    """Every post option reaches RenderConfig from its flag and from TOML [render]; flags win over
    the file; a bad [render] value is a one-line error naming the file."""
    seen = record_render_configs(monkeypatch)
    common = [str(quad), "--width", "16", "--height", "12", "--device", device.id, "-q", *CAMERA_ARGS]
    flags = ["--supersample", "2", "--supersample-filter", "mitchell", "--bloom", "--bloom-threshold", "0.5",
             "--bloom-strength", "0.3", "--bloom-radius", "8", "--motion-blur", "--shutter", "0.25",
             "--motion-blur-samples", "4", "--hatching", "--hatching-scale", "2", "--hatching-saturation", "0.5"]
    assert cli.main(["render", *common, "-o", str(tmp_path / "a.png"), *flags]) == 0, capsys.readouterr().err
    c = seen[-1]
    assert (c.supersample, c.supersample_filter, c.bloom, c.bloom_threshold, c.bloom_strength, c.bloom_radius,
            c.motion_blur, c.shutter, c.motion_blur_samples, c.hatching, c.hatching_scale, c.hatching_saturation) == \
        (2, "mitchell", True, 0.5, 0.3, 8.0, True, 0.25, 4, True, 2.0, 0.5)

    toml = tmp_path / "scene.toml"
    toml.write_text(f'[[mesh]]\npath = "{quad.name}"\n\n[camera]\neye = [0, 0, 3]\ntarget = [0, 0, 0]\n\n'
                    f'[render]\nwidth = 16\nheight = 12\nbloom = true\nsupersample = 3\nexposure = 2.0\n')
    assert cli.main(["render", str(toml), "-o", str(tmp_path / "t.png"), "--device", device.id, "-q"]) == 0
    assert (seen[-1].bloom, seen[-1].supersample, seen[-1].exposure) == (True, 3, 2.0)
    assert cli.main(["render", str(toml), "-o", str(tmp_path / "t.png"), "--device", device.id, "-q",
                     "--supersample", "1"]) == 0
    assert seen[-1].supersample == 1 and seen[-1].bloom
    toml.write_text(f'[[mesh]]\npath = "{quad.name}"\n\n[render]\nsupersample = 9\n')
    capsys.readouterr()
    assert cli.main(["render", str(toml), "-o", str(tmp_path / "t.png"), "--device", device.id]) != 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "scene.toml" in err[0] and "supersample" in err[0], err
    toml.write_text(f'[[mesh]]\npath = "{quad.name}"\n\n[render]\nbloooom = true\n')
    assert cli.main(["render", str(toml), "-o", str(tmp_path / "t.png"), "--device", device.id]) != 0
    assert "bloooom" in capsys.readouterr().err


@needs_loaders
def test_previous_camera_flags_give_velocity(quad, tmp_path, device):
    out = tmp_path / "v.png"
    assert cli.main(["render", str(quad), "-o", str(out), "--width", "16", "--height", "12", "--device", device.id,
                     "-q", *CAMERA_ARGS, "--previous-eye", "0.2,0,3", "--previous-target", "0.2,0,0",
                     "--aov", "velocity"]) == 0
    vel = np.load(tmp_path / "v.velocity.npy")
    assert np.abs(vel[..., 0]).max() > 0.3 and np.abs(vel[..., 1]).max() < 1e-2
    assert cli.main(["render", str(quad), "-o", str(out), "--width", "16", "--height", "12", "--device", device.id,
                     "-q", *CAMERA_ARGS, "--aov", "velocity"]) == 0
    assert np.abs(np.load(tmp_path / "v.velocity.npy")).max() == 0
