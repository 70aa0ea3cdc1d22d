"""Edge-smoothing pass (kernels/edge_aa.cl): the report's two-pass edge AA on the LDR planes.

Pass 1 (`edge_detect`) marks the pixels where the G-buffer is discontinuous with a direct
neighbour (relative depth jump above `edge_depth_threshold`, normal angle above
`edge_normal_threshold_deg`, or foreground against background): the `edges` mask (Frame.edges),
plus which of the 8 neighbours (the diagonals too) differ. Pass 2 (`edge_blur`) copies unmarked
pixels; a marked one orients itself by the 8 flags and is blurred along the edge. Both process
runs of VEC pixels per work-item (kernels/vec.h).
In the pipeline only when `RenderConfig.edge_aa` (docs/post.md: tone map -> edge AA -> FXAA ->
encode)."""
from __future__ import annotations

import math

import numpy as np

from clrender.device import capabilities
from clrender.abi import gbuffer as layout
from clrender.passes.base import RenderPass, empty, round_up

PIXELS_PER_GROUP = 256      # work-groups of 256 pixels of one row (256 / VEC work-items)


def work_group(vec: int) -> tuple[int, int]:
    """(work-items along x, rows) of the edge AA and FXAA kernels' work-groups; a work-item
    owns a run of `vec` pixels of one row (kernels/vec.h, row_run.h). One row per group: on
    CPUs a group's runs then read consecutive addresses (4 rows × 64 pixels measured 20-30 %
    slower on PoCL)."""
    return max(PIXELS_PER_GROUP // vec, 1), 1


def global_size(width: int, height: int, vec: int) -> tuple[int, int]:
    wx, wy = work_group(vec)
    return round_up(-(-width // vec), wx), round_up(height, wy)


class EdgeAaPass(RenderPass):
    name = "edge_aa"
    inputs = ("ldr", "gbuffer")
    outputs = ("ldr", "edges")

    @classmethod
    def runs(cls, config):
        return bool(config.edge_aa)

    @classmethod
    def buffer_bytes(cls, width, height, config, scene=None):
        return {"edge_aa.ldr+edges+flags": 14 * width * height}

    def __init__(self, device, config):
        super().__init__(device, config)
        self.vec = capabilities.pixel_vector_width(device.cl_device)
        defines = {**layout.kernel_defines(), "VEC": self.vec}
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
        gsize, lsize = global_size(w, h, self.vec), work_group(self.vec)
        self.detect(self.queue, gsize, lsize, res["gbuffer"].data, np.int32(w), np.int32(h), self.depth_threshold,
                    self.cos_threshold, self.edges.data, self.flags.data)
        self.blur(self.queue, gsize, lsize, self.source.data, self.edges.data, self.flags.data, np.int32(w),
                  np.int32(h), self.ldr.data)
