"""Setup pass (kernels/setup.cl): transform, clip, cull and snap triangles into prims."""
from __future__ import annotations

import numpy as np

from .. import structs
from .base import Overflow, RenderPass, empty, round_up, scan_for, zeros


SELECT = {"all": 0, "opaque": 1, "blend": 2, "dither": 3}


class SetupPass(RenderPass):
    name = "setup"
    inputs = ("positions", "triangles", "tri_material", "materials", "view_proj", "n_tris", "near")
    outputs = ("prims", "prim_total", "prim_capacity", "tri_status")

    def __init__(self, device, config, ortho: bool = False, select: str = "all", sample: tuple = (0, 0)):
        """ortho: the view is orthographic (a sun shadow cascade); see setup.cl ORTHO.
        select: which triangles become prims (setup.cl SELECT_*): "all", "opaque" (BLEND
        triangles are left to the transparency pass), "blend" (only those), "dither" (all;
        BLEND prims get the screen-door flag). sample: (dx, dy) in 1/256 pixel, the sub-sample
        the raster covers instead of the pixel centre (docs/raster_contract.md §10)."""
        super().__init__(device, config)
        self.select = np.int32(SELECT[select])
        self.sample = tuple(np.int32(v) for v in sample)
        defines = {"ORTHO": 1} if ortho else None
        self.count_kernel = device.kernel("setup.cl", "setup_count", defines)
        self.emit_kernel = device.kernel("setup.cl", "setup_emit", defines)
        self.scan = scan_for(device)
        self.n_tris = -1
        self.capacity = 0
        self.prim_total = zeros(self.queue, 1, np.int32)

    def prepare_scene(self, scene_res):
        n = scene_res["n_tris"]
        if n != self.n_tris:
            self.n_tris = n
            self.prim_count = zeros(self.queue, n, np.int32)
            self.prim_offset = zeros(self.queue, n, np.int32)
            self.status = zeros(self.queue, n, np.uint8)
            self.staged = empty(self.queue, n, structs.prim_dtype)   # first prim of each triangle
            # Most triangles yield at most one prim; clipping can yield more (grown on demand).
            self._allocate_prims(max(1024, n + n // 8))

    def reserve(self, capacity):
        """Start from room for `capacity` prims (a setup that keeps a known subset of triangles)."""
        if capacity != self.capacity:
            self._allocate_prims(capacity)

    def _allocate_prims(self, capacity):
        self.capacity = int(capacity)
        self.prims = empty(self.queue, self.capacity, structs.prim_dtype)

    def publish(self, res):
        res.buffers.update(prims=self.prims, prim_total=self.prim_total, tri_status=self.status)
        res.values["prim_capacity"] = self.capacity

    def run(self, res):
        n = self.n_tris
        if n == 0:
            self.prim_total.fill(0)
            return
        w, h = res["width"], res["height"]
        common = (res["positions"].data, res["triangles"].data, res["tri_material"].data,
                  res["materials"].data, res["view_proj"].data, np.int32(n), np.int32(w), np.int32(h),
                  np.float32(res["near"]), self.select, *self.sample)
        gsize = (round_up(n, 64),)
        self.count_kernel(self.queue, gsize, None, *common, self.prim_count.data, self.status.data,
                          self.staged.data)
        self.scan(self.prim_count, self.prim_offset, self.prim_total, size=n, queue=self.queue)
        self.emit_kernel(self.queue, gsize, None, *common, self.prim_offset.data, self.prim_count.data,
                         self.staged.data, np.int32(self.capacity), self.prims.data)

    def overflows(self):
        return [Overflow("prims", self.prim_total, self.capacity)]

    def grow(self, name, needed):
        self._allocate_prims(round_up(needed + needed // 4, 1024))

    def triangle_stats(self) -> dict:
        """Per-reason triangle counts from the status bytes (reads back T bytes)."""
        if self.n_tris <= 0:
            return {"triangles_in": 0, **{v: 0 for k, v in structs.STATUS_NAMES.items() if k}, "clipped": 0}
        status = self.status.get(queue=self.queue)[: self.n_tris]
        counts = np.bincount(status & 15, minlength=8)
        out = {"triangles_in": int(self.n_tris)}
        for code, name in structs.STATUS_NAMES.items():
            if code:
                out[name] = int(counts[code])
        out["clipped"] = int(np.count_nonzero(status & structs.STATUS_CLIPPED))
        return out
