"""Template pass (kernels/_template.cl): copy both files to start a new pass; it shows the contract
(clrender/passes/base.py) and nothing else. It computes the luminance of the HDR colour.

    inputs / outputs   the resources it reads and writes, by name: the pipeline wires by them
    runs(config)       whether a pipeline for `config` has the pass (off: no program, no buffer)
    buffer_bytes(...)  the bytes allocate() makes: clrender/render/memory.py's estimate sums them
    allocate()         the buffers behind its outputs, once per resolution
    publish()          put its outputs into the frame's resources
    run()              enqueue its kernels, never wait on the device

To wire a copy in: add the class to clrender/render/plan.py's ORDER (where it runs in the frame),
and name the kernel file after the module (kernels/X.cl <-> passes/X.py). tests/test_pass_template.py
builds and runs this one against NumPy.
"""
from __future__ import annotations

import numpy as np

from clrender.passes.base import RenderPass, empty, launch_1d

REC709 = (0.2126, 0.7152, 0.0722)


class TemplatePass(RenderPass):
    name = "template"
    inputs = ("color", "width", "height")
    outputs = ("luminance",)

    @classmethod
    def runs(cls, config) -> bool:
        return True            # e.g. `return bool(config.my_effect)`: off, the pass does not exist

    @classmethod
    def buffer_bytes(cls, width, height, config, scene=None) -> dict:
        return {"template.luminance": 4 * width * height}     # what allocate() makes, in bytes

    def __init__(self, device, config, weights=REC709):
        super().__init__(device, config)
        # built at its first launch (or by the pipeline's up-front build), never here
        self.kernel = device.kernel("_template.cl", "luminance",
                                    {f"LUMA_{c}": f"{w!r}f" for c, w in zip("RGB", weights)})

    def allocate(self, width, height):
        self.luminance = empty(self.queue, width * height, np.float32)

    def publish(self, res):
        res.buffers["luminance"] = self.luminance

    def run(self, res):
        w, h = res["width"], res["height"]
        self.kernel(self.queue, *launch_1d(w * h), res["color"].data, np.int32(w), np.int32(h),
                    self.luminance.data)
