"""OpenCL: which devices exist and which is preferred (choice), whether one runs the kernels (probe),
opening it, building and caching programs (core, cache),
what an implementation can do (capabilities, icd), memory limits (limits), buffer helpers (buffers),
pass timing (timestamps) and the prefix sum (scan).
Knows no pass and no scene."""
from clrender._lazy import exports

__all__, __getattr__, __dir__ = exports(__name__, {
    "core": ("Device", "ProgramSpec",),
    "choice": ("DeviceInfo", "DeviceError", "list_devices", "match_devices", "kernels_dir", "no_device_error",),
    "probe": ("open_device", "select_devices", "default_device_info",),
    "report": ("devices_table", "device_record",),
    "scan": ("prefix_sum_for",),
    "limits": ("check_buffer",),
    "buffers": ("fill_zero",),
}, fallback="core")
