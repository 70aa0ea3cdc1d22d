"""Scene + Camera → Frame: Renderer (the one-call API), Pipeline (passes wired per
configuration, the frame loop), which passes run (plan), the camera's upload (camera_upload),
Frame.stats (stats), build progress (build_progress), the frame's arrays (frame; read from the device: readback), the scene's
device buffers (scene_upload, texture_pool) and the memory budget (memory)."""
from clrender._lazy import exports

__all__, __getattr__, __dir__ = exports(__name__, {
    "renderer": ("Renderer", "RenderConfig",),
    "frame": ("Frame",),
    "pipeline": ("Pipeline", "pass_ms",),
})
