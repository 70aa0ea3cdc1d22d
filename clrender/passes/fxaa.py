"""FXAA pass (kernels/fxaa.cl): luminance-edge anti-aliasing of the LDR planes, FXAA 3.11
"quality" style (local contrast test, edge orientation, an 8-step search for the edge's ends,
blend by the distance to them plus a subpixel term). In the pipeline only when
`RenderConfig.color_aa == "fxaa"` (docs/post.md: tone map -> edge AA -> FXAA -> encode)."""
from __future__ import annotations

import numpy as np

from clrender.device import capabilities
from clrender.passes.base import RenderPass, empty
from clrender.passes.edge_aa import global_size, work_group


class FxaaPass(RenderPass):
    name = "fxaa"
    inputs = ("ldr",)
    outputs = ("ldr",)

    @classmethod
    def runs(cls, config):
        return config.color_aa == "fxaa"

    @classmethod
    def buffer_bytes(cls, width, height, config, scene=None):
        return {"fxaa.ldr+luma": 16 * width * height}

    def __init__(self, device, config):
        super().__init__(device, config)
        self.vec = capabilities.pixel_vector_width(device.cl_device)
        defines = {"VEC": self.vec}
        self.luma_kernel = device.kernel("fxaa.cl", "fxaa_luma", defines)
        self.kernel = device.kernel("fxaa.cl", "fxaa", defines)

    def allocate(self, width, height):
        self.luma = empty(self.queue, width * height, np.float32)
        self.ldr = empty(self.queue, 3 * width * height, np.float32)

    def publish(self, res):
        self.source = res["ldr"]            # the previous LDR planes; ours replace them for later passes
        res.buffers["ldr"] = self.ldr

    def run(self, res):
        w, h = res["width"], res["height"]
        gsize, lsize = global_size(w, h, self.vec), work_group(self.vec)
        self.luma_kernel(self.queue, gsize, lsize, self.source.data, np.int32(w), np.int32(h), self.luma.data)
        self.kernel(self.queue, gsize, lsize, self.source.data, self.luma.data, np.int32(w), np.int32(h),
                    self.ldr.data)
