"""Frame.stats accounts for render()'s wall time: the host phases add up to wall_ms, and the pass
times (profiling events) are told apart from the totals."""
from __future__ import annotations

from pathlib import Path

import pytest

from clrender.cli import app as cli
from clrender import load_scene
from clrender.render.pipeline import HOST_PHASES, NOT_PASS_MS, pass_ms

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def demo():
    return load_scene(str(REPO / "scenes" / "demo.toml"))


def test_host_phases_add_up_to_the_wall_time(make_renderer, demo):
    renderer = make_renderer(88, 56)       # not a size other modules' tests measure buffers at
    first = renderer.render(demo).stats
    stats = renderer.render(demo).stats
    for s in (first, stats):
        host = s["host"]
        assert tuple(host) == HOST_PHASES
        assert all(v >= 0.0 for v in host.values())
        assert s["wall_ms"] > 0 and abs(sum(host.values()) - s["wall_ms"]) <= 1e-6 * s["wall_ms"] + 1e-9
        # the overflow totals are read after the passes were enqueued: that read waits for the device
        assert host["enqueue_ms"] > 0 and host["overflow_wait_ms"] > 0 and host["readback_ms"] > 0
    passes = pass_ms(stats)
    assert not set(passes) & set(NOT_PASS_MS) and "host" not in passes
    assert {"raster_ms", "gbuffer_ms", "shade_ms"} <= set(passes)
    # total_ms sums the passes that ran; stage breakdowns (not in the total) may add more keys
    assert 0 < stats["total_ms"] <= sum(passes.values()) * (1 + 1e-9)


def test_cli_prints_render_wall_time_and_host_phases(device, tmp_path, capsys):
    assert cli.main(["render", str(REPO / "scenes" / "demo.toml"), "-o", str(tmp_path / "d.png"),
                     "--width", "64", "--height", "48", "--device", device.id]) == 0
    err = capsys.readouterr().err
    assert "render() " in err and "overflow_wait" in err and "readback" in err
    line = next(ln for ln in err.splitlines() if "passes (ms):" in ln)
    assert "wall" not in line.split(";")[0] and "host" not in line.split(";")[0]
