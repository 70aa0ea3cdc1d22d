"""The deferred pipeline: wires passes by resource name, allocates buffers once per
resolution, builds programs once, times every pass with OpenCL profiling, and handles
buffers whose size is known only on the device (count, grow, render again)."""
from __future__ import annotations

from contextlib import contextmanager, nullcontext
from time import perf_counter as _perf_counter

import weakref

import numpy as np
import pyopencl as cl
import pyopencl.array as cla

from clrender.abi import gbuffer as layout
from clrender import progress
from clrender.device.core import lazy_kernels
from clrender.render.frame import Readback, SnapshotPool
from clrender.passes.base import zeros
from clrender.device.timestamps import elapsed_ms, stamp
from clrender.passes.encode import EncodePass
from clrender.passes.resolve import ResolvePass
from clrender.passes import (
    AbufferPass, BinningPass, CompositePass, FragmentsPass, GBufferPass, LightCullPass, ParticlesPass, PeelPass,
    RasterPass, Resources, SetupPass, ShadePass, ShadowPass, SsaoBlurPass, SsaoPass, TonemapPass)

MAX_RETRIES = 8
# Frame.stats["host"]: where render()'s wall time goes on the host, in order. upload: scene and
# light uploads (Renderer.render); prepare: per-scene pass setup; enqueue: launching the passes
# (Python and the driver's enqueue calls); overflow_wait: reading the overflow totals, which waits
# for the device to finish the frame; readback: copying the AOVs to numpy; stats: the counters
# read back for Frame.stats; other: the rest of render() (Frame assembly, checks). They add up
# to stats["wall_ms"]. Device time is in the per-pass *_ms (profiling events).
HOST_PHASES = ("upload_ms", "prepare_ms", "enqueue_ms", "overflow_wait_ms", "readback_ms", "stats_ms", "other_ms")
# *_ms keys of Frame.stats that are not a pass's own device time
NOT_PASS_MS = ("total_ms", "span_ms", "wall_ms")


def pass_ms(stats: dict) -> dict:
    """The device time of each pass (and stage breakdowns) in a Frame.stats dict."""
    return {k: v for k, v in stats.items() if k.endswith("_ms") and k not in NOT_PASS_MS}


class _HostClock:
    """Accumulates host time per phase between `lap` calls."""

    def __init__(self):
        self.laps = {}
        self.last = _perf_counter()

    def lap(self, phase: str) -> None:
        now = _perf_counter()
        self.laps[phase] = self.laps.get(phase, 0.0) + (now - self.last) * 1e3
        self.last = now

