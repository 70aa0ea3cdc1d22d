"""Edge-smoothing pass (kernels/edge_aa.cl): the report's two-pass edge AA on the LDR planes.

Pass 1 (`edge_detect`) marks the pixels where the G-buffer is discontinuous with a direct
neighbour (relative depth jump above `edge_depth_threshold`, normal angle above
`edge_normal_threshold_deg`, or foreground against background): the `edges` mask (Frame.edges)
plus which neighbours differ. Pass 2 (`edge_blur`) copies unmarked pixels; a marked one also
tests its diagonal neighbours, orients itself by the 8 flags and is blurred along the edge.
In the pipeline only when `RenderConfig.edge_aa` (docs/post.md: tone map -> edge AA -> FXAA ->
encode)."""
from __future__ import annotations

import math

import numpy as np

from .. import gbuffer as layout
from .base import RenderPass, empty, round_up

WG = 8          # work-groups of WG × WG pixels


def global_size_2d(width: int, height: int) -> tuple[int, int]:
    return round_up(width, WG), round_up(height, WG)


class EdgeAaPass(RenderPass):
    name = "edge_aa"
    inputs = ("ldr", "gbuffer")
    outputs = ("ldr", "edges")

    def __init__(self, device, config):
        super().__init__(device, config)
        defines = {**layout.kernel_defines(), "VEC": 1}
        self.detect = device.kernel("edge_aa.cl", "edge_detect", defines)
        self.blur = device.kernel("edge_aa.cl", "edge_blur", defines)
        self.depth_threshold = np.float32(config.edge_depth_threshold)
        self.cos_threshold = np.float32(math.cos(math.radians(config.edge_normal_threshold_deg)))

    def allocate(self, width, height):
        self.edges = empty(self.queue, width * height, np.uint8)
        self.flags = empty(self.queue, width * height, np.uint8)
        self.ldr = empty(self.queue, 3 * width * height, np.float32)

    def publish(self, res):
        self.source = res["ldr"]            # the tone-mapped planes; ours replace them for later passes
        res.buffers["ldr"] = self.ldr
        res.buffers["edges"] = self.edges

    def run(self, res):
        w, h = res["width"], res["height"]
        gsize, lsize = global_size_2d(w, h), (WG, WG)
        self.detect(self.queue, gsize, lsize, res["gbuffer"].data, np.int32(w), np.int32(h), self.depth_threshold,
                    self.cos_threshold, self.edges.data, self.flags.data)
        self.blur(self.queue, gsize, lsize, self.source.data, self.edges.data, self.flags.data, res["gbuffer"].data,
                  np.int32(w), np.int32(h), self.depth_threshold, self.cos_threshold, self.ldr.data)
