"""OpenCL: choosing a device (core, probe), building and caching programs (core, cache),
what an implementation can do (capabilities, icd), pass timing (timestamps) and the prefix sum (scan).
Knows no pass and no scene."""
from clrender._lazy import exports

__all__, __getattr__, __dir__ = exports(__name__, {
    "core": ("Device", "DeviceInfo", "DeviceError", "ProgramSpec", "list_devices", "kernels_dir", "no_device_error",),
    "probe": ("open_device", "select_devices", "default_device_info",),
    "report": ("devices_table", "device_record",),
    "scan": ("prefix_sum_for",),
}, fallback="core")
