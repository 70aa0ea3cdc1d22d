"""G-buffer pass (kernels/gbuffer.cl): resolve visibility into the packed G-buffer."""
from __future__ import annotations

import numpy as np

from .. import capabilities
from .. import gbuffer as layout
from .base import RenderPass, empty, round_up


class GBufferPass(RenderPass):
    name = "gbuffer"
    inputs = ("vis_depth", "vis_prim", "prims", "positions", "normals", "uvs", "triangles", "materials",
              "texels", "srgb_lut", "srgb_encode", "tex_infos", "tex_levels", "prev_view_proj")
    outputs = ("gbuffer",)

    def __init__(self, device, config):
        super().__init__(device, config)
        self.vec = capabilities.pixel_vector_width(device.cl_device)
        self.kernel = device.kernel("gbuffer.cl", "gbuffer_resolve", {**layout.kernel_defines(), "VEC": self.vec})

    def allocate(self, width, height):
        self.gbuffer = empty(self.queue, len(layout.PLANES) * width * height, np.uint32)

    def publish(self, res):
        res.buffers["gbuffer"] = self.gbuffer

    def run(self, res):
        w, h = res["width"], res["height"]
        self.kernel(self.queue, (round_up(-(-w * h // self.vec), 64),), (64,),
                    res["vis_depth"].data, res["vis_prim"].data, res["prims"].data,
                    np.int32(w), np.int32(h), np.float32(res["far"]),
                    res["positions"].data, res["normals"].data, res["uvs"].data, res["triangles"].data,
                    res["materials"].data, res["texels"].data, res["srgb_lut"].data, res["srgb_encode"].data,
                    res["tex_infos"].data, res["tex_levels"].data,
                    res["prev_view_proj"].data, np.int32(res["has_prev"]), self.gbuffer.data)
