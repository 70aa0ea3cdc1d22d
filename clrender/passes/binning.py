"""Binning pass (kernels/binning.cl): per-tile prim lists by count, prefix sum, fill."""
from __future__ import annotations

import numpy as np

from .base import Overflow, RenderPass, round_up, scan_for, zeros


class BinningPass(RenderPass):
    name = "binning"
    inputs = ("prims", "prim_total", "prim_capacity")
    outputs = ("tile_counts", "tile_offsets", "tile_prims", "tile_list_capacity")

    def __init__(self, device, config):
        super().__init__(device, config)
        self.tile = config.tile_size
        self.count_kernel = device.kernel("binning.cl", "bin_count", {"TILE": self.tile})
        self.fill_kernel = device.kernel("binning.cl", "bin_fill", {"TILE": self.tile})
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
        self._allocate_list(8 * n)        # a new resolution drops a list grown for the old one

    def _allocate_list(self, capacity):
        self.list_capacity = int(capacity)
        self.tile_prims = zeros(self.queue, self.list_capacity, np.int32)

    def publish(self, res):
        res.buffers.update(tile_counts=self.tile_counts, tile_offsets=self.tile_offsets, tile_prims=self.tile_prims)
        res.values.update(tile_list_capacity=self.list_capacity, tiles_x=self.tiles_x, tiles_y=self.tiles_y)

    def run(self, res):
        w, h = res["width"], res["height"]
        self.tile_counts.fill(0)
        self.tile_cursor.fill(0)
        cap = res["prim_capacity"]
        gsize = (round_up(cap, 64),)
        common = (res["prims"].data, res["prim_total"].data, np.int32(cap), np.int32(w), np.int32(h),
                  np.int32(self.tiles_x))
        self.count_kernel(self.queue, gsize, None, *common, self.tile_counts.data)
        self.scan(self.tile_counts, self.tile_offsets, self.total, queue=self.queue)
        self.fill_kernel(self.queue, gsize, None, *common, self.tile_offsets.data, self.tile_cursor.data,
                         np.int32(self.list_capacity), self.tile_prims.data)

    def overflows(self):
        return [Overflow("tile_prims", self.total, self.list_capacity)]

    def grow(self, name, needed):
        self._allocate_list(round_up(needed + needed // 4, 4096))
