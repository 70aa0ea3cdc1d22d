"""`Frame`: one rendered frame, its arrays read back from the device on first access.

A 720p frame holds about 40 MB of AOVs (G-buffer planes, HDR colour, light counts, image...);
copying them all to numpy cost more than the shading on CPUs (fresh host pages for every array),
and most callers use one or two. So `Renderer.render` returns a Frame whose arrays are still on
the device, behind a `Readback`: `frame.image`, `frame.depth`, ... copy what they need when
first read (a decoded field reads only its G-buffer plane), and keep it. The values are those the
eager copy gave: the same arrays, dtypes and shapes.

The device buffers belong to the pipeline and the next `render()` overwrites them. Before it
enqueues anything, the pipeline retires the previous frame's readback: what that frame has not
read yet is copied on the device into buffers of its own (a queued copy, no wait; from a pool,
so a render loop allocates nothing), or read to the host when those copies would exceed
`SnapshotPool.budget` (frames kept in bulk without being read). Either way a Frame's arrays are
fixed when render() returns, whatever is rendered after it, and pickling a Frame reads it all.
Large reads go to host buffers reused once no array references them (`HostArrays`), so a render
loop does not fault in fresh pages for every frame.
"""
from __future__ import annotations

import sys
import threading
import weakref
from dataclasses import dataclass, field
from functools import cached_property
from typing import Callable, Optional

import numpy as np
import pyopencl as cl
import pyopencl.array as cla

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


class _Planes:
    """What layout.decode indexes: G-buffer plane i, read alone unless the whole buffer is."""

    def __init__(self, frame: "Frame"):
        self.frame = frame

    def __getitem__(self, i: int) -> np.ndarray:
        return self.frame._plane(i)


