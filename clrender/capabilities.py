"""Every question clrender asks of an OpenCL device, answered in one place.

Modelled on pyopencl.characterize: small functions of a `pyopencl.Device`, so kernels
and passes never guess at GPU-like limits.
"""
from __future__ import annotations

import pyopencl as cl

SIMULATOR_NAMES = ("oclgrind",)


def is_cpu(dev: cl.Device) -> bool:
    return bool(dev.type & cl.device_type.CPU)


def is_gpu(dev: cl.Device) -> bool:
    return bool(dev.type & cl.device_type.GPU)


def is_simulator(dev: cl.Device) -> bool:
    text = f"{dev.platform.name} {dev.name} {dev.vendor}".lower()
    return any(name in text for name in SIMULATOR_NAMES)


def fill_buffer_marks_initialized(dev: cl.Device) -> bool:
    """Whether clEnqueueFillBuffer's output counts as written: not on Oclgrind, whose
    uninitialized-value checker would then report every later read of a zeroed buffer."""
    return not is_simulator(dev)


_COMPILER_PROBE = "kernel void probe(global int* out) { out[get_global_id(0)] = 1; }"
_compiles: dict = {}


def compiler_error(dev: cl.Device):
    """None when the device builds a trivial OpenCL C kernel, else the build error (cached).
    Some installs list a device whose compiler cannot target this CPU (e.g. an LLVM older than
    the CPU): `select_devices("all")` leaves such a device out instead of failing every test."""
    key = dev.int_ptr
    if key not in _compiles:
        try:
            cl.Program(cl.Context([dev]), _COMPILER_PROBE).build()
            _compiles[key] = None
        except cl.Error as exc:
            lines = [ln.strip() for ln in str(exc).splitlines() if "error" in ln.lower()]
            _compiles[key] = (lines[-1] if lines else str(exc).splitlines()[0])[:200]
    return _compiles[key]


def max_work_group_size(dev: cl.Device) -> int:
    return int(dev.max_work_group_size)


def local_mem_bytes(dev: cl.Device) -> int:
    # CL_NONE (0) means no dedicated local memory; pyopencl names only LOCAL and GLOBAL.
    return int(dev.local_mem_size) if int(dev.local_mem_type) != 0 else 0


def has_int64_atomics(dev: cl.Device) -> bool:
    ext = dev.extensions.split()
    return "cl_khr_int64_base_atomics" in ext


def correctly_rounded_divide_sqrt(dev: cl.Device) -> bool:
    return bool(dev.single_fp_config & cl.device_fp_config.CORRECTLY_ROUNDED_DIVIDE_SQRT)


def tile_size_for(dev: cl.Device, requested: int) -> int:
    """A square tile of `requested` pixels per side must fit one work-group."""
    if requested * requested > max_work_group_size(dev) or requested > min(dev.max_work_item_sizes[:2]):
        raise ValueError(f"tile size {requested} needs a work-group of {requested * requested} work-items; "
                         f"{dev.name} allows {max_work_group_size(dev)} "
                         f"(per-dimension {list(dev.max_work_item_sizes[:2])})")
    return requested


SCAN_ITEMS = 8    # counts per work-item in kernels/scan.cl


def scan_shape(dev: cl.Device, preferred: int = 128) -> tuple[int, int]:
    """(work-group size, items per work-item) for kernels/scan.cl: the largest power of two
    up to `preferred` that the device's work-group limits allow and whose staging arrays,
    (wg·items + 2·wg) ints, fit in half of CL_DEVICE_LOCAL_MEM_SIZE."""
    limit = min(preferred, max_work_group_size(dev), int(dev.max_work_item_sizes[0]))
    local_budget = int(dev.local_mem_size) // 2
    wg = 1
    while wg * 2 <= limit and (wg * 2) * (SCAN_ITEMS + 2) * 4 <= local_budget:
        wg *= 2
    return wg, SCAN_ITEMS


def pixel_vector_width(dev: cl.Device) -> int:
    """Pixels per work-item in per-pixel kernels (kernels/vec.h): 1 on GPUs (a pixel per
    lane); on CPUs an explicit vector as wide as the SIMD unit, since PoCL cannot vectorize
    across work-items through loops and library calls. CLRENDER_VEC overrides (tests)."""
    import os
    forced = os.environ.get("CLRENDER_VEC")
    if forced:
        width = int(forced)
    elif is_simulator(dev):
        width = 1          # Oclgrind reports every device type; it runs the GPU path (a pixel per work-item)
    elif is_cpu(dev):
        width = 16 if int(dev.preferred_vector_width_float) >= 16 else 8
    else:
        width = 1
    if width not in (1, 4, 8, 16):
        raise ValueError(f"pixel vector width must be 1, 4, 8 or 16, got {width}")
    return width


def shadow_tile_size(dev: cl.Device, config) -> int:
    """Raster tile of the shadow maps: config.shadow_tile_size, else 32 on CPUs (a work-group of
    32/VEC x 1 work-items walking whole tile columns: a 2048² map bins 16x fewer tile entries
    than with 8-pixel tiles) and the camera's tile_size on GPUs (a pixel per work-item: 32² would
    exceed most work-group limits)."""
    if config.shadow_tile_size is not None:
        return tile_size_for(dev, config.shadow_tile_size)
    return 32 if pixel_vector_width(dev) > 1 else tile_size_for(dev, config.tile_size)


def raster_vector_width(dev: cl.Device, tile: int) -> int:
    """A raster work-item's pixel run must fit in its tile row."""
    return min(pixel_vector_width(dev), tile)


def build_options(dev: cl.Device) -> list[str]:
    """Options every clrender program is built with on this device."""
    opts = ["-cl-std=CL1.2"]
    # Bit-exact rasterization (docs/raster_contract.md) needs IEEE division.
    if correctly_rounded_divide_sqrt(dev):
        opts.append("-cl-fp32-correctly-rounded-divide-sqrt")
    # Oclgrind 21.10's uninitialized-value checker stops at LLVM's `freeze` instruction, which
    # the optimizer emits (div/rem pairs, speculation); unoptimized code checks the same source.
    if is_simulator(dev):
        opts.append("-cl-opt-disable")
    return opts


def summary(dev: cl.Device, tolerant: bool = False) -> dict:
    """The limits clrender relies on, for `clrender devices` and reports. tolerant: a query the
    driver fails gives None for that field instead of raising (one broken field must not hide
    the rest)."""
    queries = {
        "type": lambda: "GPU" if is_gpu(dev) else "CPU" if is_cpu(dev) else "ACCELERATOR"
                        if dev.type & cl.device_type.ACCELERATOR else "OTHER",
        "version": lambda: dev.version,
        "driver": lambda: dev.driver_version,
        "compute_units": lambda: int(dev.max_compute_units),
        "max_work_group_size": lambda: max_work_group_size(dev),
        "max_work_item_sizes": lambda: list(dev.max_work_item_sizes),
        "local_mem_bytes": lambda: local_mem_bytes(dev),
        "global_mem_bytes": lambda: int(dev.global_mem_size),
        "max_alloc_bytes": lambda: int(dev.max_mem_alloc_size),
        "int64_atomics": lambda: has_int64_atomics(dev),
        "image_support": lambda: bool(dev.image_support),
        "correctly_rounded_divide": lambda: correctly_rounded_divide_sqrt(dev),
        "simulator": lambda: is_simulator(dev),
    }
    if not tolerant:
        return {key: query() for key, query in queries.items()}
    out = {}
    for key, query in queries.items():
        try:
            out[key] = query()
        except Exception:
            out[key] = None
    return out
