"""Rules every kernel file keeps, checked on the sources and on each device.

- Each kernels/*.cl builds on its own with its defaults (`#ifndef X #define X default`).
- Each opens with a block stating its algorithm, buffers and work-group mapping.
- Nothing assumes a GPU: no sub-group/warp lockstep, no 64-bit atomics (clrender uses none,
  so devices without cl_khr_int64_*_atomics run the same code), and the local memory a kernel
  declares fits the device's CL_DEVICE_LOCAL_MEM_SIZE.
"""
import re
from pathlib import Path

import pytest

KERNELS = Path(__file__).resolve().parent.parent / "kernels"
SOURCES = sorted(p.name for p in KERNELS.glob("*.cl"))
GPU_ONLY = re.compile(r"\b(sub_group_\w+|get_sub_group_\w+|intel_sub_group\w*|atom_\w+|atomic_\w+\s*\(\s*\(\s*(global|local)\s+(u?long)"
                      r"|cl_khr_int64_(base|extended)_atomics|__shfl\w*|warp\w*)\b")


def test_every_kernel_file_is_covered():
    assert {"setup.cl", "binning.cl", "raster.cl", "gbuffer.cl", "light_cull.cl", "shade.cl", "tonemap.cl",
            "scan.cl"} <= set(SOURCES)


@pytest.mark.parametrize("name", SOURCES)
def test_opens_with_algorithm_buffers_and_work_groups(name):
    text = (KERNELS / name).read_text()
    head = text[: text.index("*/")] if text.startswith("/*") else ""
    assert head.startswith(f"/* {name}:"), f"{name} must open with a block comment naming itself"
    for word in ("Algorithm", "Buffers", "Work-group"):
        assert word in head, f"{name}'s opening block does not state its {word}"


@pytest.mark.parametrize("name", SOURCES)
def test_no_gpu_only_constructs(name):
    text = re.sub(r"/\*.*?\*/|//[^\n]*", "", (KERNELS / name).read_text(), flags=re.S)
    found = GPU_ONLY.findall(text)
    assert not found, f"{name} uses GPU-only constructs: {found}"


@pytest.mark.parametrize("name", SOURCES)
def test_builds_alone_with_defaults_and_fits_local_memory(device, name):
    import pyopencl as cl
    from clrender.device.core import Device
    dev = Device.get(device)
    program = dev.program(name)
    for kernel in program.all_kernels():
        local = kernel.get_work_group_info(cl.kernel_work_group_info.LOCAL_MEM_SIZE, dev.cl_device)
        assert local <= dev.cl_device.local_mem_size, (name, kernel.function_name, local)
