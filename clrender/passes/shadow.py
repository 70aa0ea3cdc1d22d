"""Shadow-map pass (report II.4 "Ombres"): the depth of the scene seen from each shadowed
light, rendered by the camera's own rasterizer stages -- SetupPass, BinningPass and a
depth-only RasterPass (kernels/setup.cl, binning.cl, raster.cl) -- into that light's square of
one shadow atlas. No kernel of its own; kernels/shadow.h (in shade.cl) reads the atlas.

Views (clrender/passes/shadow_views.py): the sun's orthographic cascades first (setup/raster built
with ORTHO=1), then one perspective view per shadowed spot light in light order. Maps of the
same (size, projection) share one set of stages and run one after another; each view's prim
and tile-list totals are copied aside so the pipeline's grow-and-retry sees every view's need.

With RenderConfig.chunk_cull each view's setup first culls the scene's triangle chunks against
the view (clrender/passes/chunk_cull.py; the chunk boxes are computed once per scene geometry and
shared with the camera), so a spot light's map reads only the triangles near its cone.

Maps are kept between frames: a view whose matrix, clip range, atlas square, scene upload and
atlas are those it was last rendered with is not rendered again (static spot lights in an
animation cost nothing after the first frame; sun cascades follow the camera and are redone).
A view whose own buffers overflow invalidates the cache, so a truncated map is never kept.

Launches nothing when the frame has no shadow map (the pipeline skips the pass).
"""
from __future__ import annotations

import numpy as np
import pyopencl as cl
import pyopencl.array as cla

from clrender.device import limits, tuning
from clrender.passes import shadow_views
from clrender.abi import structs
from clrender.errors import DeviceMemoryError
from clrender.device.timestamps import elapsed_ms, stamp
from clrender.passes.base import Overflow, RenderPass, Resources, empty, zeros
from clrender.passes.binning import BinningPass
from clrender.passes.raster import RasterPass
from clrender.passes.setup import SetupPass

STAGES = ("setup", "binning", "raster")


class _MapStages:
    """Setup, binning and depth-only raster sized for maps of one side and projection."""

    def __init__(self, device, config, size: int, ortho: bool, scene_res):
        tile = tuning.shadow_tile_size(device.cl_device, config)
        self.setup = SetupPass(device, config, ortho=ortho, status=False)    # nothing reads a map's statuses
        self.binning = BinningPass(device, config, tile)
        self.raster = RasterPass(device, config, ortho=ortho, depth_only=True, tile=tile)
        for p in (self.setup, self.binning, self.raster):
            p.allocate(size, size)
        if scene_res is not None:
            self.prepare_scene(scene_res)

    def prepare_scene(self, scene_res):
        """Room for the scene's prims and tile lists (no first-frame overflow and re-render)."""
        self.setup.prepare_scene(scene_res)
        self.binning.prepare_scene(scene_res)


def _may_overlap(a, b) -> bool:
    """Do two atlas squares (row stride, x0, y0, size) share a word? Squares of one layout are
    compared as rectangles; across layouts (another stride) as the linear spans they cover."""
    (sa, xa, ya, na), (sb, xb, yb, nb) = a, b
    if sa == sb:
        return xa < xb + nb and xb < xa + na and ya < yb + nb and yb < ya + na
    lo_a, hi_a = ya * sa + xa, (ya + na - 1) * sa + xa + na
    lo_b, hi_b = yb * sb + xb, (yb + nb - 1) * sb + xb + nb
    return lo_a < hi_b and lo_b < hi_a


