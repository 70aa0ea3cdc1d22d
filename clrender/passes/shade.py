"""Shading pass (kernels/shade.cl): the light buffer and global multiply, from the G-buffer."""
from __future__ import annotations

import numpy as np
import pyopencl as cl
import pyopencl.array as cla

from dataclasses import dataclass

from clrender.device import capabilities
from clrender.abi import structs
from clrender.abi import gbuffer as layout
from clrender.passes.ibl import ENV_OUTPUTS, env_kernel_args
from clrender.passes.base import RenderPass, empty, view_defines, zeros


SHADOW_FILTERS = {"hard": 0, "pcf3x3": 1, "poisson": 2}


@dataclass(frozen=True)
class LightEnv:
    """What lighting.h's LightEnv is built from, for the forward passes over transparent
    fragments: (tile_light_offsets, tile_light_counts, tile_lights, list capacity, light
    tiles_x) and the shadow-map and sun arguments, in kernel order."""
    lists: tuple
    shadow_and_sun: tuple


class PairSums:
    """Sums shade.cl's light_pairs planes (evaluated, useful: int per pixel) on the device with a
    pyopencl reduction into 64-bit totals; only the two totals are read back, after the frame.
    The reduction's first-stage scratch comes from one kept buffer, not a new one per frame."""

    _kernels: dict = {}

    def __init__(self, device):
        from pyopencl.reduction import ReductionKernel
        key = device.info.id
        if key not in PairSums._kernels:
            PairSums._kernels[key] = ReductionKernel(device.context, np.int64, neutral="0", reduce_expr="a+b",
                                                     map_expr="(long)x[i]", arguments="__global const int *x")
        self.kernel = PairSums._kernels[key]
        self.context = device.context
        self.totals = [zeros(device.queue, 1, np.int64) for _ in range(2)]
        self._scratch = None

    def _allocate(self, nbytes):
        if self._scratch is None or self._scratch.size < nbytes:
            self._scratch = cl.Buffer(self.context, cl.mem_flags.READ_WRITE, max(int(nbytes), 8))
        return self._scratch

    def __call__(self, planes, npix, queue):
        for k, total in enumerate(self.totals):
            self.kernel(planes, out=total, range=slice(k * npix, (k + 1) * npix), queue=queue, allocator=self._allocate)

    def stats(self) -> dict:
        evaluated, useful = (int(t.get()[0]) for t in self.totals)
        ratio = evaluated / useful if useful else (1.0 if evaluated == 0 else float("inf"))
        return {"light_pairs_evaluated": evaluated, "light_pairs_useful": useful, "light_pairs_ratio": ratio}


