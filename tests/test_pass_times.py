"""Per-pass milliseconds are real on every implementation. They come from profiling timestamps
around each pass (clrender/device/timestamps.py): marker events where the device stamps markers, a
one-work-item kernel launch where it does not (Intel's CPU runtime gives markers start = end = 0,
so its pass times all read 0.00 ms while its frames took tens of ms)."""
from __future__ import annotations

from pathlib import Path

import pytest

from clrender import load_scene

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def demo():
    return load_scene(str(REPO / "scenes" / "demo.toml"))


@pytest.fixture(params=["device stamps", "kernel stamps"])
def stamps(request, monkeypatch):
    """The device's own choice, and the kernel-launch stamps forced (so every device in CI runs the
    path Intel's runtime takes)."""
    if request.param == "kernel stamps":
        from clrender.device import capabilities
        monkeypatch.setattr(capabilities, "markers_carry_time", lambda dev: False)
    return request.param


def test_a_stamp_carries_device_time(device, stamps):
    from clrender.device import timestamps
    from clrender.device.core import Device
    dev = Device.get(device)
    first, second = timestamps.stamp(dev), timestamps.stamp(dev)
    second.wait()
    # two stamps with nothing between may read the same time (Oclgrind's clock is coarse)
    assert 0 < first.profile.start <= first.profile.end <= second.profile.end
    assert timestamps.elapsed_ms(first, second) >= 0


def test_pass_times_add_up_to_the_frame(make_renderer, demo, stamps):
    renderer = make_renderer(104, 72)      # not a size other modules' tests measure buffers at
    renderer.render(demo)                  # builds and first launches
    stats = renderer.render(demo).stats
    assert stats["wall_ms"] > 1.0          # a frame that took time ...
    ran = {f"{p.name}_ms" for p in renderer.pipeline.passes} & set(stats)
    assert {"setup_ms", "binning_ms", "raster_ms", "gbuffer_ms", "shade_ms", "tonemap_ms"} <= ran
    # ... has pass times, each pass that ran launched kernels and took time
    zero = sorted(k for k in ran if not stats[k] > 0)
    assert not zero, f"passes with no device time: {zero} ({stats['wall_ms']:.1f} ms frame)"
    # the passes tile the frame's device span (the first pass's start to the last one's end)
    span, total = stats["span_ms"], stats["total_ms"]
    assert 0 < span <= stats["wall_ms"] * 1.05 + 0.5
    assert 0.5 * span <= total <= span * 1.01 + 0.01, (total, span)
