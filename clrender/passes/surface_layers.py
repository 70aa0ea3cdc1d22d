"""Surface layers pass (kernels/surface_layers.cl): the glTF material extensions' layers (IOR, specular,
clearcoat, sheen, iridescence, anisotropy; docs/shading.md) shaded over the pixels whose material
has them, after the pipeline's opaque shading (deferred shade, light pre-pass material, or
light-indexed forward shade), in place in the colour planes.

It exists in every pipeline but runs, and builds its program, only for a scene with layered
materials (`active`): the layer parameters are read from the material records at shading time,
through the visibility buffer's prim, so the G-buffer is not widened and a scene without layers
costs nothing more. The lights' arguments, the sun and the shadow maps are ShadePass's."""
from __future__ import annotations

import numpy as np
import pyopencl.array as cla

from clrender.abi import structs
from clrender.device import capabilities
from clrender.passes.base import SCENE_INPUTS, RenderPass, empty, launch_1d, scene_args, zeros
from clrender.passes.ibl import ENV_OUTPUTS, env_kernel_args
from clrender.passes.shade import ShadePass

SHEEN_LUT_SIZE = 32        # kernels/layered_brdf.h SHEEN_LUT_SIZE: E(mu, roughness), 32 x 32


class SurfaceLayersPass(ShadePass):
    name = "surface_layers"
    outputs = ("surface_layer_args",)     # for the forward passes; the colour is changed in place

    @classmethod
    def runs(cls, config):
        return config.shading != "blinn_phong"       # the report's model everywhere: no layers

    @classmethod
    def buffer_bytes(cls, width, height, config, scene=None):
        return {"surface_layers.sheen_lut": 4 * SHEEN_LUT_SIZE * SHEEN_LUT_SIZE}

    def __init__(self, device, config, ortho: bool = False):
        RenderPass.__init__(self, device, config)
        self.ortho = bool(ortho)
        self.brute_force = config.light_culling == "brute_force"
        self.ssao = bool(config.ssao) and config.pipeline != "light_indexed"
        self.inputs = ("color", "vis_prim", "vis_depth", "prims") + SCENE_INPUTS + (
            "gbuffer", "layered_materials", "has_tangents", "lights", "n_lights", "ambient", "camera_params", "sun") + (
            ENV_OUTPUTS) + (() if self.brute_force else ("tile_light_counts", "tile_light_offsets", "tile_lights")) + (
            ("ao",) if self.ssao else ()) + (("shadow_atlas", "shadow_views", "shadow_layout") if config.shadows else ())
        self.tile = capabilities.tile_size_for(device.cl_device, config.light_tile_size)
        self.vec = min(capabilities.pixel_vector_width(device.cl_device), self.tile)
        # deferred: the surface from the full G-buffer; the thin G-buffers lack base colour or normals
        self.from_gbuffer = config.pipeline == "deferred"
        defines = {**self._light_defines(config), "SSAO": int(self.ssao), "MULTISCATTER": int(config.multiscatter),
                   "SHEEN_LUT_SIZE": SHEEN_LUT_SIZE, "FROM_GBUFFER": int(self.from_gbuffer)}
        self.kernel = device.kernel("surface_layers.cl", "surface_layers", defines)
        self.lut_kernel = device.kernel("surface_layers.cl", "sheen_albedo_lut", defines)
        self.no_list = zeros(self.queue, 1, np.int32)
        self.no_ao = zeros(self.queue, 1, np.float32)
        self.no_views = cla.to_device(self.queue, np.zeros(1, structs.shadow_view_dtype))
        self.sun = zeros(self.queue, 6, np.float32)
        self.sun_key = None
        # made at the first frame with layers, kept; the forward passes over transparent fragments
        # read it too (res["surface_layer_args"])
        self.sheen_lut = empty(self.queue, SHEEN_LUT_SIZE * SHEEN_LUT_SIZE, np.float32)
        self.lut_made = False

    def pair_stats(self) -> dict:
        return {}                       # the opaque pass counted this frame's (pixel, light) pairs

    def active(self, res):
        return res["layered_materials"] > 0

    def allocate(self, width, height):
        self.tiles_x, self.tiles_y = -(-width // self.tile), -(-height // self.tile)

    def publish(self, res):
        if self.active(res):    # forward.h's SURFACE_LAYERS arguments (transparent fragments)
            res.values["surface_layer_args"] = (res.buffers["material_ext"].data, np.int32(res["has_tangents"]),
                                                self.sheen_lut.data)
        sun = res["sun"]
        key = None if sun is None else (sun.direction, sun.color)
        if key is not None and key != self.sun_key:
            self.sun.set(np.array(sun.direction + sun.color, np.float32), queue=self.queue)
        self.sun_key = key

    def run(self, res):
        if not self.lut_made:
            self.lut_made = True
            self.lut_kernel(self.queue, *launch_1d(SHEEN_LUT_SIZE * SHEEN_LUT_SIZE), self.sheen_lut.data)
        t = self.tile
        offsets, counts, lists, capacity, _ = self._lists(res)
        self.kernel(self.queue, (self.tiles_x * t // self.vec, self.tiles_y * t), (t // self.vec, t),
                    res["vis_prim"].data, res["vis_depth"].data, np.int32(res["width"]), np.int32(res["height"]),
                    *scene_args(res, res["prims"]), res.buffers["material_ext"].data, np.int32(res["has_tangents"]),
                    res["camera_params"].data, res["lights"].data, np.int32(res["n_lights"]),
                    np.float32(res["ambient"]), (res["ao"] if self.ssao else self.no_ao).data,
                    offsets.data, counts.data, lists.data, np.int32(capacity), np.int32(self.tiles_x),
                    *self._shadow_args(res), *env_kernel_args(res), self.sheen_lut.data, res["gbuffer"].data,
                    np.float32(res["far"]), res["color"].data)
