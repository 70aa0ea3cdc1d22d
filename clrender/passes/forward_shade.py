"""Forward shading pass (kernels/forward_shade.cl): pass 2 of the light-indexed pipeline
(docs/variants.md). After the depth pre-pass, the tiled light culling and a second raster, each
visible fragment is shaded with its tile's light list and its material directly; the G-buffer
planes the pre-pass did not write (albedo/specular, normal/power, velocity) are written as AOVs.
The lights' arguments, the sun and the shadow maps are ShadePass's."""
from __future__ import annotations

import numpy as np

from clrender.abi import gbuffer as layout
from clrender.passes.base import SCENE_INPUTS, SceneKernel
from clrender.passes.ibl import env_kernel_args
from clrender.passes.shade import ShadePass

AOV_PLANES = tuple(p for p in layout.PLANES if p not in layout.DEPTH_PLANES)


class ForwardShadePass(ShadePass):
    name = "forward_shade"

    @classmethod
    def runs(cls, config):
        return config.pipeline == "light_indexed"

    def __init__(self, device, config, ortho: bool = False):
        super().__init__(device, config, ortho)
        self.inputs = tuple(i for i in self.inputs if i != "ao") + (
            "vis_prim", "vis_depth", "prims") + SCENE_INPUTS + ("srgb_encode", "prev_view_proj")

    def _build_kernel(self, device, config):
        return SceneKernel(device, "forward_shade.cl", "forward_shade",
                           {**self._light_defines(config), "GB_WRITE": layout.plane_mask(AOV_PLANES)})

    def run(self, res):
        t = self.tile
        offsets, counts, lists, capacity, _ = self._lists(res)
        self._clear_shadow(res)
        prev_positions = res.buffers.get("prev_positions")          # only when some object moved
        has_prev = int(res["has_prev"] or prev_positions is not None)
        self.kernel(self.queue, (self.tiles_x * t // self.vec, self.tiles_y * t), (t // self.vec, t),
                    res["vis_prim"].data, res["vis_depth"].data,
                    np.int32(res["width"]), np.int32(res["height"]), np.float32(res["far"]),
                    *self.kernel.scene_args(res, res["prims"]), res["srgb_encode"].data, res["prev_view_proj"].data,
                    (prev_positions if prev_positions is not None else res["positions"]).data, np.int32(has_prev),
                    res["camera_params"].data, res["lights"].data, np.int32(res["n_lights"]),
                    np.float32(res["ambient"]), offsets.data, counts.data, lists.data, np.int32(capacity),
                    np.int32(self.tiles_x), *self._shadow_args(res), *env_kernel_args(res), self.color.data,
                    res["gbuffer"].data,
                    self.light_count.data, self.shadow.data, self.light_pairs.data)
        self.pair_sum(self.light_pairs, res["width"] * res["height"], self.queue)
