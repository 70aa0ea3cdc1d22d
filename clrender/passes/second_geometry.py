"""The second geometry pass of the light pre-pass and light-indexed pipelines (report V.2, V.3:
"all the geometry is submitted twice"; docs/variants.md). No kernel of its own: it runs the
camera's raster (kernels/raster.cl) again, and with `msaa=N` the setup, binning and raster once
per sub-sample of the standard D3D pattern (docs/raster_contract.md §10).

- `RasterAgainPass`: the raster again over pass 1's bins, into pass 1's visibility buffer (pass 1's
  G-buffer pass has consumed it): the same fragments, at the cost of a second rasterization.
- `SampleGeometryPass`: for each sub-sample s, a setup of the geometry shifted by minus the
  sample's offset (so pixel centres land on the sample), its binning and raster, each with
  buffers of its own; publishes `vis_prim_s` and `prims_s` for the material pass.
"""
from __future__ import annotations

from .base import RenderPass, Resources
from .binning import BinningPass
from .raster import RasterPass
from .setup import SetupPass

# Sample offsets from the pixel centre in 1/16 pixel, y down: Direct3D's standard multisample
# patterns (D3D11_STANDARD_MULTISAMPLE_PATTERN); ×16 gives the raster's 1/256 units.
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

    def __init__(self, device, config, first: RasterPass, ortho: bool = False):
        super().__init__(device, config, ortho=ortho)
        self.first = first

    def allocate(self, width, height):
        self.vis_depth, self.vis_prim = self.first.vis_depth, self.first.vis_prim


class SampleGeometryPass(RenderPass):
    name = "msaa_geometry"
    inputs = SetupPass.inputs + ("uvs", "texels", "srgb_lut", "tex_infos", "tex_levels", "colors", "n_vertices",
                                 "has_colors")

    def __init__(self, device, config, samples: int, select: str, ortho: bool = False):
        super().__init__(device, config)
        self.trios = [(SetupPass(device, config, select=select, sample=offset, ortho=ortho), BinningPass(device, config),
                       RasterPass(device, config, ortho=ortho)) for offset in sample_offsets(samples)]
        self.outputs = tuple(n for s in range(samples) for n in (f"vis_prim_{s}", f"prims_{s}"))

    def allocate(self, width, height):
        for trio in self.trios:
            for p in trio:
                p.allocate(width, height)

    def prepare_scene(self, scene_buffers):
        for trio in self.trios:
            for p in trio:
                p.prepare_scene(scene_buffers)

    def publish(self, res):
        self.subs = []
        for s, trio in enumerate(self.trios):
            sub = Resources(buffers=dict(res.buffers), values=dict(res.values))
            for p in trio:
                p.publish(sub)
            res.buffers[f"vis_prim_{s}"] = sub["vis_prim"]
            res.buffers[f"prims_{s}"] = sub["prims"]
            self.subs.append(sub)

    def run(self, res):
        for sub, trio in zip(self.subs, self.trios):
            for p in trio:
                p.publish(sub)                   # after a grow, the buffers are new
                p.run(sub)

    def overflows(self):
        from .base import Overflow
        return [Overflow(f"{s}:{ov.name}", ov.total, ov.capacity)
                for s, trio in enumerate(self.trios) for p in trio for ov in p.overflows()]

    def grow(self, name, needed):
        s, inner = name.split(":", 1)
        for p in self.trios[int(s)]:
            if any(ov.name == inner for ov in p.overflows()):
                p.grow(inner, needed)
                return
        raise KeyError(name)
