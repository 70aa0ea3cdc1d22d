"""A Frame's arrays → files: PNG/JPEG, 16-bit PNG, EXR layers, NPY, video, AOV previews and
contact sheets, written atomically."""
from clrender._lazy import exports

__all__, __getattr__, __dir__ = exports(__name__, {
    "aov_io": ("write_outputs", "write_image", "write_exr", "write_video", "write_aovs", "preview", "contact_sheet", "atomic_write", "read_exr",),
})
