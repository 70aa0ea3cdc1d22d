"""A Frame's arrays → files: PNG/JPEG, 16-bit PNG, EXR layers, NPY, video, AOV previews and
contact sheets, written atomically. Which AOVs there are: the table in clrender/abi/aovs.py."""
from clrender._lazy import exports

__all__, __getattr__, __dir__ = exports(__name__, {
    "aov_io": ("write_outputs", "write_image", "write_aovs",),
    "exr": ("write_exr", "read_exr",),
    "video": ("write_video",),
    "previews": ("preview", "contact_sheet",),
    "atomic": ("atomic_write",),
})
