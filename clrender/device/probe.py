"""Which OpenCL device clrender uses, and whether its driver really runs clrender's kernels.

A trivial kernel is not enough of a test: pip's PoCL 3.0 on some CPUs builds it, then crashes
(after minutes of compiling) or fails clrender's own programs with INVALID_KERNEL_NAME. So before a
device is used, a child process (`python -m clrender.tools.probe_child P:D NAME`) builds and launches what
the default Renderer runs (one triangle, one light). A device whose child fails or dies is reported
in one line and never loads a broken build into this process. Only the device that will be used is
asked (the one named, else the first of `device.preference_order`; the next one only if it fails),
and the child's compiles are not lost: PoCL's kernel cache is shared between processes, so the
caller's own builds of the same programs are cache hits and the probe costs a process start. The
child reports each program and kernel it builds; this process shows them as a progress stage. The
answer is cached (clrender/device/cache.py) per driver, device and kernel sources.
"""
from __future__ import annotations

import hashlib
import os
import subprocess
import sys
import threading
import warnings
from pathlib import Path
from typing import Optional

from clrender.device import cache, capabilities
from clrender import progress
from clrender.device.core import (
    ENV_DEVICE, Device, DeviceError, DeviceInfo, kernels_dir, list_devices, match_devices, no_device_error,
    preference_order)

PROBE_TIMEOUT_S = 900
ENV_IN_PROBE = "CLRENDER_PROBE_CHILD"       # set in the child: it is the probe
_probed_here: set = set()     # cl_device.int_ptr of the devices this process asked a child about
_answers: dict = {}


def kernels_key(dev, salt: bytes = b"") -> str:
    """A cache key for what a device's kernels answer: `salt` (what is cached), the driver's
    identity (capabilities.driver_identity) and every kernel source. The probe's answer and the
    raster's tune (clrender/device/tuning.py) are keyed by it: a new driver or kernel asks again."""
    h = hashlib.sha256(salt)
    for part in capabilities.driver_identity(dev):
        h.update(part.encode() + b"\0")
    for p in sorted(kernels_dir().rglob("*")):
        if p.suffix in (".cl", ".h"):
            h.update(p.name.encode() + p.read_bytes())
    return h.hexdigest()[:32]


def _key(info: DeviceInfo) -> str:
    return kernels_key(info.cl_device)


def probe_error(info: DeviceInfo) -> Optional[str]:
    """None when `info`'s device builds and runs clrender's kernels, else why not (one line)."""
    if os.environ.get(ENV_IN_PROBE):
        return None
    key = _key(info)
    if key in _answers:
        return _answers[key]
    name = f"probe/{key}.json"
    record = cache.read_json(name)
    if isinstance(record, dict) and "error" in record:
        answer = record["error"]
    else:
        import time
        from clrender.interrupt import raise_if_interrupted
        start = time.monotonic()
        answer = _ask_child(info)
        # A Ctrl-C kills the child's compiler too: that failure says nothing about the device and
        # must not be cached as its verdict (every later run would refuse a good device)
        raise_if_interrupted(start)
        cache.write_json(name, {"device": info.label, "error": answer})
        _probed_here.add(info.cl_device.int_ptr)
    _answers[key] = answer
    return answer


def probed_in_this_process(info: DeviceInfo) -> bool:
    """Whether this process ran `info`'s probe (a cold start: the machine or the kernels are new)."""
    return info.cl_device.int_ptr in _probed_here


