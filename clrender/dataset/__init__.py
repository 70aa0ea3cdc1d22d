"""Synthetic datasets for NeRF / COLMAP tools: the views and camera files (views), what each
view writes (outputs), and the reader (load_dataset).

`clrender.dataset` was a module before the package: its names stay importable from here."""
from clrender._lazy import exports

__all__, __getattr__, __dir__ = exports(__name__, {
    "views": ("load_dataset", "layout_cameras", "file_cameras", "read_camera_file", "export_documents",),
}, fallback="views")
