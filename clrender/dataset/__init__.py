"""Synthetic datasets for NeRF / COLMAP tools: the views (views), the camera files (camera_file:
`clrender view`'s saved shots, `render --camera`), what each view writes (outputs), and the
reader (load_dataset).

`clrender.dataset` was a module before the package: its names stay importable from here."""
from clrender._lazy import exports

__all__, __getattr__, __dir__ = exports(__name__, {
    "views": ("load_dataset", "layout_cameras", "export_documents",),
    "camera_file": ("read_camera_file", "file_cameras", "entry_camera", "camera_entry", "append_camera"),
}, fallback="views")
