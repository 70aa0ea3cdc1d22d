"""Render passes: one pass module per kernel file (kernels/<name>.cl <-> passes/<name>.py)."""
from .abuffer import AbufferPass
from .base import RenderPass, Resources
from .binning import BinningPass
from .chunk_cull import ChunkCullPass
from .composite import CompositePass
from .fragments import FragmentsPass
from .gbuffer import GBufferPass
from .light_cull import LightCullPass
from .particles import ParticlesPass
from .peel import PeelPass
from .raster import RasterPass
from .setup import SetupPass
from .shade import ShadePass
from .shadow import ShadowPass
from .ssao import SsaoPass
from .ssao_blur import SsaoBlurPass
from .tonemap import TonemapPass

__all__ = ["RenderPass", "Resources", "ChunkCullPass", "SetupPass", "BinningPass", "RasterPass", "GBufferPass",
           "LightCullPass", "ParticlesPass", "SsaoPass", "SsaoBlurPass", "ShadowPass", "ShadePass",
           "TonemapPass", "FragmentsPass", "AbufferPass", "PeelPass", "CompositePass"]
