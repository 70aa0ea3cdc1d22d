"""Hatching pass (kernels/hatching.cl): the report's non-photorealistic post effect (IV.3,
"crayonnage"), tonal art maps after Praun et al. 2001 (clrender/passes/tam.py), drawn on white paper with
ink outlines. In the LDR chain after FXAA, before encode (docs/post.md "Hatching"): reads `ldr`
and the G-buffer (`gbuffer`, the output resolution's), publishes its own `ldr`.

One kernel launch: pixels without geometry (triangle id -1) are paper white; foreground pixels
discontinuous with a direct neighbour (edge_aa.cl's test, with RenderConfig.edge_depth_threshold
and edge_normal_threshold_deg; inked on the nearer side) are black ink; the others get the
strokes over their desaturated colour."""
from __future__ import annotations

import math
import weakref

import numpy as np
import pyopencl.array as cla

from clrender.device import capabilities
from clrender.passes import tam
from clrender.abi import gbuffer as layout
from clrender.passes.base import RenderPass, empty, launch_2d

# One upload of the tonal art map per device (shared by that device's renderers).
_TAM_ON_DEVICE: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()


def tam_buffer(device) -> cla.Array:
    """The tonal art map on `device` (clrender.passes.tam.device_layout()), uploaded once."""
    buf = _TAM_ON_DEVICE.get(device)
    if buf is None:
        buf = cla.to_device(device.queue, tam.device_layout())
        _TAM_ON_DEVICE[device] = buf
    return buf


def mip_levels(scale: float) -> tuple[int, float, int, float, float]:
    """(level0, k0, level1, k1, frac): the trilinear lookup for `hatching_scale` pixels per
    level-0 texel. The ideal level is log2(1/scale) (0 when magnifying, the 1×1 level at most);
    k_i = 1 / (scale · 2^level_i) maps pixel coordinates to level_i texels."""
    lam = min(max(0.0, -math.log2(float(scale))), tam.LEVELS - 1.0)
    level0 = int(math.floor(lam))
    level1 = min(level0 + 1, tam.LEVELS - 1)
    frac = lam - level0 if level1 > level0 else 0.0
    inv = 1.0 / float(scale)
    return level0, inv / 2.0 ** level0, level1, inv / 2.0 ** level1, frac


class HatchingPass(RenderPass):
    name = "hatching"
    inputs = ("ldr", "gbuffer")
    outputs = ("ldr",)

    @classmethod
    def runs(cls, config):
        return bool(config.hatching)

    @classmethod
    def buffer_bytes(cls, width, height, config, scene=None):
        return {"hatching.out+tam": 12 * width * height + tam.DEVICE_BYTES}

    def __init__(self, device, config):
        super().__init__(device, config)
        self.vec = capabilities.pixel_vector_width(device.cl_device)
        self.kernel = device.kernel("hatching.cl", "hatching", {**layout.kernel_defines(), "VEC": self.vec,
                                                                "TAM_SIZE": tam.SIZE, "TONES": tam.TONES})
        self.tam = tam_buffer(device)
        level0, k0, level1, k1, frac = mip_levels(config.hatching_scale)
        self.args = (np.int32(level0), np.float32(k0), np.int32(level1), np.float32(k1), np.float32(frac),
                     np.float32(config.hatching_saturation), np.float32(config.edge_depth_threshold),
                     np.float32(math.cos(math.radians(config.edge_normal_threshold_deg))))

    def allocate(self, width, height):
        self.size = (width, height)
        self.out = empty(self.queue, 3 * width * height, np.float32)

    def publish(self, res):
        self.src = res["ldr"]
        res.buffers["ldr"] = self.out

    def run(self, res):
        w, h = self.size
        # work-item (i, y): the run of `vec` pixels of row y from x = i·vec; fixed 8×8 groups
        self.kernel(self.queue, *launch_2d(-(-w // self.vec), h), self.src.data, res["gbuffer"].data,
                    np.int32(w), np.int32(h), self.tam.data, *self.args, self.out.data)
