"""Which OpenCL devices exist and which one clrender prefers: DeviceInfo (what clrender knows of a
device without opening it), the implementations it knows by name, listing, matching a --device spec,
and the measured preference order. Opening a device and building programs: clrender/device/core.py;
whether a driver really runs the kernels (a child process): clrender/device/probe.py.
"""
from __future__ import annotations

import os
import re
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Iterable, Optional, Sequence

from clrender.device import cache, capabilities, icd

cache.configure_pocl_cache()          # before the first OpenCL call: PoCL's kernel cache under clrender's cap
icd.register()                        # before the first OpenCL call: pip's Intel runtime visible (clrender/device/icd.py)
import pyopencl as cl                 # noqa: E402

# Intel's compiler logs "Compilation started/done" for every program, which pyopencl reports as a
# CompilerWarning saying only that there was output (for clrender's programs and pyopencl's own
# reductions and scans alike). That one message is hidden; PYOPENCL_COMPILER_OUTPUT=1 still shows
# the output itself (another message), and clrender's builds log it at debug level.
warnings.filterwarnings("ignore", message="Non-empty compiler output encountered", category=cl.CompilerWarning,
                        module="pyopencl")

ENV_DEVICE = "CLRENDER_DEVICE"
ENV_PROGRAM_CACHE = "CLRENDER_PROGRAM_CACHE"


from clrender.errors import DeviceError  # noqa: E402,F401  (re-exported)


def kernels_dir() -> Path:
    """kernels/ ships inside the package when installed; in a checkout it sits beside it."""
    here = Path(__file__).resolve().parents[1]          # clrender/ (this file is clrender/device/core.py)
    for candidate in (here / "kernels", here.parent / "kernels"):
        if (candidate / "structs.h").is_file():
            return candidate
    raise DeviceError(f"clrender's OpenCL sources (kernels/) were not found next to {here}")


# Implementations clrender knows by key: (name in messages, what installs it where a pip or
# package command does). Each key is also a --device name (DeviceInfo.matches).
IMPLEMENTATION_NAMES = {
    "intel": ("Intel's CPU runtime", "pip install opencl-rt"),
    "pocl": ("PoCL", "pip install pocl-binary-distribution"),
    "oclgrind": ("Oclgrind", "apt-get install oclgrind"),
    "nvidia": ("NVIDIA's driver", None),
    "amd": ("AMD's driver", None),
    "intel-gpu": ("Intel's GPU runtime", None),
}
ORIGINS = ("pip", "conda", "system")

# The default device among CPU implementations, best first: (implementation, lowest version), the
# first entry a device meets ranks it (then the newest version first; GPUs come before all and
# simulators after). Chosen by measurement, not by name (python -m bench.devices, docs/devices.md):
# PoCL 3.1 (LLVM 15) renders the user's frame 1.10-1.19x faster than Intel's runtime, which is
# 1.24-1.39x faster than pip's PoCL 3.0 (LLVM 14) and first-runs in 2/3 of its time (AVX-512, before
# kernels/vec.h inlined 3.0's built-ins; on AVX2 after it the three frames are within 20 %).
CPU_IMPLEMENTATION_ORDER = (("pocl", (3, 1)), ("intel", ()), ("pocl", ()))
CPU_IMPLEMENTATIONS = tuple(dict.fromkeys(key for key, _ in CPU_IMPLEMENTATION_ORDER))


@dataclass(frozen=True)
class DeviceInfo:
    id: str                 # "P:D" platform and device indices
    platform: str
    name: str
    cl_device: cl.Device

    @property
    def label(self) -> str:
        short = re.sub(r"\s+", " ", self.name).strip()
        return f"{self.id} {self.platform_short}: {short}"

    @property
    def platform_short(self) -> str:
        if self.is_pocl:
            words = self.cl_device.platform.version.split()
            return f"pocl {words[3]}" if len(words) > 3 else "pocl"
        return self.platform

    @property
    def is_pocl(self) -> bool:
        text = self.platform.lower()
        return "portable computing" in text or "pocl" in text

    @property
    def is_simulator(self) -> bool:
        return capabilities.is_simulator(self.cl_device)

    @property
    def implementation(self) -> str:
        """"pocl", "intel", "oclgrind", "nvidia", ... (capabilities.implementation_key)."""
        return capabilities.implementation_key(self.platform)

    @property
    def implementation_version(self) -> str:
        return capabilities.implementation_version(self.cl_device, self.implementation)

    @property
    def origin(self) -> Optional[str]:
        """"pip", "conda" or "system": where the driver library came from (capabilities.library_origin)."""
        return capabilities.library_origin(capabilities.driver_library(self.cl_device))

    @property
    def vector_widths(self) -> dict:
        return capabilities.vector_widths(self.cl_device)

    @property
    def description(self) -> str:
        """"3:0 PoCL 3.0-rc2 from pip", "1:0 Intel's CPU runtime 2021.11.3.0.17_160000 from pip":
        the device in notices and errors, saying which implementation it is."""
        name = IMPLEMENTATION_NAMES.get(self.implementation, (self.platform,))[0]
        try:                                # it names devices in errors: a broken driver must not raise here
            version, origin = self.implementation_version, self.origin
        except Exception:
            version, origin = "?", None
        return f"{self.id} {name} {version}" + (f" from {origin}" if origin in ("pip", "conda") else "")

    def matches(self, spec: str, keys: Iterable[str] = ()) -> bool:
        """Whether `spec` picks this device: "P:D"; an implementation key (one of IMPLEMENTATION_NAMES
        or of `keys`: only that implementation's devices, though PoCL's device names contain
        "Intel"); an origin ("pip", "conda", "system"); else a substring of "platform / name /
        platform version / driver version" (e.g. "debian", "3.0-rc2", "xeon"). Words separated by
        spaces each narrow: "pocl pip" is pip's PoCL."""
        spec = spec.strip().lower()
        keys = {*IMPLEMENTATION_NAMES, *keys}
        haystack = (f"{self.platform} / {self.name} / {self.cl_device.platform.version} / "
                    f"{self.cl_device.driver_version}").lower()

        def one(word: str) -> bool:
            if word == self.id:
                return True
            if word in keys:
                return word == self.implementation
            if word in ORIGINS:
                return word == self.origin
            return word in haystack
        words = spec.split()
        return one(spec) or (len(words) > 1 and all(one(w) for w in words))