class ShadowPass(RenderPass):
    name = "shadow"
    inputs = ("positions", "triangles", "tri_material", "materials", "n_tris", "uvs", "texels",
              "tex_infos", "tex_levels", "colors", "n_vertices", "has_colors", "shadow_lights", "sun", "camera", "scene_bounds", "width", "height")
    outputs = ("shadow_atlas", "shadow_views", "shadow_layout", "shadow_view_count")

    builds_on_publish = True

    @classmethod
    def runs(cls, config):
        return bool(config.shadows)     # off: shade.cl built without lookups

    def active(self, res):
        return bool(res["shadow_view_count"])    # no shadowed light, no shadowed sun: no kernel

    def __init__(self, device, config):
        super().__init__(device, config)
        self.stages: dict = {}
        self.scene_res = None
        self.layout = shadow_views.EMPTY
        self.layout_key = None
        self.atlas = empty(self.queue, 1, np.float32)
        self.views = cla.to_device(self.queue, np.zeros(1, structs.shadow_view_dtype))
        self.matrices: list = []      # per view: float[16] for setup.cl
        self.totals: list = []        # per view: (prims needed, tile entries needed) int[1] each
        self.events: list = []
        self.rendered: dict = {}      # view index -> (inputs it was rendered from, referenced buffers)
        self.cached_views = 0

    def prepare_scene(self, scene_res):
        self.scene_res = scene_res
        # Kept maps of another scene upload can never be reused: let its buffers go now.
        self.rendered = {k: kept for k, kept in self.rendered.items() if kept[1][0] is scene_res["positions"]}
        for st in self.stages.values():
            st.prepare_scene(scene_res)

    def publish(self, res):
        layout = shadow_views.layout(res["shadow_lights"], res["sun"], res["camera"], res["width"] / res["height"],
                                     res["scene_bounds"], self.config)
        records = layout.records()
        key = (records.tobytes(), tuple((v.size, v.ortho, v.near, v.far) for v in layout.views))
        if key != self.layout_key:
            self._upload(layout, records)
            self.layout_key = key
        self.layout = layout
        res.buffers.update(shadow_atlas=self.atlas, shadow_views=self.views)
        res.values.update(shadow_layout=layout, shadow_view_count=len(layout.views))

    def _upload(self, layout, records):
        """Stages for new map sizes, atlas and view records, per-view matrices (host work,
        done once per change of layout, not per frame)."""
        for v in layout.views:
            if (v.size, v.ortho) not in self.stages:
                self.stages[v.size, v.ortho] = _MapStages(self.device, self.config, v.size, v.ortho, self.scene_res)
        texels = layout.atlas_width * layout.atlas_height
        if texels > self.atlas.size:
            self._check_atlas_fits(layout, 4 * texels)
            self.atlas = None                 # release the old atlas before allocating the new one
            self.atlas = empty(self.queue, texels, np.float32)
        self.views = cla.to_device(self.queue, records)
        while len(self.matrices) < len(layout.views):
            self.matrices.append(zeros(self.queue, 16, np.float32))
            self.totals.append((zeros(self.queue, 1, np.int32), zeros(self.queue, 1, np.int32)))
        for m, v in zip(self.matrices, layout.views):
            m.set(np.ascontiguousarray(v.matrix, np.float32).reshape(-1), queue=self.queue)

    def _check_atlas_fits(self, layout, nbytes):
        total, max_alloc = limits.limits(self.device.cl_device)
        if nbytes > min(max_alloc, total):
            raise DeviceMemoryError(
                f"the shadow atlas ({layout.atlas_width}x{layout.atlas_height} texels for {len(layout.views)} maps) "
                f"needs {nbytes} bytes but {self.device.name} allows {min(max_alloc, total)} per allocation; "
                f"lower the lights' shadow_map_size")

    def _view_inputs(self, res, v):
        """What a map's texels depend on; buffers are compared by identity (kept referenced)."""
        scene = tuple(res[name] for name in ("positions", "triangles", "tri_material", "materials", "texels",
                                             "tex_infos", "tex_levels", "uvs", "colors"))
        square = (self.layout.atlas_width, v.x0, v.y0, v.size)      # atlas row stride and square
        return (v.matrix.tobytes(), v.near, v.far, v.ortho, square), scene + (self.atlas,)

    def _unchanged(self, k, inputs):
        kept = self.rendered.get(k)
        return kept is not None and kept[0] == inputs[0] and all(a is b for a, b in zip(kept[1], inputs[1]))

    def _claim(self, k, inputs):
        """View k is about to overwrite its atlas square: kept maps it may touch are gone."""
        square = inputs[0][4]
        self.rendered = {j: kept for j, kept in self.rendered.items()
                         if j != k and not _may_overlap(kept[0][4], square)}
        self.rendered[k] = inputs

    def run(self, res):
        self.events = []
        self.cached_views = 0
        self.rendered = {k: kept for k, kept in self.rendered.items() if k < len(self.layout.views)}
        stride = self.layout.atlas_width
        for k, v in enumerate(self.layout.views):
            inputs = self._view_inputs(res, v)
            if self.config.shadow_map_reuse and self._unchanged(k, inputs):
                self.cached_views += 1
                continue
            self._claim(k, inputs)
            st = self.stages[v.size, v.ortho]
            sub = Resources(buffers={**res.buffers, "view_proj": self.matrices[k], "raster_target": self.atlas},
                            values={**res.values, "width": v.size, "height": v.size, "near": v.near, "far": v.far,
                                    "raster_offset": v.y0 * stride + v.x0, "raster_stride": stride})
            # A timestamp between consecutive stages (4 a view, not 6: on Intel's runtime each is a
            # kernel launch); a stage's time includes what its publish and its total's copy enqueue.
            start = stamp(self.device)
            for stage, total in ((st.setup, st.setup.prim_total), (st.binning, st.binning.total), (st.raster, None)):
                stage.publish(sub)
                stage.run(sub)
                if total is not None:    # this view's need, before the next view overwrites it
                    slot = self.totals[k][0 if stage is st.setup else 1]
                    cl.enqueue_copy(self.queue, slot.data, total.data, byte_count=4)
                self.events.append((stage.name, start, stamp(self.device)))
                start = self.events[-1][2]

    def overflows(self):
        out = []
        for k, v in enumerate(self.layout.views):
            st = self.stages[v.size, v.ortho]
            tag = f"{v.size}:{int(v.ortho)}"
            out.append(Overflow(f"{tag}:prims", self.totals[k][0], st.setup.capacity))
            out.append(Overflow(f"{tag}:tile_prims", self.totals[k][1], st.binning.list_capacity))
        return out

    def grow(self, name, needed):
        self.rendered.clear()          # a map rendered with too small a buffer is incomplete
        size, ortho, what = name.split(":")
        st = self.stages[int(size), bool(int(ortho))]
        (st.setup if what == "prims" else st.binning).grow(what, needed)

    def pass_stats(self) -> dict:
        """ms of the shadow maps' setup, binning and raster (sums over views), and the map count."""
        out = {f"shadow_{s}_ms": 0.0 for s in STAGES}
        for name, start, end in self.events:
            out[f"shadow_{name}_ms"] += elapsed_ms(start, end)
        out["shadow_maps"] = len(self.layout.views)
        out["shadow_maps_reused"] = self.cached_views
        out["shadow_atlas_texels"] = self.layout.atlas_width * self.layout.atlas_height
        return out
