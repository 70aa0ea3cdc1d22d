"""The CLI's outputs, interrupts and one-line errors (issue 34, items 5, 6, 8):

* an output that is one of the scene's own files (its texture, MTL, buffer...) is an error before
  anything renders, in `render`, `render --frames` and `dataset`; an unwritable output is too,
  naming the output (never a hidden temporary file);
* temporary files left by a killed writer are removed by the next write into the folder and by
  `--resume`; a full disk is one line naming the file, no "Exception ignored" tracebacks;
* Ctrl-C during trimesh's import, a kernel build, a device probe or a frame loop ends the job with
  exit 130 and one line, and poisons no cache;
* loader failures nobody anticipated (AttributeError, MemoryError, RecursionError) are SceneError
  lines naming the file; truncated STL, a corrupt EXR header and `--seed -1` name what is wrong.
"""
from __future__ import annotations

import errno
import os
import shutil
import signal
import struct
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest

from clrender.cli import app as cli
from clrender.scene.model import SceneError
from helpers import in_ci

ROOT = Path(__file__).resolve().parents[1]
SCENES = ROOT / "scenes"
SMALL = ["--width", "24", "--height", "16", "-q"]


def _crate(tmp_path) -> Path:
    """A copy of the bundled textured OBJ crate (crate.obj, crate.mtl, crate.png) in its own folder."""
    folder = tmp_path / "scene"
    folder.mkdir()
    for name in ("crate.obj", "crate.mtl", "crate.png"):
        shutil.copy(SCENES / name, folder / name)
    return folder / "crate.obj"


def _run_cli(capsys, *argv) -> tuple[int, str]:
    rc = cli.main([str(a) for a in argv])
    err = capsys.readouterr().err
    return rc, err


def _error_lines(err: str) -> list[str]:
    return [ln for ln in err.splitlines() if ln.strip()]


# -- outputs never destroy inputs -----------------------------------------------------------------
def test_render_into_the_scene_folder_refuses_to_overwrite_its_texture(tmp_path, capsys):
    obj = _crate(tmp_path)
    texture = obj.parent / "crate.png"
    before = texture.read_bytes()
    rc, err = _run_cli(capsys, "render", obj, "-o", obj.parent, *SMALL)
    assert rc == 1
    lines = _error_lines(err)
    assert len(lines) == 1, err
    assert "crate.png" in lines[0] and str(obj) in lines[0] and "overwrite" in lines[0], lines[0]
    assert texture.read_bytes() == before


def test_aov_and_mtl_outputs_over_inputs_are_refused(tmp_path, capsys):
    """`-o crate.png --aov ...` names its AOVs <stem>.<aov>.npy/png; an image named after the MTL's
    folder file or a TOML's mesh is caught the same way (the loader records every file it read)."""
    obj = _crate(tmp_path)
    (obj.parent / "crate.depth.png").write_bytes(b"not really")      # a file the scene does not read: fine
    rc, err = _run_cli(capsys, "render", obj, "-o", obj.parent / "crate.mtl.png", *SMALL)
    assert rc == 0, err
    toml = obj.parent / "scene.toml"
    toml.write_text('[[mesh]]\npath = "crate.obj"\n')
    rc, err = _run_cli(capsys, "render", toml, "-o", obj.parent / "out" / ".." / "crate.png", *SMALL)
    assert rc == 1 and "would overwrite" in err and "scene.toml" in err, err


def test_frames_and_dataset_refuse_to_overwrite_inputs(tmp_path, capsys):
    obj = _crate(tmp_path)
    rc, err = _run_cli(capsys, "render", obj, "-o", obj.parent / "{name}.png", "--frames", "0", *SMALL)
    assert rc == 1 and "crate.png" in err and "would overwrite" in err, err
    assert len(_error_lines(err)) == 1, err
    # a dataset whose images/ folder holds the scene's texture
    images = obj.parent / "images"
    images.mkdir()
    shutil.copy(obj.parent / "crate.png", images / "0000.png")
    (obj.parent / "crate.mtl").write_text((obj.parent / "crate.mtl").read_text().replace("crate.png",
                                                                                        "images/0000.png"))
    rc, err = _run_cli(capsys, "dataset", obj, "-o", obj.parent, "--views", "1", "--aov", "none", *SMALL)
    assert rc == 1 and "images/0000.png" in err and "would overwrite" in err, err
    assert not (obj.parent / "transforms.json").exists()          # nothing written before the check


