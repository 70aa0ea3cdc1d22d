"""Motion blur pass (kernels/motion_blur.cl): the report's post-process motion blur (IV.2) on the
linear HDR colour, at the output resolution (docs/post.md: bloom -> motion blur -> tone map), by
McGuire et al.'s reconstruction filter (I3D 2012).

Each pixel's G-buffer velocity (pixels per frame, current − previous) times `shutter` is the
motion over the exposure, centred on the current frame; half of it is the pixel's blur radius V
(static below half a pixel of motion, at most MAX_RADIUS pixels). The velocities are smoothed
as the report advises by a tile max and a 3×3 neighbour max over MAX_RADIUS-pixel tiles: every
pixel of a tile samples along the longest motion that can reach it, so a moving object's blur
extends over the static pixels it sweeps and no farther. `motion_blur_samples` point taps along
it are weighted by depth order and each surface's own blur radius (foreground over background,
background revealed behind a blurred object). Tiles with no motion near them copy their colour
bit for bit. In the pipeline only when `RenderConfig.motion_blur`."""
from __future__ import annotations

import numpy as np

from clrender.device import capabilities
from clrender.abi import gbuffer as layout
from clrender.passes.base import RenderPass, empty, launch_2d, round_up

MAX_RADIUS = 32         # pixels: the longest half blur |V|, and the tile side
MIN_LENGTH = 0.5        # pixels: shorter motion during the exposure is static
SOFT_Z = 0.02           # relative depth difference over which "in front" fades into "behind"


class MotionBlurPass(RenderPass):
    name = "motion_blur"
    inputs = ("color", "gbuffer")
    outputs = ("color",)

    @classmethod
    def runs(cls, config):
        return bool(config.motion_blur)

    @classmethod
    def buffer_bytes(cls, width, height, config, scene=None):
        """The partial maxima counted for one pixel per work-item (VEC = 1): an upper bound."""
        tiles_y = -(-height // MAX_RADIUS)
        tiles = -(-width // MAX_RADIUS) * tiles_y
        return {"motion_blur.inv_len+color+tiles": 16 * width * height + 16 * width * tiles_y + 8 * tiles}

    def __init__(self, device, config):
        super().__init__(device, config)
        self.vec = capabilities.pixel_vector_width(device.cl_device)
        defines = {**layout.kernel_defines(), "VEC": self.vec, "MB_MAX_RADIUS": MAX_RADIUS, "MB_TILE": MAX_RADIUS,
                   "MB_MIN_LENGTH": f"{MIN_LENGTH}f", "MB_SOFT_Z": f"{SOFT_Z}f"}
        self.velocity_kernel = device.kernel("motion_blur.cl", "mb_velocity", defines)
        self.neighbor_kernel = device.kernel("motion_blur.cl", "mb_neighbor_max", defines)
        self.gather_kernel = device.kernel("motion_blur.cl", "mb_gather", defines)
        self.shutter = np.float32(config.shutter)
        self.samples = np.int32(config.motion_blur_samples)

    def allocate(self, width, height):
        self.runs = -(-width // self.vec)
        self.tiles = (-(-width // MAX_RADIUS), -(-height // MAX_RADIUS))
        self.inv_len = empty(self.queue, width * height, np.float32)
        self.partial = empty(self.queue, 4 * self.runs * self.tiles[1], np.float32)
        self.neighbor = empty(self.queue, 2 * self.tiles[0] * self.tiles[1], np.float32)
        self.color = empty(self.queue, 3 * width * height, np.float32)

    def publish(self, res):
        self.source = res["color"]          # the HDR planes before the blur; ours replace them
        res.buffers["color"] = self.color

    def run(self, res):
        w, h = res["width"], res["height"]
        iw, ih = np.int32(w), np.int32(h)
        tx, ty = self.tiles
        gbuffer = res["gbuffer"].data
        self.velocity_kernel(self.queue, *launch_2d(self.runs, ty, (16, 4)), gbuffer, iw, ih, self.shutter,
                             self.inv_len.data, self.partial.data)
        self.neighbor_kernel(self.queue, *launch_2d(tx, ty), self.partial.data, iw, np.int32(tx), np.int32(ty),
                             self.neighbor.data)
        group = (4, 4) if self.vec > 1 else (16, 4)       # runs × rows
        self.gather_kernel(self.queue, (round_up(self.runs, group[0]), round_up(h, group[1])), group,
                           self.source.data, gbuffer,
                           self.inv_len.data, self.neighbor.data, iw, ih, np.int32(tx), self.samples,
                           self.color.data)
