"""Light culling pass (kernels/light_cull.cl): per-tile light index lists from the G-buffer depth."""
from __future__ import annotations

import numpy as np

from clrender.device import capabilities
from clrender.abi import gbuffer as layout
from clrender.passes.base import Overflow, RenderPass, empty, launch_1d, round_up, scan_for, view_defines, zeros


class TileLightLists(RenderPass):
    """Per-tile light index lists (counts, offsets, entries) and what every pass that makes them
    shares (LightCullPass, light_quads.LightQuadsPass): allocation per resolution, the published
    resources ShadePass reads, growth on overflow, the per-tile statistics."""
    outputs = ("tile_light_counts", "tile_light_offsets", "tile_lights", "light_list_capacity", "light_tiles_x")

    def _allocate_lists(self, width, height):
        self.tiles_x, self.tiles_y = -(-width // self.tile), -(-height // self.tile)
        n = self.tiles_x * self.tiles_y
        self.counts = zeros(self.queue, n, np.int32)
        self.offsets = zeros(self.queue, n, np.int32)
        self._allocate_list(16 * n)        # a new resolution drops a list grown for the old one

    def _allocate_list(self, capacity):
        self.list_capacity = int(capacity)
        self.lights_list = zeros(self.queue, self.list_capacity, np.int32)

    def publish(self, res):
        res.buffers.update(tile_light_counts=self.counts, tile_light_offsets=self.offsets,
                           tile_lights=self.lights_list)
        res.values.update(light_list_capacity=self.list_capacity, light_tiles_x=self.tiles_x)

    def overflows(self):
        return [Overflow("tile_lights", self.total, self.list_capacity)]

    def grow(self, name, needed):
        self._allocate_list(round_up(needed + needed // 4, 4096))

    def tile_stats(self) -> dict:
        counts = self.counts.get(queue=self.queue)[: self.tiles_x * self.tiles_y]
        return {"lights_per_tile_avg": float(counts.mean()) if counts.size else 0.0,
                "lights_per_tile_max": int(counts.max()) if counts.size else 0,
                "light_list_entries": int(counts.sum())}


class LightCullPass(TileLightLists):
    name = "light_cull"
    inputs = ("lights", "n_lights", "gbuffer", "view_matrix", "tan_x", "tan_y", "shift_x", "shift_y")

    @classmethod
    def runs(cls, config):
        return config.light_culling in ("tiled", "stencil")

    @classmethod
    def buffer_bytes(cls, width, height, config, scene=None):
        tiles = -(-width // config.light_tile_size) * -(-height // config.light_tile_size)
        return {"light_cull.tiles": 24 * tiles, "light_cull.tile_lights": 4 * 16 * tiles}

    def __init__(self, device, config, ortho: bool = False):
        """ortho: an orthographic camera (light_cull.cl ORTHO: tile frusta are boxes)."""
        super().__init__(device, config)
        self.tile = config.light_tile_size
        self.vec = capabilities.pixel_vector_width(device.cl_device)
        defines = {**layout.kernel_defines(), "LTILE": self.tile, "VEC": self.vec,
                   "DEPTH_MASK": int(config.light_depth_mask), **view_defines(ortho)}
        kernel = lambda name: device.kernel("light_cull.cl", name, defines)   # noqa: E731
        self.bounds_kernel = kernel("light_view_bounds")
        self.depth_kernel = kernel("tile_depth_bounds")
        self.count_kernel = kernel("light_cull_count")
        self.fill_kernel = kernel("light_cull_fill")
        self.scan = scan_for(device)
        self.total = zeros(self.queue, 1, np.int32)
        self.n_padded = 0
        self.list_capacity = 0

    def allocate(self, width, height):
        self._allocate_lists(width, height)
        self.tile_depth = empty(self.queue, 4 * self.tiles_x * self.tiles_y, np.float32)

    def prepare_scene(self, scene_res):
        needed = round_up(max(scene_res["n_lights"], 1), self.vec)
        if needed > self.n_padded:
            self.n_padded = needed
            self.spheres = [empty(self.queue, needed, np.float32) for _ in range(4)]

    def run(self, res):
        w, h = res["width"], res["height"]
        n_lights = res["n_lights"]
        n_padded = round_up(max(n_lights, 1), self.vec)
        sx, sy, sz, sr = (s.data for s in self.spheres)
        self.bounds_kernel(self.queue, *launch_1d(n_padded), res["lights"].data, np.int32(n_lights),
                           np.int32(n_padded), res["view_matrix"].data, sx, sy, sz, sr)
        n_tiles = self.tiles_x * self.tiles_y
        gsize, lsize = launch_1d(n_tiles)
        fragments = "has_fragments" in res and res["has_fragments"]     # transparent fragments widen tiles
        self.depth_kernel(self.queue, gsize, lsize, res["gbuffer"].data, np.int32(w), np.int32(h),
                          np.float32(res["far"]), np.int32(self.tiles_x), np.int32(self.tiles_y),
                          np.int32(fragments), (res["t_range"] if fragments else self.tile_depth).data,
                          self.tile_depth.data)
        cull = (sx, sy, sz, sr, np.int32(n_padded), self.tile_depth.data, np.int32(self.tiles_x),
                np.int32(self.tiles_y), np.int32(w), np.int32(h), np.float32(res["tan_x"]), np.float32(res["tan_y"]),
                np.float32(res["shift_x"]), np.float32(res["shift_y"]))
        self.count_kernel(self.queue, gsize, lsize, *cull, self.counts.data)
        self.scan(self.counts, self.offsets, self.total, queue=self.queue)
        self.fill_kernel(self.queue, gsize, lsize, *cull, self.offsets.data, np.int32(self.list_capacity),
                         self.lights_list.data)
