"""`clrender check`: the portability run across OpenCL devices."""
import json
from pathlib import Path

import numpy as np

from clrender.tools import check
from clrender.cli import app as cli
from helpers import skip_or_fail

REPO = Path(__file__).resolve().parents[1]


def test_compare_flags_any_integer_difference():
    ids = np.arange(12, dtype=np.int32).reshape(3, 4)
    other = ids.copy()
    assert check.compare("triangle_id", ids, other)[-1]
    other[1, 2] = -1
    max_abs, _, over, text, ok = check.compare("triangle_id", ids, other)
    assert not ok and over == 1 and text == "identical" and max_abs == 7


def test_compare_float_tolerances():
    color = np.full((4, 4, 3), 2.0, np.float32)
    near = color + np.float32(1e-4)                 # 0.5e-4 of peak: inside 1e-4·peak
    assert check.compare("color", color, near)[-1]
    far = color.copy()
    far[0, 0, 0] += 1e-2                            # 5e-3 of the value, 5e-3 of peak: over both
    assert not check.compare("color", color, far)[-1]
    dim = color.copy()
    dim[1, 1, 1] = 0.02                             # a dim value off by 5e-4 of peak and 5% of itself
    off = dim.copy()
    off[1, 1, 1] += np.float32(1e-3)
    assert not check.compare("color", dim, off)[-1]
    peak = color.copy()
    peak[3, 3, 0] = 400.0                           # a GGX highlight: within 1e-3 of itself passes
    assert check.compare("color", peak, peak + np.float32(0.2) * (peak == 400.0))[-1]
    assert not check.compare("color", peak, peak + np.float32(0.8) * (peak == 400.0))[-1]
    nan = color.copy()
    nan[2, 2, 1] = np.nan
    assert not check.compare("color", color, nan)[-1], "NaN must never pass"
    depth = np.array([[1.0, np.inf]], np.float32)
    assert check.compare("depth", depth, depth.copy())[-1], "matching background (+inf) agrees"
    assert not check.compare("depth", depth, np.array([[1.0, 5.0]], np.float32))[-1]


def _compared_devices():
    """Two real devices (the default and the next: `clrender check --device all` in .ci/run compares
    every implementation); with fewer than two, a real one and Oclgrind (a second implementation,
    slow: the callers keep their cases small); with fewer than two of those, skip (CI: fail)."""
    from clrender.device.core import preference_order
    from clrender.device.probe import select_devices
    devices = preference_order(select_devices("all"))[:2]
    if len(devices) < 2:
        devices = sorted(select_devices("all", simulators=True), key=lambda d: d.is_simulator)[:2]
    if len(devices) < 2:
        skip_or_fail(f"only one OpenCL device ({devices[0].label}): nothing to compare")
    return devices


def test_report_on_every_device_agrees():
    devices = _compared_devices()
    simulated = any(d.is_simulator for d in devices)
    size = (24, 16) if simulated else (48, 32)
    only = ("demo", "dense") if simulated else ()       # `clrender check` in .ci/run runs every case
    report = check.run_check(devices, width=size[0], height=size[1], only=only)
    assert report.ok, report.table()
    assert len(report.devices) == 2 or not simulated
    assert {"demo", "dense"} <= {r.case for r in report.rows}
    assert simulated or {"layers", "transmission"} <= {r.case for r in report.rows}, "the see-through kernels' case"
    assert {r.aov for r in report.rows} == set(check.AOVS)


def test_cli_check_exit_status_and_json(tmp_path, capsys, monkeypatch):
    devices = _compared_devices()
    scene = REPO / "scenes" / "demo.toml"
    args = ["check", "--device", "all", "--scene", str(scene), "--width", "16", "--height", "12", "-q"]
    monkeypatch.setattr("clrender.device.probe.select_devices", lambda spec=None, simulators=False: devices)
    out = tmp_path / "report.json"
    assert cli.main(args + ["--json", str(out), "--min-devices", "2"]) == 0       # the devices agree
    report = json.loads(out.read_text())
    assert report["ok"] and len(report["devices"]) == 2 and report["rows"]
    assert "reference device" in capsys.readouterr().out
    # A mismatch makes the command fail.
    monkeypatch.setattr(check, "compare", lambda *args, **kw: (1.0, 1.0, 1, "forced", False))
    assert cli.main(args) == 1
    # Fewer devices than --min-devices fail too, before any comparison can pass.
    assert cli.main(args + ["--min-devices", "3"]) == 1
    assert "--min-devices 3 wanted" in capsys.readouterr().err
    assert cli.main(["check", "--scene", str(tmp_path / "missing.glb")]) != 0