def _ask_child(info: DeviceInfo) -> Optional[str]:
    """Run the probe child, turning its "progress" lines into a progress stage; its last line is
    "ok" or why it failed."""
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, [str(Path(__file__).resolve().parents[2]),
                                                                      os.environ.get("PYTHONPATH")])))
    env[ENV_IN_PROBE] = "1"
    proc = subprocess.Popen([sys.executable, "-m", "clrender.tools.probe_child", info.id, info.name, info.platform], env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    timed_out = threading.Event()

    def kill():
        timed_out.set()
        proc.kill()
    timer = threading.Timer(PROBE_TIMEOUT_S, kill)
    timer.start()
    lines = []
    try:
        with progress.stage("checking the device (building and running clrender's kernels)", None,
                            info.label) as stage:
            for line in proc.stdout:
                line = line.strip()
                if line.startswith("progress "):
                    stage.advance(line[len("progress "):])
                elif line.startswith("total "):
                    pass                  # the child's own stages' totals: this one counts what it did
                elif line.startswith("built "):
                    progress.log.debug("%s on %s (probe child)", line, info.label)
                elif line:
                    lines.append(line)
        proc.wait()
    finally:
        timer.cancel()
    if proc.returncode == 0 and lines and lines[-1] == "ok":
        return None
    if proc.returncode == -2:                      # SIGINT: interrupted, not a verdict on the device
        raise KeyboardInterrupt
    if timed_out.is_set():
        return f"clrender's kernels did not build and run within {PROBE_TIMEOUT_S} s"
    why = lines[-1] if lines else ""
    if proc.returncode < 0 and not why:
        why = f"the driver crashed building or running clrender's kernels (signal {-proc.returncode})"
    return (why or f"exit status {proc.returncode}")[:200]


_warned: set = set()


def _warn_unusable(d: DeviceInfo, error: str, consequence: str) -> None:
    if d.id not in _warned:
        _warned.add(d.id)
        warnings.warn(f"OpenCL device {d.label} cannot run clrender's kernels ({error}); {consequence}",
                      stacklevel=3)


def select_devices(spec: Optional[str] = None, simulators: bool = False) -> list[DeviceInfo]:
    """Devices for a list ("all", a name substring or "P:D"): `all` is every device but simulators
    (unless `simulators`), each probed; those that cannot run clrender's kernels are left out with
    a warning naming them. A name or id several devices match: the same. A single match is
    returned unprobed (a Renderer on it probes it: open_device)."""
    devices = list_devices()
    if not devices:
        raise no_device_error()
    if spec is None or spec.strip().lower() == "all":
        chosen = devices if simulators else [d for d in devices if not d.is_simulator]
    else:
        chosen = match_devices(spec, devices)
        if len(chosen) == 1:
            return chosen
    usable = []
    for d in chosen:
        error = probe_error(d)
        if error is None:
            usable.append(d)
        else:
            _warn_unusable(d, error, "left out")
    return usable or chosen


def default_device_info(spec: Optional[str | DeviceInfo] = None) -> DeviceInfo:
    """The device a Renderer uses: `spec` (a DeviceInfo, name or "P:D"), else $CLRENDER_DEVICE, else
    the first of device.preference_order (a GPU, else the CPU implementations in their measured
    order, ...) whose probe passes. Only that device is probed (the next one only if it fails, said in
    one line naming both). DeviceError, in one line: a named device that fails its probe (no other
    is used in its place), or no usable device (with what to install)."""
    if isinstance(spec, DeviceInfo):
        candidates, named, from_env = [spec], True, False
    else:
        from_env = spec is None and bool(os.environ.get(ENV_DEVICE))
        spec = spec if spec is not None else os.environ.get(ENV_DEVICE) or None
        named = spec is not None
        devices = list_devices()
        candidates = preference_order(match_devices(spec, devices) if named else devices)
        if not named:
            candidates = [d for d in candidates if not d.is_simulator] or candidates
    if not candidates:
        raise no_device_error()
    failed = []
    for d in candidates:
        error = probe_error(d)
        if error is None:
            if failed:
                _notice_fallback(failed, d)
            return d
        failed.append((d, error))
    if named and len(candidates) == 1:
        # a request, not a preference: another device behind the user's back would hide the failure
        by = f" (${ENV_DEVICE}={spec})" if from_env else ""
        d, error = failed[0]
        raise DeviceError(f"the requested device{by} {d.description} failed clrender's probe ({error}); no other "
                          f"device is used in its place: name another (`clrender devices` lists them)")
    raise DeviceError("no OpenCL device runs clrender's kernels ("
                      + "; ".join(f"{d.description}: {error}" for d, error in failed) + ")"
                      + _what_to_install(devices if not isinstance(spec, DeviceInfo) else candidates))


def _notice_fallback(failed: list, chosen: DeviceInfo) -> None:
    """One line (a warning, and the "clrender" logger) naming the device(s) that failed their probe
    and the one used instead; once per process for the same outcome."""
    line = (", ".join(f"{d.description} failed clrender's probe ({error})" for d, error in failed)
            + f"; using the next device, {chosen.description}, instead")
    key = (tuple(d.id for d, _ in failed), chosen.id)
    if key not in _warned:
        _warned.add(key)
        progress.log.info("%s", line)
        warnings.warn(line, stacklevel=3)


def _what_to_install(devices) -> str:
    """"; install another: ..." for the CPU implementations clrender knows that are missing."""
    from clrender.device.core import CPU_IMPLEMENTATIONS, missing_hint
    hints = [h for h in (missing_hint(key, devices) for key in CPU_IMPLEMENTATIONS) if h]
    if hints:
        return "; install another implementation: " + "; ".join(hints)
    return "; `clrender devices` shows each device's probe"


def worker_device_spec(explicit: Optional[str] = None) -> Optional[str]:
    """The device spec of this process: explicit, else $CLRENDER_DEVICE, else the first GPU when
    running in a Dask worker with a `GPU` resource, else None (the default device)."""
    if explicit:
        return explicit
    if os.environ.get(ENV_DEVICE):
        return os.environ[ENV_DEVICE]
    try:
        from distributed import get_worker
        resources = get_worker().state.total_resources
    except (ImportError, ValueError, AttributeError):
        return None
    if resources.get("GPU", 0) > 0:
        from clrender.device import capabilities
        gpus = [d for d in list_devices() if capabilities.is_gpu(d.cl_device)]
        return gpus[0].id if gpus else None
    return None


def open_device(spec: Optional[str | DeviceInfo] = None) -> Device:
    """The probed Device for `spec` (see default_device_info)."""
    return Device.get(default_device_info(spec))
