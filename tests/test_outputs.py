"""Output writers (issue 14 item 3, atomic writes of item 2): multi-layer OpenEXR, 16-bit PNG,
video (.mp4 H.264, .gif), and atomic writes (temporary name + os.replace)."""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

import clrender
from clrender.outputs import aov_io
from clrender.outputs import video  # write_video and its ffmpeg check (moved out of aov_io)
from clrender.cli import app as cli
from clrender.abi.gbuffer import linear_to_srgb8

ROOT = Path(__file__).resolve().parent.parent
DEMO = ROOT / "scenes" / "demo.toml"
W, H = 48, 32
FLOAT_AOVS = [a for a in cli.AOVS if a not in aov_io.INT_AOVS]

needs_exr = pytest.mark.skipif(not aov_io.exr_available(), reason="OpenEXR not installed (clrender[outputs])")
needs_ffmpeg = pytest.mark.skipif(not aov_io.ffmpeg_available(), reason="imageio-ffmpeg not installed")


@pytest.fixture(autouse=True)
def _no_debug(monkeypatch):
    monkeypatch.delenv(cli.ENV_DEBUG, raising=False)


@pytest.fixture(scope="module")
def demo_scene():
    return clrender.load_scene(str(DEMO))


@pytest.fixture(scope="module")
def frame(device, demo_scene):
    return clrender.Renderer(W, H, device=device.id).render(demo_scene)


def _psnr(a: np.ndarray, b: np.ndarray) -> float:
    mse = np.mean((a.astype(np.float64) - b.astype(np.float64)) ** 2)
    return float("inf") if mse == 0 else 10 * np.log10(255.0 ** 2 / mse)


def _read_png16(path) -> np.ndarray:
    """Decode with ffmpeg (imageio-ffmpeg) as rgb48: Pillow, imageio's default PNG backend, reads
    16-bit RGB PNGs truncated to 8 bits."""
    import imageio_ffmpeg
    gen = imageio_ffmpeg.read_frames(str(path), pix_fmt="rgb48le", bits_per_pixel=48)
    meta = next(gen)
    w, h = meta["size"]
    data = next(gen)
    gen.close()
    return np.frombuffer(data, "<u2").reshape(h, w, 3)


# -- EXR --------------------------------------------------------------------------------------
@needs_exr
def test_exr_round_trip_every_float_aov_bit_exact(frame, tmp_path):
    path = aov_io.write_exr(tmp_path / "f.exr", frame, FLOAT_AOVS)
    channels = aov_io.read_exr(path)
    expected = {}
    for aov in FLOAT_AOVS:
        expected.update(aov_io.exr_channels(aov, frame.aov(aov)))
    assert set(channels) == set(expected)
    for name in ("color.R", "color.G", "color.B", "depth.Z", "normal.X", "normal.Y", "normal.Z",
                 "velocity.X", "velocity.Y", "ao", "albedo.R", "linear_depth.Z"):
        assert name in channels, name
    for aov in FLOAT_AOVS:
        data = np.asarray(frame.aov(aov)).astype(np.float32)
        data = data[..., None] if data.ndim == 2 else data
        names = list(aov_io.exr_channels(aov, frame.aov(aov)))
        assert len(names) == data.shape[2]
        for i, name in enumerate(names):
            got = channels[name]
            assert got.dtype == np.float32 and got.shape == (H, W), name
            # bit-exact: compare the float32 bit patterns (inf background depth, -0.0, NaN alike)
            np.testing.assert_array_equal(got.view(np.uint32), np.ascontiguousarray(data[..., i]).view(np.uint32),
                                          err_msg=name)
    assert np.isinf(channels["depth.Z"][frame.triangle_id < 0]).all()