def test_several_scenes_an_output_of_one_is_an_input_of_another(tmp_path, capsys):
    """Scene a's image would replace the texture scene b reads: refused before a renders."""
    obj = _crate(tmp_path)
    a = obj.parent / "a.obj"
    shutil.copy(obj, a)
    (obj.parent / "b.mtl").write_text((obj.parent / "crate.mtl").read_text().replace("crate.png", "a.png"))
    b = obj.parent / "b.obj"
    b.write_text(obj.read_text().replace("mtllib crate.mtl", "mtllib b.mtl"))
    shutil.copy(obj.parent / "crate.png", obj.parent / "a.png")
    before = (obj.parent / "a.png").read_bytes()
    rc, err = _run_cli(capsys, "render", a, b, "-o", obj.parent, *SMALL)
    assert rc == 1 and "a.png" in err and "b.obj" in err, err
    assert (obj.parent / "a.png").read_bytes() == before


def test_unwritable_output_fails_before_rendering_naming_the_output(tmp_path, capsys, monkeypatch):
    obj = _crate(tmp_path)
    blocker = tmp_path / "file"
    blocker.write_text("x")
    import threading

    from clrender.render import renderer
    rendered = []
    original = renderer.Renderer.render

    def render(self, *args, **kwargs):
        if threading.current_thread() is threading.main_thread():      # not the CLI's warm-up thread
            rendered.append(1)
        return original(self, *args, **kwargs)
    monkeypatch.setattr(renderer.Renderer, "render", render)
    rc, err = _run_cli(capsys, "render", obj, "-o", blocker / "out.png", *SMALL)
    assert rc == 1 and not rendered
    assert str(blocker / "out.png") in err and ".tmp" not in err and len(_error_lines(err)) == 1, err


def test_write_errors_name_the_output_not_the_temporary_file(tmp_path):
    from clrender.outputs.aov_io import atomic_write

    def fail(tmp):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), tmp)
    with pytest.raises(OSError) as info:
        atomic_write(tmp_path / "out.png", fail)
    text = str(info.value)
    assert str(tmp_path / "out.png") in text and ".tmp" not in text and "No space left" in text, text
    assert os.listdir(tmp_path) == []


# -- leftovers of killed writers --------------------------------------------------------------------
def _dead_pid() -> int:
    p = subprocess.Popen([sys.executable, "-c", "pass"])
    p.wait()
    return p.pid


def test_leftover_temporaries_are_removed_by_the_next_write_and_by_resume(tmp_path):
    from clrender.outputs import aov_io
    dead = _dead_pid()
    stale = tmp_path / f".frame_0001.{dead}.abcd1234.tmp.exr"     # a SIGKILL mid-write left it
    old = tmp_path / ".frame_0002.k2j4h5g6.tmp.png"                # older clrender: no pid, an hour old
    live = tmp_path / f".frame_0003.{os.getpid()}.zz99yy88.tmp.png"  # a write in progress here: kept
    user = tmp_path / ".notes.tmp.txt"                             # not ours: kept
    for p in (stale, old, live, user):
        p.write_bytes(b"half")
    os.utime(old, (time.time() - 2 * aov_io.STALE_TEMP_S,) * 2)
    aov_io._SCANNED.discard(os.path.abspath(tmp_path))
    aov_io.atomic_write(tmp_path / "other.txt", lambda tmp: Path(tmp).write_text("x"))
    assert not stale.exists() and not old.exists()
    assert live.exists() and user.exists()


