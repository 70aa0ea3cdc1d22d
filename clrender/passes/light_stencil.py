"""Light stencil pass (kernels/light_stencil.cl): after LightCullPass, per-pixel bit masks of the
tile-list entries whose light reaches the pixel (report V.1's stencil variant, exact); shade.cl
built with STENCIL walks only the set bits. The words per pixel, ceil(longest tile list / 32),
are known only on the device: the buffer grows and the frame is redone when they overflow."""
from __future__ import annotations

import numpy as np

from clrender.device import capabilities
from clrender.abi import gbuffer as layout
from clrender.passes.base import Overflow, RenderPass, empty, fill_zero, launch_1d, view_defines, zeros

INITIAL_WORDS = 1        # 32 lights per tile list before the first growth


class LightStencilPass(RenderPass):
    name = "light_stencil"
    inputs = ("gbuffer", "lights", "camera_params", "far", "tile_light_counts", "tile_light_offsets",
              "tile_lights", "light_list_capacity", "light_tiles_x")
    outputs = ("light_stencil", "light_stencil_words")

    @classmethod
    def runs(cls, config):
        return config.light_culling == "stencil"

    @classmethod
    def buffer_bytes(cls, width, height, config, scene=None):
        return {"light_stencil.words": 4 * INITIAL_WORDS * width * height}

    def __init__(self, device, config, ortho: bool = False):
        """ortho: an orthographic camera (lighting.h ORTHO positions)."""
        super().__init__(device, config)
        self.tile = capabilities.tile_size_for(device.cl_device, config.light_tile_size)
        self.vec = min(capabilities.pixel_vector_width(device.cl_device), self.tile)   # shade.cl's runs
        defines = {**layout.kernel_defines(), "LTILE": self.tile, "VEC": self.vec, **view_defines(ortho)}
        self.kernel = device.kernel("light_stencil.cl", "light_stencil", defines)
        self.words_kernel = device.kernel("light_stencil.cl", "stencil_words_needed", defines)
        self.needed = zeros(self.queue, 1, np.int32)
        self.words = 0
        self.pixels = 0

    def allocate(self, width, height):
        self.tiles_x, self.tiles_y = -(-width // self.tile), -(-height // self.tile)
        self.pixels = width * height
        self._allocate_words(INITIAL_WORDS)       # a new resolution drops words grown for the old one

    def _allocate_words(self, words):
        self.words = int(words)
        self.stencil = empty(self.queue, self.words * self.pixels, np.uint32)

    def publish(self, res):
        res.buffers["light_stencil"] = self.stencil
        res.values["light_stencil_words"] = self.words

    def run(self, res):
        t = self.tile
        n_tiles = self.tiles_x * self.tiles_y
        fill_zero(self.needed, self.queue)
        self.words_kernel(self.queue, *launch_1d(n_tiles), res["tile_light_counts"].data,
                          np.int32(n_tiles), self.needed.data)
        self.kernel(self.queue, (self.tiles_x * t // self.vec, self.tiles_y * t), (t // self.vec, t),
                    res["gbuffer"].data, np.int32(res["width"]), np.int32(res["height"]), np.float32(res["far"]),
                    res["camera_params"].data, res["lights"].data, res["tile_light_offsets"].data,
                    res["tile_light_counts"].data, res["tile_lights"].data, np.int32(res["light_list_capacity"]),
                    np.int32(self.tiles_x), np.int32(self.words), self.stencil.data)

    def overflows(self):
        return [Overflow("light_stencil", self.needed, self.words)]

    def grow(self, name, needed):
        self._allocate_words(needed + needed // 4)

    def stencil_bits(self) -> np.ndarray:
        """(words, H·W) uint32 of the last frame (words past a tile's list are undefined)."""
        return self.stencil.get(queue=self.queue).reshape(self.words, self.pixels)
