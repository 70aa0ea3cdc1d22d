"""Over-sampling resolve (kernels/resolve.cl): with `supersample=k` every pass before this one
rendered k·W × k·H; this pass filters the HDR colour down to W × H (box, Lanczos-2 or Mitchell,
separable) and keeps for the G-buffer the sample nearest each pixel's centre (docs/post.md).
From here on the frame is at the output resolution: it republishes `width` and `height`."""
from __future__ import annotations

import numpy as np

from .. import gbuffer as layout
from .base import RenderPass, empty, round_up

FILTERS = {"box": 0, "lanczos2": 1, "mitchell": 2}
GROUP = (16, 4)


class ResolvePass(RenderPass):
    name = "resolve"
    inputs = ("color", "gbuffer", "width", "height")
    outputs = ("color", "gbuffer", "width", "height")

    def __init__(self, device, config):
        super().__init__(device, config)
        self.k = config.supersample
        defines = {**layout.kernel_defines(), "K": self.k, "FILTER": FILTERS[config.supersample_filter]}
        self.rows_kernel = device.kernel("resolve.cl", "resolve_rows", defines)
        self.cols_kernel = device.kernel("resolve.cl", "resolve_cols", defines)
        self.gbuffer_kernel = device.kernel("resolve.cl", "decimate_gbuffer", defines)

    def allocate(self, width, height):
        """width, height: the output size."""
        self.size = (width, height)
        self.rows = empty(self.queue, 3 * width * self.k * height, np.float32)
        self.color = empty(self.queue, 3 * width * height, np.float32)
        self.gbuffer = empty(self.queue, len(layout.PLANES) * width * height, np.uint32)

    def publish(self, res):
        self.internal = (res["color"], res["gbuffer"])
        res.buffers.update(color=self.color, gbuffer=self.gbuffer)
        res.values.update(width=self.size[0], height=self.size[1])

    def run(self, res):
        w, h = self.size
        color, gbuffer = self.internal
        gx, gy = GROUP
        self.rows_kernel(self.queue, (round_up(w, gx), round_up(self.k * h, gy)), GROUP, color.data,
                         np.int32(w), np.int32(h), self.rows.data)
        self.cols_kernel(self.queue, (round_up(w, gx), round_up(h, gy)), GROUP, self.rows.data,
                         np.int32(w), np.int32(h), self.color.data)
        self.gbuffer_kernel(self.queue, (round_up(w, gx), round_up(h, gy)), GROUP, gbuffer.data,
                            np.int32(w), np.int32(h), self.gbuffer.data)
