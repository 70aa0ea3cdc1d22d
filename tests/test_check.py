"""`clrender check`: the portability run across OpenCL devices."""
import json

import numpy as np
import pytest

from clrender import check, cli


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
    far[0, 0, 0] += 1e-3
    assert not check.compare("color", color, far)[-1]
    nan = color.copy()
    nan[2, 2, 1] = np.nan
    assert not check.compare("color", color, nan)[-1], "NaN must never pass"
    depth = np.array([[1.0, np.inf]], np.float32)
    assert check.compare("depth", depth, depth.copy())[-1], "matching background (+inf) agrees"
    assert not check.compare("depth", depth, np.array([[1.0, 5.0]], np.float32))[-1]


def test_report_on_every_real_device_agrees():
    from clrender.device import select_devices
    devices = select_devices("all")
    if len(devices) < 2:
        pytest.skip("only one OpenCL device (non-simulator) here: nothing to compare")
    report = check.run_check(devices, width=48, height=32)      # every real device (a GPU too)
    assert report.ok, report.table()
    cases = {r.case for r in report.rows}
    assert {"soup", "dense", "lights"} <= cases
    assert {r.aov for r in report.rows} == set(check.AOVS)


def test_cli_check_exit_status_and_json(tmp_path, capsys, monkeypatch):
    out = tmp_path / "report.json"
    rc = cli.main(["check", "--device", "pocl", "--width", "32", "--height", "24", "--json", str(out), "-q"])
    report = json.loads(out.read_text())
    assert rc == (0 if report["ok"] else 1)
    assert "reference device" in capsys.readouterr().out
    # A mismatch makes the command fail.
    monkeypatch.setattr(check, "compare", lambda aov, a, b: (1.0, 1.0, 1, "forced", False))
    rc = cli.main(["check", "--device", "pocl", "--width", "32", "--height", "24", "-q"])
    from clrender.device import select_devices
    assert rc == (1 if len(select_devices("pocl")) > 1 else 0)
    assert cli.main(["check", "--scene", str(tmp_path / "missing.glb")]) != 0
