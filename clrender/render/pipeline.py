"""The pipeline: wires the passes a configuration runs (clrender/render/plan.py) by resource
name, allocates buffers once per resolution, builds programs once, runs the frame loop, times
every pass with OpenCL profiling, and handles buffers whose size is known only on the device
(count, grow, render again). Camera upload, stats, readback and build progress live in their own
render/ modules."""
from __future__ import annotations

import inspect
import weakref

import numpy as np
import pyopencl as cl
import pyopencl.array as cla

from clrender.abi import gbuffer as layout
from clrender.device.timestamps import stamp
from clrender.render import plan
from clrender.render.build_progress import BuildProgress
from clrender.render.camera_upload import camera_buffers, upload_camera
from clrender.render.frame import Readback, SnapshotPool
from clrender.render.stats import HOST_PHASES, NOT_PASS_MS, HostClock, frame_stats, pass_ms  # noqa: F401  (their old home)
from clrender.passes import (
    AbufferPass, BinningPass, FragmentsPass, GBufferPass, LightCullPass, PeelPass, RasterPass, Resources,
    SetupPass, ShadowPass, TonemapPass)
from clrender.passes.light_quads import LightQuadsPass
from clrender.passes.material import MaterialPass
from clrender.passes.second_geometry import RasterAgainPass, SampleGeometryPass

MAX_RETRIES = 8


