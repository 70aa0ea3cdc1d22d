"""Batch rendering in this process (clrender.batch, `clrender render --frames`): frames against the
API, the manifest, per-frame failures, resume after SIGKILL, and bad input refused before rendering."""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import imageio.v3 as iio
import numpy as np
import pytest

from clrender import Renderer, load_scene
from clrender.outputs import video  # write_video and its ffmpeg check
from clrender.cli import app as cli, batch as cli_batch
from clrender.batch.jobs import render_frames

REPO = Path(__file__).resolve().parents[1]
ORBIT = REPO / "scenes" / "orbit.toml"
DEMO_GLTF = REPO / "scenes" / "demo.gltf"
W, H, FPS = 96, 64, 4.0

# the camera passes through its target at t = 0.5 s: that frame cannot render, the others can
BAD_MIDDLE = f"""
[[mesh]]
path = "{DEMO_GLTF.as_posix()}"
[camera]
fov_y_deg = 50
[[camera.keys]]
time = 0.0
eye = [0.0, 1.0, 6.0]
target = [0.0, 1.0, 0.0]
[[camera.keys]]
time = 1.0
eye = [0.0, 1.0, -6.0]
target = [0.0, 1.0, 0.0]
"""


def _manifest(folder: Path) -> dict:
    return json.loads((folder / "manifest.json").read_text())


def test_frames_equal_the_api_render_of_the_posed_scene(device, tmp_path):
    result = render_frames(ORBIT, range(0, 4), tmp_path / "f_{frame:02d}.png", fps=FPS, width=W, height=H,
                           aovs=("depth", "velocity"), device=device.id)
    assert result.ok and [f for _, f in result.rendered] == [0, 1, 2, 3] and not result.skipped
    scene = load_scene(str(ORBIT))
    renderer = Renderer(W, H, device=device.id)
    images = []
    for f in range(4):
        previous = scene.pose(f / FPS, 1 / FPS)
        frame = renderer.render(scene, scene.camera, previous_camera=previous, time=f / FPS)
        got = iio.imread(tmp_path / f"f_{f:02d}.png")
        np.testing.assert_array_equal(got, frame.image)
        np.testing.assert_array_equal(np.load(tmp_path / f"f_{f:02d}.depth.npy").view(np.uint32),
                                      frame.depth.view(np.uint32))
        np.testing.assert_array_equal(np.load(tmp_path / f"f_{f:02d}.velocity.npy"), frame.velocity)
        assert np.abs(frame.velocity[np.isfinite(frame.depth)]).max() > 0.5      # the orbit moves
        images.append(got)
    assert all(np.abs(a.astype(int) - b).mean() > 1 for a, b in zip(images, images[1:]))   # not one frame 4x
    m = _manifest(tmp_path)
    assert [r["frame"] for r in m["frames"]] == [0, 1, 2, 3]
    for r in m["frames"]:
        assert r["status"] == "ok" and r["time"] == r["frame"] / FPS
        assert [o["path"] for o in r["outputs"]] == [f"f_{r['frame']:02d}{s}" for s in
                                                     (".png", ".depth.npy", ".depth.png", ".velocity.npy",
                                                      ".velocity.png")]
        assert all(o["bytes"] == (tmp_path / o["path"]).stat().st_size for o in r["outputs"])
        assert r["stats"]["total_ms"] > 0 and r["device"] and r["worker"]
    assert m["job"]["fps"] == FPS and m["clrender"]


def test_cli_one_bad_frame_does_not_lose_the_others(device, tmp_path, capsys):
    scene = tmp_path / "bad_middle.toml"
    scene.write_text(BAD_MIDDLE)
    out = tmp_path / "out"
    rc = cli.main(["render", str(scene), "--frames", "0:5", "--fps", "4", "--width", str(W), "--height", str(H),
                   "-o", str(out / "f_{frame}.png"), "--device", device.id,
                   "--allow-outside", str(DEMO_GLTF.parent)])      # the TOML names the repo's demo.gltf
    err = capsys.readouterr().err
    assert rc == 1
    # frame 2 (t = 0.5) and frame 3, whose previous camera (t - 1/fps, for the velocity) is at 0.5
    assert sorted(p.name for p in out.glob("*.png")) == ["f_0.png", "f_1.png", "f_4.png"]
    m = _manifest(out)
    status = {r["frame"]: r["status"] for r in m["frames"]}
    assert status == {0: "ok", 1: "ok", 2: "failed", 3: "failed", 4: "ok"}
    error = next(r["error"] for r in m["frames"] if r["frame"] == 2)
    assert error.startswith(str(scene)) and "t=0.5" in error       # names the file and the time
    assert f"frame 2: {error}" in err.splitlines()[-3] and "2 of 5 frames failed" in err
    assert "frame/s" in err or "s/frame" in err            # the progress bar was on stderr


