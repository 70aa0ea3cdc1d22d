"""The viewer without a browser (clrender/viewer/server.py, clrender/cli/view.py): the panels
read the option and AOV tables, refused options and bad environment paths leave the viewer
running, the published picture is the frame's (and its pick highlight), saved views reopen, the
animation time poses the scene, and the command line's bad input ends in one line before any
server runs. The page itself is tests/test_viewer_browser.py."""
from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

pytest.importorskip("viser", reason="the viewer needs viser (pip install clrender[view])")

from clrender import Renderer, load_scene  # noqa: E402
from clrender.abi.aovs import WRITTEN  # noqa: E402
from clrender.cli import main  # noqa: E402
from clrender.config import OPTIONS  # noqa: E402
from clrender.dataset.camera_file import read_camera_file  # noqa: E402
from clrender.viewer import view  # noqa: E402
from clrender.viewer.pick import highlight, pick  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
DEMO = ROOT / "scenes" / "demo.toml"
WORM = ROOT / "scenes" / "worm.gltf"
W, H = 96, 64


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.fixture
def viewer(tmp_path):
    """A viewer of the demo scene at a fixed size (its first frame renders without a page); the
    pictures it publishes are recorded in `v.published`."""
    v = view(str(DEMO), width=W, height=H, port=free_port(), cameras=str(tmp_path / "cams.json"),
             transport="png", show=False)
    v.published = []
    original = v.server.scene.set_background_image

    def record(image, *args, **kwargs):
        v.published.append(np.array(image))
        return original(image, *args, **kwargs)
    v.server.scene.set_background_image = record
    try:
        assert v.wait_idle(300)
        yield v
    finally:
        v.close()


def test_panels_read_the_option_and_aov_tables(viewer):
    assert sorted(viewer.panels.options) == sorted(o.name for o in OPTIONS)     # every row has its widget
    assert tuple(viewer.panels.aov.options) == ("image", *WRITTEN)


def test_the_first_frame_is_the_scene_camera_at_full_size(viewer):
    scene = load_scene(DEMO)
    frame = viewer.frame
    assert viewer.camera == scene.default_camera()
    assert (frame.width, frame.height) == (W, H)
    ref = Renderer(W, H, device=viewer.device.info, config=viewer.config).render(scene, scene.default_camera())
    assert np.array_equal(frame.image, ref.image)
    assert ref.image.max() > 40                                         # not a black frame


def test_a_refused_option_keeps_the_config_and_a_good_one_renders(viewer):
    assert viewer.config.ssao is False
    assert viewer.set_option("pipeline", "light_indexed")
    assert not viewer.set_option("ssao", True)                          # light_indexed has no normals for SSAO
    assert viewer.config.ssao is False and "ssao" in viewer.panels.message.content
    assert viewer.set_option("pipeline", "deferred") and viewer.set_option("ssao", True)
    assert viewer.wait_idle(300)
    shown = viewer.loop.last_full
    assert shown.state.config.ssao and shown.state.config.pipeline == "deferred"
    assert not viewer.errors


