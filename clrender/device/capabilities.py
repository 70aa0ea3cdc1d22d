"""Every question clrender asks of an OpenCL device, answered in one place.

Modelled on pyopencl.characterize: small functions of a `pyopencl.Device`, so kernels
and passes never guess at GPU-like limits.
"""
from __future__ import annotations

import ctypes
import hashlib
import os
import platform
import re
import sys
from functools import lru_cache
from pathlib import Path
from typing import Optional

import pyopencl as cl

SIMULATOR_NAMES = ("oclgrind",)


def is_cpu(dev: cl.Device) -> bool:
    return bool(dev.type & cl.device_type.CPU)


def is_gpu(dev: cl.Device) -> bool:
    return bool(dev.type & cl.device_type.GPU)


def is_simulator(dev: cl.Device) -> bool:
    text = f"{dev.platform.name} {dev.name} {dev.vendor}".lower()
    return any(name in text for name in SIMULATOR_NAMES)


# Which OpenCL implementation a device belongs to: a short stable key (`--device KEY` picks its
# devices), its version, and where its library came from. Device names do not say it: PoCL names
# its CPU device after the CPU ("pthread-Intel(R) Xeon(R) ..."), like Intel's own runtime does.

def implementation_key(platform_name: str) -> str:
    """"pocl", "intel" (Intel's CPU runtime, platform "Intel(R) OpenCL"), "intel-gpu" (Intel's
    GPU runtime: "Intel(R) OpenCL Graphics"/"HD Graphics"), "oclgrind", "nvidia", "amd", else the
    platform name's first word, lowercased, without punctuation."""
    text = platform_name.strip().lower()
    if "portable computing language" in text or "pocl" in text:
        return "pocl"
    if "oclgrind" in text:
        return "oclgrind"
    if text.startswith("intel"):
        return "intel-gpu" if "graphics" in text else "intel"
    if "nvidia" in text:
        return "nvidia"
    if text.startswith("amd") or "advanced micro devices" in text:
        return "amd"
    words = re.sub(r"[^a-z0-9_ -]", "", text).split()
    return words[0] if words else "unknown"


def implementation(dev: cl.Device) -> str:
    return implementation_key(dev.platform.name)


def implementation_version(dev: cl.Device, key: Optional[str] = None) -> str:
    """PoCL: its release from the platform version ("3.0-rc2", "3.1+debian"); others: the driver
    version, less a leading implementation name ("Oclgrind 21.10" -> "21.10")."""
    key = key or implementation(dev)
    if key == "pocl":
        m = re.search(r"\bpocl\s+(\S+)", dev.platform.version, re.I)
        if m:
            return m.group(1)
    words = str(dev.driver_version).split()
    if len(words) == 2 and words[0].lower() == key:
        return words[1]
    return " ".join(words) or "?"


class _DlInfo(ctypes.Structure):
    _fields_ = [("dli_fname", ctypes.c_char_p), ("dli_fbase", ctypes.c_void_p),
                ("dli_sname", ctypes.c_char_p), ("dli_saddr", ctypes.c_void_p)]


def driver_library(dev: cl.Device) -> Optional[str]:
    """The file of the library that implements `dev`'s platform (None where unknowable). Under an
    ICD loader (Linux) every OpenCL object starts with a pointer to its driver's dispatch table,
    which lies in the driver library's data: dladdr() names the file mapped there. This asks the
    running process, so it is right whichever ICD file, path or copy the loader went through."""
    if not sys.platform.startswith("linux"):
        return None
    return _library_at(int(dev.platform.int_ptr))


@lru_cache(maxsize=None)
def _library_at(platform_ptr: int) -> Optional[str]:
    try:
        libc = ctypes.CDLL(None)
        dladdr = libc.dladdr
        dladdr.argtypes, dladdr.restype = [ctypes.c_void_p, ctypes.POINTER(_DlInfo)], ctypes.c_int
        dispatch = ctypes.c_void_p.from_address(platform_ptr).value
        info = _DlInfo()
        if dispatch and dladdr(dispatch, ctypes.byref(info)) and info.dli_fname:
            return os.path.realpath(os.fsdecode(info.dli_fname))
    except (AttributeError, OSError, ValueError):
        pass
    return None


@lru_cache(maxsize=None)
def library_origin(path: Optional[str]) -> Optional[str]:
    """Where a driver library came from: "pip" (a Python package of this environment installed it:
    it lies in a site-packages folder, like the PoCL bundled in pyopencl's wheel, or it is the file
    a known pip distribution's RECORD lists, like opencl-rt's <prefix>/lib/libintelocl.so),
    "conda" (inside a conda environment), else "system" (a distribution's package, a vendor's
    installer). None when the library is unknown. Version strings cannot tell: pip's and Debian's
    PoCL both say "RELOC" and "DISTRO"."""
    if path is None:
        return None
    real = Path(os.path.realpath(path))
    parts = real.parts
    if "site-packages" in parts or ("dist-packages" in parts and not str(real).startswith("/usr/lib/")):
        return "pip"                        # /usr/lib/python3/dist-packages: Debian's own packages
    from clrender.device import icd
    if any(os.path.realpath(p.library) == str(real) for p in icd.pip_implementations()):
        return "pip"
    for prefix in {sys.prefix, sys.base_prefix, os.environ.get("CONDA_PREFIX") or sys.prefix}:
        if (Path(prefix) / "conda-meta").is_dir() and real.is_relative_to(os.path.realpath(prefix)):
            return "conda"
    return "system"


