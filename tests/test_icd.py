"""Registering pip-installed OpenCL implementations (clrender/device/icd.py) and reporting ICD files whose
library does not load. The subprocess tests run `clrender devices --no-probe` (a platform query,
no kernel builds: about 2 s each) in a fresh process, since the loader reads $OCL_ICD_VENDORS once."""
from __future__ import annotations

import json
import logging
import os
import subprocess
import sys
import warnings
from pathlib import Path

import pytest

from clrender.device import icd
from helpers import skip_or_fail

REPO = Path(__file__).resolve().parents[1]
INTEL_PLATFORM = "Intel(R) OpenCL"
DEBIAN_POCL_ICD = Path("/etc/OpenCL/vendors/pocl.icd")


def _intel():
    found = [p for p in icd.pip_implementations() if p.name == "intel"]
    if not found:
        skip_or_fail("Intel's OpenCL CPU runtime is not installed (pip install -e \".[intel]\")")
    return found[0]


@pytest.fixture
def clean_env(monkeypatch, tmp_path):
    """No $OCL_ICD_VENDORS (this pytest process registered its own), a private cache folder."""
    for name in (icd.ENV_VENDORS, icd.ENV_REGISTERED, icd.ENV_REGISTER):
        monkeypatch.delenv(name, raising=False)
    monkeypatch.setenv("CLRENDER_CACHE_DIR", str(tmp_path / "cache"))
    return monkeypatch


def _devices(env_changes: dict, tmp_path, *args) -> subprocess.CompletedProcess:
    env = dict(os.environ, CLRENDER_CACHE_DIR=str(tmp_path / "cache"),
               PYTHONPATH=os.pathsep.join(filter(None, [str(REPO), os.environ.get("PYTHONPATH")])))
    for name in (icd.ENV_VENDORS, icd.ENV_REGISTERED, icd.ENV_REGISTER, "CLRENDER_DEBUG"):
        env.pop(name, None)
    env.update(env_changes)
    return subprocess.run([sys.executable, "-m", "clrender", "devices", "--no-probe", *args], cwd=tmp_path,
                          env=env, capture_output=True, text=True, timeout=120)


def _platforms(proc) -> list[str]:
    assert proc.returncode == 0, proc.stderr
    return [r["platform"] for r in json.loads(proc.stdout)]


# -- pip_implementations / register (in this process) ------------------------------------------------
def test_pip_implementations_finds_intel_without_loading_it():
    intel = _intel()
    assert intel.library.name == "libintelocl.so" and intel.library.is_file() and intel.needs_icd


def test_register_writes_system_icds_plus_pip_ones(clean_env, tmp_path):
    intel = _intel()
    system = tmp_path / "vendors"
    system.mkdir()
    (system / "a.icd").write_text("/opt/a/liba.so\n")
    (system / "b.icd").write_text("libb.so.1\n")
    (system / "README").write_text("not an ICD file")
    clean_env.setenv(icd.ENV_VENDOR_PATH, str(system))

    folder = icd.register()
    assert folder is not None and os.environ[icd.ENV_VENDORS] == str(folder)
    assert folder.is_relative_to(tmp_path / "cache" / "icd")
    files = {p.name: p.read_text() for p in folder.iterdir()}
    assert files.pop("a.icd") == "/opt/a/liba.so\n" and files.pop("b.icd") == "libb.so.1\n"
    assert list(files.values()) == [f"{intel.library}\n"]

    # a second process start (the variable unset again) finds the same folder: nothing rewritten
    clean_env.delenv(icd.ENV_VENDORS)
    assert icd.register() == folder
    # the process's own registration inherited by a child: left as it is, no second folder
    assert icd.register() is None and os.environ[icd.ENV_VENDORS] == str(folder)
    assert len(list((tmp_path / "cache" / "icd").iterdir())) == 1

    # a new system ICD: a new folder, so a running process's folder never changes under it
    (system / "c.icd").write_text("/opt/c/libc.so\n")
    clean_env.delenv(icd.ENV_VENDORS)
    newer = icd.register()
    assert newer != folder and (newer / "c.icd").is_file() and (folder / "a.icd").is_file()


def test_register_uses_a_temporary_folder_when_the_cache_is_unusable(clean_env, tmp_path):
    _intel()
    clean_env.setenv("CLRENDER_CACHE_MAX_MB", "0")          # no cache
    clean_env.setenv(icd.ENV_VENDOR_PATH, str(tmp_path / "none"))
    folder = icd.register()
    assert folder is not None and not folder.is_relative_to(tmp_path)
    assert [p.name for p in folder.iterdir()] == ["clrender-pip-intel.icd"]


def test_register_skips_an_implementation_the_system_already_registers(clean_env, tmp_path):
    intel = _intel()
    system = tmp_path / "vendors"
    system.mkdir()
    (system / "intel.icd").write_text(f"{intel.library}\n")
    clean_env.setenv(icd.ENV_VENDOR_PATH, str(system))
    assert icd.register() is None and icd.ENV_VENDORS not in os.environ


def test_register_leaves_the_users_setting_and_can_be_turned_off(clean_env, tmp_path, caplog):
    _intel()
    clean_env.setenv(icd.ENV_VENDORS, str(tmp_path))
    with caplog.at_level(logging.DEBUG, logger="clrender"):
        assert icd.register() is None
    assert os.environ[icd.ENV_VENDORS] == str(tmp_path)
    assert any("leaves it alone" in r.getMessage() and "intel" in r.getMessage() for r in caplog.records)

    clean_env.delenv(icd.ENV_VENDORS)
    clean_env.setenv(icd.ENV_REGISTER, "0")
    assert icd.register() is None and icd.ENV_VENDORS not in os.environ