def test_resume_after_sigkill_renders_only_the_missing_frames(device, tmp_path):
    def run(out: Path, *extra) -> subprocess.Popen:
        env = dict(os.environ, PYTHONPATH=str(REPO))
        return subprocess.Popen([sys.executable, "-m", "clrender", "render", str(ORBIT), "--frames", "0:16",
                                 "--width", "320", "--height", "180", "--ssao", "-o", str(out / "f_{frame:02d}.png"),
                                 "--aov", "depth", "--device", device.id, "-q", *extra], env=env, cwd=REPO,
                                stderr=subprocess.PIPE, text=True)

    killed, clean = tmp_path / "killed", tmp_path / "clean"
    proc = run(killed)
    deadline = time.monotonic() + 240
    while time.monotonic() < deadline and proc.poll() is None:
        try:
            done = [r for r in _manifest(killed)["frames"] if r["status"] == "ok"]
        except (OSError, ValueError):
            done = []
        if len(done) >= 1:             # the manifest is first written at the first finished frame
            proc.send_signal(signal.SIGKILL)
            break
        time.sleep(0.005)
    proc.wait(timeout=60)
    assert proc.returncode == -signal.SIGKILL, "the job finished before it could be killed: " + proc.stderr.read()
    before = {r["frame"]: r for r in _manifest(killed)["frames"]}
    assert 1 <= len(before) < 16
    stamps = {f: os.stat(killed / f"f_{f:02d}.png").st_mtime_ns for f in before}
    assert all(".tmp" not in p.name for p in killed.glob("f_*"))   # a killed write never has a final name

    assert run(killed, "--resume").wait(timeout=300) == 0
    after = {r["frame"]: r for r in _manifest(killed)["frames"]}
    assert sorted(after) == list(range(16)) and all(r["status"] == "ok" for r in after.values())
    for f, r in before.items():                         # frames complete before the kill were not rendered again
        assert after[f]["run"] == r["run"]
        assert os.stat(killed / f"f_{f:02d}.png").st_mtime_ns == stamps[f]
    assert len({r["run"] for r in after.values()}) == 2

    assert run(clean).wait(timeout=300) == 0
    for f in range(16):
        for suffix in (".png", ".depth.npy"):
            name = f"f_{f:02d}{suffix}"
            assert (killed / name).read_bytes() == (clean / name).read_bytes(), name


def test_resume_rerenders_what_went_missing(device, tmp_path, capsys):
    args = ["render", str(ORBIT), "--frames", "0:3", "--width", str(W), "--height", str(H), "-o", str(tmp_path) + "/",
            "--device", device.id, "-q"]
    assert cli.main(args) == 0
    first = _manifest(tmp_path)
    (tmp_path / "orbit_0001.png").unlink()
    assert cli.main(args + ["--resume"]) == 0
    second = _manifest(tmp_path)
    runs = [(a["run"] == b["run"]) for a, b in zip(first["frames"], second["frames"])]
    assert runs == [True, False, True]
    assert (tmp_path / "orbit_0001.png").exists()
    # a different job in the same folder is refused on --resume
    assert cli.main(args[:5] + [str(W + 2)] + args[6:] + ["--resume"]) == 1
    assert "different job (width differ)" in capsys.readouterr().err


@pytest.mark.parametrize("extra, message", [
    (["--frames", "5:5"], "empty range"),
    (["--frames", "9:2"], "reversed range (end 2 < start 9)"),
    (["--time-range", "3:1"], "reversed range"),
    (["--frames", "0:3", "-o", "{OUT}/{frame_no}.png"], "unknown field {frame_no}"),
    (["--frames", "0:3", "-o", "{OUT}/f.png"], "put {frame} in it"),
    (["--frames", "0:3", "-o", "{FILE}/sub/"], "is not writable"),
    (["--frames", "0:3", "--video", "{OUT}/v.mp4"], "needs ffmpeg"),
    (["--frames", "0:3", "--scheduler", "tcp://127.0.0.1:9"], "cannot reach the scheduler"),
    (["--frames", "0:3", "--time", "1"], "--time is for a single frame"),
    (["--frames", "0:3", "--workers", "2", "--scheduler", "tcp://127.0.0.1:9"], "exclude each other"),
    (["--frames", "0:3", "--resources", "GPU=1"], "--resources goes with --scheduler"),
])
def test_bad_batch_input_is_one_line_before_rendering(tmp_path, capsys, monkeypatch, extra, message):
    monkeypatch.setattr(video, "ffmpeg_available", lambda: False)
    monkeypatch.setattr(cli_batch, "SCHEDULER_TIMEOUT_S", 2)
    rendered = []
    monkeypatch.setattr("clrender.batch.jobs.render_task", lambda task: rendered.append(task))
    (tmp_path / "file").write_text("")
    out = tmp_path / "out"
    extra = [e.replace("{OUT}", str(out)).replace("{FILE}", str(tmp_path / "file")) for e in extra]
    if "-o" not in extra:
        extra += ["-o", str(out) + "/"]
    rc = cli.main(["render", str(ORBIT), "--width", "8", "--height", "8", *extra])
    err = capsys.readouterr().err
    assert rc != 0 and not rendered
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1 and lines[0].startswith("clrender: error: ") and message in lines[0], err
    assert not (out / "manifest.json").exists()