def test_published_picture_is_the_frames_preview_and_the_pick_highlight(viewer):
    frame = viewer.frame
    assert np.array_equal(viewer.published[-1], frame.image)
    viewer.set_aov("object_id")
    assert np.array_equal(viewer.published[-1], frame.preview("object_id"))
    ids = frame.object_id
    ys, xs = np.nonzero(ids >= 0)
    y, x = int(ys[len(ys) // 2]), int(xs[len(xs) // 2])
    viewer._clicked(SimpleNamespace(screen_pos=((x + 0.5) / W, (y + 0.5) / H)))
    expected = pick(frame, viewer.scene, x, y)
    assert viewer.last_pick == expected and expected.object_id == ids[y, x]
    assert expected.object_name in viewer.panels.pick.content
    assert np.array_equal(viewer.published[-1], highlight(frame.preview("object_id"), ids == ids[y, x]))
    viewer.set_highlight(False)
    assert np.array_equal(viewer.published[-1], frame.preview("object_id"))
    viewer._clicked(SimpleNamespace(screen_pos=(0.001, 0.001)))        # the corner: sky
    if ids[0, 0] < 0:
        assert viewer.last_pick is None and "background" in viewer.panels.pick.content


def test_environment_paths_are_confined_and_errors_keep_the_viewer(viewer, tmp_path, monkeypatch):
    import clrender.scene.environment as environment
    opened = []
    real = environment.load_environment
    monkeypatch.setattr(environment, "load_environment", lambda src, *a, **k: (opened.append(src), real(src, *a, **k))[1])
    outside = tmp_path / "sky.exr"
    outside.write_bytes(b"not read")
    for text, words in (("missing.exr", "no such file"), (str(outside), "outside the scene's folder"),
                        ("../../../etc/passwd", "outside the scene's folder"), ("demo.toml", "not an environment image")):
        message = viewer.set_environment("file", text, 1.0, 0.0)
        assert message.startswith("**error:**") and words in message, message
        assert words in viewer.panels.message.content
    assert opened == []                                                  # refused before anything is opened
    frames = viewer.loop.counts["full"]
    assert viewer.set_environment("none", "", 1.0, 0.0) == "lighting: none"
    assert viewer.wait_idle(300) and viewer.loop.counts["full"] == frames + 1
    dark = viewer.frame.image
    viewer.set_environment("studio", "", 2.0, 0.0)
    assert viewer.wait_idle(300)
    assert viewer.frame.image.astype(int).sum() > dark.astype(int).sum()      # the studio lights it
    assert not viewer.errors


def test_save_view_appends_and_a_new_viewer_lists_it(viewer, tmp_path):
    label = viewer.save_view()
    cf = read_camera_file(tmp_path / "cams.json")
    assert len(cf.entries) == 1 and (cf.width, cf.height) == (W, H) and label == "file: view 1"
    assert cf.entries[0]["eye"] == list(viewer.camera.eye)
    assert viewer.panels.cameras.value == label
    viewer.save_view()
    assert len(read_camera_file(tmp_path / "cams.json").entries) == 2
    viewer.close()
    again = view(str(DEMO), width=W, height=H, port=free_port(), cameras=str(tmp_path / "cams.json"), show=False)
    try:
        assert [label for label in again.camera_labels() if label.startswith("file:")] == ["file: view 1", "file: view 2"]
    finally:
        again.close()


def test_the_time_slider_poses_the_animation(tmp_path):
    v = view(str(WORM), width=W, height=H, port=free_port(), transport="png", show=False)
    try:
        assert v.animated and v.duration == pytest.approx(2.0)
        assert v.wait_idle(300)
        v.set_time(0.7)
        assert v.wait_idle(300)
        shown = v.loop.last_full
        assert shown.state.time == pytest.approx(0.7)
        scene = load_scene(WORM)
        scene.pose(0.7)
        ref = Renderer(W, H, device=v.device.info, config=v.config).render(scene, shown.state.camera, time=0.7)
        assert np.array_equal(shown.frame.image, ref.image)
        scene.pose(0.0)
        still = Renderer(W, H, device=v.device.info, config=v.config).render(scene, shown.state.camera, time=0.0)
        assert not np.array_equal(still.image, ref.image)                # the worm moved
    finally:
        v.close()


# -- the command line ---------------------------------------------------------------------------
def test_a_port_in_use_is_one_line(capsys):
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen(1)
        port = busy.getsockname()[1]
        assert main(["view", str(DEMO), "--port", str(port)]) != 0
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and f"port {port}" in err and "in use" in err, err


def test_a_scene_that_fails_to_load_is_one_line_and_no_server(tmp_path, capsys):
    bad = tmp_path / "bad.gltf"
    bad.write_text("{ not json")
    port = free_port()
    assert main(["view", str(bad), "--port", str(port)]) != 0
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "bad.gltf" in err, err
    with socket.socket() as s:                                           # nothing left listening
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        s.bind(("127.0.0.1", port))


def _start_cli(args, env_extra=None):
    env = {**os.environ, **(env_extra or {})}
    proc = subprocess.Popen([sys.executable, "-m", "clrender", "view", *args], stderr=subprocess.PIPE,
                            stdout=subprocess.PIPE, text=True, env=env, cwd=ROOT)
    deadline, lines = time.monotonic() + 240, []
    while time.monotonic() < deadline:
        line = proc.stderr.readline()
        if not line:
            break
        lines.append(line)
        if "Ctrl-C to stop" in line:
            return proc, lines
    proc.kill()
    raise AssertionError("the viewer did not print its URL: " + "".join(lines))


def test_ctrl_c_stops_cleanly_and_a_public_host_warns(tmp_path):
    port = free_port()
    proc, lines = _start_cli([str(DEMO), "--port", str(port), "--host", "127.0.0.2", "--width", "32", "--height", "24",
                              "--cameras", str(tmp_path / "c.json")])
    try:
        assert f"http://127.0.0.2:{port}" in "".join(lines)
        assert any("warning" in ln and "anyone who can reach this port" in ln for ln in lines), lines
        time.sleep(1.0)
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 0, err
    assert "stopped" in err and "Traceback" not in err and "Traceback" not in out, err
