"""Pip's PoCL 3.0 (LLVM 14) on AVX-512 CPUs its LLVM cannot name (issue 35 item 6).

PoCL compiles for `-target-cpu` = LLVM's getHostCPUName() (PoCL 3.0 has no setting to change it)
but links the kernel library variant its own feature check picks (avx512 wherever the CPU has
avx512f). LLVM 14 calls every AMD family-19h CPU "znver3", so on Zen 4 (EPYC Genoa, Ryzen 7000)
the target has no AVX-512 while PoCL reports a preferred float width of 16: clrender's 16-wide
pixel runs then sent LLVM 14's InstCombine into a loop in gbuffer_resolve's work-group function
that ended in SIGSEGV after ~3 minutes (measured here under the shim: signal 11 after 175 s).
clrender now asks the compiler whether its target has AVX-512 (capabilities.pixel_vector_width)
and uses 8-wide runs when it has not.

These tests make this machine look like a Zen 4 to pip's PoCL: tests/fake_cpuid.c, an LD_PRELOAD
shim answering CPUID with AMD family 19h model 11h (needs a C compiler and CPUID faulting,
the "cpuid_fault" CPU flag; skipped otherwise).
"""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _pip_pocl():
    """(id, name) of pip's PoCL 3.0 CPU device (LLVM 14, bundled with pyopencl), else skip."""
    from clrender.device.core import list_devices
    for d in list_devices():
        if "PoCL 3.0" in d.cl_device.platform.version and "LLVM 14" in d.cl_device.platform.version:
            return d.id, d.name
    pytest.skip("pip's PoCL 3.0 (LLVM 14) is not installed")


@pytest.fixture(scope="module")
def zen4_env(tmp_path_factory):
    """Environment that makes pip's PoCL see a Zen 4 (fresh caches, the shim preloaded)."""
    cc = shutil.which("cc") or shutil.which("gcc")
    if cc is None:
        pytest.skip("no C compiler for the CPUID shim")
    tmp = tmp_path_factory.mktemp("zen4")
    lib = tmp / "fake_cpuid.so"
    subprocess.run([cc, "-O2", "-shared", "-fPIC", "-o", str(lib), str(ROOT / "tests" / "fake_cpuid.c")],
                   check=True, capture_output=True)
    env = dict(os.environ, FAKECPU="zen4", LD_PRELOAD=str(lib), CLRENDER_CACHE_DIR=str(tmp / "clrender"),
               POCL_CACHE_DIR=str(tmp / "pocl"), PYTHONPATH=str(ROOT), PYTHONWARNINGS="ignore")
    env.pop("CLRENDER_VEC", None)
    if subprocess.run([sys.executable, "-c", "pass"], env=env).returncode == 3:
        pytest.skip("this CPU or kernel has no CPUID faulting (arch_prctl ARCH_SET_CPUID)")
    return env


_WIDTH = """
import sys
from clrender import capabilities
from clrender.device import list_devices
d = next(d for d in list_devices() if d.id == sys.argv[1])
print(capabilities.pixel_vector_width(d.cl_device), int(d.cl_device.preferred_vector_width_float))
"""


def _width(env, device_id) -> tuple[int, int]:
    out = subprocess.run([sys.executable, "-c", _WIDTH, device_id], env=env, capture_output=True, text=True,
                         timeout=120)
    assert out.returncode == 0, out.stderr[-2000:]
    vec, preferred = out.stdout.split()
    return int(vec), int(preferred)


def test_pip_pocl_on_zen4_runs_8_wide_pixel_runs(zen4_env, tmp_path):
    device_id, _ = _pip_pocl()
    vec, preferred = _width(zen4_env, device_id)
    assert preferred == 16 or "avx512f" not in Path("/proc/cpuinfo").read_text()
    assert vec == 8, f"PoCL prefers {preferred}-wide floats but its LLVM 14 target (znver3) has no AVX-512"
    # where LLVM names the CPU as an AVX-512 one (this one, unshimmed), the width stays what PoCL prefers
    # (its own cache: the answer is kept per CPU model from /proc/cpuinfo, which the shim leaves alone)
    plain = {k: v for k, v in zen4_env.items() if k not in ("LD_PRELOAD", "FAKECPU")}
    plain["CLRENDER_CACHE_DIR"] = str(tmp_path / "plain")
    vec, preferred = _width(plain, device_id)
    assert vec == (16 if preferred >= 16 else 8)


def test_pip_pocl_probe_passes_on_zen4(zen4_env):
    """The device probe's child (what `clrender devices` and the default device run) builds and
    launches the default pipeline on pip's PoCL as a Zen 4 sees it. Before the fix: SIGSEGV in
    LLVM 14's InstCombine (gbuffer_resolve, VEC 16) after ~3 min; now ~25 s on 2 busy cores."""
    device_id, name = _pip_pocl()
    env = dict(zen4_env, CLRENDER_PROBE_CHILD="1")
    start = time.monotonic()
    try:
        out = subprocess.run([sys.executable, "-m", "clrender.tools.probe_child", device_id, name], env=env,
                             capture_output=True, text=True, timeout=150)
    except subprocess.TimeoutExpired:
        pytest.fail("the probe child did not finish within 150 s (LLVM 14 looping on 16-wide vectors?)")
    lines = [ln for ln in out.stdout.splitlines() if ln.strip() and not ln.startswith(("progress ", "total ", "built "))]
    assert out.returncode == 0 and lines[-1:] == ["ok"], \
        f"exit {out.returncode} after {time.monotonic() - start:.0f} s: {lines[-1:]}"
