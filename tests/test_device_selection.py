"""Device names and the default device (issue 35): implementations by key ("intel", "pocl",
"oclgrind", ...), their versions, origins and vector widths; a default that falls back, in one line,
from a device whose probe fails; a named device that never does. Mostly fake devices and a fake
probe: no child process, no kernel build."""
from __future__ import annotations

import logging
import re
import warnings
from pathlib import Path
from types import SimpleNamespace

import pyopencl as cl
import pytest

from clrender.device import capabilities, probe as device_probe, icd
from clrender.device.core import (
    CPU_IMPLEMENTATION_ORDER, DeviceError, DeviceInfo, list_devices, match_devices, preference_order)

CPU, GPU = int(cl.device_type.CPU), int(cl.device_type.GPU)


def _fake(id_, platform, name, platform_version, driver, type_=CPU, library=None, pref=16, native=16):
    """A DeviceInfo over a stand-in cl.Device answering what clrender asks of one."""
    plat = SimpleNamespace(name=platform, version=platform_version, vendor=platform)
    dev = SimpleNamespace(platform=plat, name=name, vendor=platform, driver_version=driver, type=type_,
                          version="OpenCL 3.0", preferred_vector_width_float=pref,
                          native_vector_width_float=native, _library=library)
    return DeviceInfo(id_, platform, name, dev)


ORACLE = _fake("0:0", "Oclgrind", "Oclgrind Simulator", "OpenCL 1.2 (Oclgrind 21.10)", "Oclgrind 21.10",
               type_=CPU | GPU, library="/usr/lib/oclgrind/liboclgrind-rt-icd.so", pref=1, native=1)
INTEL = _fake("1:0", "Intel(R) OpenCL", "Intel(R) Xeon(R) Processor", "OpenCL 2.1 LINUX", "2021.11.3.0.17_160000",
              library="/venv/lib/libintelocl.so", pref=1, native=16)
DEBIAN = _fake("2:0", "Portable Computing Language", "pthread-skylake-avx512-Intel(R) Xeon(R) Processor",
               "OpenCL 3.0 PoCL 3.1+debian  Linux, None+Asserts, RELOC, SPIR, LLVM 15.0.6, SLEEF, DISTRO",
               "3.1+debian", library="/lib/x86_64-linux-gnu/libpocl.so.2.10.0")
PIP_POCL = _fake("3:0", "Portable Computing Language", "pthread-Intel(R) Xeon(R) Processor",
                 "OpenCL 3.0 PoCL 3.0-rc2  Linux, Release, RELOC, LLVM 14.0.6, SLEEF, DISTRO", "3.0-rc2",
                 library="/venv/lib/python3.11/site-packages/pyopencl/.libs/libpocl-21062cec.so")
NVIDIA = _fake("4:0", "NVIDIA CUDA", "NVIDIA H100", "OpenCL 3.0 CUDA 12.4.0", "550.54", type_=GPU,
               library="/usr/lib/x86_64-linux-gnu/libnvidia-opencl.so.1", pref=1, native=1)
ALL = [ORACLE, INTEL, DEBIAN, PIP_POCL]


@pytest.fixture(autouse=True)
def fake_libraries(monkeypatch):
    """Fakes name their driver library themselves (real devices: dladdr on the dispatch table), and
    pip installed the fake Intel runtime's file (real: opencl-rt's RECORD). Returns pip's list."""
    real = capabilities.driver_library
    monkeypatch.setattr(capabilities, "driver_library",
                        lambda dev: dev._library if isinstance(dev, SimpleNamespace) else real(dev))
    pip = [icd.PipImplementation("intel", Path(INTEL.cl_device._library), True)]
    monkeypatch.setattr(icd, "pip_implementations", lambda: list(pip))
    capabilities.library_origin.cache_clear()
    yield pip
    capabilities.library_origin.cache_clear()


def _ids(devices):
    return [d.id for d in devices]


def test_implementation_keys_versions_and_origins():
    assert [d.implementation for d in ALL + [NVIDIA]] == ["oclgrind", "intel", "pocl", "pocl", "nvidia"]
    assert [d.implementation_version for d in ALL] == ["21.10", "2021.11.3.0.17_160000", "3.1+debian", "3.0-rc2"]
    assert [d.origin for d in ALL] == ["system", "pip", "system", "pip"]
    assert INTEL.vector_widths == {"preferred_float": 1, "native_float": 16, "pixel": 8}
    assert PIP_POCL.vector_widths == {"preferred_float": 16, "native_float": 16, "pixel": 16}
    assert PIP_POCL.description == "3:0 PoCL 3.0-rc2 from pip"
    assert INTEL.description == "1:0 Intel's CPU runtime 2021.11.3.0.17_160000 from pip"
    assert DEBIAN.description == "2:0 PoCL 3.1+debian"


