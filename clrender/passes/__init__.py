"""Render passes: one pass module per kernel file (kernels/<name>.cl <-> passes/<name>.py)."""
from .base import RenderPass, Resources
from .binning import BinningPass
from .gbuffer import GBufferPass
from .raster import RasterPass
from .setup import SetupPass

__all__ = ["RenderPass", "Resources", "SetupPass", "BinningPass", "RasterPass", "GBufferPass"]
