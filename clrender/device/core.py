"""OpenCL device discovery and the program cache: what clrender knows of a device, in one place.

A `Device` owns one context and one profiling-enabled in-order queue. Programs are built once per
(device, source + included headers, sorted build options), shared by every Renderer in the process,
and only when a kernel of theirs is first needed: `Device.kernel()` returns a `LazyKernel`, which
builds its program at the first launch (or when the pipeline builds a frame's programs up front,
with progress: `Device.build()`).

Which device to use, and whether its driver really runs clrender's kernels (asked of a child
process), is the layer above: clrender/device/probe.py. The device's limits: clrender/device/capabilities.py.
"""
from __future__ import annotations

import hashlib
import os
import re
import threading
import time
import warnings
from contextlib import nullcontext
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path
from typing import Iterable, Optional, Sequence

from clrender.device import cache, capabilities, icd
from clrender import progress

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


class DeviceError(RuntimeError):
    """No OpenCL device matches, none is installed, or a program does not build on it."""


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
# 1.24-1.39x faster than pip's PoCL 3.0 (LLVM 14) and first-runs in 2/3 of its time.
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


@dataclass(frozen=True)
class ProgramSpec:
    """One program build: a kernels/ file with its -D defines (the device adds its base options)."""
    filename: str
    defines: tuple = ()          # sorted (name, value) pairs

    @classmethod
    def of(cls, filename: str, defines: Optional[dict] = None) -> "ProgramSpec":
        return cls(filename, tuple(sorted((str(k), str(v)) for k, v in (defines or {}).items())))

    def __str__(self) -> str:
        return self.filename + "".join(f" {k}={v}" for k, v in self.defines)


class LazyKernel:
    """A kernel whose program is built at its first use; launches like a pyopencl Kernel."""

    __slots__ = ("device", "spec", "name", "_kernel")

    def __init__(self, device: "Device", spec: ProgramSpec, name: str):
        self.device, self.spec, self.name, self._kernel = device, spec, name, None

    @property
    def built(self) -> bool:
        return self.device.has_program(self.spec)

    def resolve(self) -> cl.Kernel:
        if self._kernel is None:
            prog = self.device.program_for(self.spec)
            cache_ = prog.__dict__.setdefault("_clrender_kernels", {})    # one Kernel object per name
            if self.name not in cache_:
                cache_[self.name] = cl.Kernel(prog, self.name)
            self._kernel = cache_[self.name]
        return self._kernel

    def __call__(self, *args, **kwargs):
        return self.resolve()(*args, **kwargs)

    def __getattr__(self, attr):
        return getattr(self.resolve(), attr)