# -- what a fresh process sees ------------------------------------------------------------------------
def test_fresh_process_sees_intel_and_the_system_devices(tmp_path):
    _intel()
    registered = _platforms(_devices({}, tmp_path, "--json"))
    assert INTEL_PLATFORM in registered
    off = _platforms(_devices({icd.ENV_REGISTER: "0"}, tmp_path, "--json"))
    assert INTEL_PLATFORM not in off
    assert sorted(p for p in registered if p != INTEL_PLATFORM) == sorted(off)   # the system's ones kept


def test_users_ocl_icd_vendors_wins(tmp_path):
    _intel()
    if not DEBIAN_POCL_ICD.is_file():
        pytest.skip(f"{DEBIAN_POCL_ICD} is not installed (Debian's pocl-opencl-icd)")
    vendors = tmp_path / "vendors"
    vendors.mkdir()
    (vendors / "pocl.icd").write_bytes(DEBIAN_POCL_ICD.read_bytes())
    platforms = _platforms(_devices({icd.ENV_VENDORS: str(vendors)}, tmp_path, "--json"))
    assert INTEL_PLATFORM not in platforms and platforms


# -- ICD files whose library does not load ------------------------------------------------------------
def _broken_vendors(tmp_path) -> Path:
    vendors = tmp_path / "vendors"
    vendors.mkdir()
    if DEBIAN_POCL_ICD.is_file():
        (vendors / "pocl.icd").write_bytes(DEBIAN_POCL_ICD.read_bytes())
    (vendors / "missing.icd").write_text(str(tmp_path / "nowhere" / "libmissing.so") + "\n")
    text = tmp_path / "libtext.so"
    text.write_text("not a shared library\n")
    (vendors / "text.icd").write_text(f"{text}\n")
    return vendors


def test_icd_problems_names_each_broken_file(monkeypatch, tmp_path):
    vendors = _broken_vendors(tmp_path)
    (vendors / "relative.icd").write_text("libclrender-no-such-library.so.7\n")
    monkeypatch.setenv(icd.ENV_VENDORS, str(vendors))
    problems = icd.icd_problems()
    assert len(problems) == 3, problems
    by_file = {name: [p for p in problems if f"{vendors / name} " in p] for name in
               ("missing.icd", "text.icd", "relative.icd")}
    assert all(len(lines) == 1 for lines in by_file.values()), problems
    assert "libmissing.so, which does not load (file not found)" in by_file["missing.icd"][0]
    assert "libtext.so, which does not load (" in by_file["text.icd"][0]
    assert "(file not found)" in by_file["relative.icd"][0]
    assert all(p.endswith("the other devices are used") for p in problems)

    monkeypatch.setenv(icd.ENV_VENDORS, str(tmp_path / "absent"))
    assert [p for p in icd.icd_problems() if "neither a folder nor a file" in p]


def test_pip_pocls_own_icd_file_is_not_reported(monkeypatch, tmp_path):
    """pyopencl/.libs/pocl.icd names "libpocl-<hash>.so", which the bundled loader finds next to
    itself: copied into a vendors folder (as users do), it loads, so no line."""
    import pyopencl
    own = Path(pyopencl.__file__).parent / ".libs" / "pocl.icd"
    if not own.is_file():
        pytest.skip("pyopencl's wheel bundles no PoCL here")
    (tmp_path / "pocl.icd").write_bytes(own.read_bytes())
    monkeypatch.setenv(icd.ENV_VENDORS, str(tmp_path))
    assert icd.icd_problems() == []


def test_no_device_error_names_the_broken_icds(monkeypatch, tmp_path):
    from clrender.device import choice as device
    monkeypatch.setenv(icd.ENV_VENDORS, str(_broken_vendors(tmp_path)))
    with pytest.raises(device.DeviceError) as info:
        device.match_devices("anything", devices=[])
    msg = str(info.value)
    assert msg.startswith("no OpenCL device found") and "missing.icd" in msg and "text.icd" in msg
    assert "\n" not in msg


def test_devices_command_reports_broken_icds_and_lists_the_rest(tmp_path):
    if not DEBIAN_POCL_ICD.is_file():
        pytest.skip(f"{DEBIAN_POCL_ICD} is not installed (Debian's pocl-opencl-icd)")
    vendors = _broken_vendors(tmp_path)
    proc = _devices({icd.ENV_VENDORS: str(vendors)}, tmp_path)
    assert proc.returncode == 0, proc.stderr
    for name in ("missing.icd", "text.icd"):
        lines = [line for line in proc.stderr.splitlines() if name in line]
        assert len(lines) == 1, proc.stderr
        assert lines[0].startswith(f"clrender: OpenCL ICD {vendors / name} names "), lines
    assert "Portable Computing Language" in proc.stdout or "pocl" in proc.stdout, proc.stdout
    assert "not probed" in proc.stdout


def test_a_platform_whose_devices_cannot_be_listed_is_named_once(monkeypatch):
    import pyopencl as cl

    from clrender.device import choice as device

    class Broken:
        name = "Broken Platform"

        def get_devices(self):
            raise cl.RuntimeError("clGetDeviceIDs failed: OUT_OF_HOST_MEMORY")

    real = cl.get_platforms()
    monkeypatch.setattr(device.cl, "get_platforms", lambda: [Broken(), *real])
    monkeypatch.setattr(device, "_platform_warned", set())
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        first = device.list_devices()
        second = device.list_devices()
    named = [w for w in caught if "Broken Platform" in str(w.message)]
    assert len(named) == 1 and "OUT_OF_HOST_MEMORY" in str(named[0].message)
    assert len(first) == len(second) == sum(len(p.get_devices()) for p in real)
    assert all(d.id.startswith(("1:", "2:", "3:", "4:", "5:", "6:")) for d in first)   # indices kept
