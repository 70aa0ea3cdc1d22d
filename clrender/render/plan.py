"""Which passes a configuration runs, in the pipeline's order, and at which size each allocates.

Each pass answers `runs(config)` itself (clrender/passes/base.py); this table only orders them.
The Pipeline builds exactly these passes, and memory.estimate() sums their `buffer_bytes`, so the
two cannot drift apart. Stages: "internal" (k·W × k·H before the resolve), "transparency" (also
internal, allocated only for a scene with BLEND or transmissive triangles), "output" (W × H: resolve and post).
"""
from __future__ import annotations

from clrender.passes.abuffer import AbufferPass
from clrender.passes.binning import BinningPass
from clrender.passes.bloom import BloomPass
from clrender.passes.composite import CompositePass
from clrender.passes.edge_aa import EdgeAaPass
from clrender.passes.encode import EncodePass
from clrender.passes.forward_shade import ForwardShadePass
from clrender.passes.fragments import FragmentsPass
from clrender.passes.fxaa import FxaaPass
from clrender.passes.gbuffer import GBufferPass
from clrender.passes.hatching import HatchingPass
from clrender.passes.ibl import IblPass
from clrender.passes.light_buffer import LightBufferPass
from clrender.passes.light_cull import LightCullPass
from clrender.passes.light_quads import LightQuadsPass
from clrender.passes.light_stencil import LightStencilPass
from clrender.passes.material import MaterialPass
from clrender.passes.motion_blur import MotionBlurPass
from clrender.passes.particles import ParticlesPass
from clrender.passes.peel import PeelPass
from clrender.passes.raster import RasterPass
from clrender.passes.resolve import ResolvePass
from clrender.passes.second_geometry import RasterAgainPass, SampleGeometryPass
from clrender.passes.setup import SetupPass
from clrender.passes.shade import ShadePass
from clrender.passes.shadow import ShadowPass
from clrender.passes.ssao import SsaoPass
from clrender.passes.ssao_blur import SsaoBlurPass
from clrender.passes.surface_layers import SurfaceLayersPass
from clrender.passes.tonemap import TonemapPass
from clrender.passes.transmission import TransmissionPass

# The frame's order (docs/variants.md, docs/post.md): geometry, the transparent fragments' walk,
# light lists, SSAO, shadow maps, the environment, the lighting variant (deferred: shade;
# light_prepass: light buffer, geometry again, material; light_indexed: geometry again, forward
# shade), the surface layers of the materials that have them, the opaque colour's mip chain for
# transmissive materials, the transparency resolve and composite, then at the output size the
# resolve of over-sampling and the post chain (HDR effects, tone map, LDR effects, encode).
ORDER = (
    SetupPass, BinningPass, RasterPass, GBufferPass, ParticlesPass, FragmentsPass,
    LightCullPass, LightStencilPass, LightQuadsPass, SsaoPass, SsaoBlurPass, ShadowPass, IblPass,
    ShadePass, LightBufferPass, RasterAgainPass, SampleGeometryPass, MaterialPass, ForwardShadePass, SurfaceLayersPass,
    TransmissionPass, AbufferPass, PeelPass, CompositePass,
    ResolvePass, BloomPass, MotionBlurPass, TonemapPass, EdgeAaPass, FxaaPass, HatchingPass, EncodePass,
)
TRANSPARENCY = (FragmentsPass, TransmissionPass, AbufferPass, PeelPass, CompositePass)
OUTPUT = (ResolvePass, BloomPass, MotionBlurPass, TonemapPass, EdgeAaPass, FxaaPass, HatchingPass, EncodePass)


def stage(cls) -> str:
    return "transparency" if cls in TRANSPARENCY else "output" if cls in OUTPUT else "internal"


def pass_classes(config) -> list:
    """The pass classes a Pipeline for `config` builds, in order."""
    return [cls for cls in ORDER if cls.runs(config)]