class Pipeline:
    def __init__(self, device, config, ortho: bool = False):
        """ortho: the camera is orthographic (Camera.is_orthographic): every pass that rasterizes the
        camera's view or rebuilds positions from its depth is built with ORTHO=1."""
        self.device = device
        self.config = config
        self.ortho = bool(ortho)
        self.queue = device.queue
        view = {"ortho": self.ortho}
        # BLEND triangles: left to the transparency passes (A-buffer, peeling) or dithered into
        # the G-buffer (screen door); a scene without any renders exactly as without this.
        fragments = config.transparency != "screen_door"
        self.select = "opaque" if fragments else "dither"
        self.raster = RasterPass(device, config, **view)
        self.passes = [SetupPass(device, config, select=self.select, **view), BinningPass(device, config),
                       self.raster, GBufferPass(device, config, planes=layout.geometry_planes(config), **view),
                       ParticlesPass(device, config)]
        self.transparency = []          # run only for scenes with BLEND triangles; allocated on first use
        if fragments:
            walk = FragmentsPass(device, config, **view)
            resolve = (AbufferPass if config.transparency == "abuffer" else PeelPass)(device, config, walk)
            self.transparency = [walk, resolve, CompositePass(device, config)]
            self.passes.append(walk)
        # Per-tile light lists (docs/light_accumulation.md): tiled culling, or the lights' screen
        # quads; "stencil" adds per-pixel bits over the tiled lists. Brute force launches no culling kernel.
        if config.light_culling in ("tiled", "stencil"):
            self.light_cull = LightCullPass(device, config, **view)
            self.passes.append(self.light_cull)
            if config.light_culling == "stencil":
                from clrender.passes.light_stencil import LightStencilPass
                self.passes.append(LightStencilPass(device, config, **view))
        elif config.light_culling == "quads":
            from clrender.passes.light_quads import LightQuadsPass
            self.light_cull = LightQuadsPass(device, config, **view)
            self.passes.append(self.light_cull)
        else:
            self.light_cull = None
        if config.ssao:                            # off: no SSAO kernel, shade uses ao = 1
            self.passes.append(SsaoPass(device, config, **view))
            if config.ssao_blur:
                self.passes.append(SsaoBlurPass(device, config))
        # Shadow maps (setup/binning/raster again, per light view); off: shade.cl built without lookups.
        self.shadow = ShadowPass(device, config) if config.shadows else None
        if self.shadow is not None:
            self.passes.append(self.shadow)
        # The environment's maps (Scene.set_environment): precomputed once per environment.
        from clrender.passes.ibl import IblPass
        self.passes += [IblPass(device, config), *self._lighting_passes(device, config), *self.transparency[1:]]
        # Over-sampling: everything so far renders k·W × k·H; the resolve filters down to W × H.
        self.post = ([ResolvePass(device, config)] if config.supersample > 1 else []) + self._post_passes(device, config)
        self.passes += self.post
        self._check_wiring()
        self.size = None
        self.transparency_size = None
        self.matrices = {name: zeros(self.queue, 16, np.float32)
                         for name in ("view_proj", "prev_view_proj", "view_matrix", "camera_params")}
        self.constants = {"srgb_encode": cla.to_device(self.queue, layout.srgb_encode_table())}
        # Frames read their AOVs on first access (clrender/render/frame.py); the last one is retired
        # (its unread AOVs copied aside on the device) before the next frame overwrites them.
        self.snapshots = SnapshotPool(self.queue, min(device.cl_device.global_mem_size // 8, 1 << 30))
        self._pending = None
        self.pose_pass = None           # skins and morph targets: built for the first deformed scene
        self._pose_timing = None        # its profiling timestamps for the next frame's stats
        self._totals = None           # the overflow totals gathered for one read
        self._launched: set = set()   # passes launched at least once (their kernels compiled)
        self._built: set = set()      # passes whose programs are all built

    def _lighting_passes(self, device, config) -> list:
        """From the light lists to the colour (docs/variants.md). deferred: shading from the
        G-buffer. light_prepass: the light buffer from the thin G-buffer, the geometry again
        (at the msaa sub-samples), the material pass. light_indexed: the raster again, then
        forward shading of the visible fragments with their tile's lights. reuse_visibility: no second
        raster, the passes read pass 1's visibility buffer (which nothing writes in between)."""
        view = {"ortho": self.ortho}
        if config.pipeline == "deferred":
            return [ShadePass(device, config, **view)]
        from clrender.passes.second_geometry import RasterAgainPass, SampleGeometryPass
        again = ([] if config.reuse_visibility else [RasterAgainPass(device, config, self.raster, **view)]
                 if config.msaa == 1 else [SampleGeometryPass(device, config, config.msaa, self.select, **view)])
        if config.pipeline == "light_prepass":
            from clrender.passes.light_buffer import LightBufferPass
            from clrender.passes.material import MaterialPass
            return [LightBufferPass(device, config, **view), *again, MaterialPass(device, config, config.msaa, **view)]
        from clrender.passes.forward_shade import ForwardShadePass
        return [*again, ForwardShadePass(device, config, **view)]

    @staticmethod
    def _post_passes(device, config) -> list:
        """The post chain at the output resolution (docs/post.md): bloom -> motion blur (HDR) ->
        tone map -> edge AA -> FXAA -> hatching (LDR) -> encode; without LDR effects one tonemap
        kernel writes the image. A disabled effect has no pass."""
        chain = []
        if config.bloom:
            from clrender.passes.bloom import BloomPass
            chain.append(BloomPass(device, config))
        if config.motion_blur:
            from clrender.passes.motion_blur import MotionBlurPass
            chain.append(MotionBlurPass(device, config))
        if not config.ldr_effects:
            return chain + [TonemapPass(device, config)]
        chain.append(TonemapPass(device, config, ldr=True))
        if config.edge_aa:
            from clrender.passes.edge_aa import EdgeAaPass
            chain.append(EdgeAaPass(device, config))
        if config.color_aa == "fxaa":
            from clrender.passes.fxaa import FxaaPass
            chain.append(FxaaPass(device, config))
        if config.hatching:
            from clrender.passes.hatching import HatchingPass
            chain.append(HatchingPass(device, config))
        return chain + [EncodePass(device, config)]

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

    def _check_wiring(self):
        produced = {"positions", "normals", "uvs", "tangents", "colors", "n_vertices", "has_colors", "surface_extras",
                    "triangles", "tri_material", "materials", "texels", "srgb_lut", "tex_infos", "tex_levels", "n_tris", "view_proj", "prev_view_proj",
                    "near", "far", "width", "height", "has_prev", "tiles_x", "tiles_y",
                    "lights", "n_lights", "ambient", "view_matrix", "camera_params", "tan_x", "tan_y",
                    "shift_x", "shift_y",
                    "srgb_encode", "particle_systems", "time", "sun", "shadow_lights", "scene_bounds", "camera",
                    "n_transparent_tris", "gltf_scene", "environment"}
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

    def _set_camera(self, camera, width, height, prev_camera):
        """Upload the camera matrices; returns the scalar camera values passes read. tan_x, tan_y:
        the image's half-extents per unit depth (perspective) or in world units (orthographic:
        ymag·aspect, ymag), as the camera block's R·tan_x, U·tan_y; shift_x, shift_y: the principal
        point in NDC (Camera.principal_offset), also the camera block's eye.w and F.w."""
        if camera.is_orthographic != self.ortho:
            raise ValueError(f"this pipeline renders {'orthographic' if self.ortho else 'perspective'} cameras, "
                             f"got a {camera.projection} one (Renderer picks the pipeline)")
        vp = camera.raster_matrix(width, height)
        prev = prev_camera.view_projection(width, height) if prev_camera else camera.view_projection(width, height)
        tan_x, tan_y = (float(v) for v in camera.half_extents(width / height))
        shift_x, shift_y = camera.principal_offset()     # an off-centre principal point (Camera.from_opencv)
        right, up, back = camera.basis()
        params = np.zeros((4, 4))
        params[0, :3], params[1, :3], params[2, :3], params[3, :3] = camera.eye, -back, right * tan_x, up * tan_y
        params[0, 3], params[1, 3] = shift_x, shift_y
        for name, m in (("view_proj", vp), ("prev_view_proj", prev), ("view_matrix", camera.view_matrix()),
                        ("camera_params", params)):
            self.matrices[name].set(np.ascontiguousarray(m, np.float32).reshape(-1), queue=self.queue)
        return dict(width=width, height=height, near=camera.near, far=camera.far,
                    has_prev=int(prev_camera is not None), tan_x=tan_x, tan_y=tan_y, shift_x=shift_x, shift_y=shift_y)

    def render(self, scene_res: Resources, camera, width, height, prev_camera=None, time=0.0):
        """Run every pass; returns (outputs: dict of host arrays, stats dict). stats["host"] splits
        the host's time (see HOST_PHASES)."""
        clock = _HostClock()
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
        internal = self._set_camera(camera, k * width, k * height, prev_camera)
        res.values.update(internal, time=float(time), camera=camera)
        for p in self.passes:
            if transparent or p not in self.transparency:
                p.prepare_scene(scene_res)
        clock.lap("prepare_ms")

        retries = 0
        while True:
            timings = []
            res.values.update(width=k * width, height=k * height)     # the resolve switches to the output size
            for p in self.transparency:
                p.clear_stage_events()
            with self._first_use_stage(res, transparent) as stage:
                for p in self.passes:
                    if p in self.transparency and not transparent:
                        continue                        # no BLEND triangle: no buffer, no kernel
                    p.publish(res)
                    if p.name == "particles" and not res["particle_systems"]:
                        continue                        # no particles: no kernel
                    if p.name == "shadow" and not res["shadow_view_count"]:
                        continue                        # no shadowed light, no shadowed sun: no kernel
                    if p.name == "ibl" and res["environment"] is None:
                        continue                        # no environment: the constant ambient, no kernel
                    if stage is not None:               # programs only known now (shadow-map stages)
                        self.device.build(k.spec for k in lazy_kernels(p))
                    # Stamps right around the run (on Intel's runtime a stamp is a kernel launch:
                    # clrender/device/timestamps.py): the host's work between passes (publish, the shadow
                    # views' planning) is not device time, whereas one stamp shared by consecutive
                    # passes would count the device's idle wait for it in the next pass
                    start = stamp(self.device)
                    p.run(res)
                    timings.append((p.name, start, stamp(self.device)))
                    if stage is not None and p not in self._launched and p.name != "shadow":
                        self._launched.add(p)
                        stage.advance(f"first launch: {p.name}")
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
        stats = {f"{name}_ms": elapsed_ms(start, end) for name, start, end in timings}
        stats["total_ms"] = sum(stats.values())
        if timings:       # first pass's start to last pass's end: the passes plus any gap between them
            stats["span_ms"] = elapsed_ms(timings[0][1], timings[-1][2])
        stats.update(self.passes[0].triangle_stats())
        stats["prims"] = int(self.passes[0].prim_total.get(queue=self.queue)[0])
        stats["tile_entries"] = int(self.passes[1].total.get(queue=self.queue)[0])
        stats["tile_size"] = self.config.tile_size
        stats["retries"] = retries
        stats["supersample"] = k
        stats["pipeline"] = self.config.pipeline
        # rasterizations of the scene: the second pass tests every msaa sample in one walk
        stats["geometry_passes"] = 1 if self.config.pipeline == "deferred" or self.config.reuse_visibility else 2
        from clrender.render.memory import pixel_buffers
        stats["bytes_per_pixel"] = pixel_buffers(self.config)
        stats.update(self._fragment_stats(readback, transparent))
        for p in self.transparency if transparent else ():
            stats.update(p.stage_stats())         # breakdowns of their pass's ms, not added to total_ms
        if self.shadow is not None and res["shadow_view_count"]:
            stats.update(self.shadow.pass_stats())     # breakdown of shadow_ms, not added to total_ms
        stats["lights"] = res["n_lights"]
        if self.light_cull is not None:
            stats.update(self.light_cull.tile_stats())
        else:
            stats.update(lights_per_tile_avg=float(res["n_lights"]), lights_per_tile_max=res["n_lights"])
        for p in self.passes:                      # (pixel, light) pairs the shading evaluated / needed
            if hasattr(p, "pair_stats"):
                stats.update(p.pair_stats())
        clock.lap("stats_ms")
        stats["host"] = clock.laps
        self._pending = weakref.ref(readback)
        return readback, stats

    def _fragment_stats(self, readback, transparent) -> dict:
        """Transparent fragments: total, per-pixel max, and those max_fragments_per_pixel dropped."""
        if not transparent:
            return {"fragments": 0, "fragments_max": 0, "fragments_dropped": 0}
        counts = readback.get("fragment_count")
        total = int(counts.sum(dtype=np.int64))
        cap = self.config.max_fragments_per_pixel
        kept = int(np.minimum(counts, cap).sum(dtype=np.int64)) if cap and self.config.transparency == "abuffer" \
            else total
        return {"fragments": total, "fragments_max": int(counts.max()) if counts.size else 0,
                "fragments_dropped": total - kept}

    def _readback(self, res, width, height, transparent) -> Readback:
        """The frame's AOVs as device sources (read on first access, clrender/render/frame.py) and
        makers of the constant ones. AOVs rendered before the resolve are at k·W × k·H: the
        Frame gets each output pixel's nearest sample."""
        k = self.config.supersample
        iw, ih = k * width, k * height
        n, out_px = iw * ih, width * height
        rb = Readback(self.queue, self.snapshots)

        def internal(planes=1, last_axis=False):
            def finish(a):
                a = a.reshape(planes, ih, iw)
                a = np.ascontiguousarray(a[:, k // 2::k, k // 2::k]) if k > 1 else a
                return np.ascontiguousarray(np.moveaxis(a, 0, -1)) if last_axis else a[0]
            return finish

        for i in range(len(layout.PLANES)):
            rb.add(f"gbuffer:{i}", res["gbuffer"][i * out_px:(i + 1) * out_px], lambda a: a.reshape(height, width))
        rb.add("color", res["color"][: 3 * out_px], lambda a: np.moveaxis(a.reshape(3, height, width), 0, -1))
        rb.add("light_count", res["light_count"][:n], internal())
        rb.add("image", res["image"][:out_px],
               lambda a: np.ascontiguousarray(a.reshape(height, width, 1).view(np.uint8)[..., :3]))
        planes = res["shadow_planes"]
        if planes:
            rb.add("shadow", res["shadow"][: planes * n], internal(planes, last_axis=True))
        else:
            rb.make("shadow", lambda: np.ones((height, width, 0), np.float32))
        if self.config.ssao:
            rb.add("ao", res["ao"][:n], internal())
        else:                                  # no SSAO kernel ran: the term is 1 everywhere
            rb.make("ao", lambda: np.ones((height, width), np.float32))
        if transparent:
            rb.add("fragment_count", self.transparency[0].frag_count[:n], internal())
            rb.add("transmittance", res["layers"][3 * n: 4 * n], internal())    # the layers' transmittance plane
            rb.add("nearest_triangle", res["layers"][6 * n: 7 * n], lambda a: internal()(a).view(np.int32))
        else:
            rb.make("fragment_count", lambda: np.zeros((height, width), np.int32))
            rb.make("transmittance", lambda: np.ones((height, width), np.float32))
        if self.config.edge_aa:
            rb.add("edges", res["edges"][:out_px], lambda a: a.reshape(height, width))
        else:
            rb.make("edges", lambda: np.zeros((height, width), np.uint8))
        if self.config.ldr_effects:            # the final LDR planes the image was encoded from
            rb.add("ldr", res["ldr"][: 3 * out_px],
                   lambda a: np.ascontiguousarray(np.moveaxis(a.reshape(3, height, width), 0, -1)))
        return rb

    def _first_use_stage(self, res, transparent):
        """A progress stage for a frame that builds programs: the programs of the passes this frame
        runs, built up front (count and ETA), then each pass's first launch (where PoCL compiles
        its kernels). None (no stage) when everything is built: a warm pipeline reports nothing. The
        shadow pass makes its map stages on the way (publish): its programs are built in the loop, or
        by their first launch, and never walked here, so a warm frame walks nothing."""
        running = [p for p in self.passes if (transparent or p not in self.transparency) and p.name != "shadow"
                   and not (p.name == "particles" and not res["particle_systems"]) and p not in self._built]
        unbuilt = {p: [k.spec for k in lazy_kernels(p) if not k.built] for p in running}
        self._built.update(p for p, specs in unbuilt.items() if not specs)    # programs are never unbuilt
        specs = [s for p_specs in unbuilt.values() for s in p_specs]
        if not specs:
            return nullcontext()

        @contextmanager
        def stage():
            first = [p for p in running if p not in self._launched]
            with progress.stage("building OpenCL programs", len(first), self.device.name) as s:
                self.device.build(specs)
                yield s
        return stage()

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
