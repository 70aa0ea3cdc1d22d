"""Motion blur pass (kernels/motion_blur.cl): the report's post-process motion blur (IV.2) on the
linear HDR colour, at the output resolution (docs/post.md: bloom -> motion blur -> tone map).

Each pixel's G-buffer velocity (pixels per frame, current − previous) times `shutter` is its blur
vector b: the exposure is `shutter` frame intervals centred on the current frame. Vectors shorter
than half a pixel are static. The velocity is then smoothed as the report advises, by a
reach-limited max dilation (rows, then columns): a pixel takes the longest blur vector among
the neighbours whose blur reaches it, so a moving object's blur extends over the static pixels it
sweeps (beyond its sharp silhouette) and no farther. Finally each pixel averages
`motion_blur_samples` bilinear taps of the colour along its smoothed b, centred on it; static
pixels copy their colour bit for bit. In the pipeline only when `RenderConfig.motion_blur`."""
from __future__ import annotations

import numpy as np

from .. import gbuffer as layout
from .base import RenderPass, empty, round_up

WG = (16, 4)
MAX_RADIUS = 32         # pixels: the longest half blur, and how far the dilation looks
MIN_LENGTH = 0.5        # pixels: shorter motion during the exposure is static


class MotionBlurPass(RenderPass):
    name = "motion_blur"
    inputs = ("color", "gbuffer")
    outputs = ("color",)

    def __init__(self, device, config):
        super().__init__(device, config)
        defines = {**layout.kernel_defines(), "MB_MAX_RADIUS": MAX_RADIUS, "MB_MIN_LENGTH": f"{MIN_LENGTH}f"}
        self.vectors_kernel = device.kernel("motion_blur.cl", "mb_blur_vectors", defines)
        self.reach_kernel = device.kernel("motion_blur.cl", "mb_tile_reach", defines)
        self.neighbor_kernel = device.kernel("motion_blur.cl", "mb_neighbor_reach", defines)
        self.dilate_x = device.kernel("motion_blur.cl", "mb_dilate_x", defines)
        self.dilate_y = device.kernel("motion_blur.cl", "mb_dilate_y", defines)
        self.gather_kernel = device.kernel("motion_blur.cl", "mb_gather", defines)
        self.shutter = np.float32(config.shutter)
        self.samples = np.int32(config.motion_blur_samples)

    def allocate(self, width, height):
        self.vectors = empty(self.queue, 2 * width * height, np.float32)
        self.dilated = empty(self.queue, 2 * width * height, np.float32)
        self.color = empty(self.queue, 3 * width * height, np.float32)
        self.tiles = (-(-width // MAX_RADIUS), -(-height // MAX_RADIUS))
        self.reach = empty(self.queue, self.tiles[0] * self.tiles[1], np.int32)
        self.neighbor = empty(self.queue, self.tiles[0] * self.tiles[1], np.int32)

    def publish(self, res):
        self.source = res["color"]          # the HDR planes before the blur; ours replace them
        res.buffers["color"] = self.color

    def run(self, res):
        w, h = res["width"], res["height"]
        gsize = (round_up(w, WG[0]), round_up(h, WG[1]))
        iw, ih = np.int32(w), np.int32(h)
        self.vectors_kernel(self.queue, gsize, WG, res["gbuffer"].data, iw, ih, self.shutter, self.vectors.data)
        tx, ty = self.tiles
        self.reach_kernel(self.queue, (tx, ty), None, self.vectors.data, iw, ih, np.int32(tx), np.int32(ty),
                          self.reach.data)
        self.neighbor_kernel(self.queue, (tx, ty), None, self.reach.data, np.int32(tx), np.int32(ty),
                             self.neighbor.data)
        self.dilate_x(self.queue, gsize, WG, self.vectors.data, self.neighbor.data, iw, ih, np.int32(tx),
                      self.dilated.data)
        self.dilate_y(self.queue, gsize, WG, self.dilated.data, self.neighbor.data, iw, ih, np.int32(tx),
                      self.vectors.data)
        self.gather_kernel(self.queue, gsize, WG, self.source.data, self.vectors.data, iw, ih, self.samples,
                           self.color.data)
