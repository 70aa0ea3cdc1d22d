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
loop does not fault in fresh pages for every frame. (Readback, SnapshotPool, HostArrays:
clrender/render/readback.py.)

Which arrays a Frame has, their dtypes, shapes and where each comes from: the AOV table,
clrender/abi/aovs.py; each of its rows is an attribute here.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
from typing import Optional

import numpy as np

from clrender.abi import aovs
from clrender.abi import gbuffer as layout
# The readback's classes lived here: tests and callers import them from this module
from clrender.render.readback import HOST_ARRAYS, HostArrays, Readback, SnapshotPool  # noqa: F401


_MODELS = {"blinn_phong": 0, "gltf": 1}       # GField.model -> its pixels' Frame.shading_model
_VIEW_CODECS = ("int32", "float32")           # gbuffer.decode returns a view of the plane: copied


def _aov(name: str) -> cached_property:
    """The accessor of AOV `name` as its row in the AOV table (clrender/abi/aovs.py) gives it: a
    "buffer" row read from its device buffer, a "gbuffer" row decoded from its field (a shading
    model's field 0 on the other model's pixels). "host" rows are Frame's own methods."""
    row = aovs.AOVS[name]
    if row.source == "buffer":
        def get(self):
            return self.readback.get(name)
    elif row.source == "gbuffer":
        f = layout.FIELDS[row.field]
        model = _MODELS.get(f.model)

        def get(self):
            v = self._decode(row.field)
            if f.codec in _VIEW_CODECS:
                v = v.copy()
            if model is not None:
                v[self.shading_model != model] = 0.0
            return v
    else:
        raise ValueError(f"AOV {name!r} is computed on the host: Frame defines its accessor")
    shape = "(H, W)" if row.channels == 1 else f"(H, W, {'K' if row.channels == aovs.VARIABLE else row.channels})"
    get.__name__, get.__doc__ = name, f"{shape} {row.dtype} {row.doc}."
    return cached_property(get)


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

    AOV_NAMES = aovs.NAMES            # the AOV table's rows (clrender/abi/aovs.py), each an attribute below

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

    # "buffer" rows of the AOV table: each AOV's own device buffer
    color = _aov("color")
    light_count = _aov("light_count")
    image = _aov("image")
    ao = _aov("ao")
    shadow = _aov("shadow")
    fragment_count = _aov("fragment_count")
    transmittance = _aov("transmittance")
    edges = _aov("edges")

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

    # "gbuffer" rows decoded as the table says; depth, normal and albedo below
    triangle_id = _aov("triangle_id")
    linear_depth = _aov("linear_depth")
    velocity = _aov("velocity")
    emissive = _aov("emissive")
    occlusion = _aov("occlusion")
    specular_intensity = _aov("specular_intensity")
    specular_power = _aov("specular_power")
    base_color = _aov("base_color")
    metallic = _aov("metallic")
    roughness = _aov("roughness")

    @cached_property
    def _background(self) -> np.ndarray:
        return self.triangle_id < 0

    @cached_property
    def _transmission_depth(self) -> Optional[np.ndarray]:
        """(H, W) float32 view depth of the nearest transmissive surface where it is the pixel's
        nearest fragment, -1 elsewhere; None for a frame without transmissive materials."""
        if "transmission_depth" not in self.readback.names():
            return None
        return self.readback.get("transmission_depth")

    @cached_property
    def depth(self) -> np.ndarray:
        """(H, W) float32 z-depth along the camera's optical axis (what OpenCV depth maps store; not
        the distance to the eye), +inf on background; `linear_depth` is depth / far. Where a
        transmissive surface (KHR_materials_transmission) is the pixel's nearest transparent fragment
        in front of the opaque surface, the depth is that surface's (the sample object_id takes, at
        the same internal resolution): a glass pane has the pane's depth, like a depth sensor seeing
        a solid. BLEND fragments keep the opaque depth, and `linear_depth`, `normal` and the other
        G-buffer AOVs stay the opaque surface's."""
        d = (self._decode("linear_depth") * np.float32(self.far)).astype(np.float32)
        tx = self._transmission_depth
        return d if tx is None else np.where(tx >= 0, tx, d).astype(np.float32)

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
    def surface_triangle(self) -> np.ndarray:
        """(H, W) int32 index into the scene's triangles, -1 on background: the nearest surface's
        triangle, which object_id and material_id are derived from. That is the nearest transparent
        (BLEND or transmissive) fragment where the A-buffer or depth peeling found one in front of
        the opaque surface, else triangle_id (the opaque surface's)."""
        tri = self.triangle_id
        if "nearest_triangle" not in self.readback.names():
            return tri
        nearest = self.readback.get("nearest_triangle")
        return np.where(nearest >= 0, nearest, tri)

    def _per_triangle(self, table: Optional[np.ndarray], what: str) -> np.ndarray:
        tri = self.surface_triangle
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
        background = self._background
        if self._transmission_depth is not None:          # a transmissive surface over the background
            background = background & (self._transmission_depth < 0)
        depth = np.where(background, np.nan, self.depth.astype(np.float64))
        out = np.empty((h, w, 3), np.float32)
        for c in range(3):             # one (H, W) float64 plane at a time: a third of the memory traffic
            ray_x, ray_y = x * right[c], (y * up[c])[:, None]
            if cam.is_orthographic:
                plane = (ray_x + ray_y) + (cam.eye[c] - depth * back[c])
            else:
                plane = cam.eye[c] + depth * ((ray_x + ray_y) - back[c])
            out[..., c] = plane
        return out

    @cached_property
    def albedo(self) -> np.ndarray:
        """(H, W, 3) diffuse albedo: as stored on Blinn-Phong pixels, base colour × (1 − metallic)
        on glTF-BRDF pixels (from the stored base colour and metallic); 0 on background."""
        a = self._decode("albedo")
        gltf = self.shading_model == 1
        if gltf.any():
            a[gltf] = self.base_color[gltf] * (1.0 - self.metallic[gltf])[:, None]
        return a

    def aov(self, name: str) -> np.ndarray:
        if name not in self.AOV_NAMES:
            raise ValueError(f"unknown AOV {name!r}; available: {', '.join(self.AOV_NAMES)}")
        return getattr(self, name)

    def preview(self, name: str = "image") -> np.ndarray:
        """(H, W, 3) uint8 picture of AOV `name` (or "image", the display image): the same pictures
        the CLI writes as <stem>.<aov>.png (clrender.outputs.previews: depth colour-mapped near white
        to far grey, normals as RGB, ids in hashed colours, counts as a heat map, velocity as a
        colour wheel)."""
        if name == "image":
            return self.image
        from clrender.outputs.previews import preview
        out = preview(name, np.asarray(self.aov(name)), self.triangle_id < 0)
        return out if out.ndim == 3 else np.repeat(out[..., None], 3, -1)

    def contact_sheet(self, names, columns: int = 4) -> np.ndarray:
        """One uint8 image of the previews of `names` (AOV names or "image"), `columns` per row,
        each labelled with its name (clrender.outputs.previews.contact_sheet)."""
        from clrender.outputs.previews import contact_sheet
        return contact_sheet([(name, self.preview(name)) for name in names], columns)

    def _repr_png_(self) -> bytes:
        """PNG bytes of the display image: Jupyter and IPython show a Frame as its picture."""
        import io

        import imageio.v3 as iio
        buf = io.BytesIO()
        iio.imwrite(buf, self.image, extension=".png")
        return buf.getvalue()
