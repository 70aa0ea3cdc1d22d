"""The host scene model, pure NumPy: Scene, Camera, Material, environments, lights rules,
animation (keyframes, skins, morphs) and tangents. No file reading beyond what a model needs (the
environment's HDR codecs: environment_files), no loaders, no OpenCL.

`clrender.scene` was a module before the package: its names stay importable from here."""
from clrender._lazy import exports

__all__, __getattr__, __dir__ = exports(__name__, {
    "model": ("Scene", "SceneObject", "Material", "Texture", "UVTransform", "Sun", "SceneError", "ALPHA_MODES", "TEXTURE_SLOTS", "SHADOW_MAP_SIZES",),
    "material": ("EXT_TEXTURE_SLOTS", "TX_TEXTURE_SLOTS"),
    "camera": ("Camera",),
    "environment": ("Environment", "STUDIO", "load_environment", "studio_environment",),
    "deform": ("Deformer", "Deformation", "Skin",),
    "keyframes": ("KeyframeAnimation", "LightKey", "LightTrack",),
    "tangents": ("generate_tangents",),
    "geometry": ("MAX_COORDINATE", "BAD_COORDINATES", "bad_vertex", "coordinates_text", "check_positions", "vertex_normals",),
}, fallback="model")
