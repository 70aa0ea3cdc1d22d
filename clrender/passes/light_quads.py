"""Light quads pass (kernels/light_quads.cl): per-tile light lists from each light's screen-space
bounding quad (report V.1's geometry-shader sprites), no tile depth bounds. It publishes exactly
LightCullPass's resources, so ShadePass (and the forward passes over transparent fragments)
read them unchanged; the culling spheres come from light_cull.cl's light_view_bounds."""
from __future__ import annotations

import numpy as np

from clrender.device import capabilities
from clrender.abi import gbuffer as layout
from clrender.passes.base import empty, launch_1d, round_up, scan_for, view_defines, zeros
from clrender.passes.light_cull import TileLightLists


class LightQuadsPass(TileLightLists):
    name = "light_quads"
    inputs = ("lights", "n_lights", "view_matrix", "tan_x", "tan_y", "shift_x", "shift_y", "near", "far", "camera")

    @classmethod
    def runs(cls, config):
        return config.light_culling == "quads"

    @classmethod
    def buffer_bytes(cls, width, height, config, scene=None):
        """Per tile: rectangle and list; per light (a scene): pixel and tile rectangles."""
        tiles = -(-width // config.light_tile_size) * -(-height // config.light_tile_size)
        out = {"light_quads.tiles": 8 * tiles, "light_quads.tile_lights": 4 * 16 * tiles}
        if scene is not None:
            out["light_quads.rects"] = 32 * len(scene.lights)
        return out

    def __init__(self, device, config, ortho: bool = False):
        """ortho: an orthographic camera (light_quads.cl ORTHO: a sphere's quad is its box)."""
        super().__init__(device, config)
        self.tile = config.light_tile_size
        self.vec = capabilities.pixel_vector_width(device.cl_device)
        # light_view_bounds is built as LightCullPass builds it: the same culling spheres.
        cull_defines = {**layout.kernel_defines(), "LTILE": self.tile, "VEC": self.vec,
                        "DEPTH_MASK": int(config.light_depth_mask)}
        self.bounds_kernel = device.kernel("light_cull.cl", "light_view_bounds", cull_defines)
        defines = {"LTILE": self.tile, "VEC": self.vec, **view_defines(ortho)}
        self.rect_kernel = device.kernel("light_quads.cl", "light_quad_rects", defines)
        self.count_kernel = device.kernel("light_quads.cl", "light_quads_count", defines)
        self.fill_kernel = device.kernel("light_quads.cl", "light_quads_fill", defines)
        self.scan = scan_for(device)
        self.total = zeros(self.queue, 1, np.int32)
        self.n_padded = 0
        self.frame_padded = 0              # the last frame's light count padded to VEC (rect planes' stride)
        self.list_capacity = 0

    def allocate(self, width, height):
        self._allocate_lists(width, height)

    def prepare_scene(self, scene_res):
        needed = round_up(max(scene_res["n_lights"], 1), self.vec)
        if needed > self.n_padded:
            self.n_padded = needed
            self.spheres = [empty(self.queue, needed, np.float32) for _ in range(4)]
            self.quad_rect = empty(self.queue, 4 * needed, np.float32)     # pixel x0, y0, x1, y1 planes
            self.quad_tiles = empty(self.queue, 4 * needed, np.int32)      # tile x0, y0, x1, y1 planes

    def run(self, res):
        w, h = res["width"], res["height"]
        n_lights = res["n_lights"]
        n_padded = round_up(max(n_lights, 1), self.vec)
        self.frame_padded = n_padded
        sx, sy, sz, sr = (s.data for s in self.spheres)
        light_grid = launch_1d(n_padded)
        self.bounds_kernel(self.queue, *light_grid, res["lights"].data, np.int32(n_lights), np.int32(n_padded),
                           res["view_matrix"].data, sx, sy, sz, sr)
        eye_distance = float(np.linalg.norm(np.asarray(res["camera"].eye, np.float64)))
        self.rect_kernel(self.queue, *light_grid, sx, sy, sz, sr, np.int32(n_padded), np.int32(w), np.int32(h),
                         np.float32(res["tan_x"]), np.float32(res["tan_y"]), np.float32(res["shift_x"]),
                         np.float32(res["shift_y"]), np.float32(res["near"]),
                         np.float32(res["far"]), np.float32(eye_distance), np.int32(self.tiles_x),
                         np.int32(self.tiles_y), self.quad_rect.data, self.quad_tiles.data)
        tiles = (self.quad_tiles.data, np.int32(n_padded), np.int32(self.tiles_x), np.int32(self.tiles_y))
        tile_grid = launch_1d(self.tiles_x * self.tiles_y)
        self.count_kernel(self.queue, *tile_grid, *tiles, self.counts.data)
        self.scan(self.counts, self.offsets, self.total, queue=self.queue)
        self.fill_kernel(self.queue, *tile_grid, *tiles, self.offsets.data, np.int32(self.list_capacity),
                         self.lights_list.data)

    def quad_rects(self, n_lights: int) -> np.ndarray:
        """(n_lights, 4) float32 pixel rectangles (x0, y0, x1, y1) of the last frame; x0 > x1: empty."""
        n = self.frame_padded
        planes = self.quad_rect.get(queue=self.queue)[: 4 * n].reshape(4, n)
        return np.ascontiguousarray(planes[:, :n_lights].T)
