"""The second geometry pass of the light pre-pass and light-indexed pipelines (report V.2, V.3:
"all the geometry is submitted twice"; docs/variants.md). No kernel of its own: it runs the
camera's raster (kernels/raster.cl) again, and with `msaa=N` at the N sub-samples of the standard
D3D pattern (docs/raster_contract.md §10): one setup, binning and raster for all samples.

- `RasterAgainPass`: the raster again over pass 1's bins, into pass 1's visibility buffer (pass 1's
  G-buffer pass has consumed it): the same fragments, at the cost of a second rasterization.
- `SampleGeometryPass`: one setup and binning widened to the samples' reach, one raster that
  keeps a nearest fragment per sample point; publishes the per-sample visibility planes and the
  shared prims for the material pass.
"""
from __future__ import annotations

from clrender.abi import structs
from clrender.device import capabilities
from clrender.passes.base import RenderPass, Resources
from clrender.passes.binning import BinningPass, initial_list_capacity
from clrender.passes.raster import RasterPass
from clrender.passes.setup import SetupPass, per_triangle_bytes

# Sample offsets from the pixel centre in 1/16 pixel, y down: Direct3D's standard multisample
# patterns (D3D11_STANDARD_MULTISAMPLE_PATTERN); ×16 gives the raster's 1/256 units. The kernels'
# copy is kernels/samples.h (tests/test_variants.py compares them).
SAMPLE_PATTERNS = {
    1: ((0, 0),),
    2: ((4, 4), (-4, -4)),
    4: ((-2, -6), (6, -2), (-6, 2), (2, 6)),
    8: ((1, -3), (-1, 3), (5, 1), (-3, -5), (-5, 5), (-7, -1), (3, 7), (7, -7)),
}


def sample_offsets(n: int) -> tuple:
    """(dx, dy) of each of the n sub-samples, in 1/256 pixel."""
    return tuple((16 * dx, 16 * dy) for dx, dy in SAMPLE_PATTERNS[n])


class RasterAgainPass(RasterPass):
    name = "raster_again"

    @classmethod
    def runs(cls, config):
        return config.pipeline != "deferred" and not config.reuse_visibility and config.msaa == 1

    @classmethod
    def buffer_bytes(cls, width, height, config, scene=None):
        return {}                   # the first raster's buffers

    def __init__(self, device, config, first: RasterPass, ortho: bool = False):
        super().__init__(device, config, ortho=ortho)
        self.first = first

    def allocate(self, width, height):
        self.vis_depth, self.vis_prim = self.first.vis_depth, self.first.vis_prim


class SampleGeometryPass(RenderPass):
    """The geometry at the msaa sub-samples: one setup and one binning that keep every prim which
    may cover a sample point (kernels/samples.h SAMPLE_SPREAD), then one raster that walks each
    tile's prims once and keeps a nearest fragment per sample (raster.cl SAMPLES). Publishes
    `msaa_vis_prims` (a plane of W·H prim indices per sample) over the shared `msaa_prims`, so
    the material pass can tell a sample that sees sample 0's prim from one that does not."""
    name = "msaa_geometry"
    inputs = SetupPass.inputs + ("uvs", "texels", "tex_infos", "tex_levels", "colors", "n_vertices",
                                 "has_colors")
    outputs = ("msaa_vis_prims", "msaa_prims")

    @classmethod
    def runs(cls, config):
        return config.pipeline != "deferred" and not config.reuse_visibility and config.msaa > 1

    @classmethod
    def buffer_bytes(cls, width, height, config, scene=None):
        """One setup and binning; a visibility buffer per sub-sample and one depth scratch."""
        px = width * height
        side = capabilities.estimate_tile(config.tile_size)   # None (tuned): the smallest candidate's, an upper bound
        tiles = -(-width // side) * -(-height // side)
        t = scene.triangle_count if scene is not None else 0
        prims = structs.prim_dtype.itemsize * max(1024, t + t // 8)
        return {"msaa_geometry": 4 * px * (config.msaa + 1) + 12 * tiles + 4 * initial_list_capacity(tiles, t)
                + prims + per_triangle_bytes(t, config)}

    def __init__(self, device, config, samples: int, select: str, ortho: bool = False):
        super().__init__(device, config)
        self.samples = samples
        self.setup = SetupPass(device, config, select=select, samples=samples, ortho=ortho)
        self.binning = BinningPass(device, config, samples=samples)
        self.raster = RasterPass(device, config, ortho=ortho, samples=samples)
        self.stages = (self.setup, self.binning, self.raster)

    def allocate(self, width, height):
        for p in self.stages:
            p.allocate(width, height)

    def prepare_scene(self, scene_buffers):
        for p in self.stages:
            p.prepare_scene(scene_buffers)

    def publish(self, res):
        self.sub = Resources(buffers=dict(res.buffers), values=dict(res.values))
        for p in self.stages:
            p.publish(self.sub)
        res.buffers.update(msaa_vis_prims=self.raster.vis_prim, msaa_prims=self.sub["prims"])

    def run(self, res):
        for p in self.stages:
            p.publish(self.sub)                  # after a grow, the buffers are new
            p.run(self.sub)

    def overflows(self):
        return [ov for p in self.stages for ov in p.overflows()]

    def grow(self, name, needed):
        for p in self.stages:
            if any(ov.name == name for ov in p.overflows()):
                p.grow(name, needed)
                return
        raise KeyError(name)
