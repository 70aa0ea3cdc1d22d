"""Encode pass (kernels/encode.cl): the LDR planes -> 8-bit sRGB image, after the LDR post
effects (docs/post.md). Only in the pipeline when one of them is on; otherwise tonemap.cl
encodes directly."""
from __future__ import annotations

import numpy as np

from clrender.device import capabilities
from clrender.abi import gbuffer as layout
from clrender.passes.base import RenderPass, empty, launch_1d


class EncodePass(RenderPass):
    name = "encode"
    inputs = ("ldr", "srgb_encode")
    outputs = ("image",)

    @classmethod
    def runs(cls, config):
        return bool(config.ldr_effects)     # else the tonemap kernel writes the image

    @classmethod
    def buffer_bytes(cls, width, height, config, scene=None):
        return {"encode.image": 4 * width * height}

    def __init__(self, device, config):
        super().__init__(device, config)
        self.vec = capabilities.pixel_vector_width(device.cl_device)
        self.kernel = device.kernel("encode.cl", "encode_image", {**layout.kernel_defines(), "VEC": self.vec})

    def allocate(self, width, height):
        self.image = empty(self.queue, width * height, np.uint32)

    def publish(self, res):
        res.buffers["image"] = self.image

    def run(self, res):
        npix = res["width"] * res["height"]
        self.kernel(self.queue, *launch_1d(-(-npix // self.vec)), res["ldr"].data, np.int32(npix),
                    res["srgb_encode"].data, self.image.data)
