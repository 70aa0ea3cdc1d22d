"""Material pass (kernels/material.cl): pass 3 of the light pre-pass pipeline (docs/variants.md).
The second geometry pass's visible surfaces (base colour × texture, specular intensity, from the
materials) times the light buffer: color = albedo·(ambient·ao + D) + s·S. With `msaa=N` the
raster ran at N sub-samples (setup.cl's sample offsets) and each sample is combined with the
pixel's light buffer, then averaged: the report's anti-aliasing on the colour. Writes the
albedo/specular plane of the G-buffer (an AOV) from the pixel centre's surface."""
from __future__ import annotations

import numpy as np

from .. import capabilities
from .. import gbuffer as layout
from .base import SCENE_INPUTS, RenderPass, empty, round_up, scene_args, view_defines
from .ibl import ENV_OUTPUTS, env_kernel_args
from .light_buffer import PRECISIONS, gltf_sums
from .second_geometry import sample_offsets


AOV_PLANES = ("albedo_spec", "emissive_occlusion")     # the planes the light pre-pass's G-buffer lacks


class MaterialPass(RenderPass):
    name = "material"
    outputs = ("color",)

    def __init__(self, device, config, samples: int = 1, ortho: bool = False):
        """samples: how many sub-sample visibility buffers run() combines; sample s reads
        res[f"vis_prim_{s}"] and res[f"prims_{s}"] (s = 0 only: "vis_prim", "prims").
        ortho: orthographic prims (surface_vec.h ORTHO)."""
        super().__init__(device, config)
        self.samples = samples
        self.vec = capabilities.pixel_vector_width(device.cl_device)
        self.inputs = ("light_buffer", "gbuffer") + SCENE_INPUTS + ("srgb_encode", "ambient", "camera_params") + \
            ENV_OUTPUTS + (
            ("ao",) if config.ssao else ()) + (
            ("vis_prim", "prims") if samples == 1 else
            tuple(n for s in range(samples) for n in (f"vis_prim_{s}", f"prims_{s}")) + ("vis_prim", "prims"))
        self.kernel = device.kernel("material.cl", "material", {
            **layout.kernel_defines(), "VEC": self.vec, "SSAO": int(config.ssao),
            "SPECULAR_RGB": int(config.light_buffer_specular == "rgb"),
            "LB_HALF": PRECISIONS[config.light_buffer_precision][1], "LB_GLTF": gltf_sums(config),
            "GB_WRITE": layout.plane_mask(AOV_PLANES), **view_defines(ortho)})

    def allocate(self, width, height):
        self.color = empty(self.queue, 3 * width * height, np.float32)
        self.spread = empty(self.queue, 3 * width * height if self.samples > 2 else 1, np.float32)
        self.no_ao = empty(self.queue, 1, np.float32)

    def publish(self, res):
        res.buffers["color"] = self.color

    def run(self, res):
        w, h = res["width"], res["height"]
        gsize = (round_up(-(-w * h // self.vec), 64),)
        ao = res["ao"] if self.config.ssao else self.no_ao
        for s, (dx, dy) in enumerate(sample_offsets(self.samples)):
            vis, prims = (("vis_prim", "prims") if self.samples == 1 else (f"vis_prim_{s}", f"prims_{s}"))
            write_aov = 0 if s else (1 if self.samples == 1 else 2)
            self.kernel(self.queue, gsize, (64,), res[vis].data, np.int32(w), np.int32(h),
                        *scene_args(res, res[prims]), res["srgb_encode"].data, res["light_buffer"].data,
                        np.float32(res["ambient"]), ao.data, np.int32(s), np.int32(self.samples), np.int32(dx), np.int32(dy),
                        np.int32(write_aov), res["camera_params"].data, *env_kernel_args(res), res["vis_prim"].data, res["prims"].data, self.color.data,
                        self.spread.data, res["gbuffer"].data)
