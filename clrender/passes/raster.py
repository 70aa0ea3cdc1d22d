"""Fine raster pass (kernels/raster.cl): one work-group per tile into the visibility buffer."""
from __future__ import annotations

import numpy as np

from .. import capabilities
from .base import RenderPass, empty


class RasterPass(RenderPass):
    name = "raster"
    inputs = ("prims", "tile_counts", "tile_offsets", "tile_prims", "uvs", "triangles", "materials",
              "texels", "srgb_lut", "tex_infos", "tex_levels")
    outputs = ("vis_depth", "vis_prim")

    def __init__(self, device, config):
        super().__init__(device, config)
        self.tile = capabilities.tile_size_for(device.cl_device, config.tile_size)
        self.vec = capabilities.raster_vector_width(device.cl_device, self.tile)
        self.kernel = device.kernel("raster.cl", "raster_tiles", {"TILE": self.tile, "VEC": self.vec})

    def allocate(self, width, height):
        self.vis_depth = empty(self.queue, width * height, np.float32)
        self.vis_prim = empty(self.queue, width * height, np.int32)

    def publish(self, res):
        res.buffers.update(vis_depth=self.vis_depth, vis_prim=self.vis_prim)

    def run(self, res):
        t = self.tile
        gsize = (res["tiles_x"] * t // self.vec, res["tiles_y"] * t)
        self.kernel(self.queue, gsize, (t // self.vec, t),
                    res["prims"].data, res["tile_offsets"].data, res["tile_counts"].data,
                    res["tile_prims"].data, np.int32(res["tile_list_capacity"]), np.int32(res["tiles_x"]),
                    np.int32(res["width"]), np.int32(res["height"]), np.float32(res["far"]),
                    res["uvs"].data, res["triangles"].data, res["materials"].data,
                    res["texels"].data, res["srgb_lut"].data, res["tex_infos"].data, res["tex_levels"].data,
                    self.vis_depth.data, self.vis_prim.data)
