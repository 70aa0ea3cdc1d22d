"""The device probe's child process: `python -m clrender.tools.probe_child P:D NAME [PLATFORM]`.

Builds and launches what the default Renderer runs (one triangle lit by one point light, 8x8),
reporting each program and first launch as "progress ..." lines, then prints "ok" or one line
saying what failed. Run by clrender/device/probe.py; a crash here costs the parent nothing. What
it compiles lands in PoCL's kernel cache, where the parent finds it.
"""
from __future__ import annotations

import os
import sys


def main(device_id: str, name: str, platform: str = "") -> int:
    import warnings
    warnings.simplefilter("ignore")
    import numpy as np

    from clrender.device import capabilities
    from clrender import progress
    from clrender.device.core import list_devices
    progress.report_lines(sys.stdout)
    # The id first; else the same platform and device under another id (a parent that listed
    # platforms before clrender registered pip's implementations numbers them differently)
    devices = list_devices()
    info = next((d for d in devices if d.id == device_id and d.name == name), None)
    if info is None and platform:
        same = [d for d in devices if d.name == name and d.platform == platform]
        info = same[0] if len(same) == 1 else None
    if info is None:
        print(f"device {device_id} ({name}) not found")
        return 2
    code = 0
    try:
        error = capabilities.compiler_error(info.cl_device)
        if error is not None:
            raise RuntimeError(error)
        from clrender.tools.warmup import render_probe_scene
        frame = render_probe_scene(info)
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
    sys.exit(main(*sys.argv[1:4]))