class Pipeline:
    def __init__(self, device, config, ortho: bool = False):
        """ortho: the camera is orthographic (Camera.is_orthographic): every pass that rasterizes the
        camera's view or rebuilds positions from its depth is built with ORTHO=1."""
        self.device = device
        self.config = config
        self.ortho = bool(ortho)
        self.queue = device.queue
        # BLEND triangles: left to the transparency passes (A-buffer, peeling) or dithered into
        # the G-buffer (screen door); a scene without any renders exactly as without this.
        self.select = "opaque" if FragmentsPass.runs(config) else "dither"
        self.passes = []
        for cls in plan.pass_classes(config):      # each pass says whether it runs for config
            self.passes.append(self._make(cls))
        by_class = {type(p): p for p in self.passes}
        # by role: the stats' counters, the light lists, the shadow maps
        self.setup, self.binning, self.raster = by_class[SetupPass], by_class[BinningPass], by_class[RasterPass]
        self.light_cull = by_class.get(LightCullPass) or by_class.get(LightQuadsPass)
        self.shadow = by_class.get(ShadowPass)
        # run only for scenes with BLEND triangles; allocated on first use
        self.transparency = [p for p in self.passes if plan.stage(type(p)) == "transparency"]
        # Over-sampling: everything before the resolve renders k·W × k·H; it filters down to W × H.
        self.post = [p for p in self.passes if plan.stage(type(p)) == "output"]
        self.size = None
        self.transparency_size = None
        self.matrices = camera_buffers(self.queue)
        self.constants = {"srgb_encode": cla.to_device(self.queue, layout.srgb_encode_table())}
        # Frames read their AOVs on first access (clrender/render/frame.py); the last one is retired
        # (its unread AOVs copied aside on the device) before the next frame overwrites them.
        self.snapshots = SnapshotPool(self.queue, min(device.cl_device.global_mem_size // 8, 1 << 30))
        self._pending = None
        self.pose_pass = None           # skins and morph targets: built for the first deformed scene
        self._pose_timing = None        # its profiling timestamps for the next frame's stats
        self._totals = None           # the overflow totals gathered for one read
        self._wired = False           # the wiring is checked against the first frame's resources
        self.progress = BuildProgress(device)

    def _make(self, cls):
        """One pass of the plan, with what it takes besides (device, config): the camera's
        projection (ortho), the passes it shares buffers with (built before it, in plan order)."""
        d, c, view = self.device, self.config, {"ortho": self.ortho}
        built = {type(p): p for p in self.passes}
        special = {
            SetupPass: lambda: SetupPass(d, c, select=self.select, **view),
            GBufferPass: lambda: GBufferPass(d, c, planes=layout.geometry_planes(c), **view),
            AbufferPass: lambda: AbufferPass(d, c, built[FragmentsPass]),
            PeelPass: lambda: PeelPass(d, c, built[FragmentsPass]),
            RasterAgainPass: lambda: RasterAgainPass(d, c, built[RasterPass], **view),
            SampleGeometryPass: lambda: SampleGeometryPass(d, c, c.msaa, self.select, **view),
            MaterialPass: lambda: MaterialPass(d, c, c.msaa, **view),
            # without LDR effects one tonemap kernel writes the image (docs/post.md)
            TonemapPass: lambda: TonemapPass(d, c, ldr=True) if c.ldr_effects else TonemapPass(d, c),
        }
        if cls in special:
            return special[cls]()
        # the passes that rasterize the camera's view or rebuild positions from its depth
        return cls(d, c, **view) if "ortho" in inspect.signature(cls).parameters else cls(d, c)

    def pose(self, upload, res: Resources) -> None:
        """Skinned and morphing vertices (Scene.deformation) posed on the device into `res` before
        the frame (clrender/passes/pose.py); the rewritten buffers go back into the scene's cached
        `upload`, so the next frame of an unchanged pose launches nothing."""
        if self.pose_pass is None:
            from clrender.passes.pose import PosePass
            self.pose_pass = PosePass(self.device, self.config)
        self.pose_pass.prepare_scene(res)
        start = stamp(self.device)
        self.pose_pass.run(res)
        self._pose_timing = ("pose", start, stamp(self.device)) if self.pose_pass.ran else None
        for name in ("positions", "normals", "tangents"):
            upload.buffers[name] = res.buffers[name]
        if "prev_positions" in upload.buffers:
            upload.buffers["prev_positions"] = res.buffers["prev_positions"]

    def _check_wiring(self, res: Resources):
        """Every input a pass declares is in the frame's resources before the passes (scene
        upload, lights, camera, constants: `res`, the first frame's) or an earlier pass's output."""
        produced = set(res.buffers) | set(res.values)
        for p in self.passes:
            missing = set(p.inputs) - produced
            if missing:
                raise RuntimeError(f"pass {p.name} reads {sorted(missing)} before any pass writes it")
            produced |= set(p.outputs)

    def resize(self, width, height, transparent: bool = False):
        """Passes before the resolve at the internal size (k·width × k·height), the post chain at
        (width, height)."""
        k = self.config.supersample
        if self.size != (width, height):
            self.snapshots.clear()
            for p in self.passes:
                if p not in self.transparency:
                    p.allocate(*((width, height) if p in self.post else (k * width, k * height)))
            self.size = (width, height)
        if transparent and self.transparency_size != (width, height):
            for p in self.transparency:
                p.allocate(k * width, k * height)
            self.transparency_size = (width, height)

    def render(self, scene_res: Resources, camera, width, height, prev_camera=None, time=0.0):
        """Run every pass; returns (outputs: dict of host arrays, stats dict). stats["host"] splits
        the host's time (see HOST_PHASES)."""
        clock = HostClock()
        previous = self._pending() if self._pending is not None else None
        if previous is not None:
            previous.retire()            # before anything below overwrites what it still reads
        transparent = bool(self.transparency) and scene_res["n_transparent_tris"] > 0
        self.resize(width, height, transparent)
        res = Resources(buffers=dict(scene_res.buffers), values=dict(scene_res.values))
        res.buffers.update(self.matrices)
        res.buffers.update(self.constants)
        k = self.config.supersample
        if prev_camera == camera and "prev_positions" not in res.buffers:
            prev_camera = None        # nothing moved: velocity exactly 0, not reprojection round-off
        internal = upload_camera(self.queue, self.matrices, camera, k * width, k * height, prev_camera, self.ortho)
        res.values.update(internal, time=float(time), camera=camera)
        if not self._wired:
            self._check_wiring(res)
            self._wired = True
        for p in self.passes:
            if transparent or p not in self.transparency:
                p.prepare_scene(scene_res)
                p.use_texel_format(scene_res.values.get("texels_linear", False))
        clock.lap("prepare_ms")

        retries = 0
        while True:
            timings = []
            res.values.update(width=k * width, height=k * height)     # the resolve switches to the output size
            for p in self.transparency:
                p.clear_stage_events()
            frame_passes = [p for p in self.passes if transparent or p not in self.transparency]
            # (a pass whose programs are made in publish is only known to be active after it)
            upfront = [p for p in frame_passes if p.builds_on_publish or p.active(res)]
            with self.progress.stage(upfront) as stage:
                for p in frame_passes:                  # no BLEND triangle: no buffer, no kernel
                    p.publish(res)
                    if not p.active(res):
                        continue                        # an effect the scene does not use: no kernel
                    self.progress.before_run(p, stage)  # programs only known now (shadow-map stages)
                    # Stamps right around the run (on Intel's runtime a stamp is a kernel launch:
                    # clrender/device/timestamps.py): the host's work between passes (publish, the shadow
                    # views' planning) is not device time, whereas one stamp shared by consecutive
                    # passes would count the device's idle wait for it in the next pass
                    start = stamp(self.device)
                    p.run(res)
                    timings.append((p.name, start, stamp(self.device)))
                    self.progress.after_run(p, stage)
            clock.lap("enqueue_ms")
            grown = self._grow_overflowing()
            clock.lap("overflow_wait_ms")
            if not grown:
                break
            retries += 1
            if retries > MAX_RETRIES:
                raise RuntimeError(f"buffers kept overflowing after {MAX_RETRIES} retries: {grown}")

        if self._pose_timing is not None:          # the vertex pre-pass ran before this frame
            timings.insert(0, self._pose_timing)
            self._pose_timing = None
        readback = self._readback(res, width, height, transparent)
        clock.lap("readback_ms")
        stats = frame_stats(self, res, timings, readback, transparent, retries)
        clock.lap("stats_ms")
        stats["host"] = clock.laps
        self._pending = weakref.ref(readback)
        return readback, stats

    def _readback(self, res, width, height, transparent) -> Readback:
        """The frame's AOVs as device sources, read on first access (clrender/render/readback.py)."""
        from clrender.render.readback import frame_readback
        frag_count = self.transparency[0].frag_count if transparent else None
        return frame_readback(self.queue, self.snapshots, self.config, res, width, height, transparent, frag_count)

    def _read_totals(self, totals: list) -> list:
        """The int32 first elements of `totals`, gathered on the device and read in one blocking
        read (the shadow pass alone has two per map: a read each cost a round trip)."""
        if len(totals) <= 1:
            return [int(t.get(queue=self.queue)[0]) for t in totals]
        if self._totals is None or self._totals.size < len(totals):
            self._totals = cla.empty(self.queue, len(totals), np.int32)
        for i, t in enumerate(totals):
            cl.enqueue_copy(self.queue, self._totals.data, t.base_data, byte_count=4, src_offset=t.offset,
                            dst_offset=4 * i)
        return [int(v) for v in self._totals.get(queue=self.queue)[: len(totals)]]

    def _grow_overflowing(self) -> list:
        grown = []
        needs = [(p, ov) for p in self.passes for ov in p.overflows()]
        largest: dict = {}        # (pass, buffer) -> (need, capacity): shadow maps of one size share buffers
        for (p, ov), total in zip(needs, self._read_totals([ov.total for _, ov in needs])):
            need, _ = largest.get((p, ov.name), (0, 0))
            largest[p, ov.name] = (max(need, total), ov.capacity)
        for (p, name), (total, capacity) in largest.items():
            if total > capacity:
                try:
                    p.grow(name, total)
                except cl.Error as exc:
                    from clrender.render.memory import DeviceMemoryError
                    raise DeviceMemoryError(f"growing {p.name} buffer {name} to {total} entries failed on "
                                            f"{self.device.name}: {exc}") from None
                grown.append((name, total, capacity))
        # Any growth means later passes consumed a truncated buffer: the caller redoes the frame.
        # Every buffer that overflowed grows now, not one per redo: a pass reads only the entries
        # its input holds, so a count behind a truncated buffer can only be short (it grows again
        # on the next redo), never inflated. (The Oclgrind tier's A-buffer and peeling frames went
        # from 3 and 2 redos to 2 and 1.)
        return grown
