"""Pure device-buffer helpers (no pass, no kernel of clrender's): allocate, zero-fill, round sizes.
passes/base.py re-exports them for the passes; device/scan.py uses them directly."""
from __future__ import annotations

import numpy as np
import pyopencl as cl
import pyopencl.array as cla

from clrender.device import capabilities


def zeros(queue, n, dtype) -> cla.Array:
    a = cla.empty(queue, max(int(n), 1), dtype)
    fill_zero(a, queue)
    return a


def fill_zero(a: cla.Array, queue=None) -> None:
    """Enqueue a = 0: clEnqueueFillBuffer, which needs no kernel (pyopencl's fill kernels cost a
    fresh process ~40 ms to build per dtype); on Oclgrind, whose checker does not count
    FillBuffer's output as written, pyopencl's fill kernel."""
    queue = queue or a.queue
    if capabilities.fill_buffer_marks_initialized(queue.device):
        cl.enqueue_fill_buffer(queue, a.base_data, np.uint8(0), a.offset, a.nbytes)
    else:
        a.fill(0, queue=queue)


def empty(queue, n, dtype) -> cla.Array:
    return cla.empty(queue, max(int(n), 1), dtype)


def round_up(n: int, multiple: int) -> int:
    return (int(n) + multiple - 1) // multiple * multiple
