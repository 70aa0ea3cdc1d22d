"""The Dask worker plugin that warms each worker up when it starts (registered by clrender.batch):
the first frames of a job then do not each wait for kernel compiles (clrender/tools/warmup.py)."""
from __future__ import annotations

import asyncio
from typing import Optional

from distributed.diagnostics.plugin import WorkerPlugin


class WarmupPlugin(WorkerPlugin):
    """Builds and first-launches what the job's options run (clrender.tools.warmup.render_probe_scene)."""
    name = "clrender-warmup"

    def __init__(self, device: Optional[str] = None, options: Optional[dict] = None):
        self.device, self.options = device, dict(options or {})

    async def setup(self, worker):
        from clrender.device.probe import default_device_info, worker_device_spec
        from clrender.tools.warmup import render_probe_scene

        def warm():
            info = default_device_info(worker_device_spec(self.device))   # a GPU worker's GPU, else its default
            render_probe_scene(info, **self.options)
        try:
            await asyncio.get_running_loop().run_in_executor(None, warm)   # off the event loop
        except Exception:
            pass            # the frames report a device that cannot render, one record each
