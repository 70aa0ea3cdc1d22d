"""Depth-peeling pass (kernels/fragments.cl `fragment_next_layer`, kernels/peel.cl): peel_layers
times, the nearest transparent fragment behind the previous layer is found per pixel, shaded
with the tile light lists and blended under the layers before it (docs/transparency.md). Each
layer walks the transparent prim lists again: the cost the report compares the A-buffer with.
Transmissive materials: the TRANSMISSION build and the tx planes, as in abuffer.py (carried
across the layers)."""
from __future__ import annotations

import numpy as np

from clrender.passes.base import RenderPass, empty
from clrender.passes.forward import (
    FORWARD_INPUTS, LAYER_PLANES, TX_PLANES, forward_args, forward_defines, forward_grid, forward_vec,
    scene_transmissive, transmissive, tx_args, variant_kernel)
from clrender.passes.fragments import walk_args, walk_global_size


class PeelPass(RenderPass):
    name = "peel"
    inputs = ("t_prims", "t_tile_offsets", "t_tile_counts", "t_tile_prims", "t_tile_list_capacity", "t_tiles_x",
              "vis_depth") + FORWARD_INPUTS
    outputs = ("layers",)

    @classmethod
    def runs(cls, config):
        return config.transparency == "depth_peeling"

    @classmethod
    def buffer_bytes(cls, width, height, config, scene=None):
        out = {"peel.layer+layers": 36 * width * height}
        if scene_transmissive(scene):
            out["peel.tx_planes"] = 4 * TX_PLANES * width * height
        return out

    def __init__(self, device, config, fragments):
        super().__init__(device, config)
        self.walk = fragments
        self.find_kernel = device.kernel("fragments.cl", "fragment_next_layer", fragments.defines)
        self.shade_kernel = device.kernel("peel.cl", "peel_shade", forward_defines(config, device, fragments.ortho))
        self.vec = forward_vec(config, device)

    def allocate(self, width, height):
        n = width * height
        self.layer_depth = empty(self.queue, n, np.float32)
        self.layer_prim = empty(self.queue, n, np.int32)
        self.layers = empty(self.queue, LAYER_PLANES * n, np.float32)
        self.tx_planes = None               # made at the first transmissive frame of this size

    def publish(self, res):
        res.buffers["layers"] = self.layers
        if transmissive(res):
            if self.tx_planes is None:
                self.tx_planes = empty(self.queue, TX_PLANES * self.layer_depth.size, np.float32)
            res.buffers["tx_planes"] = self.tx_planes

    def run(self, res):
        w, h = res["width"], res["height"]
        t, vec = self.walk.tile, self.walk.vec
        walk = walk_args(res)
        forward = forward_args(res, res["t_prims"])
        grid = forward_grid(w, h, self.vec)
        shade = variant_kernel(self, "shade_kernel", res)
        tx = tx_args(res)
        for layer in range(self.config.peel_layers):
            with self.timed("find"):
                self.find_kernel(self.queue, walk_global_size(res, t, vec), (t // vec, t), *walk,
                                 np.int32(layer), self.layer_depth.data, self.layer_prim.data)
            with self.timed("shade"):
                shade(self.queue, *grid, self.layer_depth.data, self.layer_prim.data, np.int32(layer), *forward,
                      self.layers.data, *tx)
