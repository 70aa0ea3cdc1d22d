"""Host mirrors of the kernels' shared headers: the structs of kernels/structs.h as numpy
dtypes, the G-buffer layout of kernels/gbuffer.h, and the table of a frame's outputs (AOVs).
Layer: above clrender.errors/config, below everything else; numpy only."""
from clrender._lazy import exports

__all__, __getattr__, __dir__ = exports(__name__, {
    "structs": ("light_dtype", "material_dtype",),
    "gbuffer": ("PLANES", "FIELDS", "linear_to_srgb8", "srgb_to_linear_lut",),
    "aovs": ("AOV", "AOVS",),
})
