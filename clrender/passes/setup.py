"""Setup pass (kernels/setup.cl): transform, clip, cull and snap triangles into prims.

With RenderConfig.chunk_cull (default) the pass first runs its own ChunkCullPass
(clrender/passes/chunk_cull.py) and setup.cl is built with CHUNK_CULL=1: count, prefix sum and
emit run over chunk slots, so only the triangles of chunks the view can see are read and set
up; the cull's time is part of this pass's. The prims (and their order) are the same."""
from __future__ import annotations

import numpy as np
import pyopencl as cl

from clrender.abi import structs
from clrender.passes.base import Overflow, RenderPass, empty, fill_zero, launch_1d, round_up, scan_for, zeros
from clrender.passes.chunk_cull import CHUNK, ChunkCullPass, chunk_defines, n_chunks


SELECT = {"all": 0, "opaque": 1, "blend": 2, "dither": 3}


def per_triangle_bytes(t: int, config) -> int:
    """The per-triangle buffers of prepare_scene: counts, offsets, statuses and staged prims; with
    the chunk cull they are per chunk slot, plus the cull's chunk lists (the chunk boxes, shared by
    every view, are counted once: buffer_bytes' "chunk_cull.bounds")."""
    prim = structs.prim_dtype.itemsize
    if not getattr(config, "chunk_cull", False):
        return (9 + prim) * t
    c = n_chunks(t)
    return (8 + prim) * c * CHUNK + t + 8 * c + (5 * c + 4)


