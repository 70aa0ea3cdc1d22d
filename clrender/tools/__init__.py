"""Tools over the API: the cross-device check (`clrender check`), warm-up (programs built ahead)
and the device probe's child process."""
from clrender._lazy import exports

__all__, __getattr__, __dir__ = exports(__name__, {
    "check": ("run_check",),
    "warmup": ("warm_up", "prepare_in_background", "render_probe_scene",),
})
