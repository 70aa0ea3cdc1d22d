"""SSAO blur pass (kernels/ssao_blur.cl): depth-aware separable blur, `ao_raw` -> `ao`.

In the pipeline only when `RenderConfig.ssao` and `ssao_blur` are both on."""
from __future__ import annotations

import numpy as np

from clrender.device import capabilities
from clrender.abi import gbuffer as layout
from clrender.passes.base import RenderPass, empty
from clrender.passes.ssao import global_size, work_group


class SsaoBlurPass(RenderPass):
    name = "ssao_blur"
    inputs = ("ao_raw", "gbuffer")
    outputs = ("ao",)

    @classmethod
    def runs(cls, config):
        return bool(config.ssao and config.ssao_blur)

    @classmethod
    def buffer_bytes(cls, width, height, config, scene=None):
        return {"ssao_blur.along_x+ao": 8 * width * height}

    def __init__(self, device, config):
        super().__init__(device, config)
        self.vec = capabilities.pixel_vector_width(device.cl_device)
        wx, wy = work_group(self.vec)
        self.kernel = device.kernel("ssao_blur.cl", "ssao_blur", {**layout.kernel_defines(), "VEC": self.vec,
                                                                  "SSAO_WG_X": wx, "SSAO_WG_Y": wy})

    def allocate(self, width, height):
        self.along_x = empty(self.queue, width * height, np.float32)   # after the first (row) pass
        self.ao = empty(self.queue, width * height, np.float32)

    def publish(self, res):
        res.buffers["ao"] = self.ao

    def run(self, res):
        w, h = res["width"], res["height"]
        gsize, lsize = global_size(w, h, self.vec), work_group(self.vec)
        common = (res["gbuffer"].data, np.int32(w), np.int32(h))
        self.kernel(self.queue, gsize, lsize, res["ao_raw"].data, *common, np.int32(1), np.int32(0),
                    self.along_x.data)
        self.kernel(self.queue, gsize, lsize, self.along_x.data, *common, np.int32(0), np.int32(1), self.ao.data)