class Device:
    """One OpenCL device with its context, queue and program cache.

    Every Renderer on the device shares them, and with them state that is not safe to touch from
    two threads at once: the kernel objects (clSetKernelArg then enqueue is not atomic), pyopencl's
    own per-context kernels (fills, copies), the scene uploads cached per device (scene_gpu), and
    the in-order queue whose order is what makes one frame's buffers consistent. `lock` serialises
    that: a Renderer holds it for each call that enqueues work (render, lights_at, posed_vertices,
    building its pipeline). One queue orders the device's work anyway, so little is lost."""

    _programs: dict = {}
    build_count = 0                     # programs built from source or binary in this process (tests)

    def __init__(self, info: DeviceInfo):
        self.info = info
        self.cl_device = info.cl_device
        self.context = cl.Context([self.cl_device])
        self.queue = cl.CommandQueue(self.context, properties=cl.command_queue_properties.PROFILING_ENABLE)
        self.lock = threading.RLock()   # see the class doc: held while enqueuing on this device
        self.base_options = capabilities.build_options(self.cl_device)
        self.built: list = []           # (ProgramSpec, seconds) in build order, this device
        # PoCL: no program binaries (see _binary_name); tests turn them on to test the store itself
        self.keep_binaries = not info.is_pocl

    @classmethod
    def get(cls, spec: Optional[str | DeviceInfo] = None) -> "Device":
        """The Device for a DeviceInfo, "P:D" or name (no probing: clrender.device.probe.open_device
        chooses and checks a device for a Renderer)."""
        if isinstance(spec, DeviceInfo):
            info = spec
        else:
            spec = spec if spec is not None else os.environ.get(ENV_DEVICE) or None
            info = match_devices(spec)[0] if spec else preference_order(list_devices())[0]
        return _device_for(info.id, info.platform, info.name)

    @property
    def name(self) -> str:
        return self.info.label

    def _key(self, spec: ProgramSpec):
        path = kernels_dir() / spec.filename
        opts = sorted({*self.base_options, f"-I{path.parent}", *(f"-D{k}={v}" for k, v in spec.defines)})
        digest = _digest(path)
        return (self.info.id, self.cl_device.int_ptr, digest, tuple(opts)), path, digest, opts

    @staticmethod
    def session_specs() -> set:
        """Every distinct (device, ProgramSpec) built in this process, as specs (tests count them)."""
        return {spec for d in _opened for spec, _ in d.built}

    def has_program(self, spec: ProgramSpec) -> bool:
        return self._key(spec)[0] in Device._programs

    def program(self, filename: str, defines: Optional[dict] = None) -> cl.Program:
        """Build (once) kernels/<filename> with -D defines."""
        return self.program_for(ProgramSpec.of(filename, defines))

    def program_for(self, spec: ProgramSpec) -> cl.Program:
        key, path, digest, opts = self._key(spec)
        prog = Device._programs.get(key)
        if prog is not None:
            return prog
        with _build_lock:                   # a warm-up thread may be building the same program
            prog = Device._programs.get(key)
            if prog is not None:
                return prog
            stage = progress.current()
            if stage is None:               # a build outside a frame's up-front builds: its own stage
                with progress.stage("building OpenCL program", 1, self.name) as own:
                    return self._build(spec, key, path, digest, opts, own)
            return self._build(spec, key, path, digest, opts, stage)

    def _build(self, spec, key, path, digest, opts, stage) -> cl.Program:
        start = time.perf_counter()
        stage.note(str(spec))
        prog = self._cached_binary(digest, opts)
        if prog is None:
            try:
                prog = _quiet_build(cl.Program(self.context, path.read_text()), opts, f"{spec} on {self.name}")
            except cl.Error as exc:
                # A Ctrl-C reaches the compiler's child processes too: their failure is the interrupt,
                # not a kernel error (nothing was stored, so the program cache stays clean)
                from clrender.interrupt import raise_if_interrupted
                raise_if_interrupted(start)
                first = next((ln.strip() for ln in str(exc).splitlines() if "error" in ln.lower()), "")
                raise DeviceError(f"building kernels/{spec} failed on {self.name}: "
                                  f"{first or str(exc).splitlines()[0]}") from None
            self._store_binary(digest, opts, prog)
        Device._programs[key] = prog
        Device.build_count += 1
        self.built.append((spec, time.perf_counter() - start))
        progress.log.debug("built %s in %.2f s on %s", spec, self.built[-1][1], self.name)
        progress.emit(f"built {spec} in {self.built[-1][1]:.2f} s")
        stage.advance(str(spec))
        return prog

    def build(self, specs: Iterable[ProgramSpec], what: str = "building OpenCL programs") -> int:
        """Build every spec not built yet, counted in the open progress stage (or one of their own:
        count and ETA); returns how many were built."""
        todo = list(dict.fromkeys(s for s in specs if not self.has_program(s)))
        if not todo:
            return 0
        stage = progress.current()
        if stage is not None:
            stage.add_total(len(todo))
        with nullcontext() if stage is not None else progress.stage(what, len(todo), self.name):
            for spec in todo:
                self.program_for(spec)
        return len(todo)

    # Program binaries. PoCL's clBuildProgram makes only LLVM IR and compiles each kernel at its first
    # launch (per local size), into its own kernel cache; asking PoCL for a program's binaries compiles
    # every kernel of the program once more for any local size (seconds per program, whether or not the
    # kernel is ever launched), so on PoCL clrender keeps no binaries and relies on PoCL's cache (which
    # lives under clrender's cache folder, clrender/device/cache.py). Other drivers (NVIDIA, Oclgrind) return
    # what they built: their binaries are kept per driver, device, source and options; a binary the
    # driver refuses is rebuilt from source. CLRENDER_PROGRAM_CACHE=0 turns this off.
    def _binary_name(self, digest: str, opts: list) -> Optional[str]:
        if os.environ.get(ENV_PROGRAM_CACHE, "1") == "0" or not self.keep_binaries:
            return None
        d, h = self.cl_device, hashlib.sha256()
        for part in (d.platform.name, d.platform.version, d.name, d.vendor, d.driver_version, d.version,
                     cl.VERSION_TEXT, digest, *opts):
            h.update(str(part).encode() + b"\0")
        return f"programs/{h.hexdigest()[:40]}.bin"

    def _cached_binary(self, digest: str, opts: list) -> Optional[cl.Program]:
        name = self._binary_name(digest, opts)
        binary = cache.read_bytes(name) if name else None
        if not binary:
            return None
        try:
            prog = _quiet_build(cl.Program(self.context, [self.cl_device], [binary]), opts, f"a cached binary on {self.name}")
        except (cl.Error, cl.RuntimeError):
            return None                 # stale or foreign binary: built from source and replaced
        prog._source = None             # cl.Kernel looks it up: else a failing clCreateKernel("_source")
        return prog

    def _store_binary(self, digest: str, opts: list, prog: cl.Program) -> None:
        name = self._binary_name(digest, opts)
        if name is None:
            return
        try:
            binary = prog.get_info(cl.program_info.BINARIES)[0]
        except cl.Error:
            return
        if binary:
            cache.write_bytes(name, bytes(binary))     # an unwritable cache only costs a build next time

    def kernel(self, filename: str, name: str, defines: Optional[dict] = None) -> LazyKernel:
        """Kernel `name` of kernels/<filename> built with `defines`, built at its first use."""
        return LazyKernel(self, ProgramSpec.of(filename, defines), name)