def test_resume_removes_leftovers_of_a_killed_run(tmp_path, capsys, device):
    obj = _crate(tmp_path)
    out = tmp_path / "frames"
    args = ["render", obj, "-o", out, "--frames", "0:2", "--device", device.id, *SMALL]
    rc, err = _run_cli(capsys, *args)
    assert rc == 0, err
    leftover = out / f".crate_0001.{_dead_pid()}.abcd1234.tmp.png"
    leftover.write_bytes(b"half a frame")
    rc, err = _run_cli(capsys, *args, "--resume")
    assert rc == 0, err
    assert not leftover.exists()
    assert sorted(p.name for p in out.iterdir()) == ["crate_0000.png", "crate_0001.png", "manifest.json"]


# -- a full disk --------------------------------------------------------------------------------------
def _tmpfs(path: Path, size: str) -> bool:
    path.mkdir()
    if os.geteuid() != 0 or shutil.which("mount") is None:
        return False
    return subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(path)],
                          capture_output=True).returncode == 0


def test_full_disk_is_one_line_naming_the_file(tmp_path):
    disk = tmp_path / "disk"
    if not _tmpfs(disk, "24k"):
        if in_ci() and os.geteuid() == 0:
            pytest.fail("CI: could not mount a tmpfs as root")
        pytest.skip("mounting a small tmpfs needs root")
    try:
        env = dict(os.environ, PYTHONPATH=str(ROOT))
        proc = subprocess.run([sys.executable, "-m", "clrender", "render", str(SCENES / "crate.obj"), "-o",
                               str(disk / "c.png"), "--aov", "depth,normal,position", "--exr",
                               "--width", "96", "--height", "64", "-q"],
                              capture_output=True, text=True, env=env, timeout=300)
        lines = _error_lines(proc.stderr)
        assert proc.returncode == 1, proc.stderr
        assert len(lines) == 1 and "Traceback" not in proc.stderr, proc.stderr
        assert str(disk) in lines[0] and "No space left" in lines[0], lines[0]
        assert not [p for p in os.listdir(disk) if ".tmp" in p]
        if (disk / "c.png").exists():              # what was written is complete
            import imageio.v3 as iio
            assert iio.imread(disk / "c.png").shape == (64, 96, 3)
    finally:
        subprocess.run(["umount", str(disk)], capture_output=True)


# -- interrupts ---------------------------------------------------------------------------------------
def test_ctrl_c_during_trimesh_import_is_not_swallowed(tmp_path):
    """trimesh imports its optional parts inside `except BaseException`: a SIGINT arriving there
    used to be swallowed and the job ran on to exit 0."""
    script = textwrap.dedent(f"""
        import importlib.abc, signal, sys
        class Hit(importlib.abc.MetaPathFinder):
            def find_spec(self, name, path, target=None):
                if name == "trimesh.voxel":          # imported inside trimesh's `except BaseException`
                    signal.raise_signal(signal.SIGINT)
                return None
        sys.meta_path.insert(0, Hit())
        from clrender import cli
        sys.exit(cli.main(["info", {str(SCENES / "crate.obj")!r}]))
    """)
    proc = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120,
                          env=dict(os.environ, PYTHONPATH=str(ROOT)))
    assert proc.returncode == 130, (proc.returncode, proc.stdout, proc.stderr)
    assert _error_lines(proc.stderr) == ["clrender: interrupted"], proc.stderr
    assert "triangles" not in proc.stdout


