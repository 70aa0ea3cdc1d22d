"""Tone-mapping pass (kernels/tonemap.cl): HDR color -> 8-bit sRGB image."""
from __future__ import annotations

import numpy as np

from .. import capabilities
from .. import gbuffer as layout
from .base import RenderPass, empty, round_up

OPERATORS = {"clamp": 0, "reinhard": 1, "aces": 2}


class TonemapPass(RenderPass):
    name = "tonemap"
    inputs = ("color", "srgb_encode")
    outputs = ("image",)

    def __init__(self, device, config):
        super().__init__(device, config)
        self.vec = capabilities.pixel_vector_width(device.cl_device)
        self.kernel = device.kernel("tonemap.cl", "tonemap_image", {**layout.kernel_defines(), "VEC": self.vec,
                                                                   "TONEMAP": OPERATORS[config.tonemap]})

    def allocate(self, width, height):
        self.image = empty(self.queue, width * height, np.uint32)

    def publish(self, res):
        res.buffers["image"] = self.image

    def run(self, res):
        npix = res["width"] * res["height"]
        self.kernel(self.queue, (round_up(-(-npix // self.vec), 64),), None, res["color"].data, np.int32(npix),
                    np.float32(self.config.exposure), res["srgb_encode"].data, self.image.data)