def _quiet_build(prog: cl.Program, opts: list, what: str) -> cl.Program:
    """prog.build(options=opts), its compiler output sent to the debug log: Intel's compiler logs
    "Compilation started/done" on every build, which pyopencl turns into a CompilerWarning per
    program (errors still raise)."""
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always", cl.CompilerWarning)
        prog = prog.build(options=opts)
    for w in said:
        if issubclass(w.category, cl.CompilerWarning):
            progress.log.debug("compiler output building %s: %s", what, w.message)
        else:
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    return prog


_digests: dict = {}
_build_lock = threading.RLock()


def _digest(path: Path) -> str:
    """sha256 of a kernel file and its headers, once per process per file (sources do not change
    under a running renderer; tests that edit kernels use fresh files)."""
    stat = path.stat()
    key = (path, stat.st_mtime_ns, stat.st_size)
    if key not in _digests:
        _digests[key] = hashlib.sha256(_source_with_includes(path).encode()).hexdigest()
    return _digests[key]


_opened: list = []          # every Device this process opened


@lru_cache(maxsize=None)
def _device_for(device_id: str, platform: str, name: str) -> Device:
    for info in list_devices():
        if info.id == device_id and info.name == name and info.platform == platform:
            _opened.append(Device(info))
            return _opened[-1]
    raise DeviceError(f"OpenCL device {device_id} ({name}) disappeared")


def lazy_kernels(obj, seen: Optional[set] = None, depth: int = 0) -> list[LazyKernel]:
    """Every LazyKernel held by `obj` (a pass) and the objects it holds: attributes, lists, tuples,
    dicts, to a few levels (sub-passes, scan helpers). What a frame will launch, found without each
    pass listing its programs twice."""
    seen = set() if seen is None else seen
    if id(obj) in seen or depth > 4:
        return []
    seen.add(id(obj))
    if isinstance(obj, LazyKernel):
        return [obj]
    if isinstance(obj, dict):
        children = list(obj.values())
    elif isinstance(obj, (list, tuple)):
        children = list(obj)
    elif hasattr(obj, "__dict__") and type(obj).__module__.startswith("clrender"):
        children = list(vars(obj).values())
    else:
        return []
    found = []
    for child in children:
        found += lazy_kernels(child, seen, depth + 1)
    return found
