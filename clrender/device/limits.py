"""The device's memory limits, and the check a buffer's size must pass before it is allocated.

Passes call `check_buffer` (or `limits`) before growing a buffer whose size only the device knew;
clrender/render/memory.py checks a whole frame with the same `limits`. Tests lower the limits by
patching `clrender.device.limits.limits` (looked up at call time here)."""
from __future__ import annotations

from clrender.errors import DeviceMemoryError


def _gb(n: int) -> str:
    return f"{n / 2**30:.2f} GiB"


def limits(cl_device) -> tuple[int, int]:
    """(global memory bytes, largest single allocation bytes) of a pyopencl device."""
    return int(cl_device.global_mem_size), int(cl_device.max_mem_alloc_size)


def check_buffer(device, what: str, entries: int, bytes_per_entry: int, capacity: int) -> None:
    """DeviceMemoryError unless `capacity` entries of `bytes_per_entry` (in 4-byte arrays) fit
    the device; raised before allocating, naming what needs the memory."""
    need = int(capacity) * bytes_per_entry
    total, max_alloc = limits(device.cl_device)
    if need > total or 4 * int(capacity) > max_alloc:
        raise DeviceMemoryError(
            f"{what} need {need} bytes ({_gb(need)}) of device memory for {entries} entries but {device.name} "
            f"has {total} bytes ({_gb(total)}), at most {max_alloc} bytes ({_gb(max_alloc)}) per allocation; "
            f"render at a smaller size or set max_fragments_per_pixel")
