"""Composite pass (kernels/composite.cl): the blended transparent layers over the shaded opaque
colour, with the refraction offset when `RenderConfig.refraction` is on. Its `color` replaces
the shade pass's for tone mapping and Frame.color; skipped (no kernel) without BLEND triangles.
A scene with transmissive materials gets the TRANSMISSION build (made at its first frame, so
other scenes never build it): per-channel transmittance and the opaque colour's mip chain
(TransmissionPass) sampled behind transmissive surfaces (docs/transmission.md)."""
from __future__ import annotations

import numpy as np

from clrender.passes.base import RenderPass, empty, launch_1d


class CompositePass(RenderPass):
    name = "composite"
    inputs = ("color", "layers")
    outputs = ("color",)

    @classmethod
    def runs(cls, config):
        return config.transparency != "screen_door"

    @classmethod
    def buffer_bytes(cls, width, height, config, scene=None):
        return {"composite.color": 12 * width * height}

    def __init__(self, device, config):
        super().__init__(device, config)
        self.defines = {"REFRACTION": int(config.refraction)}
        self.kernel = device.kernel("composite.cl", "composite", self.defines)

    def allocate(self, width, height):
        self.color = empty(self.queue, 3 * width * height, np.float32)

    def publish(self, res):
        self.opaque = res["color"]          # shade's colour; ours replaces it for later passes
        res.buffers["color"] = self.color

    def run(self, res):
        w, h = res["width"], res["height"]
        args = (self.opaque.data, res["layers"].data, np.int32(w), np.int32(h), self.color.data)
        if "tx_planes" not in res.buffers:
            self.kernel(self.queue, *launch_1d(w * h), *args)
            return
        if "kernel_transmission" not in self.__dict__:
            self.kernel_transmission = self.device.kernel("composite.cl", "composite",
                                                          {**self.defines, "TRANSMISSION": 1})
        self.kernel_transmission(self.queue, *launch_1d(w * h), *args, res["tx_planes"].data,
                                 res["opaque_mips"].data, res["opaque_mip_levels"].data,
                                 np.int32(res["opaque_mip_count"]))
