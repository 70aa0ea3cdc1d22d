"""SSAO pass (kernels/ssao.cl): the ambient-occlusion term that scales the ambient light.

In the pipeline only when `RenderConfig.ssao` is on; then the shade pass reads `ao`. With
`ssao_blur` the raw term goes to `ao_raw` and the blur pass (passes/ssao_blur.py) writes `ao`."""
from __future__ import annotations

import numpy as np

from clrender.device import capabilities
from clrender.abi import gbuffer as layout
from clrender.passes.base import RenderPass, empty, round_up, view_defines

PIXELS_PER_GROUP_X, GROUP_ROWS = 16, 8     # a work-group covers 16×8 pixels whatever VEC is


def work_group(vec: int) -> tuple[int, int]:
    """(work-items along x, rows) of the SSAO kernels' work-groups."""
    return max(PIXELS_PER_GROUP_X // vec, 1), GROUP_ROWS


def global_size(width: int, height: int, vec: int) -> tuple[int, int]:
    wx, wy = work_group(vec)
    return round_up(-(-width // vec), wx), round_up(height, wy)


class SsaoPass(RenderPass):
    name = "ssao"
    inputs = ("gbuffer", "camera_params", "far", "tan_x", "tan_y")

    @classmethod
    def runs(cls, config):
        return bool(config.ssao)                 # off: shade uses ao = 1

    @classmethod
    def buffer_bytes(cls, width, height, config, scene=None):
        return {"ssao.ao": 4 * width * height}

    def __init__(self, device, config, ortho: bool = False):
        """ortho: an orthographic camera (ssao.cl ORTHO: parallel view rays)."""
        super().__init__(device, config)
        self.outputs = ("ao_raw",) if config.ssao_blur else ("ao",)
        self.vec = capabilities.pixel_vector_width(device.cl_device)
        wx, wy = work_group(self.vec)
        self.kernel = device.kernel("ssao.cl", "ssao", {**layout.kernel_defines(), "VEC": self.vec,
                                                        "SSAO_WG_X": wx, "SSAO_WG_Y": wy, **view_defines(ortho)})

    def allocate(self, width, height):
        self.ao = empty(self.queue, width * height, np.float32)

    def publish(self, res):
        res.buffers[self.outputs[0]] = self.ao

    def run(self, res):
        w, h = res["width"], res["height"]
        self.kernel(self.queue, global_size(w, h, self.vec), work_group(self.vec),
                    res["gbuffer"].data, np.int32(w), np.int32(h), np.float32(res["far"]),
                    res["camera_params"].data, np.float32(res["tan_x"]), np.float32(res["tan_y"]),
                    np.float32(self.config.ssao_radius), np.float32(self.config.ssao_strength), self.ao.data)
