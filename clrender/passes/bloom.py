"""Bloom pass (kernels/bloom.cl): the report's glow (section IV.1). What saturates is isolated,
blurred over a mip pyramid and added back to the linear HDR colour before tone mapping:

    bright = max(color - bloom_threshold, 0)            per channel
    color' = color + bloom_strength * blur(bright)
    blur   = (1/L) * sum_{l=1..L} U^l G_l D_l            equal weights, total weight 1

D_l: l successive 2x2 means (level l is ceil(w/2^l) x ceil(h/2^l); odd sizes clamp to the edge).
G_l: separable Gaussian, sigma = SIGMA coarse pixels at every level (2^l * SIGMA output pixels),
     taps k = -R..R, exp(-k^2 / (2 SIGMA^2)) normalized to 1, R = max(1, ceil(3 SIGMA)), clamp-to-edge.
U:   bilinear 2x upsample, fine pixel x reads the coarser level at (x + 0.5) / 2 - 0.5 (weights
     3/4, 1/4; clamp-to-edge); U^l is l of them, run as a cascade acc_l = G_l D_l + U acc_{l+1}.
bloom_radius r (output pixels) -> L = clamp(ceil(log2 r) - 1, 1, MAX_LEVELS), SIGMA = r / 2^(L+1):
the levels' Gaussians have sigma r/2, r/4, ..., r/2^L output pixels (coarsest first).

The profile of one bright pixel: the mean of L bumps, bump l centred on the centre of the pixel's
level-l block with per-axis variance 4^l (s2 + 1/4) - 1/4 output pixels^2 (s2 = sum k^2 w_k, the
taps' variance, ~ SIGMA^2); level 1 is the core, level L (sigma ~ r/2) the reach.
Energy: the blur's weights total 1 (means x 4^l, normalized taps, U's weights totalling 4 per
coarse pixel), so the pass adds bloom_strength x sum(bright) for content away from the borders.
Nothing above the threshold: the output is bit-identical to the input. Reads `color`, publishes
its own `color`; with bloom off the pipeline builds no pass and runs no kernel.

Each work-item computes a run of VEC horizontally adjacent pixels (kernels/vec.h; VEC = 1 on GPUs
and Oclgrind), in 3L + 1 launches (10 at the default L = 3). The results do not depend on VEC (the same float
operations in the same order per pixel).
"""
from __future__ import annotations

import math

import numpy as np
import pyopencl.array as cla

from clrender.device import capabilities
from clrender.passes.base import RenderPass, empty, round_up

GROUP = (32, 8)          # VEC = 1 (GPUs): a pixel per work-item
CPU_GROUP = (16, 1)      # VEC > 1 (CPUs): runs of VEC pixels, a group along one row (measured on PoCL)
MAX_LEVELS = 12


def bloom_levels(radius: float) -> tuple[int, float, int]:
    """(L, SIGMA in coarse pixels, tap radius R) for bloom_radius `radius` (output pixels)."""
    levels = min(max(math.ceil(math.log2(radius)) - 1, 1), MAX_LEVELS)
    sigma = radius / 2.0 ** (levels + 1)
    return levels, sigma, max(1, math.ceil(3.0 * sigma))


def gaussian_taps(sigma: float, radius: int) -> np.ndarray:
    """Normalized Gaussian weights for k = -radius..radius (float64)."""
    k = np.arange(-radius, radius + 1, dtype=np.float64)
    w = np.exp(-k * k / (2.0 * sigma * sigma))
    return w / w.sum()


def level_sizes(width: int, height: int, levels: int) -> list[tuple[int, int]]:
    """[(w_l, h_l) for l = 1..levels]: each halving rounds up."""
    out, w, h = [], width, height
    for _ in range(levels):
        w, h = (w + 1) // 2, (h + 1) // 2
        out.append((w, h))
    return out