def test_interrupted_build_is_an_interrupt_and_caches_nothing(monkeypatch):
    """A SIGINT kills the compiler's child processes too: the build's failure is the interrupt."""
    import pyopencl as cl

    from clrender.device import core as device_module
    from clrender import interrupt
    from clrender.device.core import Device, ProgramSpec
    dev = Device.__new__(Device)
    dev.context, dev.built, dev.keep_binaries = None, [], False

    ctrl_c = [True]

    class Failing:
        def __init__(self, *args):
            pass

        def build(self, options=None):
            if ctrl_c[0]:
                interrupt._STATE["last"] = time.monotonic()   # what install()'s handler records
            raise cl.RuntimeError("clBuildProgram failed: BUILD_PROGRAM_FAILURE")
    monkeypatch.setattr(device_module.cl, "Program", Failing)
    monkeypatch.setattr(Device, "name", property(lambda self: "test device"))
    spec = ProgramSpec.of("tonemap.cl")
    key = ("test", str(spec))
    before = dict(Device._programs)
    with pytest.raises(KeyboardInterrupt):
        dev._build(spec, key, device_module.kernels_dir() / "tonemap.cl", "digest", [], _Stage())
    assert Device._programs == before
    interrupt._STATE["last"], ctrl_c[0] = None, False
    with pytest.raises(device_module.DeviceError):                  # without an interrupt: the error
        dev._build(spec, key, device_module.kernels_dir() / "tonemap.cl", "digest", [], _Stage())


class _Stage:
    def note(self, item):
        pass

    def advance(self, item=""):
        pass


def test_interrupted_device_probe_is_not_cached_as_a_broken_device(monkeypatch):
    from clrender.device import probe as device_probe
    from clrender import interrupt
    writes = []
    monkeypatch.setattr(device_probe.cache, "read_json", lambda name: None)
    monkeypatch.setattr(device_probe.cache, "write_json", lambda name, data: writes.append(name))
    monkeypatch.setattr(device_probe, "_key", lambda info: "k")
    monkeypatch.setattr(device_probe, "_answers", {})

    def child_killed_by_ctrl_c(info):
        interrupt._STATE["last"] = time.monotonic()
        return "BuildProgramFailure: clBuildProgram failed"
    monkeypatch.setattr(device_probe, "_ask_child", child_killed_by_ctrl_c)
    monkeypatch.delenv(device_probe.ENV_IN_PROBE, raising=False)
    try:
        with pytest.raises(KeyboardInterrupt):
            device_probe.probe_error(object())
    finally:
        interrupt._STATE["last"] = None
    assert writes == []


def test_ctrl_c_in_a_frame_loop_exits_130_quickly_leaving_nothing_half_written(tmp_path, device):
    out = tmp_path / "frames"
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    proc = subprocess.Popen([sys.executable, "-m", "clrender", "render", str(SCENES / "crate.obj"), "-o", str(out),
                             "--frames", "0:2000", "--device", device.id, "--width", "24", "--height", "16",
                             "--aov", "depth"],
                            stderr=subprocess.PIPE, stdout=subprocess.DEVNULL, env=env, start_new_session=True)
    deadline = time.monotonic() + 240              # the first run on a machine builds the kernels
    while proc.poll() is None and time.monotonic() < deadline and len(list(out.glob("crate_*.png"))) < 3:
        time.sleep(0.05)
    assert proc.poll() is None, "the job ended before it was interrupted"
    os.killpg(proc.pid, signal.SIGINT)                     # what Ctrl-C on a terminal does
    sent = time.monotonic()
    err = proc.communicate(timeout=60)[1].decode()
    took = time.monotonic() - sent
    assert proc.returncode == 130, err
    assert err.rstrip().splitlines()[-1] == "clrender: interrupted", err
    assert "Traceback" not in err
    assert took < 2.0, took                        # ~0.1 s here; 2 s leaves room for a loaded CI machine
    names = os.listdir(out)
    assert not [n for n in names if ".tmp" in n], names
    assert "manifest.json" in names


# -- one line, naming the file -------------------------------------------------------------------------
@pytest.mark.parametrize("exc, words", [(AttributeError("'NoneType' object has no attribute 'vertices'"),
                                         ["AttributeError"]),
                                        (MemoryError(), ["out of memory"]),
                                        (RecursionError("maximum recursion depth exceeded"), ["nested too deeply"])])