def list_devices() -> list[DeviceInfo]:
    try:
        platforms = cl.get_platforms()
    except cl.Error:
        platforms = []
    found = []
    for p_index, platform in enumerate(platforms):
        try:
            devices = platform.get_devices()
        except cl.Error as exc:           # skipped, but said: a silently missing driver is a mystery
            _warn_platform(platform, exc)
            continue
        for d_index, dev in enumerate(devices):
            found.append(DeviceInfo(f"{p_index}:{d_index}", platform.name.strip(), dev.name.strip(), dev))
    return found


_platform_warned: set = set()


def _warn_platform(platform, exc: Exception) -> None:
    name = getattr(platform, "name", "?").strip()
    if getattr(exc, "code", None) == cl.status_code.DEVICE_NOT_FOUND:
        return                            # a platform with no device (a GPU driver without its GPU)
    if name not in _platform_warned:      # once per process: list_devices() runs many times
        _platform_warned.add(name)
        warnings.warn(f"OpenCL platform {name!r} is skipped: listing its devices failed ({exc})", stacklevel=3)


def no_device_error() -> DeviceError:
    """The one line for an OpenCL loader that lists no device: what installs one, and any ICD file
    whose library does not load (the loader skips those silently)."""
    return DeviceError(icd.explain("no OpenCL device found: install one, e.g. `pip install -e \".[pocl,intel]\"` "
                                   "(pip's PoCL and Intel's CPU runtime)"))


def match_devices(spec: str, devices: Optional[Sequence[DeviceInfo]] = None) -> list[DeviceInfo]:
    """The devices a name substring or "P:D" picks (no probing); DeviceError when none."""
    devices = list_devices() if devices is None else list(devices)
    if not devices:
        raise no_device_error()
    keys = {d.implementation for d in devices}
    chosen = [d for d in devices if d.matches(spec, keys)]
    if not chosen:
        raise DeviceError(icd.explain(f"no OpenCL device matches {spec!r}"
                                      + "".join(f": {hint}" for hint in [missing_hint(spec, devices)] if hint)
                                      + f"; installed: {installed_summary(devices)}"))
    return chosen


def installed_summary(devices: Sequence[DeviceInfo]) -> str:
    """"0:0 Oclgrind 21.10, 1:0 Intel's CPU runtime 2021.11... from pip, ...": what is installed."""
    return ", ".join(d.description for d in devices) or "nothing"


def missing_hint(spec: str, devices: Sequence[DeviceInfo]) -> Optional[str]:
    """For an implementation key none of `devices` has: that it is not installed, and what installs
    it; or, when pip did install it, that the OpenCL loader does not list it."""
    key = spec.strip().lower()
    if key not in IMPLEMENTATION_NAMES or any(d.implementation == key for d in devices):
        return None
    name, install = IMPLEMENTATION_NAMES[key]
    pip_installed = [p for p in icd.pip_implementations() if p.name == key]
    if pip_installed:
        user = os.environ.get(icd.ENV_VENDORS)
        why = (f" ($OCL_ICD_VENDORS={user} is set and does not name it)"
               if user and user != os.environ.get(icd.ENV_REGISTERED) else "")
        return f"{name} is installed ({pip_installed[0].library}) but the OpenCL loader lists no device of it{why}"
    return f"{name} is not installed" + (f" ({install})" if install else "")


def _version_key(d: DeviceInfo) -> tuple:
    """Newest first when sorted: the version's numbers, a release before its release candidates."""
    version = d.implementation_version
    numbers = tuple(int(n) for n in re.findall(r"\d+", re.split(r"[-+~]", version)[0])[:6])
    return tuple(-n for n in numbers) + (int("rc" in version.lower()),)


def preference_order(devices: Sequence[DeviceInfo]) -> list[DeviceInfo]:
    """The order the default device is chosen in: GPUs; then CPU implementations in
    CPU_IMPLEMENTATION_ORDER (measured), newest version first within each (a newer LLVM knows newer
    CPUs); then other devices; simulators last. Stable within each group."""
    def rank(d: DeviceInfo):
        if d.is_simulator:
            return (3,)
        if capabilities.is_gpu(d.cl_device):
            return (0,)
        if capabilities.is_cpu(d.cl_device):
            version = _version_key(d)
            newer = tuple(-v for v in version[:-1])
            for index, (key, lowest) in enumerate(CPU_IMPLEMENTATION_ORDER):
                if d.implementation == key and newer[:len(lowest)] >= lowest:
                    return (1, index, version)
        return (2,)
    return sorted(devices, key=rank)
