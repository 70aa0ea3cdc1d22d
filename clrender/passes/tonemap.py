"""Tone-mapping pass (kernels/tonemap.cl): HDR color -> 8-bit sRGB image."""
from __future__ import annotations

import numpy as np

from clrender.device import capabilities
from clrender.abi import gbuffer as layout
from clrender.passes.base import RenderPass, empty, launch_1d

OPERATORS = {"clamp": 0, "reinhard": 1, "aces": 2}


class TonemapPass(RenderPass):
    """ldr=False: HDR colour -> image in one kernel. ldr=True (LDR post effects follow): the
    tone-mapped linear planes `ldr`, which EncodePass turns into the image."""
    name = "tonemap"
    inputs = ("color", "srgb_encode")

    @classmethod
    def buffer_bytes(cls, width, height, config, scene=None):
        """The packed image, or (LDR effects after it) three float planes."""
        return {"tonemap.image": (12 if config.ldr_effects else 4) * width * height}

    def __init__(self, device, config, ldr: bool = False):
        super().__init__(device, config)
        self.ldr = ldr
        self.outputs = ("ldr",) if ldr else ("image",)
        self.vec = capabilities.pixel_vector_width(device.cl_device)
        self.kernel = device.kernel("tonemap.cl", "tonemap_ldr" if ldr else "tonemap_image",
                                    {**layout.kernel_defines(), "VEC": self.vec})

    def allocate(self, width, height):
        self.out = empty(self.queue, (3 if self.ldr else 1) * width * height, np.float32 if self.ldr else np.uint32)

    def publish(self, res):
        res.buffers[self.outputs[0]] = self.out

    def run(self, res):
        npix = res["width"] * res["height"]
        extra = () if self.ldr else (res["srgb_encode"].data,)
        self.kernel(self.queue, *launch_1d(-(-npix // self.vec)), res["color"].data, np.int32(npix),
                    np.float32(self.config.exposure), np.int32(OPERATORS[self.config.tonemap]), *extra,
                    self.out.data)
