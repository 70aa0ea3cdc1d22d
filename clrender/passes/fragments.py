"""Transparent fragments (kernels/fragments.cl): BLEND triangles set up and binned in prim lists
of their own (setup.cl with select = "blend", binning.cl), then counted per pixel in front of
the opaque surface, with their depth range (light culling widens its tiles by it).

Shared by the A-buffer and depth peeling (docs/transparency.md). The pipeline skips it (no
kernel) when the scene has no BLEND triangle."""
from __future__ import annotations

import numpy as np

from clrender.abi import structs
from clrender.device import capabilities, tuning
from clrender.passes.base import Overflow, RenderPass, Resources, empty, view_defines
from clrender.passes.binning import BinningPass
from clrender.passes.setup import SetupPass, per_triangle_bytes


def transparent_triangle_count(scene, blend_only: bool = False) -> int:
    """Triangles with a BLEND or transmissive material (Material.see_through: they skip the G-buffer,
    docs/transparency.md); blend_only: BLEND ones (shading="blinn_phong" has no transmission)."""
    blend = np.array([m.alpha_mode == "BLEND" if blend_only else m.see_through for m in scene.materials] or [False])
    return int(np.count_nonzero(blend[scene.triangle_material])) if scene.triangle_count else 0


class FragmentsPass(RenderPass):
    name = "fragments"
    inputs = ("positions", "triangles", "tri_material", "materials", "view_proj", "n_tris", "near",
              "n_transparent_tris", "vis_depth")
    outputs = ("t_prims", "t_tile_offsets", "t_tile_counts", "t_tile_prims", "t_tile_list_capacity", "t_tiles_x",
               "frag_count", "frag_list_len", "t_range", "has_fragments")

    @classmethod
    def runs(cls, config):
        return config.transparency != "screen_door"     # screen door: BLEND dithered into the G-buffer

    @classmethod
    def buffer_bytes(cls, width, height, config, scene=None):
        """Per pixel: count, list length, depth range; its own setup (BLEND triangles) and binning."""
        if scene is None:
            return {}
        t = capabilities.estimate_tile(config.tile_size)
        tiles = -(-width // t) * -(-height // t)
        n_blend = transparent_triangle_count(scene)
        return {"fragments.counts+range": 16 * width * height, "fragments.binning": 44 * tiles,
                "fragments.setup": per_triangle_bytes(scene.triangle_count, config)
                + structs.prim_dtype.itemsize * max(1024, n_blend + n_blend // 8)}

    def __init__(self, device, config, ortho: bool = False):
        """ortho: an orthographic camera (setup.cl / coverage.h ORTHO; the forward passes read it)."""
        super().__init__(device, config)
        self.ortho = bool(ortho)
        self.setup = SetupPass(device, config, select="blend", ortho=ortho)
        self.tile = tuning.camera_tile_size(device.cl_device, config)
        self.binning = BinningPass(device, config, self.tile)
        self.vec = tuning.raster_vector_width(device.cl_device, self.tile)
        self.defines = {"TILE": self.tile, "VEC": self.vec, "MAX_FRAGMENTS": config.max_fragments_per_pixel,
                        **view_defines(ortho)}
        self.count_kernel = device.kernel("fragments.cl", "fragment_count", self.defines)
        self.scene_key = None

    def allocate(self, width, height):
        self.setup.allocate(width, height)
        self.binning.allocate(width, height)
        n = width * height
        self.frag_count = empty(self.queue, n, np.int32)
        self.list_len = empty(self.queue, n, np.int32)
        self.t_range = empty(self.queue, 2 * n, np.float32)

    def prepare_scene(self, scene_res):
        self.setup.prepare_scene(scene_res)
        key = (id(scene_res["positions"]), scene_res["n_transparent_tris"])
        if key != self.scene_key:                      # a new scene: room for its BLEND triangles only
            self.scene_key = key
            t = scene_res["n_transparent_tris"]
            self.setup.reserve(max(1024, t + t // 8))

    def publish(self, res):
        sub = self._sub(res)
        res.buffers.update(t_prims=self.setup.prims, t_tile_offsets=self.binning.tile_offsets,
                           t_tile_counts=self.binning.tile_counts, t_tile_prims=self.binning.tile_prims,
                           frag_count=self.frag_count, frag_list_len=self.list_len, t_range=self.t_range)
        res.values.update(t_tile_list_capacity=sub["tile_list_capacity"], t_tiles_x=sub["tiles_x"],
                          has_fragments=bool(res["n_transparent_tris"]))

    def _sub(self, res) -> Resources:
        """The inner setup and binning read and write their usual names in a private copy."""
        sub = Resources(buffers=dict(res.buffers), values=dict(res.values))
        self.setup.publish(sub)
        self.binning.publish(sub)
        return sub

    def run(self, res):
        sub = self._sub(res)
        with self.timed("setup"):
            self.setup.run(sub)
        with self.timed("binning"):
            self.binning.run(sub)
        t = self.tile
        with self.timed("count"):
            self.count_kernel(self.queue, walk_global_size(res, t, self.vec), (t // self.vec, t),
                              *walk_args(res), self.frag_count.data, self.list_len.data, self.t_range.data)

    def overflows(self):
        return [Overflow("t_prims", self.setup.prim_total, self.setup.capacity),
                Overflow("t_tile_prims", self.binning.total, self.binning.list_capacity)]

    def grow(self, name, needed):
        (self.setup if name == "t_prims" else self.binning).grow(name[2:], needed)


def walk_global_size(res, tile: int, vec: int) -> tuple:
    """fragments.cl kernels: one (tile/vec, tile) work-group per tile of the transparent lists."""
    tiles_y = -(-res["height"] // tile)
    return res["t_tiles_x"] * tile // vec, tiles_y * tile


def walk_args(res) -> tuple:
    """The leading arguments of every fragments.cl kernel: transparent prims and tile lists,
    image size, far and the opaque depth."""
    return (res["t_prims"].data, res["t_tile_offsets"].data, res["t_tile_counts"].data, res["t_tile_prims"].data,
            np.int32(res["t_tile_list_capacity"]), np.int32(res["t_tiles_x"]), np.int32(res["width"]),
            np.int32(res["height"]), np.float32(res["far"]), res["vis_depth"].data)
