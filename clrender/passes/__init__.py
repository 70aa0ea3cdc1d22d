"""Render passes: one pass module per kernel file (kernels/<name>.cl <-> passes/<name>.py), the
contract in base.py; _template.py <-> kernels/_template.cl is a minimal pass to copy."""
from clrender.passes.abuffer import AbufferPass
from clrender.passes.base import RenderPass, Resources
from clrender.passes.binning import BinningPass
from clrender.passes.chunk_cull import ChunkCullPass
from clrender.passes.composite import CompositePass
from clrender.passes.fragments import FragmentsPass
from clrender.passes.gbuffer import GBufferPass
from clrender.passes.light_cull import LightCullPass
from clrender.passes.particles import ParticlesPass
from clrender.passes.peel import PeelPass
from clrender.passes.raster import RasterPass
from clrender.passes.setup import SetupPass
from clrender.passes.shade import ShadePass
from clrender.passes.shadow import ShadowPass
from clrender.passes.ssao import SsaoPass
from clrender.passes.ssao_blur import SsaoBlurPass
from clrender.passes.tonemap import TonemapPass

__all__ = ["RenderPass", "Resources", "ChunkCullPass", "SetupPass", "BinningPass", "RasterPass", "GBufferPass",
           "LightCullPass", "ParticlesPass", "SsaoPass", "SsaoBlurPass", "ShadowPass", "ShadePass",
           "TonemapPass", "FragmentsPass", "AbufferPass", "PeelPass", "CompositePass"]