def test_an_implementation_key_picks_that_implementation_only():
    # PoCL's device names contain "Intel(R) Xeon": "intel" is Intel's runtime, not a substring
    assert _ids(match_devices("intel", ALL)) == ["1:0"]
    assert _ids(match_devices("INTEL", ALL)) == ["1:0"]
    assert _ids(match_devices("pocl", ALL)) == ["2:0", "3:0"]
    assert _ids(match_devices("oclgrind", ALL)) == ["0:0"]
    # the old rules still work: "P:D", a substring of platform / device / version
    assert _ids(match_devices("3:0", ALL)) == ["3:0"]
    assert _ids(match_devices("debian", ALL)) == ["2:0"]
    assert _ids(match_devices("3.0-rc2", ALL)) == ["3:0"]
    assert _ids(match_devices("xeon", ALL)) == ["1:0", "2:0", "3:0"]
    assert _ids(match_devices("skylake", ALL)) == ["2:0"]
    # origins, and words that narrow each other
    assert _ids(match_devices("pip", ALL)) == ["1:0", "3:0"]
    assert _ids(match_devices("system", ALL)) == ["0:0", "2:0"]
    assert _ids(match_devices("pocl pip", ALL)) == ["3:0"]
    assert _ids(match_devices("pocl 3.1", ALL)) == ["2:0"]


def test_a_name_matching_nothing_lists_what_is_installed_and_what_to_install(fake_libraries):
    fake_libraries.clear()                                  # pip did not install Intel's runtime either
    with pytest.raises(DeviceError) as info:
        match_devices("intel", [ORACLE, DEBIAN, PIP_POCL])
    msg = str(info.value)
    assert "\n" not in msg
    assert "Intel's CPU runtime is not installed" in msg and "pip install opencl-rt" in msg
    for d in (ORACLE, DEBIAN, PIP_POCL):
        assert d.id in msg and d.implementation_version in msg
    with pytest.raises(DeviceError, match=r"PoCL is not installed.*pip install pocl-binary-distribution"):
        match_devices("pocl", [INTEL])
    with pytest.raises(DeviceError) as info:
        match_devices("no-such-thing", ALL)
    msg = str(info.value)
    assert "'no-such-thing'" in msg and "pip install" not in msg and all(d.id in msg for d in ALL)


def test_an_installed_implementation_the_loader_does_not_list_is_said(monkeypatch):
    monkeypatch.setenv("OCL_ICD_VENDORS", "/somewhere/else")
    monkeypatch.delenv("CLRENDER_ICD_VENDORS", raising=False)
    with pytest.raises(DeviceError) as info:
        match_devices("intel", [ORACLE, DEBIAN, PIP_POCL])
    msg = str(info.value)
    assert "Intel's CPU runtime is installed (/venv/lib/libintelocl.so) but the OpenCL loader lists no device" in msg
    assert "OCL_ICD_VENDORS=/somewhere/else" in msg and "\n" not in msg


def test_preference_order_gpus_then_the_measured_cpu_order_then_simulators():
    # measured (docs/devices.md): PoCL 3.1 before Intel's runtime before pip's PoCL 3.0-rc2; an
    # implementation the table does not name comes after
    assert CPU_IMPLEMENTATION_ORDER == (("pocl", (3, 1)), ("intel", ()), ("pocl", ()))
    order = preference_order([ORACLE, PIP_POCL, DEBIAN, INTEL, NVIDIA])
    assert _ids(order) == ["4:0", "2:0", "1:0", "3:0", "0:0"]
    assert _ids(preference_order([PIP_POCL, INTEL])) == ["1:0", "3:0"]          # a pip-only install
    other = _fake("5:0", "Clover", "AMD Radeon (LLVM)", "OpenCL 1.1 Mesa", "23.0", type_=CPU)
    assert _ids(preference_order([other, ORACLE, PIP_POCL])) == ["3:0", "5:0", "0:0"]


@pytest.fixture
def fake_probe(monkeypatch):
    """device_probe over ALL with probe answers from a dict (id -> error or None); records asks."""
    answers, asked = {}, []
    monkeypatch.delenv("CLRENDER_DEVICE", raising=False)
    monkeypatch.setattr(device_probe, "list_devices", lambda: list(ALL))
    monkeypatch.setattr(device_probe, "_warned", set())

    def probe_error(d):
        asked.append(d.id)
        return answers.get(d.id)
    monkeypatch.setattr(device_probe, "probe_error", probe_error)
    return SimpleNamespace(answers=answers, asked=asked)


def test_the_default_falls_back_with_one_line_naming_both(fake_probe, caplog):
    fake_probe.answers["2:0"] = "the driver crashed building or running clrender's kernels (signal 11)"
    with caplog.at_level(logging.INFO, logger="clrender"):
        with pytest.warns(UserWarning) as record:
            chosen = device_probe.default_device_info()
    assert chosen.id == "1:0" and fake_probe.asked == ["2:0", "1:0"]
    assert len(record) == 1
    line = str(record[0].message)
    assert "\n" not in line
    assert re.search(r"2:0 PoCL 3\.1\+debian.* failed clrender's probe \(.*signal 11\).*"
                     r"using .*1:0 Intel's CPU runtime 2021\.11.* instead", line), line
    assert [r.getMessage() for r in caplog.records if "failed clrender's probe" in r.getMessage()] == [line]


