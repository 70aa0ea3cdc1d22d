"""OpenCL device discovery, selection and the program cache.

A `Device` owns one context and one profiling-enabled in-order queue. Programs are built
once per (device, source + included headers, sorted build options) and shared by every
Renderer in the process.
"""
from __future__ import annotations

import hashlib
import os
import re
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Optional, Sequence

import pyopencl as cl

from . import capabilities

ENV_DEVICE = "CLRENDER_DEVICE"
ENV_PROGRAM_CACHE = "CLRENDER_PROGRAM_CACHE"


class DeviceError(RuntimeError):
    """No OpenCL device matches, or none is installed."""


def kernels_dir() -> Path:
    """kernels/ ships inside the package when installed; in a checkout it sits beside it."""
    here = Path(__file__).resolve().parent
    for candidate in (here / "kernels", here.parent / "kernels"):
        if (candidate / "structs.h").is_file():
            return candidate
    raise DeviceError(f"clrender's OpenCL sources (kernels/) were not found next to {here}")


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
        text = self.platform.lower()
        if "portable computing" in text or "pocl" in text:
            words = self.cl_device.platform.version.split()
            return f"pocl {words[3]}" if len(words) > 3 else "pocl"
        return self.platform

    @property
    def is_simulator(self) -> bool:
        return capabilities.is_simulator(self.cl_device)

    def matches(self, spec: str) -> bool:
        spec = spec.strip().lower()
        haystack = f"{self.platform} / {self.name} / {self.cl_device.platform.version}".lower()
        return spec == self.id or spec in haystack


def list_devices() -> list[DeviceInfo]:
    try:
        platforms = cl.get_platforms()
    except cl.Error:
        platforms = []
    found = []
    for p_index, platform in enumerate(platforms):
        try:
            devices = platform.get_devices()
        except cl.Error:
            continue
        for d_index, dev in enumerate(devices):
            found.append(DeviceInfo(f"{p_index}:{d_index}", platform.name.strip(), dev.name.strip(), dev))
    return found


def select_devices(spec: Optional[str] = None, simulators: bool = False) -> list[DeviceInfo]:
    """`all` (every device but simulators, unless `simulators`), a name substring, or `P:D`. Of
    several devices, those whose compiler cannot build a trivial kernel are left out with a
    warning naming them."""
    devices = list_devices()
    if not devices:
        raise DeviceError("no OpenCL device found: install one, e.g. `pip install pocl-binary-distribution`")
    if spec is None or spec.strip().lower() == "all":
        wanted = devices if simulators else [d for d in devices if not d.is_simulator]
        usable = []
        for d in wanted:
            error = usable_error(d)
            if error is None:
                usable.append(d)
            else:
                _warn_unusable(d, error)
        return usable or wanted or devices
    chosen = [d for d in devices if d.matches(spec)]
    if not chosen:
        names = "; ".join(d.label for d in devices)
        raise DeviceError(f"no OpenCL device matches {spec!r}; available: {names}")
    if len(chosen) > 1:          # a name several devices match: the ones that cannot build kernels drop out
        usable = [d for d in chosen if usable_error(d) is None]
        for d in chosen:
            if d not in usable:
                _warn_unusable(d, usable_error(d))
        chosen = usable or chosen
    return chosen


def usable_error(d: DeviceInfo) -> Optional[str]:
    """None when device `d`, asked in a child process (clrender.device_probe), builds and runs
    clrender's kernels; else why not."""
    from .device_probe import probe_error
    return probe_error(d)


_warned: set = set()


def _warn_unusable(d: DeviceInfo, error: str) -> None:
    if d.id not in _warned:
        _warned.add(d.id)
        import warnings
        warnings.warn(f"OpenCL device {d.label} cannot build kernels ({error}); left out of 'all'", stacklevel=3)


def default_device_info(spec: Optional[str] = None) -> DeviceInfo:
    """Explicit spec, else $CLRENDER_DEVICE, else a GPU, else a PoCL CPU, else the first."""
    spec = spec if spec is not None else os.environ.get(ENV_DEVICE) or None
    if spec is not None:
        return select_devices(spec)[0]
    devices = select_devices("all")
    for pick in (lambda d: capabilities.is_gpu(d.cl_device),
                 lambda d: "portable computing" in d.platform.lower() and capabilities.is_cpu(d.cl_device)):
        for d in devices:
            if pick(d):
                return d
    return devices[0]


