"""Profiling timestamps in a device's queue: what every per-pass, per-stage and per-view time in
Frame.stats is measured between (clrender/render/pipeline.py, passes/base.py `timed`, passes/shadow.py).

A stamp is a marker event where the device's markers carry profiling time, else a launch of an
empty one-work-item kernel (kernels/timestamp.cl): Intel's CPU runtime reports start = end = 0 for
markers but real times for kernels. Work between two stamps takes `elapsed_ms(start, end)`: the
first stamp's start to the second's end. On Intel a kernel stamp costs ~8 us of host time to
enqueue (a marker ~2-16 us elsewhere) and well under 1 us of device time.
"""
from __future__ import annotations

import pyopencl as cl

from clrender.device import capabilities
from clrender.device.core import ProgramSpec

SPEC = ProgramSpec.of("timestamp.cl")


def stamp(device, queue=None) -> cl.Event:
    """Enqueue a timestamp on `queue` (default: the clrender Device's queue, which profiles)."""
    queue = queue if queue is not None else device.queue
    if capabilities.markers_carry_time(device.cl_device):
        return cl.enqueue_marker(queue)
    return cl.enqueue_nd_range_kernel(queue, _kernel(device), (1,), (1,))


def elapsed_ms(start: cl.Event, end: cl.Event) -> float:
    """Device milliseconds from stamp `start` to stamp `end` (both complete)."""
    return (end.profile.end - start.profile.start) * 1e-6


def _kernel(device) -> cl.Kernel:
    # One Kernel object per Device, built through its program cache (its own progress stage when
    # built outside a frame's up-front builds). It has no arguments, so launching it from two
    # threads needs no clSetKernelArg/enqueue lock.
    kernel = device.__dict__.get("_timestamp_kernel")
    if kernel is None:
        device.build([SPEC])
        kernel = device.__dict__["_timestamp_kernel"] = cl.Kernel(device.program_for(SPEC), "timestamp")
    return kernel