def test_unexpected_loader_failures_are_scene_errors_naming_the_file(tmp_path, monkeypatch, exc, words):
    from clrender.loaders import load_scene, mesh
    obj = _crate(tmp_path)

    def boom(path):
        raise exc
    monkeypatch.setattr(mesh, "load_obj", boom)
    with pytest.raises(SceneError) as info:
        load_scene(obj)
    text = str(info.value)
    assert text.startswith(str(obj)) and "\n" not in text and all(w in text for w in words), text


def test_keyboard_interrupt_in_a_loader_stays_an_interrupt(tmp_path, monkeypatch):
    from clrender.loaders import load_scene, mesh
    obj = _crate(tmp_path)

    def interrupted(path):
        raise KeyboardInterrupt
    monkeypatch.setattr(mesh, "load_obj", interrupted)
    with pytest.raises(KeyboardInterrupt):
        load_scene(obj)


def test_unexpected_error_is_one_line_and_debug_shows_the_traceback(tmp_path, monkeypatch, capsys):
    from clrender.loaders import mesh
    obj = _crate(tmp_path)
    monkeypatch.setattr(mesh, "load_obj", lambda path: {}["no such key"])
    monkeypatch.delenv("CLRENDER_DEBUG", raising=False)
    monkeypatch.delenv("CLRENDER_LOG", raising=False)
    rc, err = _run_cli(capsys, "info", obj)
    assert rc == 1 and _error_lines(err) == [f"clrender: error: {obj}: cannot load (KeyError: 'no such key')"], err
    monkeypatch.setenv("CLRENDER_LOG", "debug")
    with pytest.raises(SceneError):                  # the traceback: the exception is not caught
        cli.main(["info", str(obj)])


def _binary_stl(n: int) -> bytes:
    tri = struct.pack("<12fH", 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0)
    return b"\x01" * 80 + struct.pack("<I", n) + tri * n


@pytest.mark.parametrize("cut", [50, 84 + 30, 84 + 100])
def test_truncated_stl_says_so(tmp_path, cut):
    path = tmp_path / "part.stl"
    path.write_bytes(_binary_stl(3)[:cut])
    from clrender.loaders import load_scene
    with pytest.raises(SceneError) as info:
        load_scene(path)
    assert str(path) in str(info.value) and "truncated or corrupt" in str(info.value), info.value
    path.write_bytes(_binary_stl(3))
    assert load_scene(path).triangle_count == 3


def test_exr_with_a_bad_size_header_is_one_line(tmp_path, capfd):
    OpenEXR = pytest.importorskip("OpenEXR")
    good = tmp_path / "good.exr"
    OpenEXR.File({"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage},
                 {c: np.ones((8, 16), np.float32) for c in "RGB"}).write(str(good))
    data = bytearray(good.read_bytes())
    at = data.find(b"dataWindow\0box2i\0") + len(b"dataWindow\0box2i\0") + 4
    data[at:at + 16] = struct.pack("<4i", 0, 0, 15, 2 ** 20)          # 2^20 rows in a 380-byte file
    bad = tmp_path / "bad.exr"
    bad.write_bytes(bytes(data))
    from clrender.scene.environment_files import read_exr
    capfd.readouterr()
    with pytest.raises(SceneError) as info:
        read_exr(bad)
    text = str(info.value)
    assert text.startswith(str(bad)) and "cannot read OpenEXR file" in text and "channel" not in text, text
    out, err = capfd.readouterr()
    assert out == "" and err == "", (out, err)          # the library's own lines are not printed
    assert read_exr(good).shape == (8, 16, 3)


def test_seed_errors_name_the_option(capsys):
    rc, err = _run_cli(capsys, "dataset", SCENES / "crate.obj", "-o", "unused", "--views", "2",
                       "--layout", "random", "--seed", "-1")
    assert rc == 2 and "--seed" in err and "'-1'" in err and len(_error_lines(err)) == 1, err
