"""The deferred pipeline: wires passes by resource name, allocates buffers once per
resolution, builds programs once, times every pass with OpenCL profiling, and handles
buffers whose size is known only on the device (count, grow, render again)."""
from __future__ import annotations

import numpy as np
import pyopencl as cl
import pyopencl.array as cla

from . import gbuffer as layout
from .passes import BinningPass, GBufferPass, RasterPass, Resources, SetupPass

MAX_RETRIES = 8


class Pipeline:
    def __init__(self, device, config):
        self.device = device
        self.config = config
        self.queue = device.queue
        self.passes = [SetupPass(device, config), BinningPass(device, config),
                       RasterPass(device, config), GBufferPass(device, config)]
        self._check_wiring()
        self.size = None
        self.view_proj = cla.zeros(self.queue, 16, np.float32)
        self.prev_view_proj = cla.zeros(self.queue, 16, np.float32)

    def _check_wiring(self):
        produced = {"positions", "normals", "uvs", "triangles", "tri_material", "materials", "texels",
                    "srgb_lut", "tex_infos", "tex_levels", "n_tris", "view_proj", "prev_view_proj",
                    "near", "far", "width", "height", "has_prev", "tiles_x", "tiles_y"}
        for p in self.passes:
            missing = set(p.inputs) - produced
            if missing:
                raise RuntimeError(f"pass {p.name} reads {sorted(missing)} before any pass writes it")
            produced |= set(p.outputs)

    def resize(self, width, height):
        if self.size != (width, height):
            for p in self.passes:
                p.allocate(width, height)
            self.size = (width, height)

    def render(self, scene_res: Resources, camera, width, height, prev_camera=None):
        """Run every pass; returns (G-buffer planes (P,H,W) uint32, stats dict)."""
        self.resize(width, height)
        vp = camera.view_projection(width, height).astype(np.float32)
        self.view_proj.set(np.ascontiguousarray(vp).reshape(-1), queue=self.queue)
        prev = prev_camera.view_projection(width, height).astype(np.float32) if prev_camera else vp
        self.prev_view_proj.set(np.ascontiguousarray(prev).reshape(-1), queue=self.queue)
        res = Resources(buffers=dict(scene_res.buffers), values=dict(scene_res.values))
        res.buffers.update(view_proj=self.view_proj, prev_view_proj=self.prev_view_proj)
        res.values.update(width=width, height=height, near=camera.near, far=camera.far,
                          has_prev=int(prev_camera is not None))
        for p in self.passes:
            p.prepare_scene(scene_res)

        retries = 0
        while True:
            timings = []
            for p in self.passes:
                p.publish(res)
                start = cl.enqueue_marker(self.queue)
                p.run(res)
                timings.append((p.name, start, cl.enqueue_marker(self.queue)))
            grown = self._grow_overflowing()
            if not grown:
                break
            retries += 1
            if retries > MAX_RETRIES:
                raise RuntimeError(f"buffers kept overflowing after {MAX_RETRIES} retries: {grown}")

        planes = res["gbuffer"].get(queue=self.queue).reshape(len(layout.PLANES), height, width)
        stats = {f"{name}_ms": (end.profile.end - start.profile.start) * 1e-6 for name, start, end in timings}
        stats["total_ms"] = sum(stats.values())
        stats.update(self.passes[0].triangle_stats())
        stats["prims"] = int(self.passes[0].prim_total.get(queue=self.queue)[0])
        stats["tile_entries"] = int(self.passes[1].total.get(queue=self.queue)[0])
        stats["tile_size"] = self.config.tile_size
        stats["retries"] = retries
        return planes, stats

    def _grow_overflowing(self) -> list:
        grown = []
        for p in self.passes:
            for ov in p.overflows():
                total = int(ov.total.get(queue=self.queue)[0])
                if total > ov.capacity:
                    p.grow(ov.name, total)
                    grown.append((ov.name, total, ov.capacity))
                    # Later passes consumed a truncated buffer: everything is redone.
                    return grown
        return grown
