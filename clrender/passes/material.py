"""Material pass (kernels/material.cl): pass 3 of the light pre-pass pipeline (docs/variants.md).
The second geometry pass's visible surfaces (base colour × texture, specular intensity, from the
materials) times the light buffer: color = albedo·(ambient·ao + D) + s·S. With `msaa=N` the
raster ran at N sub-samples (docs/raster_contract.md §10) and each sample is combined with the
pixel's light buffer, then averaged: the report's anti-aliasing on the colour; a sample that
sees sample 0's prim is not evaluated again (material.cl material_samples). With one sample it
writes the G-buffer's surface planes (AOVs) from the pixel centre's surface; with msaa, pass 1's
G-buffer pass writes them (clrender/abi/gbuffer.py geometry_planes)."""
from __future__ import annotations

import numpy as np

from clrender.device import capabilities
from clrender.abi import gbuffer as layout
from clrender.passes.base import SCENE_INPUTS, RenderPass, SceneKernel, empty, round_up, view_defines
from clrender.passes.ibl import ENV_OUTPUTS, env_kernel_args
from clrender.passes.light_buffer import PRECISIONS, gltf_sums


SAMPLE_RUNS = 8        # runs of VEC pixels per work-item of material_samples (material.cl default)
AOV_PLANES = ("albedo_spec", "emissive_occlusion")     # the planes the light pre-pass's G-buffer lacks


class MaterialPass(RenderPass):
    name = "material"
    outputs = ("color",)

    @classmethod
    def runs(cls, config):
        return config.pipeline == "light_prepass"

    @classmethod
    def buffer_bytes(cls, width, height, config, scene=None):
        px, s = width * height, config.msaa
        return {"material.color+spread+deltas": 12 * px + (12 * px if s > 1 else 4) + max(12 * (s - 2) * px, 4)}

    def __init__(self, device, config, samples: int = 1, ortho: bool = False):
        """samples: how many sub-samples run() combines: plane s of res["msaa_vis_prims"] over
        res["msaa_prims"] (one sample: "vis_prim", "prims").
        ortho: orthographic prims (surface_vec.h ORTHO)."""
        super().__init__(device, config)
        self.samples = samples
        self.vec = capabilities.pixel_vector_width(device.cl_device)
        self.inputs = ("light_buffer", "gbuffer") + SCENE_INPUTS + ("srgb_encode", "ambient", "camera_params") + \
            ENV_OUTPUTS + (
            ("ao",) if config.ssao else ()) + (
            ("vis_prim", "prims") if samples == 1 else
            ("msaa_vis_prims", "msaa_prims"))
        defines = {
            **layout.kernel_defines(), "VEC": self.vec, "SSAO": int(config.ssao),
            "SPECULAR_RGB": int(config.light_buffer_specular == "rgb"),
            "LB_HALF": PRECISIONS[config.light_buffer_precision][1], "LB_GLTF": gltf_sums(config),
            "GB_WRITE": layout.plane_mask(AOV_PLANES), **view_defines(ortho)}
        self.kernel = SceneKernel(device, "material.cl", "material", defines)
        self.samples_kernel = SceneKernel(device, "material.cl", "material_samples", defines) if samples > 1 else None

    def allocate(self, width, height):
        self.color = empty(self.queue, 3 * width * height, np.float32)
        self.spread = empty(self.queue, 3 * width * height if self.samples > 1 else 1, np.float32)
        # c_s - c_0 of the samples before the last, for later samples that see the same prim
        self.deltas = empty(self.queue, max(3 * (self.samples - 2) * width * height, 1), np.float32)
        self.no_ao = empty(self.queue, 1, np.float32)

    def publish(self, res):
        res.buffers["color"] = self.color

    def run(self, res):
        w, h = res["width"], res["height"]
        ao = res["ao"] if self.config.ssao else self.no_ao
        shading = (res["srgb_encode"].data, res["light_buffer"].data, np.float32(res["ambient"]), ao.data)
        if self.samples == 1:
            vis, prims, write_aov = res["vis_prim"], res["prims"], 1
        else:                            # pass 1 wrote the surface planes (gbuffer.geometry_planes)
            vis, prims, write_aov = res["msaa_vis_prims"], res["msaa_prims"], 0
        gsize = (round_up(-(-w * h // self.vec), 64),)
        self.kernel(self.queue, gsize, (64,), vis.data, np.int32(w), np.int32(h), *self.kernel.scene_args(res, prims),
                    *shading, np.int32(self.samples), np.int32(write_aov), res["camera_params"].data, *env_kernel_args(res),
                    self.color.data, self.spread.data, res["gbuffer"].data)
        # samples s > 0: only the pixels where s sees another prim than sample 0 (material.cl)
        gsize = (round_up(-(-w * h // (self.vec * SAMPLE_RUNS)), 64),)
        for s in range(1, self.samples):
            self.samples_kernel(self.queue, gsize, (64,), vis.data, np.int32(w),
                                np.int32(h), *self.samples_kernel.scene_args(res, prims), *shading, np.int32(s), np.int32(self.samples),
                                res["camera_params"].data, *env_kernel_args(res), self.color.data, self.spread.data,
                                self.deltas.data)
