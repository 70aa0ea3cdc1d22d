"""Batch rendering on a Dask LocalCluster (clrender.batch with a client): bit-identical to the
single-process run, and complete, each frame exactly once, when a worker is killed mid-job."""
from __future__ import annotations

import json
import logging
import os
import signal
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from clrender.outputs import aov_io
from clrender.batch.jobs import render_frames

distributed = pytest.importorskip("distributed", reason="Dask tests need dask[distributed] (pip install -e .[test])")

REPO = Path(__file__).resolve().parents[1]
ORBIT = REPO / "scenes" / "orbit.toml"
W, H, FRAMES = 96, 64, range(0, 12)


@pytest.fixture(scope="module")
def client():
    cluster = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None,
                                       silence_logs=logging.ERROR,
                                       env={"POCL_CPU_MAX_CU_NUM": "1", "PYTHONWARNINGS": "ignore"})
    with cluster, distributed.Client(cluster) as c:
        yield c


def _job(out: Path, device, client=None, **kw):
    return render_frames(ORBIT, FRAMES, out / "f_{frame:02d}.png", client=client, fps=8, width=W, height=H,
                         aovs=("depth", "velocity"), exr=True, device=device.id, **kw)


def test_local_cluster_frames_are_bit_identical_to_one_process(device, client, tmp_path):
    local, dask = tmp_path / "local", tmp_path / "dask"
    a = _job(local, device)
    b = _job(dask, device, client)
    assert a.ok and b.ok and len(b.rendered) == 12
    workers = {r["worker"] for r in json.loads((dask / "manifest.json").read_text())["frames"]}
    assert len(workers) == 2 and os.getpid() not in {int(w.rsplit(":", 1)[1]) for w in workers}
    for f in FRAMES:
        assert (local / f"f_{f:02d}.png").read_bytes() == (dask / f"f_{f:02d}.png").read_bytes()
        for name, channel in aov_io.read_exr(local / f"f_{f:02d}.exr").items():
            other = aov_io.read_exr(dask / f"f_{f:02d}.exr")[name]
            np.testing.assert_array_equal(channel.view(np.uint32), other.view(np.uint32), err_msg=name)
    # the frames differ from each other (a black or frozen frame would also be "identical")
    assert len({(local / f"f_{f:02d}.png").read_bytes() for f in FRAMES}) == 12


def test_killed_worker_every_frame_completes_exactly_once(device, client, tmp_path):
    reference = _job(tmp_path / "ref", device)
    assert reference.ok
    out = tmp_path / "killed"
    killed = []

    def kill_one_worker_after_a_frame():
        deadline = time.monotonic() + 300
        while time.monotonic() < deadline:
            try:
                frames = json.loads((out / "manifest.json").read_text())["frames"]
            except (OSError, ValueError):
                frames = []
            if frames:                  # written at the first finished frame
                busy = [w for w, p in client.processing().items() if p]
                if busy:
                    pid = client.run(os.getpid, workers=[busy[0]])[busy[0]]
                    os.kill(pid, signal.SIGKILL)
                    killed.append(pid)
                    return
            time.sleep(0.01)

    killer = threading.Thread(target=kill_one_worker_after_a_frame)
    killer.start()
    result = _job(out, device, client)
    killer.join()
    assert killed, "no worker was killed: the job ended first"
    assert result.ok and len(result.rendered) == 12
    assert sorted(f for _, f in result.rendered) == list(FRAMES)          # each frame once
    frames = json.loads((out / "manifest.json").read_text())["frames"]
    assert sorted(r["frame"] for r in frames) == list(FRAMES) and all(r["status"] == "ok" for r in frames)
    assert all(".tmp" not in p.name for p in out.glob("f_*"))
    for f in FRAMES:
        assert (out / f"f_{f:02d}.png").read_bytes() == (tmp_path / "ref" / f"f_{f:02d}.png").read_bytes()
