"""Over-sampling resolve (kernels/resolve.cl): with `supersample=k` every pass before this one
rendered k·W × k·H; this pass filters the HDR colour down to W × H (box, Lanczos-2 or Mitchell,
separable) and keeps for the G-buffer the sample nearest each pixel's centre (docs/post.md).
From here on the frame is at the output resolution: it republishes `width` and `height`."""
from __future__ import annotations

import numpy as np
import pyopencl.array as cla

from clrender.abi import gbuffer as layout
from clrender.passes.base import RenderPass, empty, round_up

GROUP = (16, 4)


def filter_weight(name: str, d: np.ndarray) -> np.ndarray:
    """The resolve filters as functions of the distance d in output pixels (docs/post.md)."""
    a = np.abs(d)
    if name == "box":
        return (a < 0.5).astype(np.float64)
    if name == "lanczos2":
        return np.where(a < 2, np.sinc(d) * np.sinc(d / 2), 0.0)
    b = c = 1.0 / 3.0                               # Mitchell-Netravali
    return np.where(a < 1, ((12 - 9 * b - 6 * c) * a**3 + (-18 + 12 * b + 6 * c) * a**2 + (6 - 2 * b)) / 6,
                    np.where(a < 2, ((-b - 6 * c) * a**3 + (6 * b + 30 * c) * a**2 + (-12 * b - 48 * c) * a
                                     + (8 * b + 24 * c)) / 6, 0.0))


def filter_taps(name: str, k: int) -> tuple[int, np.ndarray]:
    """(first tap offset, weights): output position o reads samples k·o + first + t, t < len(weights)."""
    radius = 0.5 if name == "box" else 2.0
    first = int(np.floor(k * 0.5 - radius * k))
    t = np.arange(int(2 * radius * k) + 2)
    w = filter_weight(name, (first + t + 0.5) / k - 0.5)
    keep = np.flatnonzero(w != 0)
    return first + int(keep[0]), w[keep[0]: keep[-1] + 1].astype(np.float32)


class ResolvePass(RenderPass):
    name = "resolve"
    inputs = ("color", "gbuffer", "width", "height")
    outputs = ("color", "gbuffer", "width", "height")

    @classmethod
    def runs(cls, config):
        return config.supersample > 1      # over-sampling: the passes before render k·W × k·H

    @classmethod
    def buffer_bytes(cls, width, height, config, scene=None):
        """At the output size: the filtered rows (k·H of them), colour and G-buffer."""
        return {"resolve.rows+color+gbuffer": 12 * width * config.supersample * height
                + (12 + 4 * len(layout.PLANES)) * width * height}

    def __init__(self, device, config):
        super().__init__(device, config)
        self.k = config.supersample
        first, weights = filter_taps(config.supersample_filter, self.k)
        self.weights = cla.to_device(self.queue, weights)
        defines = {**layout.kernel_defines(), "K": self.k, "TAPS": len(weights), "FIRST_TAP": first}
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
                         np.int32(w), np.int32(h), self.weights.data, self.rows.data)
        self.cols_kernel(self.queue, (round_up(w, gx), round_up(h, gy)), GROUP, self.rows.data,
                         np.int32(w), np.int32(h), self.weights.data, self.color.data)
        self.gbuffer_kernel(self.queue, (round_up(w, gx), round_up(h, gy)), GROUP, gbuffer.data,
                            np.int32(w), np.int32(h), self.gbuffer.data)
