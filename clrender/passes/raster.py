"""Fine raster pass (kernels/raster.cl): one work-group per tile into the visibility buffer."""
from __future__ import annotations

import numpy as np

from clrender.device import capabilities, tuning
from clrender.passes.base import RenderPass, empty


class RasterPass(RenderPass):
    name = "raster"
    inputs = ("prims", "tile_counts", "tile_offsets", "tile_prims", "uvs", "triangles", "materials",
              "texels", "tex_infos", "tex_levels", "colors", "n_vertices", "has_colors")
    outputs = ("vis_depth", "vis_prim")

    @classmethod
    def buffer_bytes(cls, width, height, config, scene=None):
        return {"raster.vis_depth+vis_prim": 8 * width * height}

    def __init__(self, device, config, ortho: bool = False, depth_only: bool = False, tile: int | None = None,
                 samples: int = 1, vec: int | None = None):
        """ortho: orthographic prims (setup.cl ORTHO). depth_only (shadow maps): no visibility
        buffer of its own; run() writes depth into res["raster_target"] at res["raster_offset"]
        with row stride res["raster_stride"] (a region of the shadow atlas), built with DEPTH_ONLY
        (the nearest depth, no visibility order). tile: as the BinningPass it reads (default
        config.tile_size, else the device's tuned tile: tuning.camera_tile_size). samples > 1:
        a nearest fragment per msaa sub-sample point (kernels/samples.h); vis_prim holds `samples`
        planes of W·H. vec: pixels per work-item (default tuning.raster_vector_width; the
        autotune times others). Neither tile nor vec changes a pixel."""
        super().__init__(device, config)
        dev = device.cl_device
        self.tile = capabilities.tile_size_for(dev, tile) if tile else tuning.camera_tile_size(dev, config)
        self.vec = min(vec, self.tile) if vec else tuning.raster_vector_width(dev, self.tile)
        self.depth_only = depth_only
        if depth_only:
            self.inputs = self.inputs + ("raster_target", "raster_offset", "raster_stride")
            self.outputs = ()
        # Rows per work-item (raster.cl RROWS): the whole tile column on CPUs, where a work-item's
        # prim loads and bounding-box tests are the cost; a pixel per work-item on GPUs.
        self.ortho = ortho
        self.samples = samples
        self.set_rows(self.tile if self.vec > 1 else 1)

    def set_rows(self, rows: int):
        """Rows per work-item (a divisor of the tile size); the result is the same for any."""
        if self.tile % rows:
            raise ValueError(f"rows per work-item {rows} must divide the tile size {self.tile}")
        self.rows = rows
        defines = {"TILE": self.tile, "VEC": self.vec, "RROWS": rows, **({"ORTHO": 1} if self.ortho else {}),
                   **({"DEPTH_ONLY": 1} if self.depth_only else {}), **({"SAMPLES": self.samples} if self.samples > 1 else {})}
        self.kernel = self.device.kernel("raster.cl", "raster_tiles", defines)

    def allocate(self, width, height):
        if self.depth_only:
            return
        self.vis_depth = empty(self.queue, width * height, np.float32)
        self.vis_prim = empty(self.queue, self.samples * width * height, np.int32)

    def publish(self, res):
        if not self.depth_only:
            res.buffers.update(vis_depth=self.vis_depth, vis_prim=self.vis_prim)

    def run(self, res):
        t = self.tile
        gsize = (res["tiles_x"] * t // self.vec, res["tiles_y"] * t // self.rows)
        if self.depth_only:
            target = (res["raster_target"].data, np.int32(res["raster_offset"]), np.int32(res["raster_stride"]), None)
        else:
            target = (self.vis_depth.data, np.int32(0), np.int32(res["width"]), self.vis_prim.data)
        self.kernel(self.queue, gsize, (t // self.vec, t // self.rows),
                    res["prims"].data, res["tile_offsets"].data, res["tile_counts"].data,
                    res["tile_prims"].data, np.int32(res["tile_list_capacity"]), np.int32(res["tiles_x"]),
                    np.int32(res["width"]), np.int32(res["height"]), np.float32(res["far"]),
                    res["uvs"].data, res["triangles"].data, res["materials"].data,
                    res["texels"].data, res["tex_infos"].data, res["tex_levels"].data,
                    res["colors"].data, np.int32(res["n_vertices"]), np.int32(res["has_colors"]), *target)
