"""glTF 2.0 (.gltf/.glb) → Scene: the spec's tables (spec), the document (document) and its
validation by part (validate), compression extensions (compression), geometry, materials, skins,
animations (animation), and the scene assembly (assemble); `info` describes a file for `clrender info`."""
from clrender._lazy import exports

__all__, __getattr__, __dir__ = exports(__name__, {
    "assemble": ("load_gltf",),
    "document": ("load_document",),
    "info": ("gltf_details", "format_details", "is_gltf",),
})
