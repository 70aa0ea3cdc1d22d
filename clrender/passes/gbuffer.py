"""G-buffer pass (kernels/gbuffer.cl): resolve visibility into the packed G-buffer.

Velocity reprojects each surface point into the previous frame: its camera (`prev_view_proj`,
motion when `has_prev`) and, for objects moved with `Scene.set_transform(..., previous=...)`, its
vertex positions (the scene upload's optional `prev_positions`; without it the current ones)."""
from __future__ import annotations

import numpy as np

from clrender.device import capabilities
from clrender.abi import gbuffer as layout
from clrender.passes.base import SCENE_INPUTS, RenderPass, SceneKernel, empty, round_up, view_defines


# Pixels per work-group (GB_TILE_W × GB_TILE_H blocks, kernels/gbuffer.cl): consecutive rows of a
# block sample the same texels while they are still in cache, unlike whole-row groups.
GB_TILE_W, GB_TILE_H = 32, 8


class GBufferPass(RenderPass):
    name = "gbuffer"
    inputs = ("vis_depth", "vis_prim", "prims") + SCENE_INPUTS + ("srgb_encode", "prev_view_proj")
    outputs = ("gbuffer",)

    @classmethod
    def buffer_bytes(cls, width, height, config, scene=None):
        return {"gbuffer": 4 * len(layout.PLANES) * width * height}

    def __init__(self, device, config, planes=layout.PLANES, ortho: bool = False):
        """planes: the G-buffer planes this pass writes (layout.PLANES names): all for the deferred
        pipeline, `THIN_PLANES` for the light pre-pass, `DEPTH_PLANES` for light-indexed. The
        others are left for a later pass to write as AOVs. ortho: orthographic prims (setup.cl ORTHO)."""
        super().__init__(device, config)
        self.vec = capabilities.pixel_vector_width(device.cl_device)
        self.planes = tuple(planes)
        defines = {**layout.kernel_defines(), "VEC": self.vec, "GB_WRITE": layout.plane_mask(self.planes),
                   "SURFACE_TEXTURES": int("albedo_spec" in self.planes),
                   "SURFACE_EXTRAS": int("emissive_occlusion" in self.planes), **view_defines(ortho)}
        self.kernel = SceneKernel(device, "gbuffer.cl", "gbuffer_resolve", defines)

    def allocate(self, width, height):
        self.gbuffer = empty(self.queue, len(layout.PLANES) * width * height, np.uint32)

    def publish(self, res):
        res.buffers["gbuffer"] = self.gbuffer

    def run(self, res):
        w, h = res["width"], res["height"]
        prev_positions = res.buffers.get("prev_positions")          # only when some object moved
        has_prev = int(res["has_prev"] or prev_positions is not None)
        if prev_positions is None:
            prev_positions = res["positions"]
        tw = max(GB_TILE_W // self.vec, 1)
        self.kernel(self.queue, (round_up(-(-w // self.vec), tw), round_up(h, GB_TILE_H)), (tw, GB_TILE_H),
                    res["vis_depth"].data, res["vis_prim"].data, np.int32(w), np.int32(h), np.float32(res["far"]),
                    *self.kernel.scene_args(res, res["prims"]), res["srgb_encode"].data,
                    res["prev_view_proj"].data, prev_positions.data, np.int32(has_prev), self.gbuffer.data)
