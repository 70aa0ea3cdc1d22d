"""Composite pass (kernels/composite.cl): the blended transparent layers over the shaded opaque
colour, with the refraction offset when `RenderConfig.refraction` is on. Its `color` replaces
the shade pass's for tone mapping and Frame.color; skipped (no kernel) without BLEND triangles."""
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
        self.kernel = device.kernel("composite.cl", "composite", {"REFRACTION": int(config.refraction)})

    def allocate(self, width, height):
        self.color = empty(self.queue, 3 * width * height, np.float32)

    def publish(self, res):
        self.opaque = res["color"]          # shade's colour; ours replaces it for later passes
        res.buffers["color"] = self.color

    def run(self, res):
        w, h = res["width"], res["height"]
        self.kernel(self.queue, *launch_1d(w * h), self.opaque.data, res["layers"].data,
                    np.int32(w), np.int32(h), self.color.data)
