"""Particle pass (kernels/particles.cl): rewrites the scene's animated light slices for `time`.

Launches nothing for a scene without particle systems."""
from __future__ import annotations

import numpy as np

from clrender.passes.base import RenderPass, launch_1d


class ParticlesPass(RenderPass):
    name = "particles"
    inputs = ("lights", "particle_systems", "time")
    outputs = ("lights",)

    def active(self, res):
        return bool(res["particle_systems"])     # no particles: no kernel

    def __init__(self, device, config):
        super().__init__(device, config)
        self.kernel = device.kernel("particles.cl", "update_particles")

    def run(self, res):
        for ps in res["particle_systems"]:
            if ps.count == 0:
                continue
            self.kernel(self.queue, *launch_1d(ps.count), res["lights"].data, np.int32(ps.first),
                        np.int32(ps.count), np.uint32(ps.seed), np.float32(res["time"]),
                        *(np.float32(v) for v in (*ps.lo, *ps.hi)), np.float32(ps.speed),
                        np.float32(ps.life_min), np.float32(ps.life_max), np.float32(ps.radius_min),
                        np.float32(ps.radius_max), np.float32(ps.intensity))