@dataclass(frozen=True, eq=False)
class Frame:
    """One rendered frame: the lit HDR color, the display image, and the packed G-buffer with
    decoded views of it. Every array is read from the device (or decoded from the G-buffer) on
    first access and kept; `fetch()` reads them all."""
    width: int
    height: int
    far: float
    stats: dict = field(default_factory=dict)
    # What `image` was encoded from, for deeper outputs (aov_io.display_linear, 16-bit PNG): the
    # tone-mapping operator and exposure; `ldr` (below) holds the final tone-mapped planes when
    # LDR post effects (edge AA, FXAA, hatching) ran.
    tonemap: str = "reinhard"
    exposure: float = 1.0
    readback: Readback = field(default_factory=Readback, repr=False)
    triangle_gltf: Optional[np.ndarray] = field(default=None, repr=False)   # (T,) bool: the triangle's material
                                                                            # is shaded with the glTF BRDF
    # Tables the ids are derived from (object_id, material_id): the scene's arrays at render() (not
    # copied, nothing computed until an id is read; Scene.set_transform and pose replace none of them)
    triangle_mesh: Optional[np.ndarray] = field(default=None, repr=False)      # (T,) int32 into scene.mesh_names
    mesh_object: Optional[np.ndarray] = field(default=None, repr=False)        # (meshes,) int32 into scene.objects
    triangle_material: Optional[np.ndarray] = field(default=None, repr=False)  # (T,) int32 into scene.materials
    camera: Optional[object] = field(default=None, repr=False)               # the Camera rendered (position)

    AOV_NAMES = ("color", "light_count", "depth", "linear_depth", "normal", "albedo", "triangle_id", "velocity",
                 "specular_intensity", "specular_power", "base_color", "metallic", "roughness", "shading_model",
                 "emissive", "occlusion", "object_id", "material_id", "position", "ao", "shadow", "fragment_count",
                 "transmittance", "edges", "image")

    # -- arrays read from the device ----------------------------------------------------------
    @cached_property
    def gbuffer(self) -> np.ndarray:
        """(planes, H, W) uint32: the packed G-buffer (layout: clrender.abi.gbuffer.FIELDS)."""
        out = np.empty((len(layout.PLANES), self.height, self.width), np.uint32)
        for i in range(len(layout.PLANES)):
            name = f"gbuffer:{i}"
            if name in self.readback.host:
                out[i] = self.readback.host[name]
            else:
                self.readback.get(name, out=out[i])
            self.readback.host[name] = out[i]          # planes read later are views of this
        return out

    def _plane(self, i: int) -> np.ndarray:
        return self.readback.get(f"gbuffer:{i}", out=None)

    @cached_property
    def color(self) -> np.ndarray:
        """(H, W, 3) float32 linear HDR."""
        return self.readback.get("color")

    @cached_property
    def light_count(self) -> np.ndarray:
        """(H, W) int32 lights the culling assigned to the pixel's tile."""
        return self.readback.get("light_count")

    @cached_property
    def image(self) -> np.ndarray:
        """(H, W, 3) uint8 sRGB, the tone-mapped colour."""
        return self.readback.get("image")

    @cached_property
    def ao(self) -> np.ndarray:
        """(H, W) float32 ambient occlusion in [0, 1], 1 = open; all ones without SSAO."""
        return self.readback.get("ao")

    @cached_property
    def shadow(self) -> np.ndarray:
        """(H, W, K) float32 visibility per shadowed light (sun first), K = 0 without."""
        return self.readback.get("shadow")

    @cached_property
    def fragment_count(self) -> np.ndarray:
        """(H, W) int32 transparent fragments in front of the opaque surface (A-buffer, peeling)."""
        return self.readback.get("fragment_count")

    @cached_property
    def transmittance(self) -> np.ndarray:
        """(H, W) float32 what the transparent layers leave of what lies behind (1 = nothing)."""
        return self.readback.get("transmittance")

    @cached_property
    def edges(self) -> np.ndarray:
        """(H, W) uint8 1 where edge_aa marked an edge pixel (all 0 without edge_aa)."""
        return self.readback.get("edges")

    @cached_property
    def ldr(self) -> Optional[np.ndarray]:
        """(H, W, 3) float32 in [0, 1]: the tone-mapped linear planes `image` was encoded from,
        when LDR post effects ran; None otherwise."""
        return self.readback.get("ldr") if "ldr" in self.readback.names() else None

    def fetch(self) -> "Frame":
        """Read every array now (the device buffers are then no longer needed)."""
        self.readback.fetch_all()
        return self

    def __getstate__(self):
        """Pickled frames carry host arrays only."""
        state = dict(self.__dict__)
        host = Readback()
        host.host = dict(self.readback.fetch_all())
        state["readback"] = host
        return state

    # -- views decoded from the G-buffer --------------------------------------------------------
    def _decode(self, name: str) -> np.ndarray:
        return layout.decode(_Planes(self), name)

    @cached_property
    def triangle_id(self) -> np.ndarray:
        return self._decode("triangle_id").copy()

    @cached_property
    def _background(self) -> np.ndarray:
        return self.triangle_id < 0

    @cached_property
    def depth(self) -> np.ndarray:
        """(H, W) float32 z-depth along the camera's optical axis (what OpenCV depth maps store; not
        the distance to the eye), +inf on background; `linear_depth` is depth / far."""
        d = self._decode("linear_depth") * np.float32(self.far)
        return d.astype(np.float32)

    @cached_property
    def linear_depth(self) -> np.ndarray:
        return self._decode("linear_depth").copy()

    @cached_property
    def normal(self) -> np.ndarray:
        n = self._decode("normal")
        n[self._background] = 0.0
        return n

    @cached_property
    def shading_model(self) -> np.ndarray:
        """(H, W) int8: 0 Blinn-Phong, 1 the glTF BRDF (RenderConfig.shading, kernels/brdf.h), -1 on
        background; from the pixel's triangle's material (the G-buffer spends no bit on it)."""
        tri = self.triangle_id
        out = np.where(tri >= 0, 0, -1).astype(np.int8)
        if self.triangle_gltf is not None and self.triangle_gltf.size:
            fg = tri >= 0
            out[fg] = self.triangle_gltf[tri[fg]].astype(np.int8)
        return out

    @cached_property
    def _surface_triangle(self) -> np.ndarray:
        """The nearest surface's triangle: the nearest transparent (BLEND) fragment where the A-buffer
        or depth peeling found one in front of the opaque surface, else triangle_id."""
        tri = self.triangle_id
        if "nearest_triangle" not in self.readback.names():
            return tri
        nearest = self.readback.get("nearest_triangle")
        return np.where(nearest >= 0, nearest, tri)

    def _per_triangle(self, table: Optional[np.ndarray], what: str) -> np.ndarray:
        tri = self._surface_triangle
        if table is None:
            raise ValueError(f"this Frame carries no per-triangle {what} table (frames from Renderer.render do)")
        out = np.full(tri.shape, -1, np.int32)
        fg = tri >= 0
        out[fg] = table[tri[fg]]
        return out

    @cached_property
    def object_id(self) -> np.ndarray:
        """(H, W) int32 index into `scene.objects` (the drawn instance: a glTF node, an OBJ group, a
        TOML [[mesh]] entry), -1 on background: the nearest surface's. That is the nearest
        transparent (BLEND) fragment where one lies in front of the opaque surface (the A-buffer's
        first fragment in its (depth, triangle id) order, depth peeling's layer 0; screen-door
        draws BLEND surfaces into the G-buffer), else the G-buffer's `triangle_id`. Derived from
        those triangle ids through per-triangle tables: the G-buffer spends no bit on it."""
        mesh = self._per_triangle(self.triangle_mesh, "object")
        return np.where(mesh >= 0, self.mesh_object[np.maximum(mesh, 0)], -1).astype(np.int32)

    @cached_property
    def material_id(self) -> np.ndarray:
        """(H, W) int32 index into `scene.materials`, -1 on background: the nearest surface's, as object_id."""
        return self._per_triangle(self.triangle_material, "material")

    @cached_property
    def position(self) -> np.ndarray:
        """(H, W, 3) float32 world-space position of the surface at each pixel centre, NaN on
        background: the camera's ray through the pixel centre (Camera.principal_offset honoured)
        at `depth`, the z-depth along the optical axis (orthographic: parallel rays). With
        supersampling the depth is the kept sample's (the one nearest the pixel centre), so on a
        slope the point may sit up to half a sample spacing off the centre ray's hit."""
        if self.camera is None:
            raise ValueError("this Frame carries no camera (frames from Renderer.render do)")
        cam = self.camera
        w, h = self.width, self.height
        tan_x, tan_y = cam.half_extents(w / h)
        ox, oy = cam.principal_offset()
        right, up, back = cam.basis()
        x = ((np.arange(w) + 0.5) * (2.0 / w) - 1.0 - ox) * tan_x            # lateral offsets of the pixel
        y = (1.0 - (np.arange(h) + 0.5) * (2.0 / h) - oy) * tan_y            # centres, per unit depth
        depth = np.where(self._background, np.nan, self.depth.astype(np.float64))
        out = np.empty((h, w, 3), np.float32)
        for c in range(3):             # one (H, W) float64 plane at a time: a third of the memory traffic
            ray_x, ray_y = x * right[c], (y * up[c])[:, None]
            if cam.is_orthographic:
                plane = (ray_x + ray_y) + (cam.eye[c] - depth * back[c])
            else:
                plane = cam.eye[c] + depth * ((ray_x + ray_y) - back[c])
            out[..., c] = plane
        return out

    def _model_field(self, name: str, model: int) -> np.ndarray:
        """A model-dependent field (clrender.abi.gbuffer: they share bits), 0 on other pixels."""
        v = self._decode(name)
        v[self.shading_model != model] = 0.0
        return v

    @cached_property
    def albedo(self) -> np.ndarray:
        """(H, W, 3) diffuse albedo: as stored on Blinn-Phong pixels, base colour × (1 − metallic)
        on glTF-BRDF pixels (from the stored base colour and metallic); 0 on background."""
        a = self._decode("albedo")
        gltf = self.shading_model == 1
        if gltf.any():
            a[gltf] = self.base_color[gltf] * (1.0 - self.metallic[gltf])[:, None]
        return a

    @cached_property
    def specular_intensity(self) -> np.ndarray:
        """(H, W) Blinn-Phong pixels' specular intensity; 0 elsewhere."""
        return self._model_field("specular_intensity", 0)

    @cached_property
    def specular_power(self) -> np.ndarray:
        """(H, W) Blinn-Phong pixels' specular power; 0 elsewhere."""
        return self._model_field("specular_power", 0)

    @cached_property
    def base_color(self) -> np.ndarray:
        """(H, W, 3) glTF-BRDF pixels' linear base colour; 0 elsewhere."""
        return self._model_field("base_color", 1)

    @cached_property
    def metallic(self) -> np.ndarray:
        """(H, W) glTF-BRDF pixels' metallic; 0 elsewhere."""
        return self._model_field("metallic", 1)

    @cached_property
    def roughness(self) -> np.ndarray:
        """(H, W) glTF-BRDF pixels' perceptual roughness; 0 elsewhere."""
        return self._model_field("roughness", 1)

    @cached_property
    def velocity(self) -> np.ndarray:
        return self._decode("velocity")

    @cached_property
    def emissive(self) -> np.ndarray:
        """(H, W, 3) emissive factor × texture in [0, 1], before the material's emissive_strength."""
        return self._decode("emissive")

    @cached_property
    def occlusion(self) -> np.ndarray:
        """(H, W) the material's ambient occlusion (occlusionTexture), 1 = open, 0 on background."""
        return self._decode("occlusion")

    def aov(self, name: str) -> np.ndarray:
        if name not in self.AOV_NAMES:
            raise ValueError(f"unknown AOV {name!r}; available: {', '.join(self.AOV_NAMES)}")
        return getattr(self, name)

    def preview(self, name: str = "image") -> np.ndarray:
        """(H, W, 3) uint8 picture of AOV `name` (or "image", the display image): the same pictures
        the CLI writes as <stem>.<aov>.png (clrender.outputs.aov_io.preview: depth colour-mapped near white
        to far grey, normals as RGB, ids in hashed colours, counts as a heat map, velocity as a
        colour wheel)."""
        if name == "image":
            return self.image
        from clrender.outputs.aov_io import preview
        out = preview(name, np.asarray(self.aov(name)), self.triangle_id < 0)
        return out if out.ndim == 3 else np.repeat(out[..., None], 3, -1)

    def contact_sheet(self, names, columns: int = 4) -> np.ndarray:
        """One uint8 image of the previews of `names` (AOV names or "image"), `columns` per row,
        each labelled with its name (clrender.outputs.aov_io.contact_sheet)."""
        from clrender.outputs.aov_io import contact_sheet
        return contact_sheet([(name, self.preview(name)) for name in names], columns)

    def _repr_png_(self) -> bytes:
        """PNG bytes of the display image: Jupyter and IPython show a Frame as its picture."""
        import io

        import imageio.v3 as iio
        buf = io.BytesIO()
        iio.imwrite(buf, self.image, extension=".png")
        return buf.getvalue()
