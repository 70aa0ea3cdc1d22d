"""A frame's arrays on the device until read: `Readback` (device sources read on first access),
`SnapshotPool` (device copies of a retired frame's unread arrays), `HostArrays` (reused host
memory for large reads), and `frame_readback`, which registers a rendered frame's AOVs as the
table (clrender/abi/aovs.py) says. Why reads are lazy: clrender/render/frame.py."""
from __future__ import annotations

import sys
import threading
import weakref
from typing import Callable, Optional

import numpy as np
import pyopencl as cl
import pyopencl.array as cla

from clrender.abi import aovs
from clrender.abi import gbuffer as layout


class SnapshotPool:
    """Device buffers that retired readbacks copy their unread AOVs into, reused once the frame
    holding them is read or collected. `budget`: bytes of copies alive at once; a retire beyond
    it reads to the host instead (so keeping many unread frames costs host memory, as it always
    did, not device memory)."""

    def __init__(self, queue, budget: int):
        self.queue = queue
        self.budget = int(budget)
        self.live = 0
        self.free: dict = {}          # nbytes -> [byte Array]
        # give_back runs in whichever thread reads a frame's last array or collects a frame (a
        # finalizer, possibly inside take's own allocation: hence re-entrant)
        self.lock = threading.RLock()

    def take(self, nbytes: int) -> Optional[cla.Array]:
        with self.lock:
            if self.live + nbytes > self.budget:
                return None
            self.live += nbytes
            bucket = self.free.get(nbytes)
            return bucket.pop() if bucket else cla.empty(self.queue, nbytes, np.uint8)

    def give_back(self, held: list) -> None:
        with self.lock:
            for copy in held:
                self.live -= copy.nbytes
                self.free.setdefault(copy.nbytes, []).append(copy)
            held.clear()

    def clear(self) -> None:
        """Drop the free buffers (a new resolution will not reuse their sizes)."""
        with self.lock:
            self.free.clear()

    @property
    def held_bytes(self) -> int:
        with self.lock:
            return self.live + sum(b.nbytes for bucket in self.free.values() for b in bucket)


class HostArrays:
    """Host memory for large reads, reused once nothing references it any more. A fresh numpy
    array of 100 MB costs 11 ms of page faults when first written (100-250 ms when the kernel is
    short of free pages: seen on 4K frames); one whose pages were touched before, 4 ms. A buffer
    is handed out again only when the pool's own list holds the last reference to it (every
    array or view made from it, however derived, references it), so reuse never aliases an
    array a caller still has. At most `budget` bytes of unreferenced buffers are kept."""

    MIN_BYTES = 4 << 20          # smaller reads: plain np.empty (few pages, nothing to gain)

    def __init__(self, budget: int = 1 << 30):
        self.budget = int(budget)
        self.buffers: list = []  # uint8 arrays, oldest first
        self.lock = threading.Lock()

    def empty(self, count: int, dtype) -> np.ndarray:
        dtype = np.dtype(dtype)
        nbytes = int(count) * dtype.itemsize
        if nbytes < self.MIN_BYTES:
            return np.empty(count, dtype)
        with self.lock:
            for i in range(len(self.buffers)):
                if self.buffers[i].nbytes == nbytes and self._unreferenced(i):
                    buf = self.buffers.pop(i)
                    break
            else:
                buf = np.empty(nbytes, np.uint8)
            self.buffers.append(buf)                 # most recently used last
            del buf
            self._trim()
            return self.buffers[-1].view(dtype)

    def _unreferenced(self, i: int) -> bool:
        return sys.getrefcount(self.buffers[i]) == 2      # the list's and getrefcount's argument

    def _trim(self) -> None:
        """Forget the oldest unreferenced buffers beyond the budget, and referenced ones beyond
        64 entries (they belong to their arrays and are freed with them)."""
        free = [i for i in range(len(self.buffers) - 1) if self._unreferenced(i)]
        excess = sum(self.buffers[i].nbytes for i in free) - self.budget
        drop = set()
        for i in free:
            if excess <= 0:
                break
            drop.add(i)
            excess -= self.buffers[i].nbytes
        busy = [i for i in range(len(self.buffers) - 1) if i not in free]
        drop.update(busy[:max(len(self.buffers) - 64, 0)])
        self.buffers = [b for i, b in enumerate(self.buffers) if i not in drop]


