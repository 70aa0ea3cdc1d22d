"""Transmission pass (kernels/transmission.cl): the mip chain of the opaque HDR colour, which the
composite samples behind transmissive surfaces (KHR_materials_transmission: the scene behind,
refracted and blurred by roughness, as the Khronos Sample Renderer does; docs/transmission.md).

It runs after the opaque shading and its surface layers and before the transparent fragments,
so the chain holds the opaque surfaces only. It exists whenever the composite does but runs,
builds its program and allocates, only for a scene with transmissive materials (`active`).
Level 0 is the colour buffer itself; levels 1.. (down to 1×1) are packed in `opaque_mips`,
located by the level table `opaque_mip_levels` (int[levels][4]: offset in floats, w, h, 0;
level 0's offset is into the colour)."""
from __future__ import annotations

import numpy as np
import pyopencl.array as cla

from clrender.passes.base import RenderPass, empty, launch_2d
from clrender.passes.forward import scene_transmissive


def mip_levels(width: int, height: int) -> list[tuple[int, int, int]]:
    """(offset, w, h) of every level of a width × height image's chain: level 0 the image itself,
    then ceil-halved sizes down to 1×1, packed 3 planes each (offsets into opaque_mips)."""
    out, offset, w, h = [(0, width, height)], 0, width, height
    while w > 1 or h > 1:
        w, h = -(-w // 2), -(-h // 2)
        out.append((offset, w, h))
        offset += 3 * w * h
    return out


def mips_floats(width: int, height: int) -> int:
    """Floats of opaque_mips (levels 1..; one placeholder for a 1×1 image, which has none)."""
    return max(sum(3 * w * h for _, w, h in mip_levels(width, height)[1:]), 1)


class TransmissionPass(RenderPass):
    name = "transmission"
    inputs = ("color",)
    outputs = ("opaque_mips", "opaque_mip_levels", "opaque_mip_count")

    @classmethod
    def runs(cls, config):
        return config.transparency != "screen_door"     # the screen door neither refracts nor blurs

    @classmethod
    def buffer_bytes(cls, width, height, config, scene=None):
        if not scene_transmissive(scene):
            return {}
        return {"transmission.opaque_mips": 4 * mips_floats(width, height),
                "transmission.mip_table": 16 * len(mip_levels(width, height))}

    def __init__(self, device, config):
        super().__init__(device, config)
        self.kernel = device.kernel("transmission.cl", "mip_level")
        self.size = None
        self.mips = self.table = None

    def active(self, res):
        # (the upload always sets it; absent only in Resources made by hand)
        return res.values.get("transmissive_materials", 0) > 0

    def allocate(self, width, height):
        self.size = (width, height)
        self.mips = self.table = None           # made at the first transmissive frame of this size
        self.levels = mip_levels(width, height)

    def publish(self, res):
        if not self.active(res):
            return
        if self.mips is None:
            self.mips = empty(self.queue, mips_floats(*self.size), np.float32)
            table = np.zeros((len(self.levels), 4), np.int32)
            table[:, :3] = self.levels
            self.table = cla.to_device(self.queue, table.reshape(-1))
        res.buffers["opaque_mips"] = self.mips
        res.buffers["opaque_mip_levels"] = self.table
        res.values["opaque_mip_count"] = len(self.levels)

    def run(self, res):
        src, src_offset = res["color"], 0           # the opaque colour (the composite has not replaced it)
        with self.timed("mips"):
            for (_, sw, sh), (offset, w, h) in zip(self.levels, self.levels[1:]):
                self.kernel(self.queue, *launch_2d(w, h), src.data, np.int32(src_offset), np.int32(sw),
                            np.int32(sh), self.mips.data, np.int32(offset), np.int32(w), np.int32(h))
                src, src_offset = self.mips, offset