@needs_exr
def test_cli_exr_is_one_multilayer_file_matching_the_npy(device, tmp_path, capsys):
    out = tmp_path / "d.png"
    rc = cli.main(["render", str(DEMO), "-o", str(out), "--width", str(W), "--height", str(H), "--device", device.id,
                   "--aov", "depth,normal,velocity,triangle_id", "--exr", "-q"])
    assert rc == 0, capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.glob("*.exr")) == ["d.exr"]
    ch = aov_io.read_exr(tmp_path / "d.exr")
    assert set(ch) == {"color.R", "color.G", "color.B", "depth.Z", "normal.X", "normal.Y", "normal.Z",
                       "velocity.X", "velocity.Y"}          # colour + the float AOVs; no triangle_id
    depth, normal = np.load(tmp_path / "d.depth.npy"), np.load(tmp_path / "d.normal.npy")
    np.testing.assert_array_equal(ch["depth.Z"].view(np.uint32), depth.view(np.uint32))
    np.testing.assert_array_equal(np.stack([ch[f"normal.{c}"] for c in "XYZ"], -1), normal)
    assert not [p for p in tmp_path.iterdir() if ".tmp" in p.name]


def test_cli_exr_missing_binding_is_one_line_error(tmp_path, capsys, monkeypatch):
    monkeypatch.setitem(aov_io._EXR_STATE, "available", False)
    rc = cli.main(["render", str(DEMO), "-o", str(tmp_path / "x.png"), "--exr", "-q"])
    assert rc != 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("clrender: error: --exr") and "OpenEXR" in err[0]
    assert list(tmp_path.iterdir()) == []


# -- 16-bit PNG -------------------------------------------------------------------------------
@needs_ffmpeg
@pytest.mark.parametrize("options", [{}, {"tonemap": "aces", "exposure": 2.0}, {"color_aa": "fxaa"}],
                         ids=["reinhard", "aces-exposure", "fxaa-ldr-planes"])
def test_png16_from_float_colour(device, demo_scene, tmp_path, options):
    """v16 = round(65535 · srgb(tonemapped float)); relation tested: |round(v16 / 257) − image8| <= 1
    everywhere; the 16-bit image is not the 8-bit one scaled (v16 % 257 != 0 somewhere); and the
    NumPy operator re-encoded to 8 bits equals the kernel's image within 1 code."""
    import imageio.v3 as iio

    f = clrender.Renderer(W, H, device=device.id, **options).render(demo_scene)
    assert (f.ldr is not None) == ("color_aa" in options)
    np.testing.assert_allclose(linear_to_srgb8(aov_io.display_linear(f)), f.image, atol=1)
    path = aov_io.write_image(f, tmp_path / "i16.png", bit_depth=16)
    v16 = _read_png16(path)
    assert v16.dtype == np.uint16 and v16.shape == (H, W, 3)
    np.testing.assert_array_equal(v16, aov_io.image16(f))
    assert np.abs(np.round(v16 / 257.0) - f.image.astype(np.float64)).max() <= 1
    assert (v16 % 257 != 0).any(), "16-bit image is just the 8-bit one scaled"
    assert len(np.unique(v16)) > len(np.unique(f.image))
    pil8 = iio.imread(path)                    # Pillow reads 16-bit RGB as its high bytes
    np.testing.assert_array_equal(pil8, (v16 >> 8).astype(np.uint8))


def test_png16_only_for_png(frame, tmp_path):
    with pytest.raises(ValueError, match="PNG only"):
        aov_io.write_image(frame, tmp_path / "a.jpg", bit_depth=16)
    with pytest.raises(ValueError):
        aov_io.write_image(frame, tmp_path / "a.png", bit_depth=12)
    assert list(tmp_path.iterdir()) == []


def test_cli_bit_depth_16_jpg_is_one_line_error(tmp_path, capsys):
    rc = cli.main(["render", str(DEMO), "-o", str(tmp_path / "x.jpg"), "--bit-depth", "16", "-q"])
    assert rc != 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--bit-depth 16" in err[0]