HOST_ARRAYS = HostArrays()


class _Source:
    """One AOV on the device: `nbytes` at `offset` of `buffer`, read as `dtype` and shaped by
    `finish` (host array -> the Frame's array)."""
    __slots__ = ("buffer", "offset", "count", "dtype", "finish")

    def __init__(self, array, finish: Callable):
        self.buffer, self.offset = array.base_data, array.offset
        self.count, self.dtype, self.finish = array.size, array.dtype, finish

    @property
    def nbytes(self) -> int:
        return self.count * self.dtype.itemsize


class Readback:
    """A frame's arrays: device sources read on first `get`, values already on the host, and
    makers of the constant ones (all ones without SSAO...), made on first use."""

    def __init__(self, queue=None, pool: Optional[SnapshotPool] = None):
        self.queue = queue
        self.pool = pool
        self.sources: dict = {}
        self.host: dict = {}
        self.makers: dict = {}
        self._held: list = []         # pool buffers this readback's sources were copied into
        # A read (any thread, after render() returned) and the retire the next render() does
        # (under the device lock) must not interleave: a source popped for reading but not yet
        # enqueued would be missed by retire and read after the next frame overwrote it.
        # Re-entrant: retire reads sources itself when the pool's budget is spent.
        self.lock = threading.RLock()
        if pool is not None:
            weakref.finalize(self, pool.give_back, self._held)

    def __getstate__(self):
        """A pickled Frame's readback holds host arrays only (Frame.__getstate__); locks do not pickle."""
        state = dict(self.__dict__)
        state.pop("lock", None)
        return state

    def __setstate__(self, state):
        self.__dict__.update(state)
        self.lock = threading.RLock()

    def add(self, name: str, array, finish: Callable = lambda a: a) -> None:
        """`array`: a pyopencl Array (or a slice of one) the pipeline keeps on the device."""
        self.sources[name] = _Source(array, finish)

    def put(self, name: str, value) -> None:
        self.host[name] = value

    def make(self, name: str, maker: Callable) -> None:
        self.makers[name] = maker

    def names(self) -> set:
        return set(self.sources) | set(self.host) | set(self.makers)

    def get(self, name: str, out: Optional[np.ndarray] = None):
        with self.lock:
            return self._get(name, out)

    def _get(self, name: str, out: Optional[np.ndarray]):
        if name in self.host:
            return self.host[name]
        if name in self.makers:
            value = self.makers.pop(name)()
        else:
            src = self.sources.pop(name)
            host = HOST_ARRAYS.empty(src.count, src.dtype) if out is None else out.reshape(-1)
            cl.enqueue_copy(self.queue, host, src.buffer, src_offset=src.offset, is_blocking=True)
            value = src.finish(host)
            if not self.sources and self.pool is not None:
                self.pool.give_back(self._held)       # everything read: the copies are free again
        self.host[name] = value
        return value

    def pending(self) -> bool:
        return bool(self.sources)

    def retire(self) -> None:
        """Detach from the pipeline's buffers before the next frame overwrites them: queue a
        device copy of each unread source into a pool buffer, or read it now when the pool's
        budget is spent."""
        with self.lock:
            for name, src in list(self.sources.items()):
                copy = self.pool.take(src.nbytes) if self.pool is not None else None
                if copy is None:
                    self._get(name, None)
                    continue
                cl.enqueue_copy(self.queue, copy.data, src.buffer, byte_count=src.nbytes, src_offset=src.offset)
                self._held.append(copy)
                src.buffer, src.offset = copy.data, 0

    def fetch_all(self) -> dict:
        with self.lock:
            for name in list(self.sources) + list(self.makers):
                self._get(name, None)
            return self.host


