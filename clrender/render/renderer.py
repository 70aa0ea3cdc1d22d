"""The one-call API: `Renderer(width, height).render(scene, camera) -> Frame`."""
from __future__ import annotations

import dataclasses
import time as _time
from dataclasses import dataclass
from typing import Optional

import numpy as np

from clrender.scene.camera import Camera
from clrender.device.core import DeviceInfo
from clrender.device.probe import open_device
from clrender.render.frame import Frame
from clrender.scene.model import Scene

TILE_SIZES = (8, 16, 32)
LIGHT_CULLING = ("tiled", "brute_force", "quads", "stencil")   # docs/light_accumulation.md
TONEMAPS = ("reinhard", "aces", "clamp")
SHADING = ("auto", "blinn_phong")   # kernels/brdf.h: per-material models, or the report's everywhere
SHADOW_FILTERS = ("pcf3x3", "poisson", "hard")
TRANSPARENCY = ("abuffer", "depth_peeling", "screen_door")
SUPERSAMPLE_FILTERS = ("box", "lanczos2", "mitchell")
COLOR_AA = ("none", "fxaa")
PIPELINES = ("deferred", "light_prepass", "light_indexed")     # docs/variants.md
MSAA = (1, 2, 4, 8)
LIGHT_BUFFER_SPECULAR = ("rgb", "luminance")
LIGHT_BUFFER_PRECISION = ("float32", "float16")
MAX_PEEL_LAYERS = 64


def _is_real(x) -> bool:
    return isinstance(x, (int, float, np.integer, np.floating)) and not isinstance(x, bool)


def _is_int(x) -> bool:
    return isinstance(x, (int, np.integer)) and not isinstance(x, bool)