# -- video ------------------------------------------------------------------------------------
def _orbit_frames(device, scene, n=4):
    r = clrender.Renderer(W, H, device=device.id)
    cam = scene.default_camera()
    eye, target = np.asarray(cam.eye, float), np.asarray(cam.target, float)
    frames = []
    for k in range(n):
        a = np.radians(12.0 * k)
        d = eye - target
        rot = np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]])
        c = clrender.Camera.look_at(tuple(target + rot @ d), tuple(target), cam.up, cam.fov_y_deg,
                                    near=cam.near, far=cam.far)
        frames.append(r.render(scene, c))
    return frames


@pytest.fixture(scope="module")
def orbit(device, demo_scene):
    return _orbit_frames(device, demo_scene)


def _read_video(path) -> np.ndarray:
    import imageio.v3 as iio
    return np.asarray(iio.imread(path, index=None))


@needs_ffmpeg
def test_mp4_frames_count_size_psnr(orbit, tmp_path):
    """H.264 (CRF 18, yuv420p) is lossy: every decoded frame k is within PSNR > 30 dB of input k,
    and closer to k than to any other input frame (measured 34-35 dB; ~21 dB to frame k+1)."""
    paths = [aov_io.write_image(f, tmp_path / f"frame_{k:04d}.png") for k, f in enumerate(orbit)]
    video = aov_io.write_video(tmp_path / "v.mp4", paths, fps=10)
    assert video.is_file() and video.stat().st_size > 0
    import imageio.v3 as iio
    decoded = np.asarray(iio.imread(video, index=None, plugin="FFMPEG"))
    assert decoded.shape == (len(orbit), H, W, 3)
    meta = iio.immeta(video, plugin="FFMPEG")
    assert meta["fps"] == pytest.approx(10) and meta["codec"] == "h264"
    for k, f in enumerate(orbit):
        psnr = _psnr(decoded[k], f.image)
        assert psnr > 30, (k, psnr)
        others = [_psnr(decoded[k], g.image) for j, g in enumerate(orbit) if j != k]
        assert psnr > max(others), (k, psnr, others)
    assert not [p for p in tmp_path.iterdir() if ".tmp" in p.name]


def test_gif_frames_count_size_psnr(orbit, tmp_path):
    """GIF: a 256-colour palette per frame; decoded frame k within PSNR > 35 dB of input k (measured ~44)."""
    video = aov_io.write_video(tmp_path / "v.gif", orbit, fps=12)
    decoded = _read_video(video)[..., :3]
    assert decoded.shape == (len(orbit), H, W, 3)
    for k, f in enumerate(orbit):
        assert _psnr(decoded[k], f.image) > 35, k


def test_video_bad_input(orbit, tmp_path, monkeypatch):
    with pytest.raises(ValueError, match="unsupported video type"):
        aov_io.write_video(tmp_path / "v.avi", orbit)
    with pytest.raises(ValueError, match="different sizes"):
        aov_io.write_video(tmp_path / "v.gif", [orbit[0].image, orbit[1].image[:, :-2]])
    with pytest.raises(ValueError, match="no frames"):
        aov_io.write_video(tmp_path / "v.gif", [])
    monkeypatch.setattr(video, "ffmpeg_available", lambda: False)
    with pytest.raises(RuntimeError, match="imageio-ffmpeg"):
        aov_io.write_video(tmp_path / "v.mp4", orbit)
    assert list(tmp_path.iterdir()) == []