def vector_widths(dev: cl.Device) -> dict:
    """The driver's preferred and native float vector widths, and the pixels per work-item
    clrender's per-pixel kernels use there (pixel_vector_width)."""
    return {"preferred_float": int(dev.preferred_vector_width_float),
            "native_float": int(dev.native_vector_width_float), "pixel": pixel_vector_width(dev)}


@lru_cache(maxsize=1)
def cpu_identity() -> str:
    """This machine's CPU: its model name and a hash of its feature flags (/proc/cpuinfo, read
    once). Part of the probe's cache key: a driver's verdict depends on the CPU (pip's PoCL fails on
    AVX-512 only), and Intel's CPU device is called "Intel(R) Xeon(R) Processor" on every Xeon."""
    model = flags = ""
    try:
        with open("/proc/cpuinfo", encoding="utf-8", errors="replace") as f:
            for line in f:
                key, _, value = line.partition(":")
                key = key.strip()
                if key == "model name" and not model:
                    model = value.strip()
                elif key in ("flags", "Features") and not flags:
                    flags = " ".join(sorted(value.split()))
                if model and flags:
                    break
    except OSError:
        pass
    model = model or platform.processor() or platform.machine()
    return f"{model} [{hashlib.sha256(flags.encode()).hexdigest()[:12]}]"


def driver_identity(dev: cl.Device) -> tuple:
    """What a verdict about a driver on this machine depends on: platform, its version, device,
    driver and device versions, and the CPU (cpu_identity). The device probe's and the SIMD probe's
    cache keys (with what each asks)."""
    return (dev.platform.name, dev.platform.version, dev.name, dev.driver_version, dev.version, cpu_identity())


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


_marker_times: dict = {}


def markers_carry_time(dev: cl.Device) -> bool:
    """Whether marker events on this device carry profiling timestamps. Intel's CPU runtime gives
    markers start = end = 0 (its kernel events have real ones): pass times there are measured
    between kernel launches instead (clrender/device/timestamps.py). Measured once per device: a marker
    on a profiling queue of its own, waited (a fraction of a ms once the driver is loaded)."""
    key = dev.int_ptr
    if key not in _marker_times:
        try:
            queue = cl.CommandQueue(cl.Context([dev]), properties=cl.command_queue_properties.PROFILING_ENABLE)
            marker = cl.enqueue_marker(queue)
            marker.wait()
            _marker_times[key] = 0 < marker.profile.start <= marker.profile.end
        except cl.Error:            # e.g. PROFILING_INFO_NOT_AVAILABLE for markers
            _marker_times[key] = False
    return _marker_times[key]


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


def tile_size_for_ok(dev: cl.Device, requested: int) -> bool:
    try:
        tile_size_for(dev, requested)
        return True
    except ValueError:
        return False


DEFAULT_TILE = 8                # the camera raster's tile where neither config nor a tune chose one
DEFAULT_SHADOW_TILE_CPU = 32    # the shadow maps' tile on CPUs, likewise


def estimate_tile(tile) -> int:
    """A tile size for buffer estimates before a device is known: None (tuned) counts as the
    smallest candidate, DEFAULT_TILE, whose tiles are the most (an upper bound)."""
    return tile or DEFAULT_TILE


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
        width = 16 if int(dev.preferred_vector_width_float) >= 16 and compiler_has_512bit_vectors(dev) else 8
    else:
        width = 1
    if width not in (1, 4, 8, 16):
        raise ValueError(f"pixel vector width must be 1, 4, 8 or 16, got {width}")
    return width


# Does PoCL's compiler target have AVX-512 (its frontend defines __AVX512F__ then)? PoCL sizes its
# preferred vector width from the CPU's features but compiles for LLVM's name of the CPU, which an
# older LLVM may not know as an AVX-512 one: LLVM 14 (pip's PoCL 3.0, which has no setting for its
# target CPU) calls every AMD family-19h CPU "znver3", so on Zen 4 it prefers 16 floats for an AVX2
# target, and clrender's 16-wide pixel runs sent its InstCombine into a loop ending in SIGSEGV after
# minutes (gbuffer_resolve; issue 35 item 6, tests/test_pocl_avx512.py). Asked with a one-kernel
# build whose kernel name says the answer; kept in clrender's cache per driver and CPU (a build is
# ~0.1 s even from PoCL's cache), so a warm start does not pay it.
_SIMD_PROBE = """
#if defined(__AVX512F__) || !defined(__x86_64__)
kernel void wide_native(void) {}
#else
kernel void wide_split(void) {}
#endif
"""
_wide: dict = {}


def compiler_has_512bit_vectors(dev: cl.Device) -> bool:
    """False where PoCL's compiler targets x86-64 without AVX-512 (16-wide vectors split in two);
    True elsewhere, and for other implementations (their compilers pick their own code paths)."""
    if implementation(dev) != "pocl" or not isinstance(dev, cl.Device):   # (tests' stand-ins build nothing)
        return True
    key = dev.int_ptr
    if key in _wide:
        return _wide[key]
    from clrender.device import cache
    h = hashlib.sha256(_SIMD_PROBE.encode())
    for part in driver_identity(dev):
        h.update(part.encode() + b"\0")
    name = f"probe/simd-{h.hexdigest()[:32]}.json"
    record = cache.read_json(name)
    if isinstance(record, dict) and isinstance(record.get("wide_native"), bool):
        _wide[key] = record["wide_native"]
        return _wide[key]
    try:
        names = cl.Program(cl.Context([dev]), _SIMD_PROBE).build().kernel_names
        _wide[key] = "wide_split" not in names
    except cl.Error:
        _wide[key] = True           # no compiler: compiler_error() and the device probe say so
        return True
    cache.write_json(name, {"device": f"{dev.platform.version} {dev.name}", "wide_native": _wide[key]})
    return _wide[key]


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