def _source_with_includes(path: Path) -> str:
    """The file plus every header it includes (recursively), for the cache key."""
    seen, parts, stack = set(), [], [path]
    while stack:
        p = stack.pop()
        if p in seen:
            continue
        seen.add(p)
        text = p.read_text()
        parts.append(text)
        for inc in re.findall(r'#include\s+"([^"]+)"', text):
            stack.append(p.parent / inc)
    return "\n".join(parts)


class Device:
    """One OpenCL device with its context, queue and program cache."""

    _programs: dict = {}

    def __init__(self, info: DeviceInfo):
        self.info = info
        self.cl_device = info.cl_device
        self.context = cl.Context([self.cl_device])
        self.queue = cl.CommandQueue(self.context, properties=cl.command_queue_properties.PROFILING_ENABLE)
        self.base_options = capabilities.build_options(self.cl_device)

    @classmethod
    def get(cls, spec: Optional[str | DeviceInfo] = None) -> "Device":
        info = spec if isinstance(spec, DeviceInfo) else default_device_info(spec)
        return _device_for(info.id, info.platform, info.name)

    @property
    def name(self) -> str:
        return self.info.label

    def program(self, filename: str, defines: Optional[dict] = None, options: Sequence[str] = ()) -> cl.Program:
        """Build (once) kernels/<filename> with -D defines and extra options."""
        path = kernels_dir() / filename
        source = path.read_text()
        opts = sorted({*self.base_options, *options, f"-I{path.parent}",
                       *(f"-D{k}={v}" for k, v in (defines or {}).items())})
        digest = hashlib.sha256(_source_with_includes(path).encode()).hexdigest()
        key = (self.info.id, self.cl_device.int_ptr, digest, tuple(opts))
        prog = Device._programs.get(key)
        if prog is None:
            prog = self._cached_binary(digest, opts)
            if prog is None:
                try:
                    prog = cl.Program(self.context, source).build(options=opts)
                except cl.RuntimeError as exc:
                    raise DeviceError(f"building kernels/{filename} failed on {self.name}:\n{exc}") from None
                self._store_binary(digest, opts, prog)
            Device._programs[key] = prog
        return prog

    # A source build costs ~0.1 s even when PoCL's kernel cache is warm (preprocessing, hashing,
    # parsing the cached bitcode); a build from the program's own binary costs ~0.02 s. Binaries are
    # kept per driver, device, source (with headers) and options; a binary the driver refuses is
    # rebuilt from source and replaced. CLRENDER_PROGRAM_CACHE=0 turns the cache off.
    def _binary_path(self, digest: str, opts: list) -> Optional[Path]:
        if os.environ.get(ENV_PROGRAM_CACHE, "1") == "0":
            return None
        from .device_probe import _cache_dir
        d, h = self.cl_device, hashlib.sha256()
        for part in (d.platform.name, d.platform.version, d.name, d.vendor, d.driver_version, d.version,
                     cl.VERSION_TEXT, digest, *opts):
            h.update(str(part).encode() + b"\0")
        return _cache_dir() / "programs" / f"{h.hexdigest()[:40]}.bin"

    def _cached_binary(self, digest: str, opts: list) -> Optional[cl.Program]:
        path = self._binary_path(digest, opts)
        try:
            binary = path.read_bytes() if path is not None else None
        except OSError:
            return None
        if not binary:
            return None
        try:
            prog = cl.Program(self.context, [self.cl_device], [binary]).build(options=opts)
        except (cl.Error, cl.RuntimeError):
            return None                 # stale or foreign binary: built from source and replaced
        prog._source = None             # cl.Kernel looks it up: else a failing clCreateKernel("_source")
        return prog

    def _store_binary(self, digest: str, opts: list, prog: cl.Program) -> None:
        path = self._binary_path(digest, opts)
        if path is None:
            return
        try:
            binary = prog.get_info(cl.program_info.BINARIES)[0]
            if binary:
                from .aov_io import atomic_write
                atomic_write(path, lambda tmp: Path(tmp).write_bytes(bytes(binary)))
        except (OSError, cl.Error):
            pass                        # an unwritable cache only costs a source build next time

    def kernel(self, filename: str, name: str, defines: Optional[dict] = None) -> cl.Kernel:
        """One shared kernel object per (program, name): retrieving kernels is not free."""
        prog = self.program(filename, defines)
        cache = prog.__dict__.setdefault("_clrender_kernels", {})
        if name not in cache:
            cache[name] = cl.Kernel(prog, name)
        return cache[name]


@lru_cache(maxsize=None)
def _device_for(device_id: str, platform: str, name: str) -> Device:
    for info in list_devices():
        if info.id == device_id and info.name == name and info.platform == platform:
            return Device(info)
    raise DeviceError(f"OpenCL device {device_id} ({name}) disappeared")