class BloomPass(RenderPass):
    name = "bloom"
    inputs = ("color",)
    outputs = ("color",)

    @classmethod
    def runs(cls, config):
        return bool(config.bloom)

    @classmethod
    def buffer_bytes(cls, width, height, config, scene=None):
        levels, _, taps = bloom_levels(config.bloom_radius)
        sizes = level_sizes(width, height, levels)
        return {"bloom.pyramid+tmp+color+taps": 12 * width * height + 12 * sum(w * h for w, h in sizes)
                + 12 * sizes[0][0] * sizes[0][1] + 4 * (2 * taps + 1)}

    def __init__(self, device, config):
        super().__init__(device, config)
        self.levels, self.sigma, self.radius = bloom_levels(float(config.bloom_radius))
        self.vec = capabilities.pixel_vector_width(device.cl_device)
        if self.vec > 1:
            self.group = CPU_GROUP
        else:
            self.group = GROUP if device.cl_device.max_work_group_size >= 256 else (16, 4)
        self.threshold = np.float32(config.bloom_threshold)
        self.scale = np.float32(float(config.bloom_strength) / self.levels)
        self.taps = cla.to_device(self.queue, gaussian_taps(self.sigma, self.radius).astype(np.float32))
        self.kernels = {name: device.kernel("bloom.cl", name, {"VEC": self.vec})
                        for name in ("bloom_bright_down", "bloom_down", "bloom_blur_rows", "bloom_blur_cols",
                                     "bloom_compose")}

    def allocate(self, width, height):
        self.size = (width, height)
        self.sizes = level_sizes(width, height, self.levels)
        self.offsets = np.cumsum([0] + [3 * w * h for w, h in self.sizes]).tolist()
        self.pyramid = empty(self.queue, self.offsets[-1], np.float32)
        w1, h1 = self.sizes[0]
        self.tmp = empty(self.queue, 3 * w1 * h1, np.float32)
        self.color = empty(self.queue, 3 * width * height, np.float32)

    def publish(self, res):
        self.source = res["color"]          # the HDR colour before bloom; ours replaces it
        res.buffers["color"] = self.color

    def _level(self, l):
        """(offset of level l (1-based) in the pyramid, in floats, w_l, h_l) as kernel arguments."""
        w, h = self.sizes[l - 1]
        return np.int32(self.offsets[l - 1]), np.int32(w), np.int32(h)

    def _grid(self, w, h):
        """Global size for a w x h destination: work-item (i, y) owns the run of VEC pixels from i * VEC."""
        return (round_up(-(-int(w) // self.vec), self.group[0]), round_up(int(h), self.group[1]))

    def run(self, res):
        k, q, pyramid = self.kernels, self.queue, self.pyramid.data
        width, height = (np.int32(n) for n in self.size)
        _, w1, h1 = self._level(1)                 # level 1 starts the pyramid (offset 0)
        k["bloom_bright_down"](q, self._grid(w1, h1), self.group, self.source.data, width, height, self.threshold,
                               pyramid, w1, h1)
        for l in range(2, self.levels + 1):
            src, w, h = self._level(l - 1)
            dst, wo, ho = self._level(l)
            k["bloom_down"](q, self._grid(wo, ho), self.group, pyramid, src, w, h, dst, wo, ho)
        radius = np.int32(self.radius)
        for l in range(self.levels, 0, -1):        # coarsest first: each level adds the coarser one, upsampled
            off, w, h = self._level(l)
            coarse, wc, hc = self._level(l + 1) if l < self.levels else (np.int32(-1), np.int32(1), np.int32(1))
            k["bloom_blur_rows"](q, self._grid(w, h), self.group, pyramid, off, w, h, self.taps.data, radius,
                                 self.tmp.data)
            k["bloom_blur_cols"](q, self._grid(w, h), self.group, self.tmp.data, w, h, self.taps.data, radius,
                                 pyramid, off, coarse, wc, hc)
        k["bloom_compose"](q, self._grid(width, height), self.group, self.source.data, width, height, pyramid, w1, h1,
                           self.scale, self.color.data)
