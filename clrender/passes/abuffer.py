"""A-buffer pass (kernels/fragments.cl `fragment_fill`, kernels/abuffer.cl): per-pixel lists of
the transparent fragments (list offsets by prefix sum of the fragments pass's counts), sorted,
shaded with the tile light lists and blended front to back (docs/transparency.md).

The fragment buffer has no cap: its total is read back after the frame and, when it exceeds
the capacity, the buffer grows (after a check against the device's memory) and the frame is
rendered again. `max_fragments_per_pixel` = K bounds every list to the K nearest fragments.
A scene with transmissive materials resolves with forward.h's TRANSMISSION build, which also
writes the tx planes (TX_PLANES: per-channel transmittance, the lookup behind, the nearest
transmissive depth), allocated at its first frame of a size and published as "tx_planes"."""
from __future__ import annotations

import numpy as np

from clrender.device import limits
from clrender.errors import DeviceMemoryError
from clrender.passes.base import Overflow, RenderPass, empty, round_up, scan_for, zeros
from clrender.passes.forward import (
    FORWARD_INPUTS, LAYER_PLANES, TX_PLANES, forward_args, forward_defines, forward_grid, forward_vec,
    scene_transmissive, transmissive, tx_args, variant_kernel)
from clrender.passes.fragments import walk_args, walk_global_size

SORT_GROUP = (8, 8)
BYTES_PER_FRAGMENT = 8          # frag_depth float + frag_prim int
MAX_FRAGMENTS = 2**31 - 1       # list offsets are 32-bit ints


class AbufferPass(RenderPass):
    name = "abuffer"
    inputs = ("t_prims", "t_tile_offsets", "t_tile_counts", "t_tile_prims", "t_tile_list_capacity", "t_tiles_x",
              "vis_depth", "frag_list_len") + FORWARD_INPUTS
    outputs = ("layers",)

    @classmethod
    def runs(cls, config):
        return config.transparency == "abuffer"

    @classmethod
    def buffer_bytes(cls, width, height, config, scene=None):
        px = width * height
        out = {"abuffer.offsets+layers": 32 * px,
               "abuffer.frag_depth+frag_prim": 8 * 2 * px}      # initial capacity: 2 fragments per pixel
        if scene_transmissive(scene):
            out["abuffer.tx_planes"] = 4 * TX_PLANES * px
        return out

    def __init__(self, device, config, fragments):
        super().__init__(device, config)
        self.walk = fragments               # the fragments pass: its tile shape and defines
        self.fill_kernel = device.kernel("fragments.cl", "fragment_fill", fragments.defines)
        defines = forward_defines(config, device, fragments.ortho)
        self.vec = forward_vec(config, device)
        self.sort_kernel = device.kernel("abuffer.cl", "abuffer_sort", defines)
        self.resolve_kernel = device.kernel("abuffer.cl", "abuffer_resolve", defines)
        self.scan = scan_for(device)
        self.total = zeros(self.queue, 1, np.int32)
        self.capacity = 0

    def allocate(self, width, height):
        n = width * height
        self.offsets = empty(self.queue, n, np.int32)
        self.layers = empty(self.queue, LAYER_PLANES * n, np.float32)
        self.tx_planes = None               # made at the first transmissive frame of this size
        if self.capacity < 2 * n:
            self._allocate_fragments(2 * n)

    def _allocate_fragments(self, capacity):
        self.capacity = int(capacity)
        self.frag_depth = self.frag_prim = None          # release before allocating
        self.frag_depth = empty(self.queue, self.capacity, np.float32)
        self.frag_prim = empty(self.queue, self.capacity, np.int32)

    def publish(self, res):
        res.buffers["layers"] = self.layers
        if transmissive(res):
            if self.tx_planes is None:
                self.tx_planes = empty(self.queue, TX_PLANES * self.offsets.size, np.float32)
            res.buffers["tx_planes"] = self.tx_planes

    def run(self, res):
        w, h = res["width"], res["height"]
        self.list_len = res["frag_list_len"]
        with self.timed("scan"):
            self.scan(res["frag_list_len"], self.offsets, self.total, size=w * h, queue=self.queue)
        t, vec = self.walk.tile, self.walk.vec
        with self.timed("fill"):
            self.fill_kernel(self.queue, walk_global_size(res, t, vec), (t // vec, t), *walk_args(res),
                             res["frag_list_len"].data, self.offsets.data, np.int32(self.capacity),
                             self.frag_depth.data, self.frag_prim.data)
        gx, gy = SORT_GROUP
        with self.timed("sort"):
            self.sort_kernel(self.queue, (round_up(w, gx), round_up(h, gy)), SORT_GROUP,
                             res["frag_list_len"].data, self.offsets.data, np.int32(self.capacity),
                             np.int32(w), np.int32(h), self.frag_depth.data, self.frag_prim.data)
        with self.timed("resolve"):
            variant_kernel(self, "resolve_kernel", res)(self.queue, *forward_grid(w, h, self.vec),
                                res["frag_list_len"].data, self.offsets.data, np.int32(self.capacity),
                                self.frag_depth.data, self.frag_prim.data, *forward_args(res, res["t_prims"]),
                                self.layers.data, *tx_args(res))

    def overflows(self):
        self._check_total()
        return [Overflow("fragments", self.total, self.capacity)]

    def _check_total(self):
        """The 32-bit prefix sum wraps past 2^31 fragments: when the frame could hold that many
        (tile-list entries × pixels per tile), count them exactly on the host and refuse."""
        entries = int(self.walk.binning.total.get(queue=self.queue)[0])
        if entries * self.walk.tile ** 2 <= MAX_FRAGMENTS:
            return
        total = int(self.list_len.get(queue=self.queue).sum(dtype=np.int64))
        if total > MAX_FRAGMENTS:
            raise DeviceMemoryError(f"the frame has {total} transparent fragments; the A-buffer holds at most "
                                    f"{MAX_FRAGMENTS} (2^31 - 1): render at a smaller size or set "
                                    f"max_fragments_per_pixel")

    def grow(self, name, needed):
        capacity = min(round_up(needed + needed // 4, 4096), MAX_FRAGMENTS)
        limits.check_buffer(self.device, "the A-buffer's fragment lists", needed, BYTES_PER_FRAGMENT, capacity)
        self._allocate_fragments(capacity)