def test_the_default_picks_the_first_usable_without_a_notice(fake_probe):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert device_probe.default_device_info().id == "2:0"
    assert fake_probe.asked == ["2:0"]


def test_no_usable_device_says_what_to_install(fake_probe, monkeypatch, fake_libraries):
    fake_libraries.clear()
    monkeypatch.setattr(device_probe, "list_devices", lambda: [ORACLE, DEBIAN, PIP_POCL])
    fake_probe.answers.update({"2:0": "INVALID_KERNEL_NAME", "3:0": "signal 11"})
    with warnings.catch_warnings():
        warnings.simplefilter("error")                      # the error is the one line
        with pytest.raises(DeviceError) as info:
            device_probe.default_device_info()
    msg = str(info.value)
    assert "\n" not in msg and "no OpenCL device runs clrender's kernels" in msg
    assert "INVALID_KERNEL_NAME" in msg and "signal 11" in msg and "pip install opencl-rt" in msg
    assert "0:0" not in fake_probe.asked, "the simulator is no default"


@pytest.mark.parametrize("how", ["argument", "environment"])
def test_a_named_device_that_fails_its_probe_is_one_line_and_no_fallback(fake_probe, monkeypatch, how):
    fake_probe.answers["1:0"] = "signal 11"
    if how == "environment":
        monkeypatch.setenv("CLRENDER_DEVICE", "intel")
    with warnings.catch_warnings():
        warnings.simplefilter("error")                      # no notice: an error instead
        with pytest.raises(DeviceError) as info:
            device_probe.default_device_info("intel" if how == "argument" else None)
    msg = str(info.value)
    assert "\n" not in msg and "1:0 Intel's CPU runtime" in msg and "signal 11" in msg
    assert fake_probe.asked == ["1:0"], "a named device is a request: no other device is tried"
    if how == "environment":
        assert "CLRENDER_DEVICE" in msg


def test_a_named_implementation_that_is_absent_is_one_line(fake_probe, monkeypatch, fake_libraries):
    fake_libraries.clear()
    monkeypatch.setattr(device_probe, "list_devices", lambda: [ORACLE, DEBIAN, PIP_POCL])
    with pytest.raises(DeviceError, match="Intel's CPU runtime is not installed.*pip install opencl-rt"):
        device_probe.default_device_info("intel")
    assert fake_probe.asked == []


def test_the_probe_cache_key_includes_the_cpu_model(monkeypatch):
    devices = list_devices()
    if not devices:
        pytest.skip("no OpenCL device")
    cpu = capabilities.cpu_identity()
    assert cpu and isinstance(cpu, str)
    first = device_probe._key(devices[0])
    monkeypatch.setattr(capabilities, "cpu_identity", lambda: cpu + " (another CPU)")
    assert device_probe._key(devices[0]) != first


def test_list_devices_reports_implementation_version_origin_and_vector_widths():
    devices = list_devices()
    if not devices:
        pytest.skip("no OpenCL device")
    for d in devices:
        assert re.fullmatch(r"[a-z0-9][a-z0-9_-]*", d.implementation), d.implementation
        assert d.implementation_version and d.origin in ("pip", "system", "conda")
        w = d.vector_widths
        assert w["preferred_float"] >= 1 and w["native_float"] >= 1 and w["pixel"] in (1, 4, 8, 16)
    pocl = [d for d in devices if d.is_pocl]
    if not pocl:
        pytest.skip("no PoCL device")
    for d in pocl:
        assert d.implementation == "pocl" and re.match(r"\d+\.\d+", d.implementation_version)
        assert d.vector_widths["pixel"] in (8, 16) and d.vector_widths["preferred_float"] >= 4
        # pip's PoCL lives in pyopencl's wheel (site-packages); a distribution's in the system
        path = capabilities.driver_library(d.cl_device)
        assert path and ("site-packages" in path) == (d.origin == "pip"), path
        if "+debian" in d.implementation_version:
            assert d.origin == "system"


def test_the_devices_report_shows_implementation_version_and_vector_widths(monkeypatch):
    from clrender.device import report as device_report
    monkeypatch.setattr(device_probe, "probe_error", lambda d: None)
    monkeypatch.setattr(capabilities, "summary", lambda dev, tolerant=False: {"type": "CPU"})
    records = [device_report.device_record(d, "1:0") for d in (INTEL, PIP_POCL)]
    assert records[0]["implementation"] == "intel" and records[0]["implementation_version"] == "2021.11.3.0.17_160000"
    assert records[0]["origin"] == "pip" and records[0]["vector_widths"] == INTEL.vector_widths
    table = device_report.devices_table(records)
    assert "intel 2021.11.3.0.17_160000 (pip)" in table and "pocl 3.0-rc2 (pip)" in table
    row = next(line for line in table.splitlines() if line.lstrip("* ").startswith("1:0"))
    assert "1/16/8" in row
