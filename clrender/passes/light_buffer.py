"""Light buffer pass (kernels/light_buffer.cl): pass 2 of the light pre-pass pipeline
(docs/variants.md). From the thin G-buffer (depth, normal, specular power) and the tiled light
lists it accumulates, per pixel, the diffuse light D (RGB) and the specular light S (RGB, or its
luminance with `light_buffer_specular="luminance"`), specular intensity left to the material
pass. The lights' arguments, the sun and the shadow maps are ShadePass's."""
from __future__ import annotations

import numpy as np

from clrender.passes.base import empty
from clrender.passes.ibl import ENV_OUTPUTS
from clrender.passes.shade import ShadePass

PRECISIONS = {"float32": (np.float32, 0), "float16": (np.float16, 1)}


def light_buffer_planes(config) -> int:
    """Planes of the light buffer: D.rgb + S.rgb, or D.rgb + S luminance; with the glTF BRDF
    (shading "auto") its third sum T after them, RGB or luminance (kernels/brdf.h)."""
    rgb = config.light_buffer_specular == "rgb"
    return (6 if rgb else 4) + (gltf_sums(config) * (3 if rgb else 1))


def gltf_sums(config) -> int:
    """LB_GLTF: whether the light buffer holds the glTF BRDF's third sum."""
    return int(config.shading == "auto")


class LightBufferPass(ShadePass):
    name = "light_buffer"
    outputs = ("light_buffer", "light_count", "shadow", "shadow_planes", "light_env")

    @classmethod
    def runs(cls, config):
        return config.pipeline == "light_prepass"

    @classmethod
    def buffer_bytes(cls, width, height, config, scene=None):
        px = width * height
        return {"light_buffer": light_buffer_planes(config) * PRECISIONS[config.light_buffer_precision][0](0).itemsize
                * px, "light_buffer.light_count": 4 * px, "light_buffer.light_pairs": 8 * px + 16}

    def __init__(self, device, config, ortho: bool = False):
        super().__init__(device, config, ortho)
        self.inputs = tuple(i for i in self.inputs if i not in ("srgb_lut", "ao") + ENV_OUTPUTS)
        self.dtype = PRECISIONS[config.light_buffer_precision][0]
        self.planes = light_buffer_planes(config)

    def _build_kernel(self, device, config):
        return device.kernel("light_buffer.cl", "light_buffer",
                             {**self._light_defines(config),
                              "SPECULAR_RGB": int(config.light_buffer_specular == "rgb"),
                              "LB_HALF": PRECISIONS[config.light_buffer_precision][1], "LB_GLTF": gltf_sums(config)})

    def allocate(self, width, height):
        self.tiles_x, self.tiles_y = -(-width // self.tile), -(-height // self.tile)
        self.light_buffer = empty(self.queue, self.planes * width * height, self.dtype)
        self.light_count = empty(self.queue, width * height, np.int32)
        self.light_pairs = empty(self.queue, 2 * width * height, np.int32)    # evaluated, useful per pixel

    def _publish_output(self, res):
        res.buffers["light_buffer"] = self.light_buffer      # the material pass makes the colour

    def run(self, res):
        t = self.tile
        offsets, counts, lists, capacity, _ = self._lists(res)
        self._clear_shadow(res)
        self.kernel(self.queue, (self.tiles_x * t // self.vec, self.tiles_y * t), (t // self.vec, t),
                    res["gbuffer"].data, np.int32(res["width"]), np.int32(res["height"]), np.float32(res["far"]),
                    res["camera_params"].data, res["lights"].data, np.int32(res["n_lights"]),
                    offsets.data, counts.data, lists.data, np.int32(capacity), np.int32(self.tiles_x),
                    *self._shadow_args(res), res["tri_material"].data, res["materials"].data,
                    np.int32(res["gltf_scene"]), self.light_buffer.data, self.light_count.data, self.shadow.data,
                    self.light_pairs.data)
        self.pair_sum(self.light_pairs, res["width"] * res["height"], self.queue)