class ShadePass(RenderPass):
    name = "shade"
    outputs = ("color", "light_count", "shadow", "shadow_planes", "light_env")

    @classmethod
    def runs(cls, config):
        return config.pipeline == "deferred"

    @classmethod
    def buffer_bytes(cls, width, height, config, scene=None):
        px = width * height
        return {"shade.color": 12 * px, "shade.light_count": 4 * px,
                "shade.light_pairs": 8 * px + 16}     # evaluated + useful per pixel, their 64-bit sums

    def __init__(self, device, config, ortho: bool = False):
        """ortho: an orthographic camera (lighting.h ORTHO: positions and view vectors)."""
        super().__init__(device, config)
        self.ortho = bool(ortho)
        self.brute_force = config.light_culling == "brute_force"
        self.stencil = config.light_culling == "stencil"      # light_stencil.cl's per-pixel bits
        self.inputs = ("gbuffer", "lights", "n_lights", "ambient", "camera_params", "srgb_lut", "surface_extras",
                       "tri_material", "materials", "gltf_scene") + ENV_OUTPUTS + (
            () if self.brute_force else ("tile_light_counts", "tile_light_offsets", "tile_lights")) + (
            ("light_stencil", "light_stencil_words") if self.stencil else ()) + (
            ("ao",) if config.ssao else ()) + ("sun",) + (
            ("shadow_atlas", "shadow_views", "shadow_layout") if config.shadows else ())
        self.tile = capabilities.tile_size_for(device.cl_device, config.light_tile_size)
        self.vec = min(capabilities.pixel_vector_width(device.cl_device), self.tile)
        self.kernel = self._build_kernel(device, config)
        self.no_list = zeros(self.queue, 1, np.int32)     # placeholder list arguments for brute force
        self.no_ao = zeros(self.queue, 1, np.float32)     # placeholder ao argument without SSAO (never read)
        self.no_views = cla.to_device(self.queue, np.zeros(1, structs.shadow_view_dtype))   # placeholders: no shadows
        self.sun = zeros(self.queue, 6, np.float32)
        self.sun_key = None
        self.shadow_planes = 0
        self.shadow = zeros(self.queue, 1, np.float32)
        self.pair_sum = PairSums(device)
        self.pair_totals = self.pair_sum.totals           # (held here so device_bytes counts them)
        self.light_pairs = None

    def _light_defines(self, config) -> dict:
        """Build options of every kernel that walks the light lists (lighting.h)."""
        return {**layout.kernel_defines(), "LTILE": self.tile, "VEC": self.vec, "BRUTE_FORCE": int(self.brute_force),
                "SHADOWS": int(config.shadows), "SHADOW_FILTER": SHADOW_FILTERS[config.shadow_filter],
                "POISSON_RADIUS": f"{float(config.shadow_filter_radius)!r}f", **view_defines(self.ortho)}

    def _build_kernel(self, device, config):
        return device.kernel("shade.cl", "shade", {**self._light_defines(config), "SSAO": int(config.ssao),
                                                   "STENCIL": int(config.light_culling == "stencil")})

    def allocate(self, width, height):
        self.tiles_x, self.tiles_y = -(-width // self.tile), -(-height // self.tile)
        self.color = empty(self.queue, 3 * width * height, np.float32)
        self.light_count = empty(self.queue, width * height, np.int32)
        self.light_pairs = empty(self.queue, 2 * width * height, np.int32)    # evaluated, useful per pixel

    def publish(self, res):
        planes = res["shadow_layout"].planes if self.config.shadows else 0
        needed = planes * res["width"] * res["height"]
        if needed > self.shadow.size:
            self.shadow = empty(self.queue, needed, np.float32)
        self.shadow_planes = planes
        sun = res["sun"]
        key = None if sun is None else (sun.direction, sun.color)
        if key is not None and key != self.sun_key:
            self.sun.set(np.array(sun.direction + sun.color, np.float32), queue=self.queue)
        self.sun_key = key
        res.buffers.update(light_count=self.light_count, shadow=self.shadow)
        self._publish_output(res)
        res.values["shadow_planes"] = planes
        if "n_transparent_tris" in res and res["n_transparent_tris"]:
            offsets, counts, lists, capacity, tiles_x = self._lists(res)
            res.values["light_env"] = LightEnv((offsets.data, counts.data, lists.data, np.int32(capacity),
                                                np.int32(tiles_x)), self._shadow_args(res))

    def _publish_output(self, res):
        res.buffers["color"] = self.color

    def _lists(self, res):
        if self.brute_force:
            return self.no_list, self.no_list, self.no_list, 0, 0
        return (res["tile_light_offsets"], res["tile_light_counts"], res["tile_lights"], res["light_list_capacity"],
                res["light_tiles_x"])

    def run(self, res):
        t = self.tile
        offsets, counts, lists, capacity, _ = self._lists(res)
        self._clear_shadow(res)
        self.kernel(self.queue, (self.tiles_x * t // self.vec, self.tiles_y * t), (t // self.vec, t),
                    res["gbuffer"].data, np.int32(res["width"]), np.int32(res["height"]), np.float32(res["far"]),
                    res["camera_params"].data, res["lights"].data, np.int32(res["n_lights"]),
                    np.float32(res["ambient"]), (res["ao"] if self.config.ssao else self.no_ao).data,
                    offsets.data, counts.data, lists.data, np.int32(capacity),
                    np.int32(self.tiles_x), res["srgb_lut"].data, *self._shadow_args(res),
                    *(((res["light_stencil"].data, np.int32(res["light_stencil_words"])) if self.stencil
                       else (self.no_list.data, np.int32(0)))),
                    np.int32(res["surface_extras"]), res["tri_material"].data, res["materials"].data,
                    np.int32(res["gltf_scene"]), *env_kernel_args(res), self.color.data, self.light_count.data, self.shadow.data, self.light_pairs.data)
        self.pair_sum(self.light_pairs, res["width"] * res["height"], self.queue)

    def _clear_shadow(self, res):
        """Frame.shadow is 1 (lit) where no light writes a visibility."""
        if self.shadow_planes:
            n = self.shadow_planes * res["width"] * res["height"]
            cl.enqueue_fill_buffer(self.queue, self.shadow.data, np.float32(1.0), 0, 4 * n)

    def pair_stats(self) -> dict:
        """light_pairs_evaluated / _useful / _ratio of the last frame (docs/light_accumulation.md)."""
        return self.pair_sum.stats() if self.light_pairs is not None else {}

    def _shadow_args(self, res):
        """Atlas, views, bias options and sun for shade.cl (and lighting.h's LightEnv)."""
        c = self.config
        sun_cascades = spot_view0 = spot_plane0 = 0
        atlas, views, stride = self.no_ao, self.no_views, 0
        if c.shadows:
            lay = res["shadow_layout"]
            if lay.views:
                atlas, views, stride = res["shadow_atlas"], res["shadow_views"], lay.atlas_width
            sun_cascades, spot_view0, spot_plane0 = lay.sun_views, lay.sun_views, int(lay.sun_views > 0)
        return (atlas.data, np.int32(stride), views.data, np.float32(c.shadow_bias), np.float32(c.shadow_slope_bias),
                np.float32(c.shadow_normal_offset), np.int32(res["sun"] is not None), self.sun.data,
                np.int32(sun_cascades), np.int32(spot_view0), np.int32(spot_plane0))
