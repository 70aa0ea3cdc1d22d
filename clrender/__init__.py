"""clrender: a tiled deferred renderer whose every pixel is computed by OpenCL kernels."""
from clrender.scene.camera import Camera
from clrender.scene.model import Material, Scene, SceneError, Sun, Texture

__all__ = ["Camera", "Material", "Scene", "SceneError", "Sun", "Texture", "load_scene",
           "Renderer", "RenderConfig", "Frame", "list_devices", "view"]


def __getattr__(name):
    # Lazy: importing clrender must not initialise OpenCL.
    if name == "load_scene":
        from clrender.loaders import load_scene
        return load_scene
    if name == "RenderConfig":                  # numpy only (clrender/config.py)
        from clrender.config import RenderConfig
        return RenderConfig
    if name in ("Renderer", "Frame"):
        from clrender.render import renderer
        return getattr(renderer, name)
    if name == "view":                          # the browser viewer (clrender/viewer/; the `view` extra)
        from clrender.viewer import view
        return view
    if name == "list_devices":
        from clrender.device.core import list_devices
        return list_devices
    raise AttributeError(name)
