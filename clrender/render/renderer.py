"""The one-call API: `Renderer(width, height).render(scene, camera) -> Frame`."""
from __future__ import annotations

import time as _time
from typing import Optional

import numpy as np

from clrender.scene.camera import Camera
from clrender.device.core import DeviceInfo
from clrender.device.probe import open_device
from clrender.render.frame import Frame
from clrender.scene.model import Scene

# RenderConfig and its option tables live in clrender/config.py (numpy only); re-exported here,
# where other code has always imported them.
from clrender.config import (  # noqa: F401
    COLOR_AA, LIGHT_BUFFER_PRECISION, LIGHT_BUFFER_SPECULAR, LIGHT_CULLING, MAX_PEEL_LAYERS, MSAA, OPTIONS,
    PIPELINES, SHADING, SHADOW_FILTERS, SUPERSAMPLE_FILTERS, TILE_SIZES, TONEMAPS, TRANSPARENCY, RenderConfig,
    _is_int, _is_real, check_int)


class Renderer:
    """Renders scenes at a fixed resolution on one OpenCL device.

    device: None (CLRENDER_DEVICE, else a GPU, else the best usable CPU runtime: device_probe),
    "P:D", an implementation key ("intel", "pocl", ...), "pip"/"system", a name substring, or a
    DeviceInfo. Programs build at the first render that needs them (progress: clrender.progress).
    Options are RenderConfig fields (e.g. tile_size=8).

    Threads: a Renderer may be shared by several threads (a thread pool submitting renders just
    works), and several Renderers on one device may render from several threads. Calls that use
    the device (render, lights_at, posed_vertices) are serialised by a per-device lock
    (Device.lock): the device runs one in-order queue, so they would not overlap on it anyway.
    Each Frame keeps its own pixels: reading one lazily in one thread while another thread renders
    with the same Renderer gives that frame's arrays (clrender/render/frame.py retires it under a lock)."""

    def __init__(self, width: int = 1280, height: int = 720, device: Optional[str | DeviceInfo] = None,
                 config: Optional[RenderConfig] = None, **options):
        for name, v in (("width", width), ("height", height)):
            check_int(name, v, 1, 16384)
        if config is not None and options:
            raise ValueError("pass either config= or keyword options, not both")
        self.width, self.height = int(width), int(height)
        self.config = config or RenderConfig.from_options(**options)
        k = self.config.supersample
        if (k * self.width) * (k * self.height) * 6 >= 2**31:      # kernels index up to 6 planes with 32-bit ints
            raise ValueError(f"{self.width}x{self.height} at supersample {k} is {k * self.width}x{k * self.height} "
                             f"internally, too many pixels for 32-bit buffer offsets; lower supersample or the size")
        self.device = open_device(device)       # probed once per machine and kernel change (device_probe)
        from clrender.device import tuning
        from clrender.render import autotune
        autotune.ensure(self.device)            # VEC and tiles measured over a device's first runs, then cached
        self.config = tuning.resolved_tiles(self.device.cl_device, self.config)   # what this device runs
        from clrender.render import memory
        memory.check(self.device, self.width, self.height, self.config)   # before building or allocating
        from clrender.render.pipeline import Pipeline
        with self.device.lock:                  # its buffers are filled by pyopencl's shared kernels
            self.pipeline = Pipeline(self.device, self.config)

    def lights_at(self, scene: Scene, time: float = 0.0) -> np.ndarray:
        """The lights a frame at `time` is shaded with (particles placed by the device)."""
        with self.device.lock:
            return self._lights_at(scene, time)

    def _lights_at(self, scene: Scene, time: float) -> np.ndarray:
        from clrender.render import scene_upload as scene_gpu
        from clrender.passes import Resources
        values = scene_gpu.upload_lights(scene, self.device)
        particles = next(p for p in self.pipeline.passes if p.name == "particles")
        particles.run(Resources(values={**values, "particle_systems": tuple(scene.particle_systems),
                                        "time": float(time)}))
        lights = values["lights"].get(queue=self.device.queue)
        return lights[: values["n_lights"]]

    def _triangle_gltf(self, scene: Scene, scene_res) -> Optional[np.ndarray]:
        """Per triangle: shaded with the glTF BRDF (Frame.shading_model); None when none is."""
        if not scene_res.values["gltf_scene"]:
            return None
        gltf = np.array([m.metallic is not None and not m.unlit for m in scene.materials])
        return gltf[scene.triangle_material]

    def _scene_resources(self, scene: Scene):
        """The scene's device buffers and values for a frame: uploads (cached), lights, and the
        posed vertices of skinned and morphing meshes (the vertex pre-pass, clrender/passes/pose.py)."""
        from clrender.render import memory, scene_upload as scene_gpu, texture_pool
        from clrender.passes import Resources
        if scene_gpu.needs_upload(scene, self.device):
            memory.check(self.device, self.width, self.height, self.config, scene)
        upload = scene_gpu.upload(scene, self.device)
        # the decoded texture pool lives with the upload (made once, at its first frame under a budget that takes it)
        linear = texture_pool.linear_texels(self.device, upload, self.config.decoded_textures_mb)
        scene_res = Resources(buffers=dict(upload.buffers), values={
            "texels_linear": linear,
            **upload.values, **scene_gpu.upload_lights(scene, self.device), "ambient": float(scene.ambient),
            "particle_systems": tuple(scene.particle_systems), "sun": scene.sun,
            "environment": getattr(scene, "environment", None), "deformation": scene.deformation})
        if scene.deformation is not None:
            self.pipeline.pose(upload, scene_res)
        return scene_res

    def posed_vertices(self, scene: Scene) -> dict:
        """The scene's vertices as the device poses them for a frame (Scene.deformation's skins and
        morph targets at the scene's current pose, `scene.pose(t, dt)`), float32 numpy arrays:
        positions (V, 3), normals (V, 3), tangents (V, 4) or None, previous_positions (V, 3) or None
        (no motion). Without a deformation: the scene's own arrays as uploaded."""
        if not isinstance(scene, Scene):
            raise TypeError(f"posed_vertices() needs a clrender.Scene, got {type(scene).__name__}")
        with self.device.lock:
            return self._posed_vertices(scene)

    def _posed_vertices(self, scene: Scene) -> dict:
        res = self._scene_resources(scene)
        nv, q = len(scene.positions), self.device.queue
        tangents = res.buffers["tangents"]
        prev = res.buffers.get("prev_positions")
        return {"positions": res.buffers["positions"].get(queue=q)[: 3 * nv].reshape(-1, 3),
                "normals": res.buffers["normals"].get(queue=q)[: 3 * nv].reshape(-1, 3),
                "tangents": tangents.get(queue=q)[: 4 * nv].reshape(-1, 4) if tangents.size == 4 * nv else None,
                "previous_positions": None if prev is None else prev.get(queue=q)[: 3 * nv].reshape(-1, 3)}

    def render(self, scene: Scene, camera: Optional[Camera] = None,
               previous_camera: Optional[Camera] = None, time: float = 0.0) -> Frame:
        """Render `scene` from `camera` (default: the scene's). `previous_camera` gives motion
        vectors; `time` (seconds) places the scene's light particles. Safe to call from several
        threads (see the class doc): calls run one at a time."""
        with self.device.lock:
            return self._render(scene, camera, previous_camera, time)

    def _render(self, scene: Scene, camera: Optional[Camera], previous_camera: Optional[Camera],
                time: float) -> Frame:
        from clrender.render import memory
        start = _time.perf_counter()
        if not isinstance(scene, Scene):
            raise TypeError(f"render() needs a clrender.Scene, got {type(scene).__name__}")
        camera = camera or scene.default_camera()
        if camera.is_orthographic != self.pipeline.ortho:
            # Orthographic cameras run the ORTHO kernel variants (docs/raster_contract.md §11): a
            # pipeline of the other kind replaces this one (programs are cached, buffers re-made).
            from clrender.render.pipeline import Pipeline
            self.pipeline = Pipeline(self.device, self.config, ortho=camera.is_orthographic)
        if not np.isfinite(time):
            raise ValueError(f"time must be finite, got {time!r}")
        scene_res = self._scene_resources(scene)
        if self.config.shading == "blinn_phong":      # the report's model and falloff for everything
            scene_res.buffers["materials"] = scene_res.buffers["materials_blinn_phong"]
            scene_res.values["gltf_scene"] = 0
            scene_res.values["lights"] = scene_res.values["lights_blinn_phong"]
            if scene_res["transmissive_materials"]:     # transmission is a glTF-BRDF feature: only BLEND is see-through
                from clrender.passes.fragments import transparent_triangle_count
                scene_res.values["transmissive_materials"] = 0
                scene_res.values.pop("transmission_args", None)
                scene_res.values["n_transparent_tris"] = transparent_triangle_count(scene, blend_only=True)
        elif self.config.multiscatter and scene_res["gltf_scene"]:   # every glTF material through the layers pass
            from clrender.render.scene_upload import multiscatter_buffers
            ms = multiscatter_buffers(scene, self.device)
            scene_res.values["layered_materials"] = ms.pop("layered_materials")
            scene_res.buffers.update(ms)
        upload_ms = (_time.perf_counter() - start) * 1e3
        readback, stats = self.pipeline.render(scene_res, camera, self.width, self.height, previous_camera, time)
        stats["device"] = self.device.name
        stats.update(memory.held_bytes(self.pipeline, scene_res))
        stats["frame_copy_bytes"] = self.pipeline.snapshots.held_bytes     # earlier frames' unread AOVs
        stats["time"] = float(time)
        frame = Frame(width=self.width, height=self.height, far=float(camera.far), stats=stats,
                      tonemap=self.config.tonemap, exposure=float(self.config.exposure), readback=readback,
                      triangle_gltf=self._triangle_gltf(scene, scene_res), triangle_mesh=scene.triangle_mesh,
                      mesh_object=scene.mesh_object, triangle_material=scene.triangle_material, camera=camera)
        stats["wall_ms"] = (_time.perf_counter() - start) * 1e3      # what the caller waited for
        host = {"upload_ms": upload_ms, **stats["host"]}
        host["other_ms"] = max(stats["wall_ms"] - sum(host.values()), 0.0)
        stats["host"] = host
        return frame
