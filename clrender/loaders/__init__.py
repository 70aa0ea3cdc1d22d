"""Scene loaders: `load_scene(path)` dispatches on the file suffix.

.gltf / .glb (glTF 2.0), .obj (+ .mtl), .ply, .stl (all through trimesh) and .toml (a scene file
that places several of those, with a camera, render settings and lights). Every loader returns one
world-space `clrender.scene.Scene` and reports bad input as `clrender.scene.SceneError`.

load (the dispatch), gltf/ (glTF 2.0), mesh (OBJ/PLY/STL), toml_tables + toml_scene (TOML scenes:
the tables checked, then assembled; format in docs/scene-format.md), common (what every loader
shares), confine (which files a scene may read), context and budget (one load's state and memory).
"""
from clrender._lazy import exports

__all__, __getattr__, __dir__ = exports(__name__, {
    "load": ("load_scene", "SUFFIXES"),
})