def _device_sources(config, res, transparent: bool, frag_count) -> dict:
    """{AOV: (device array, first plane)} for each "buffer" row of the AOV table: where the pipeline's
    passes left it this frame (their resource names); None where no pass wrote it (the row's fill)."""
    return {
        "color": (res["color"], 0),
        "light_count": (res["light_count"], 0),
        "image": (res["image"], 0),
        "shadow": (res["shadow"], 0) if res["shadow_planes"] else None,
        "ao": (res["ao"], 0) if config.ssao else None,          # no SSAO kernel ran: the term is 1 everywhere
        "fragment_count": (frag_count, 0) if transparent else None,
        "transmittance": (res["layers"], 3) if transparent else None,    # the layers' transmittance plane
        "edges": (res["edges"], 0) if config.edge_aa else None,
    }


def frame_readback(queue, pool, config, res, width: int, height: int, transparent: bool,
                   frag_count=None) -> Readback:
    """A rendered frame's arrays as device sources (read on first access) and makers of the
    constant ones, as the AOV table says (clrender/abi/aovs.py: each "buffer" row's resolution,
    packing and fill), plus the G-buffer planes and the internal arrays Frame derives AOVs from.
    Arrays rendered before the resolve are at k·W × k·H: the Frame gets each output pixel's
    nearest sample. `frag_count`: the transparency pass's fragment counts."""
    k = config.supersample
    iw, ih = k * width, k * height
    n, out_px = iw * ih, width * height
    rb = Readback(queue, pool)

    def internal(planes=1, last_axis=False):
        def finish(a):
            a = a.reshape(planes, ih, iw)
            a = np.ascontiguousarray(a[:, k // 2::k, k // 2::k]) if k > 1 else a
            return np.ascontiguousarray(np.moveaxis(a, 0, -1)) if last_axis else a[0]
        return finish

    def output(planes, last_axis):
        if last_axis:
            return lambda a: np.moveaxis(a.reshape(planes, height, width), 0, -1)
        return lambda a: a.reshape(height, width)

    for i in range(len(layout.PLANES)):
        rb.add(f"gbuffer:{i}", res["gbuffer"][i * out_px:(i + 1) * out_px], lambda a: a.reshape(height, width))
    sources = _device_sources(config, res, transparent, frag_count)
    for aov in aovs.by_source("buffer"):
        where = sources[aov.name]
        if where is None:
            shape, fill, dtype = aov.shape(height, width, 0), aov.fill, np.dtype(aov.dtype)
            rb.make(aov.name, lambda shape=shape, fill=fill, dtype=dtype: np.full(shape, fill, dtype))
            continue
        array, first = where
        last_axis = aov.channels != 1
        planes = res["shadow_planes"] if aov.channels == aovs.VARIABLE else aov.channels
        if aov.packing == "rgba8":           # one RGBA word per pixel: the RGB bytes
            planes = 1
            finish = lambda a: np.ascontiguousarray(a.reshape(height, width, 1).view(np.uint8)[..., :3])  # noqa: E731
        elif aov.resolution == "internal":
            finish = internal(planes, last_axis)
        else:
            finish = output(planes, last_axis)
        px = n if aov.resolution == "internal" else out_px
        rb.add(aov.name, array[first * px: (first + planes) * px], finish)
    if transparent:       # the nearest transparent fragment's triangle (Frame.object_id, material_id)
        rb.add("nearest_triangle", res["layers"][6 * n: 7 * n], lambda a: internal()(a).view(np.int32))
    if transparent and "tx_planes" in res.buffers:     # the nearest transmissive surface's view depth (Frame.depth)
        rb.add("transmission_depth", res["tx_planes"][8 * n: 9 * n], internal())
    if config.ldr_effects:            # the final LDR planes the image was encoded from (Frame.ldr)
        rb.add("ldr", res["ldr"][: 3 * out_px],
               lambda a: np.ascontiguousarray(np.moveaxis(a.reshape(3, height, width), 0, -1)))
    return rb