class SetupPass(RenderPass):
    name = "setup"
    inputs = ("positions", "triangles", "tri_material", "materials", "view_proj", "n_tris", "near")
    outputs = ("prims", "prim_total", "prim_capacity", "tri_status")

    @classmethod
    def buffer_bytes(cls, width, height, config, scene=None):
        """Room for 1024 prims before a scene; for one, the per-triangle buffers and n + n/8 prims
        (clipping can add some; grown on demand), and the chunk cull's boxes (shared by every view)."""
        prim = structs.prim_dtype.itemsize
        if scene is None:
            return {"setup.prims": prim * 1024}
        t = scene.triangle_count
        out = {"setup.per_triangle": per_triangle_bytes(t, config), "setup.prims": prim * max(1024, t + t // 8)}
        if getattr(config, "chunk_cull", False):
            out["chunk_cull.bounds"] = 32 * n_chunks(t)
        return out

    def __init__(self, device, config, ortho: bool = False, select: str = "all", samples: int = 1,
                 status: bool = True):
        """ortho: the view is orthographic (a sun shadow cascade); see setup.cl ORTHO.
        select: which triangles become prims (setup.cl SELECT_*): "all", "opaque" (BLEND
        triangles are left to the transparency pass), "blend" (only those), "dither" (all;
        BLEND prims get the screen-door flag). samples: keep prims that may cover any of the
        msaa sub-sample points (kernels/samples.h, docs/raster_contract.md §10), not only a centre.
        status=False (shadow maps, whose statuses nothing reads): with the chunk cull, the
        triangles of culled chunks keep a stale tri_status and triangle_stats() refuses."""
        super().__init__(device, config)
        self.select = np.int32(SELECT[select])
        self.write_status = bool(status)
        self.cull = ChunkCullPass(device, config, ortho=ortho) if getattr(config, "chunk_cull", False) else None
        defines = {"ORTHO": 1} if ortho else {}
        if self.cull is not None:
            defines = {**chunk_defines(ortho), "CHUNK_CULL": 1}
        if samples > 1:
            defines = {**defines, "SAMPLES": int(samples)}
        self.count_kernel = device.kernel("setup.cl", "setup_count", defines)
        self.emit_kernel = device.kernel("setup.cl", "setup_emit", defines)
        self.checked_group = self.cull is None     # the chunk cull's work-group, checked once built
        self.scan = scan_for(device)
        self.n_tris = -1
        self.slots = 0
        self.capacity = 0
        self.prim_total = zeros(self.queue, 1, np.int32)

    def prepare_scene(self, scene_res):
        n = scene_res["n_tris"]
        if self.cull is not None:
            self.cull.prepare_scene(scene_res)
        if n != self.n_tris:
            self.n_tris = n
            # per triangle, or per chunk slot with the cull (a partial last chunk's slots too)
            self.slots = n_chunks(n) * CHUNK if self.cull is not None else n
            self.prim_count = zeros(self.queue, self.slots, np.int32)
            self.prim_offset = zeros(self.queue, self.slots, np.int32)     # with the cull: offset in its chunk
            if self.cull is not None:
                self.chunk_prims = zeros(self.queue, n_chunks(n), np.int32)
                self.chunk_offset = zeros(self.queue, n_chunks(n), np.int32)
            self.status = zeros(self.queue, n, np.uint8)
            self.staged = empty(self.queue, self.slots, structs.prim_dtype)   # first prim of each triangle (slot)
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

    def _check_group(self):
        """The chunk cull runs one chunk per work-group: the built kernel must allow that many."""
        if self.count_kernel.get_work_group_info(cl.kernel_work_group_info.WORK_GROUP_SIZE,
                                                 self.device.cl_device) < CHUNK:
            raise RuntimeError(f"setup.cl's chunk cull needs work-groups of {CHUNK} (one chunk) and "
                               f"{self.device.name} allows fewer for setup_count: set RenderConfig chunk_cull=False")
        self.checked_group = True

    def run(self, res):
        if not self.checked_group:
            self._check_group()
        n = self.n_tris
        if n == 0:
            fill_zero(self.prim_total, self.queue)
            return
        w, h = res["width"], res["height"]
        common = (res["positions"].data, res["triangles"].data, res["tri_material"].data,
                  res["materials"].data, res["view_proj"].data, np.int32(n), np.int32(w), np.int32(h),
                  np.float32(res["near"]), self.select)
        if self.cull is not None:
            self._run_slots(res, common)
            return
        gsize, lsize = launch_1d(n)
        self.count_kernel(self.queue, gsize, lsize, *common, self.prim_count.data, self.status.data,
                          self.staged.data)
        self.scan(self.prim_count, self.prim_offset, self.prim_total, size=n, queue=self.queue)
        self.emit_kernel(self.queue, gsize, lsize, *common, self.prim_offset.data, self.prim_count.data,
                         self.staged.data, np.int32(self.capacity), self.prims.data)

    def _run_slots(self, res, common):
        """With the chunk cull (setup.cl CHUNK_CULL): the cull, then count and emit over chunk
        slots, the prefix sum over the chunks' prim totals."""
        c = self.cull
        c.run(res)
        self.count_kernel(self.queue, (self.slots,), (CHUNK,), *common, self.prim_count.data, self.status.data,
                          self.staged.data, c.chunk_list.data, c.chunk_count.data, c.chunk_status.data,
                          np.int32(self.write_status), self.prim_offset.data, self.chunk_prims.data)
        self.scan(self.chunk_prims, self.chunk_offset, self.prim_total, size=c.n_chunks, queue=self.queue)
        self.emit_kernel(self.queue, *launch_1d(self.slots), *common, self.prim_offset.data,
                         self.prim_count.data, self.staged.data, np.int32(self.capacity), self.prims.data,
                         c.chunk_list.data, c.chunk_count.data, self.chunk_offset.data, np.int32(self.slots))

    def overflows(self):
        return [Overflow("prims", self.prim_total, self.capacity)]

    def grow(self, name, needed):
        self._allocate_prims(round_up(needed + needed // 4, 1024))

    def triangle_stats(self) -> dict:
        """Per-reason triangle counts from the status bytes (reads back T bytes). Triangles of
        culled chunks count under the reason setup would have given them; `chunks` is the
        number of chunks and `culled_chunks` those the chunk cull skipped (0 without the cull)."""
        if self.cull is not None and not self.write_status:
            raise RuntimeError("this setup does not write the statuses of culled chunks (status=False)")
        chunks = {"chunks": n_chunks(max(self.n_tris, 0)), "culled_chunks": 0}
        if self.n_tris <= 0:
            return {"triangles_in": 0, **{v: 0 for k, v in structs.STATUS_NAMES.items() if k}, "clipped": 0,
                    **chunks}
        if self.cull is not None:
            chunks["culled_chunks"] = chunks["chunks"] - self.cull.visible_chunks()
        status = self.status.get(queue=self.queue)[: self.n_tris]
        counts = np.bincount(status & 15, minlength=8)
        out = {"triangles_in": int(self.n_tris)}
        for code, name in structs.STATUS_NAMES.items():
            if code:
                out[name] = int(counts[code])
        out["clipped"] = int(np.count_nonzero(status & structs.STATUS_CLIPPED))
        out.update(chunks)
        return out