def test_cli_missing_ffmpeg_is_one_line_error_before_rendering(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(video, "ffmpeg_available", lambda: False)
    rc = cli.main(["render", str(DEMO), "-o", str(tmp_path / "x.png"), "--video", str(tmp_path / "v.mp4"), "-q"])
    assert rc != 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("clrender: error: --video") and "ffmpeg" in err[0]
    assert list(tmp_path.iterdir()) == []                  # nothing rendered or written


@needs_ffmpeg
def test_cli_video_and_16_bit(device, tmp_path, capsys):
    crate = ROOT / "scenes" / "crate.obj"
    rc = cli.main(["render", str(DEMO), str(crate), "-o", str(tmp_path / "{index}_{name}.png"), "--width", str(W),
                   "--height", str(H), "--device", device.id, "--bit-depth", "16", "--video", str(tmp_path / "v.mp4"),
                   "--fps", "5", "-q"])
    assert rc == 0, capsys.readouterr().err
    assert _read_png16(tmp_path / "1_demo.png").dtype == np.uint16
    import imageio.v3 as iio
    decoded = np.asarray(iio.imread(tmp_path / "v.mp4", index=None, plugin="FFMPEG"))
    assert decoded.shape == (2, H, W, 3)


# -- atomic writes ----------------------------------------------------------------------------
def _fail_replace(*args, **kwargs):
    raise OSError("injected failure between write and rename")


@pytest.mark.parametrize("what", ["png8", "png16", "npy", "exr", "gif", "mp4"])
def test_failure_before_rename_leaves_nothing(frame, orbit, tmp_path, monkeypatch, what):
    if what == "exr" and not aov_io.exr_available():
        pytest.skip("OpenEXR not installed")
    if what == "mp4" and not aov_io.ffmpeg_available():
        pytest.skip("imageio-ffmpeg not installed")
    seen = []
    real_replace = os.replace

    def spy(src, dst):           # the temporary file is complete and beside the target when renamed
        seen.append((Path(src), Path(dst), Path(src).stat().st_size))
        _fail_replace()
    monkeypatch.setattr(aov_io.os, "replace", spy)
    target = tmp_path / {"png8": "a.png", "png16": "a.png", "npy": "a.npy", "exr": "a.exr", "gif": "a.gif",
                         "mp4": "a.mp4"}[what]
    with pytest.raises(OSError, match="injected"):
        if what in ("png8", "png16"):
            aov_io.write_image(frame, target, 16 if what == "png16" else 8)
        elif what == "npy":
            aov_io._save_npy(target, frame.depth)
        elif what == "exr":
            aov_io.write_exr(target, frame, ["depth", "normal"])
        else:
            aov_io.write_video(target, orbit, fps=8)
    assert len(seen) == 1
    src, dst, size = seen[0]
    assert dst == target and src.parent == target.parent and src != target and size > 0
    assert not target.exists()
    assert list(tmp_path.iterdir()) == [], "temporary file left behind"
    monkeypatch.setattr(aov_io.os, "replace", real_replace)


def test_failing_writer_keeps_previous_file(tmp_path):
    target = tmp_path / "keep.png"
    target.write_bytes(b"complete old content")

    def half_then_fail(tmp):
        with open(tmp, "wb") as f:
            f.write(b"partial")
        raise RuntimeError("writer died")
    with pytest.raises(RuntimeError, match="writer died"):
        aov_io.atomic_write(target, half_then_fail)
    assert target.read_bytes() == b"complete old content"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["keep.png"]
    aov_io.atomic_write(target, lambda tmp: Path(tmp).write_bytes(b"new"))
    assert target.read_bytes() == b"new" and sorted(p.name for p in tmp_path.iterdir()) == ["keep.png"]
    umask = os.umask(0o022)
    os.umask(umask)
    assert target.stat().st_mode & 0o777 == 0o666 & ~umask      # not mkstemp's 0600


def test_cli_writes_every_file_through_atomic_write(device, tmp_path, capsys, monkeypatch):
    """Every output of `clrender render` (image, AOV .npy and .png, EXR) passes through os.replace
    from a temporary name in the same folder."""
    renamed = []
    real_replace = os.replace

    def spy(src, dst):
        renamed.append((Path(src), Path(dst)))
        real_replace(src, dst)
    monkeypatch.setattr(aov_io.os, "replace", spy)
    rc = cli.main(["render", str(DEMO), "-o", str(tmp_path / "c.png"), "--width", str(W), "--height", str(H),
                   "--device", device.id, "--aov", "depth,triangle_id", "-q"]
                  + (["--exr"] if aov_io.exr_available() else []))
    assert rc == 0, capsys.readouterr().err
    files = sorted(p for p in tmp_path.iterdir())
    assert sorted(dst for _, dst in renamed) == files
    assert all(src.parent == dst.parent and src.name.startswith(f".{dst.stem}.") for src, dst in renamed)
