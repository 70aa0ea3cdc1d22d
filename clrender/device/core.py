"""Opening an OpenCL device and its program cache.

A `Device` owns one context and one profiling-enabled in-order queue. Programs are built once per
(device, source + included headers, sorted build options), shared by every Renderer in the process,
and only when a kernel of theirs is first needed: `Device.kernel()` returns a `LazyKernel`, which
builds its program at the first launch (or when the pipeline builds a frame's programs up front,
with progress: `Device.build()`).

Which devices exist and which is preferred: clrender/device/choice.py. Whether its driver really runs clrender's kernels (asked of a child
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
from typing import Iterable, Optional

from clrender import progress
from clrender.device import cache, capabilities
# choice first: it registers pip's ICDs and PoCL's cache before the first OpenCL call; its names
# stay importable from here (clrender.device.core was the one device module).
from clrender.device.choice import (  # noqa: F401
    CPU_IMPLEMENTATION_ORDER, CPU_IMPLEMENTATIONS, ENV_DEVICE, ENV_PROGRAM_CACHE, IMPLEMENTATION_NAMES, ORIGINS,
    DeviceError, DeviceInfo, installed_summary, kernels_dir, list_devices, match_devices, missing_hint,
    no_device_error, preference_order)
import pyopencl as cl  # noqa: E402


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