def check_int(name: str, value, lo: int, hi: int) -> int:
    """`value` as an int in [lo, hi]; ValueError naming the parameter and, for a value that is not
    an integer at all, its type: bool is an int to Python but True is no width, and "160" or
    160.0 are refused rather than converted."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise ValueError(f"{name} must be an integer in [{lo}, {hi}], got {type(value).__name__} {value!r}")
    if not lo <= value <= hi:
        raise ValueError(f"{name} must be an integer in [{lo}, {hi}], got {value}")
    return int(value)


@dataclass(frozen=True)
class RenderConfig:
    """Render options. Unknown names are errors (see `RenderConfig.from_options`)."""
    pipeline: str = "deferred"  # "deferred", "light_prepass" or "light_indexed" (docs/variants.md)
    shading: str = "auto"       # "auto": glTF metallic-roughness materials with the glTF BRDF, the others
                                # Blinn-Phong; "blinn_phong": everything through the report's model (docs/shading.md)
    msaa: int = 1              # light_prepass: colour sub-samples per pixel (1, 2, 4, 8; D3D standard patterns)
    light_buffer_specular: str = "rgb"       # light_prepass: "rgb" or "luminance" (the classic LPP trade-off)
    light_buffer_precision: str = "float32"  # light_prepass: "float32" or "float16" light buffer
    reuse_visibility: bool = False   # light_prepass / light_indexed (msaa 1): read pass 1's visibility buffer
                                     # instead of rasterizing again (not the report's two geometry passes;
                                     # the same pixels bit for bit: docs/variants.md)
    tile_size: int = 8         # raster tiles; bench.gbuffer on a 2-core AVX-512 CPU: 8 < 16 < 32 ms
    light_tile_size: int = 32  # light-culling tiles; bench.lights at 1024/4096 lights: 32 < 16 < 8 ms
    shadow_tile_size: Optional[int] = None   # shadow-map raster tiles (8, 16, 32); None: 32 on CPUs (bench.shadows:
                                             # binning 117 -> 20 ms, raster 307 -> 262 ms vs 8), tile_size on GPUs
    light_culling: str = "tiled"   # "brute_force", "quads", "stencil" (docs/light_accumulation.md)
    light_depth_mask: bool = False   # Harada's 2.5D culling: 32 depth slices per tile
    tonemap: str = "reinhard"
    exposure: float = 1.0
    ssao: bool = False         # off by default: on CPUs it costs several shading passes (README, SSAO)
    ssao_radius: float = 1.0   # world units: how far the ambient occlusion looks around each point
    ssao_strength: float = 1.0  # ao = 1 - strength·occlusion, clamped to [0, 1]
    ssao_blur: bool = True     # depth-aware blur of the per-pixel-rotated samples
    shadows: bool = True       # shadow maps for shadowed spots and the sun; False: shade.cl has no lookup
    shadow_filter: str = "pcf3x3"    # "pcf3x3" (smooth 3x3 box), "poisson" (16 rotated taps), "hard"
    shadow_filter_radius: float = 2.0   # poisson disk radius, texels
    shadow_bias: float = 1.0         # constant depth bias, texels of the map at the receiver
    shadow_slope_bias: float = 1.0   # slope-scaled bias: × tan(angle to the light) × filter reach, texels
    shadow_normal_offset: float = 1.0   # receivers move along their normal by this × sin(angle), texels
    sun_cascades: int = 3            # cascaded shadow maps of the sun (1 = one map over the whole view)
    sun_split_lambda: float = 0.75   # cascade splits: lambda·logarithmic + (1 - lambda)·uniform
    shadow_atlas_max: int = 16384    # atlas side limit: maps that do not fit are an error, never dropped
    shadow_map_reuse: bool = True    # keep a map whose light view and scene are unchanged since the last frame
    chunk_cull: bool = True          # setup skips chunks of 128 triangles a view cannot see (passes/chunk_cull.py; bit-identical)
    transparency: str = "abuffer"    # BLEND materials: "abuffer", "depth_peeling" or "screen_door" (docs/transparency.md)
    peel_layers: int = 4             # depth_peeling: layers peeled per pixel (1..64)
    max_fragments_per_pixel: int = 0   # abuffer: keep only the K nearest fragments (0 = all; drops are counted)
    refraction: bool = False         # distort what lies behind transparent surfaces by their materials' refraction
    supersample: int = 1             # render at k·W × k·H and filter down in linear HDR (1..4; docs/post.md)
    supersample_filter: str = "box"  # "box", "lanczos2" or "mitchell" (separable, radius 2 output pixels)
    edge_aa: bool = False            # the report's edge-smoothing filter on the tone-mapped image
    edge_depth_threshold: float = 0.05   # edge_aa: relative view-depth jump that marks an edge
    edge_normal_threshold_deg: float = 30.0   # edge_aa: normal angle that marks an edge
    color_aa: str = "none"           # "fxaa": luminance-edge anti-aliasing of the tone-mapped image
    bloom: bool = False              # what saturates (HDR colour above bloom_threshold), blurred and added back
    bloom_threshold: float = 1.0     # linear HDR level above which colour blooms
    bloom_strength: float = 0.1      # the bloom adds strength × the thresholded energy
    bloom_radius: float = 16.0       # output pixels: the blur's reach (a mip pyramid keeps large radii cheap)
    motion_blur: bool = False        # HDR colour sampled along the (smoothed) per-pixel velocity
    shutter: float = 0.5             # motion blur: exposure as a fraction of the frame interval
    motion_blur_samples: int = 8     # motion blur: samples along the velocity
    hatching: bool = False           # the report's non-photorealistic post effect (tonal art maps)
    hatching_scale: float = 1.0      # hatching: stroke texture scale (1 = one texel per pixel at the finest level)
    hatching_saturation: float = 0.3   # hatching: colour kept (0 = black ink on white, 1 = full colour)

    def __post_init__(self):
        # `8.0 in TILE_SIZES` is True: the type is checked too (sizes become kernel -D defines)
        if not (_is_int(self.tile_size) and self.tile_size in TILE_SIZES):
            raise ValueError(f"tile_size must be one of {TILE_SIZES}, got {self.tile_size!r}")
        if self.shadow_tile_size is not None and not (_is_int(self.shadow_tile_size)
                                                      and self.shadow_tile_size in TILE_SIZES):
            raise ValueError(f"shadow_tile_size must be None or one of {TILE_SIZES}, got {self.shadow_tile_size!r}")
        if not (_is_int(self.light_tile_size) and self.light_tile_size in TILE_SIZES):
            raise ValueError(f"light_tile_size must be one of {TILE_SIZES}, got {self.light_tile_size!r}")
        if self.light_culling not in LIGHT_CULLING:
            raise ValueError(f"light_culling must be one of {LIGHT_CULLING}, got {self.light_culling!r}")
        if not isinstance(self.light_depth_mask, bool):
            raise ValueError(f"light_depth_mask must be True or False, got {self.light_depth_mask!r}")
        if self.shading not in SHADING:
            raise ValueError(f"shading must be one of {SHADING}, got {self.shading!r}")
        if self.tonemap not in TONEMAPS:
            raise ValueError(f"tonemap must be one of {TONEMAPS}, got {self.tonemap!r}")
        if not (_is_real(self.exposure) and np.isfinite(self.exposure) and self.exposure > 0):
            raise ValueError(f"exposure must be a positive number, got {self.exposure!r}")
        for name in ("ssao", "ssao_blur"):
            if not isinstance(getattr(self, name), bool):
                raise ValueError(f"{name} must be True or False, got {getattr(self, name)!r}")
        if not (_is_real(self.ssao_radius) and np.isfinite(self.ssao_radius) and self.ssao_radius > 0):
            raise ValueError(f"ssao_radius must be a positive number (world units), got {self.ssao_radius!r}")
        if not (_is_real(self.ssao_strength) and np.isfinite(self.ssao_strength) and self.ssao_strength >= 0):
            raise ValueError(f"ssao_strength must be a number >= 0, got {self.ssao_strength!r}")
        self._check_shadow_options()
        self._check_transparency_options()
        self._check_aa_options()
        self._check_pipeline_options()

    def _check_pipeline_options(self):
        if self.pipeline not in PIPELINES:
            raise ValueError(f"pipeline must be one of {PIPELINES}, got {self.pipeline!r}")
        if not (isinstance(self.msaa, (int, np.integer)) and not isinstance(self.msaa, bool) and self.msaa in MSAA):
            raise ValueError(f"msaa must be one of {MSAA}, got {self.msaa!r}")
        if self.light_buffer_specular not in LIGHT_BUFFER_SPECULAR:
            raise ValueError(f"light_buffer_specular must be one of {LIGHT_BUFFER_SPECULAR}, "
                             f"got {self.light_buffer_specular!r}")
        if self.light_buffer_precision not in LIGHT_BUFFER_PRECISION:
            raise ValueError(f"light_buffer_precision must be one of {LIGHT_BUFFER_PRECISION}, "
                             f"got {self.light_buffer_precision!r}")
        if self.pipeline != "light_prepass":
            for name, default in (("msaa", 1), ("light_buffer_specular", "rgb"), ("light_buffer_precision", "float32")):
                if getattr(self, name) != default:
                    raise ValueError(f"{name} applies to pipeline='light_prepass' (the light buffer and its colour "
                                     f"pass), not {self.pipeline!r}" + (
                                         "; over-sampling (supersample) anti-aliases every pipeline"
                                         if name == "msaa" else ""))
        if not isinstance(self.reuse_visibility, bool):
            raise ValueError(f"reuse_visibility must be True or False, got {self.reuse_visibility!r}")
        if self.reuse_visibility and self.pipeline == "deferred":
            raise ValueError("reuse_visibility applies to pipeline='light_prepass' or 'light_indexed' (their second "
                             "geometry pass); 'deferred' rasterizes once")
        if self.reuse_visibility and self.msaa != 1:
            raise ValueError(f"reuse_visibility reads pass 1's pixel-centre visibility; msaa={self.msaa} rasterizes "
                             f"at sub-samples, which pass 1 never saw")
        if self.pipeline != "deferred" and self.light_culling not in ("tiled", "brute_force"):
            raise ValueError(f"light_culling={self.light_culling!r} is a light-accumulation variant of the deferred "
                             f"pipeline; pipeline={self.pipeline!r} takes 'tiled' or 'brute_force'")
        if self.pipeline == "light_indexed" and self.ssao:
            raise ValueError("ssao needs the G-buffer's normals, which pipeline='light_indexed' never stores "
                             "(depth and triangle id only); use 'deferred' or 'light_prepass'")

    def _check_aa_options(self):
        if not (isinstance(self.supersample, (int, np.integer)) and not isinstance(self.supersample, bool)
                and 1 <= self.supersample <= 4):
            raise ValueError(f"supersample must be an integer in [1, 4], got {self.supersample!r}")
        if self.supersample_filter not in SUPERSAMPLE_FILTERS:
            raise ValueError(f"supersample_filter must be one of {SUPERSAMPLE_FILTERS}, got {self.supersample_filter!r}")
        if not isinstance(self.edge_aa, bool):
            raise ValueError(f"edge_aa must be True or False, got {self.edge_aa!r}")
        if not (_is_real(self.edge_depth_threshold) and np.isfinite(self.edge_depth_threshold)
                and self.edge_depth_threshold > 0):
            raise ValueError(f"edge_depth_threshold must be a positive number, got {self.edge_depth_threshold!r}")
        if not (_is_real(self.edge_normal_threshold_deg) and 0 < self.edge_normal_threshold_deg <= 180):
            raise ValueError(f"edge_normal_threshold_deg must be in (0, 180], got {self.edge_normal_threshold_deg!r}")
        if self.color_aa not in COLOR_AA:
            raise ValueError(f"color_aa must be one of {COLOR_AA}, got {self.color_aa!r}")
        self._check_post_options()

    def _check_post_options(self):
        for name in ("bloom", "motion_blur", "hatching"):
            if not isinstance(getattr(self, name), bool):
                raise ValueError(f"{name} must be True or False, got {getattr(self, name)!r}")
        for name, lo, lo_open in (("bloom_threshold", 0.0, False), ("bloom_strength", 0.0, False),
                                  ("bloom_radius", 0.0, True), ("shutter", 0.0, True), ("hatching_scale", 0.0, True)):
            v = getattr(self, name)
            if not (_is_real(v) and np.isfinite(v) and (v > lo if lo_open else v >= lo)):
                raise ValueError(f"{name} must be a number {'>' if lo_open else '>='} {lo}, got {v!r}")
        if not (_is_real(self.hatching_saturation) and 0.0 <= self.hatching_saturation <= 1.0):
            raise ValueError(f"hatching_saturation must be in [0, 1], got {self.hatching_saturation!r}")
        n = self.motion_blur_samples
        if not (isinstance(n, (int, np.integer)) and not isinstance(n, bool) and 2 <= n <= 64):
            raise ValueError(f"motion_blur_samples must be an integer in [2, 64], got {n!r}")

    @property
    def ldr_effects(self) -> bool:
        """Post effects on the tone-mapped image (then tone mapping and encoding are separate passes)."""
        return self.edge_aa or self.color_aa != "none" or self.hatching

    def _check_transparency_options(self):
        if self.transparency not in TRANSPARENCY:
            raise ValueError(f"transparency must be one of {TRANSPARENCY}, got {self.transparency!r}")
        if not (isinstance(self.peel_layers, (int, np.integer)) and not isinstance(self.peel_layers, bool)
                and 1 <= self.peel_layers <= MAX_PEEL_LAYERS):
            raise ValueError(f"peel_layers must be an integer in [1, {MAX_PEEL_LAYERS}], got {self.peel_layers!r}")
        k = self.max_fragments_per_pixel
        if not (isinstance(k, (int, np.integer)) and not isinstance(k, bool) and 0 <= k <= 2**20):
            raise ValueError(f"max_fragments_per_pixel must be an integer >= 0 (0 = no cap), got {k!r}")
        if not isinstance(self.refraction, bool):
            raise ValueError(f"refraction must be True or False, got {self.refraction!r}")

    def _check_shadow_options(self):
        for name in ("shadows", "shadow_map_reuse", "chunk_cull"):
            if not isinstance(getattr(self, name), bool):
                raise ValueError(f"{name} must be True or False, got {getattr(self, name)!r}")
        if self.shadow_filter not in SHADOW_FILTERS:
            raise ValueError(f"shadow_filter must be one of {SHADOW_FILTERS}, got {self.shadow_filter!r}")
        for name, lo in (("shadow_bias", 0.0), ("shadow_slope_bias", 0.0), ("shadow_normal_offset", 0.0),
                         ("shadow_filter_radius", 0.5)):
            v = getattr(self, name)
            if not (_is_real(v) and np.isfinite(v) and v >= lo):
                raise ValueError(f"{name} must be a number >= {lo} (texels), got {v!r}")
        if not (isinstance(self.sun_cascades, (int, np.integer)) and not isinstance(self.sun_cascades, bool)
                and 1 <= self.sun_cascades <= 4):
            raise ValueError(f"sun_cascades must be an integer in [1, 4], got {self.sun_cascades!r}")
        if not (_is_real(self.sun_split_lambda) and 0.0 <= self.sun_split_lambda <= 1.0):
            raise ValueError(f"sun_split_lambda must be in [0, 1], got {self.sun_split_lambda!r}")
        if not (isinstance(self.shadow_atlas_max, (int, np.integer)) and not isinstance(self.shadow_atlas_max, bool)
                and 16 <= self.shadow_atlas_max <= 32768):
            raise ValueError(f"shadow_atlas_max must be an integer in [16, 32768], got {self.shadow_atlas_max!r}")

    @classmethod
    def from_options(cls, **options) -> "RenderConfig":
        known = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(options) - known)
        if unknown:
            raise ValueError(f"unknown render option(s) {unknown}; known: {sorted(known)}")
        return cls(**options)


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
        from clrender.render import memory, scene_upload as scene_gpu
        from clrender.passes import Resources
        if scene_gpu.needs_upload(scene, self.device):
            memory.check(self.device, self.width, self.height, self.config, scene)
        upload = scene_gpu.upload(scene, self.device)
        scene_res = Resources(buffers=dict(upload.buffers), values={
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
