"""Shading pass (kernels/shade.cl): the light buffer and global multiply, from the G-buffer."""
from __future__ import annotations

import numpy as np

from .. import capabilities
from .. import gbuffer as layout
from .base import RenderPass, empty, zeros


class ShadePass(RenderPass):
    name = "shade"
    outputs = ("color", "light_count")

    def __init__(self, device, config):
        super().__init__(device, config)
        self.brute_force = config.light_culling == "brute_force"
        self.inputs = ("gbuffer", "lights", "n_lights", "ambient", "camera_params", "srgb_lut") + (
            () if self.brute_force else ("tile_light_counts", "tile_light_offsets", "tile_lights"))
        self.tile = capabilities.tile_size_for(device.cl_device, config.light_tile_size)
        self.vec = min(capabilities.pixel_vector_width(device.cl_device), self.tile)
        self.kernel = device.kernel("shade.cl", "shade", {**layout.kernel_defines(), "LTILE": self.tile,
                                                          "VEC": self.vec, "BRUTE_FORCE": int(self.brute_force)})
        self.no_list = zeros(self.queue, 1, np.int32)     # placeholder list arguments for brute force

    def allocate(self, width, height):
        self.tiles_x, self.tiles_y = -(-width // self.tile), -(-height // self.tile)
        self.color = empty(self.queue, 3 * width * height, np.float32)
        self.light_count = empty(self.queue, width * height, np.int32)

    def publish(self, res):
        res.buffers.update(color=self.color, light_count=self.light_count)

    def run(self, res):
        t = self.tile
        if self.brute_force:
            offsets = counts = lists = self.no_list
            capacity = 0
        else:
            offsets, counts, lists = res["tile_light_offsets"], res["tile_light_counts"], res["tile_lights"]
            capacity = res["light_list_capacity"]
        self.kernel(self.queue, (self.tiles_x * t // self.vec, self.tiles_y * t), (t // self.vec, t),
                    res["gbuffer"].data, np.int32(res["width"]), np.int32(res["height"]), np.float32(res["far"]),
                    res["camera_params"].data, res["lights"].data, np.int32(res["n_lights"]),
                    np.float32(res["ambient"]), offsets.data, counts.data, lists.data, np.int32(capacity),
                    np.int32(self.tiles_x), res["srgb_lut"].data, self.color.data, self.light_count.data)
