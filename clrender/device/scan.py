"""Exclusive prefix sum with grand total on device buffers (kernels/scan.cl).

Passes turn per-item counts into list offsets with it (count, scan, fill). It replaces
pyopencl's GenericScanKernel, which Oclgrind flags (a global-memory race in scan_lev1 and
uninitialized reads), so that every kernel clrender runs is clean under the simulator.
"""
from __future__ import annotations

import numpy as np
import pyopencl as cl
import pyopencl.array as cla

from clrender.device import capabilities
from clrender.device.buffers import fill_zero


class PrefixSum:
    """`scan(counts, offsets, total, size=None, queue=None)`: offsets[i] = Σ counts[:i] for
    i < size (default counts.size), total[0] = Σ counts[:size]. Enqueues only, never waits.
    Scratch buffers (one per recursion level) are kept and grown, never allocated per call."""

    def __init__(self, device):
        self.work_group, items = capabilities.scan_shape(device.cl_device)
        self.block = self.work_group * items
        defines = {"SCAN_WG": self.work_group, "SCAN_ITEMS": items}
        self.scan_blocks = device.kernel("scan.cl", "scan_blocks", defines)
        self.add_offsets = device.kernel("scan.cl", "scan_add_offsets", defines)
        self.context = device.context
        self._scratch: list[tuple[cl.Buffer, cl.Buffer, int]] = []   # per level: sums, offsets, capacity

    def __call__(self, counts: cla.Array, offsets: cla.Array, total: cla.Array, size=None, queue=None):
        n = counts.size if size is None else int(size)
        if n > min(counts.size, offsets.size):
            raise ValueError(f"scan of {n} items over buffers of {counts.size} and {offsets.size}")
        queue = queue or counts.queue
        if n == 0:
            fill_zero(total, queue)
            return
        self._scan(queue, 0, counts.data, n, offsets.data, total.data)

    def _scan(self, queue, level, counts, n, offsets, total):
        n_blocks = -(-n // self.block)
        if n_blocks == 1:                  # the block total is the grand total
            self.scan_blocks(queue, (self.work_group,), (self.work_group,), counts, np.int32(n), offsets, total)
            return
        sums, sum_offsets = self._level(level, n_blocks)
        self.scan_blocks(queue, (n_blocks * self.work_group,), (self.work_group,), counts, np.int32(n),
                         offsets, sums)
        self._scan(queue, level + 1, sums, n_blocks, sum_offsets, total)
        # a fixed local size: PoCL compiles per local size (passes/base.py launch_1d)
        self.add_offsets(queue, (-(-n // 64) * 64,), (64,), offsets, np.int32(n), sum_offsets)

    def _level(self, level, n_blocks):
        if level == len(self._scratch) or self._scratch[level][2] < n_blocks:
            capacity = max(n_blocks, 2 * self._scratch[level][2] if level < len(self._scratch) else 0)
            pair = tuple(cl.Buffer(self.context, cl.mem_flags.READ_WRITE, 4 * capacity) for _ in range(2))
            entry = (*pair, capacity)
            if level == len(self._scratch):
                self._scratch.append(entry)
            else:
                self._scratch[level] = entry
        return self._scratch[level][:2]

    @property
    def scratch_bytes(self) -> int:
        return sum(8 * capacity for _, _, capacity in self._scratch)


_SCANS: dict = {}


def prefix_sum_for(device) -> PrefixSum:
    """One PrefixSum per device (the passes of every renderer on it share its scratch)."""
    scan = _SCANS.get(device.info.id)
    if scan is None:
        scan = _SCANS[device.info.id] = PrefixSum(device)
    return scan
