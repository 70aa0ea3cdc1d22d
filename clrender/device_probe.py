"""Whether an OpenCL device really builds and runs clrender's kernels, asked in a child process.

A trivial kernel is not enough of a test: pip's PoCL 3.0 on some CPUs compiles it, then fails
clrender's own programs with INVALID_KERNEL_NAME, or crashes the process outright when its
kernel cache is cold. So `select_devices` and `clrender devices` ask a child process
(`python -m clrender.device_probe P:D NAME`) to build every kernel file and the Renderer variants,
and to render one triangle; a device whose child fails or dies is left out (reported as failed),
and this process never loads a broken driver's builds. The answer is cached on disk ($CLRENDER_CACHE_DIR, else
~/.cache/clrender) per driver, device and kernel sources, so each machine asks once per kernel
change (not per environment: PoCL's work-group method or disabled kernel cache would only make
the same answer slower to get).
"""
from __future__ import annotations

import hashlib
import json
import os
import subprocess
import sys
from pathlib import Path
from typing import Optional

PROBE_TIMEOUT_S = 900
_answers: dict = {}


def _cache_dir() -> Path:
    return Path(os.environ.get("CLRENDER_CACHE_DIR") or Path.home() / ".cache" / "clrender")


def _key(info) -> str:
    from .device import kernels_dir
    d = info.cl_device
    h = hashlib.sha256()
    for part in (d.platform.name, d.platform.version, d.name, d.driver_version, d.version):
        h.update(part.encode() + b"\0")
    for p in sorted(kernels_dir().rglob("*")):
        if p.suffix in (".cl", ".h"):
            h.update(p.name.encode() + p.read_bytes())
    return h.hexdigest()[:32]


def probe_error(info) -> Optional[str]:
    """None when `info`'s device builds and runs clrender's kernels, else why not (one line)."""
    key = _key(info)
    if key in _answers:
        return _answers[key]
    path = _cache_dir() / f"probe-{key}.json"
    try:
        answer = json.loads(path.read_text())["error"]
    except (OSError, ValueError, KeyError):
        answer = _ask_child(info)
        from .aov_io import atomic_write
        text = json.dumps({"device": info.label, "error": answer})
        try:
            atomic_write(path, lambda tmp: Path(tmp).write_text(text))
        except OSError:
            pass                          # an unwritable cache only costs a probe next time
    _answers[key] = answer
    return answer


def _ask_child(info) -> Optional[str]:
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(filter(None, [str(Path(__file__).resolve().parents[1]),
                                                                      os.environ.get("PYTHONPATH")])))
    try:
        proc = subprocess.run([sys.executable, "-m", "clrender.device_probe", info.id, info.name], env=env,
                              capture_output=True, text=True, timeout=PROBE_TIMEOUT_S)
    except subprocess.TimeoutExpired:
        return f"clrender's kernels did not build within {PROBE_TIMEOUT_S} s"
    if proc.returncode == 0 and proc.stdout.strip().endswith("ok"):
        return None
    lines = [ln.strip() for ln in proc.stdout.splitlines() if ln.strip()]
    why = lines[-1] if lines else ""
    if proc.returncode < 0 and not why:
        why = f"the driver crashed building clrender's kernels (signal {-proc.returncode})"
    return (why or f"exit status {proc.returncode}")[:200]


def _child(device_id: str, name: str) -> int:
    import warnings
    warnings.simplefilter("ignore")
    import numpy as np

    from . import capabilities
    from .camera import Camera
    from .device import list_devices
    from .device_report import build_every_kernel
    from .renderer import Renderer
    from .scene import Scene
    info = next((d for d in list_devices() if d.id == device_id and d.name == name), None)
    if info is None:
        print(f"device {device_id} ({name}) not found")
        return 2
    code = 0
    try:
        error = capabilities.compiler_error(info.cl_device)
        if error is not None:
            raise RuntimeError(error)
        build_every_kernel(info)
        scene = Scene.from_arrays(np.array([[-1, -1, 0], [1, -1, 0], [0, 1, 0]], np.float32),
                                  np.array([[0, 1, 2]], np.int32))
        frame = Renderer(8, 8, device=info).render(scene, Camera.look_at((0, 0, 3), (0, 0, 0)))
        if not (np.isfinite(frame.depth).sum() > 0 and frame.image.any()):
            print("a test triangle rendered empty")
            code = 1
    except Exception as exc:
        print(f"{type(exc).__name__}: {(str(exc).strip().splitlines() or [''])[0]}")
        code = 1
    print("ok" if code == 0 else "", flush=True)
    sys.stderr.flush()
    os._exit(code)                # skip the driver's teardown (pip's PoCL 3.0 may abort in it)


if __name__ == "__main__":
    sys.exit(_child(sys.argv[1], sys.argv[2]))
