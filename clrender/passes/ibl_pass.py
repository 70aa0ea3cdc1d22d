"""IBL pass: the scene's environment (Scene.set_environment) made ready for the lighting passes:
its maps precomputed on the device once per environment (kernels/ibl.cl, `ibl_maps`, cached),
then every frame only the ENV_PARAMS arguments (kernels/environment.h) with its intensity and
rotation. A scene without an environment launches no kernel: the lighting passes get 1-element
placeholders and has_env = 0 (the constant `scene.ambient` term)."""
from __future__ import annotations

import numpy as np

from .base import RenderPass, zeros
from .ibl import ibl_maps

ENV_OUTPUTS = ("env_args", "has_env", "env_background")


class IblPass(RenderPass):
    name = "ibl"
    inputs = ("environment",)
    outputs = ENV_OUTPUTS

    def __init__(self, device, config):
        super().__init__(device, config)
        self.placeholder = tuple(zeros(self.queue, 8, dt).data for dt in
                                 (np.float32, np.int32, np.float32, np.float32, np.float32))

    def publish(self, res):
        env = res["environment"]
        if env is None:
            res.values.update(env_args=self.placeholder, has_env=0, env_background=0)

    def run(self, res):
        env = res["environment"]
        maps = ibl_maps(self.device, self.queue, env.pixels, key=env.key)
        res.values.update(env_args=maps.args(env.intensity, env.rotation_deg), has_env=1,
                          env_background=int(env.background))


def env_kernel_args(res) -> tuple:
    """(has_env, env_background, *ENV_PARAMS) for a lighting kernel."""
    return (np.int32(res["has_env"]), np.int32(res["env_background"]), *res["env_args"])
