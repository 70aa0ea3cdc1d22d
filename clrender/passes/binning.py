"""Binning pass (kernels/binning.cl): per-tile prim lists by count, prefix sum, fill."""
from __future__ import annotations

import numpy as np

from clrender.device.capabilities import estimate_tile
from clrender.device.tuning import camera_tile_size
from clrender.passes.base import Overflow, RenderPass, fill_zero, launch_1d, round_up, scan_for, zeros

# Initial tile-list room once the scene is known: min(2 per triangle, LIST_PER_TILE per tile).
# Sponza's atrium (262k triangles, 1280x720, 8-pixel tiles) bins 293k entries, 1.1 per triangle
# and 20 a tile: from 8 a tile its first frame overflowed and was redone. 64 a tile is at most
# 4 bytes a pixel at 8x8 (against setup's 90 bytes a triangle); a heavier frame still grows and
# redoes (overflows / grow). Larger tiles (the shadow maps' 32) get as much room per pixel.
LIST_PER_TILE = 64


def initial_list_capacity(tiles: int, n_tris: int | None = None, tile: int = 8) -> int:
    """Tile-list entries a BinningPass starts from: 8 a tile, then (prepare_scene) room for the scene."""
    base = 8 * tiles
    per_tile = LIST_PER_TILE * max(tile // 8, 1) ** 2
    return base if n_tris is None else max(base, min(2 * int(n_tris), per_tile * tiles))


class BinningPass(RenderPass):
    name = "binning"
    inputs = ("prims", "prim_total", "prim_capacity")
    outputs = ("tile_counts", "tile_offsets", "tile_prims", "tile_list_capacity")

    @classmethod
    def buffer_bytes(cls, width, height, config, scene=None):
        """Per tile: count, offset, cursor; the tile lists at their initial capacity."""
        t = estimate_tile(config.tile_size)          # None (tuned): the smallest candidate's, an upper bound
        tiles = -(-width // t) * -(-height // t)
        n_tris = None if scene is None else scene.triangle_count
        return {"binning.tiles": 12 * tiles, "binning.tile_prims": 4 * initial_list_capacity(tiles, n_tris)}

    def __init__(self, device, config, tile: int | None = None, samples: int = 1):
        """tile: the tile side (default config.tile_size, else the device's tuned tile:
        tuning.camera_tile_size; shadow maps bin to their own).
        samples: bin for every msaa sub-sample point (kernels/samples.h), not only the centres."""
        super().__init__(device, config)
        self.tile = tile or camera_tile_size(device.cl_device, config)
        defines = {"TILE": self.tile, **({"SAMPLES": int(samples)} if samples > 1 else {})}
        self.count_kernel = device.kernel("binning.cl", "bin_count", defines)
        self.fill_kernel = device.kernel("binning.cl", "bin_fill", defines)
        self.scan = scan_for(device)
        self.list_capacity = 0
        self.total = zeros(self.queue, 1, np.int32)

    def allocate(self, width, height):
        self.tiles_x = -(-width // self.tile)
        self.tiles_y = -(-height // self.tile)
        n = self.tiles_x * self.tiles_y
        self.tile_counts = zeros(self.queue, n, np.int32)
        self.tile_offsets = zeros(self.queue, n, np.int32)
        self.tile_cursor = zeros(self.queue, n, np.int32)
        self._allocate_list(initial_list_capacity(n))     # a new resolution drops a list grown for the old one

    def prepare_scene(self, scene_res):
        if not hasattr(self, "tiles_x"):
            return                        # not allocated yet: allocate() starts the list
        want = initial_list_capacity(self.tiles_x * self.tiles_y, scene_res["n_tris"], self.tile)
        if want > self.list_capacity:
            self._allocate_list(want)

    def _allocate_list(self, capacity):
        self.list_capacity = int(capacity)
        self.tile_prims = zeros(self.queue, self.list_capacity, np.int32)

    def publish(self, res):
        res.buffers.update(tile_counts=self.tile_counts, tile_offsets=self.tile_offsets, tile_prims=self.tile_prims)
        res.values.update(tile_list_capacity=self.list_capacity, tiles_x=self.tiles_x, tiles_y=self.tiles_y)

    def run(self, res):
        w, h = res["width"], res["height"]
        fill_zero(self.tile_counts, self.queue)
        fill_zero(self.tile_cursor, self.queue)
        cap = res["prim_capacity"]
        gsize, lsize = launch_1d(cap)
        common = (res["prims"].data, res["prim_total"].data, np.int32(cap), np.int32(w), np.int32(h),
                  np.int32(self.tiles_x))
        self.count_kernel(self.queue, gsize, lsize, *common, self.tile_counts.data)
        self.scan(self.tile_counts, self.tile_offsets, self.total, queue=self.queue)
        self.fill_kernel(self.queue, gsize, lsize, *common, self.tile_offsets.data, self.tile_cursor.data,
                         np.int32(self.list_capacity), self.tile_prims.data)

    def overflows(self):
        return [Overflow("tile_prims", self.total, self.list_capacity)]

    def grow(self, name, needed):
        self._allocate_list(round_up(needed + needed // 4, 4096))
