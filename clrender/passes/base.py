"""The render-pass contract (after Falcor's RenderPass).

A pass declares the named resources it reads (`inputs`) and writes (`outputs`), owns the
device buffers behind its outputs, builds its program once, and has a `run()` that only
enqueues work. The pipeline wires passes by those names.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pyopencl.array as cla

from clrender.device.buffers import empty, fill_zero, round_up, zeros  # noqa: F401  (re-exported for the passes)
from clrender.device.scan import prefix_sum_for
from clrender.device.timestamps import elapsed_ms, stamp


@dataclass
class Resources:
    """Named device buffers and per-frame values shared between passes."""
    buffers: dict = field(default_factory=dict)
    values: dict = field(default_factory=dict)

    def __getitem__(self, name):
        if name in self.buffers:
            return self.buffers[name]
        if name in self.values:
            return self.values[name]
        raise KeyError(f"resource {name!r} was not produced by any pass or the scene upload")

    def __contains__(self, name):
        return name in self.buffers or name in self.values


@dataclass(frozen=True)
class Overflow:
    """A buffer whose needed size is only known on the device: the pipeline compares
    `total` (read back after the frame) with `capacity`, grows and renders again."""
    name: str
    total: cla.Array
    capacity: int


# The scene resources a surface is evaluated from, in the order of kernels/surface_types.h
# SCENE_PARAMS (after the prims), as the scene upload names them (clrender/render/scene_upload.py).
SCENE_INPUTS = ("positions", "normals", "uvs", "triangles", "materials", "texels", "srgb_lut", "tex_infos",
                "tex_levels", "tangents", "colors", "n_vertices", "has_colors")


def scene_args(res: Resources, prims, texels_linear: bool = False) -> tuple:
    """Kernel arguments for SCENE_PARAMS(prims): the prims buffer, then the SCENE_INPUTS (the
    decoded texture pool for a program built with TEXELS_LINEAR 1)."""
    args = [prims.data]
    for name in SCENE_INPUTS:
        v = res["texels_linear" if texels_linear and name == "texels" else name]
        args.append(np.int32(v) if name in ("n_vertices", "has_colors") else v.data)
    return tuple(args)


class SceneKernel:
    """A kernel over SCENE_PARAMS, built for the texture pool a frame samples: RGBA8 words or the
    decoded floats (kernels/texture_vec.h TEXELS_LINEAR, clrender/render/texture_pool.py
    linear_texels). The pipeline selects the format before the frame's programs are built
    (RenderPass.use_texel_format), so only the variant in use is made and built."""

    def __init__(self, device, filename: str, name: str, defines: dict):
        self.device, self.filename, self.name, self.defines = device, filename, name, dict(defines)
        self.variants: dict = {}
        self.linear = False

    def select(self, linear: bool) -> None:
        self.linear = bool(linear)
        if self.linear not in self.variants:
            self.variants[self.linear] = self.device.kernel(self.filename, self.name,
                                                            {**self.defines, "TEXELS_LINEAR": int(self.linear)})

    def scene_args(self, res: "Resources", prims) -> tuple:
        return scene_args(res, prims, self.linear)

    def __call__(self, *args, **kwargs):
        if self.linear not in self.variants:
            self.select(self.linear)
        return self.variants[self.linear](*args, **kwargs)


class RenderPass:
    name: str = ""
    inputs: tuple[str, ...] = ()
    outputs: tuple[str, ...] = ()
    # The shadow pass makes its programs on the way (per map size, in publish): the pipeline's
    # up-front build and first-launch progress skip it.
    builds_on_publish: bool = False

    @classmethod
    def runs(cls, config) -> bool:
        """Whether a pipeline for `config` has this pass. A disabled effect has no pass: it builds
        no program, allocates nothing and launches no kernel (clrender/render/plan.py)."""
        return True

    def active(self, res: Resources) -> bool:
        """Whether this frame launches the pass (asked after `publish`): False when the scene does
        not use the effect (no particle system, no shadowed light, no environment)."""
        return True

    @classmethod
    def buffer_bytes(cls, width: int, height: int, config, scene=None) -> dict:
        """{label: bytes} of the buffers `allocate(width, height)` makes (and, given `scene`,
        `prepare_scene` at its initial capacities): clrender/render/memory.py's estimate sums
        them; tests/test_pass_buffers.py compares them with what the pass holds."""
        return {}

    def __init__(self, device, config):
        self.device = device
        self.config = config
        self.queue = device.queue

    def allocate(self, width: int, height: int) -> None:
        """(Re)allocate resolution-dependent buffers; called once per resolution. Declare their
        sizes in `buffer_bytes`."""

    def prepare_scene(self, scene_buffers: Resources) -> None:
        """(Re)allocate scene-size-dependent buffers; called when the scene changes."""

    def use_texel_format(self, linear: bool) -> None:
        """The frame's texture pool format (SceneKernel): every SceneKernel the pass holds follows it."""
        for value in vars(self).values():
            if isinstance(value, SceneKernel):
                value.select(linear)

    def publish(self, res: Resources) -> None:
        """Put this pass's outputs into `res`."""

    def run(self, res: Resources) -> None:
        """Enqueue this pass's work. Never waits on the device."""
        raise NotImplementedError

    def overflows(self) -> list[Overflow]:
        return []

    def timed(self, stage: str):
        """Context manager: profiling timestamps around the work a stage of this pass enqueues;
        `stage_stats()` sums them per stage ("<pass>_<stage>_ms") after the frame."""
        return _Timed(self, stage)

    def stage_stats(self) -> dict:
        out: dict = {}
        for stage, start, end in getattr(self, "_stage_events", ()):
            key = f"{self.name}_{stage}_ms"
            out[key] = out.get(key, 0.0) + elapsed_ms(start, end)
        return out

    def clear_stage_events(self) -> None:
        self._stage_events = []

    def grow(self, name: str, needed: int) -> None:
        raise NotImplementedError(f"{type(self).__name__} cannot grow {name}")


class _Timed:
    def __init__(self, owner, stage):
        self.owner, self.stage = owner, stage

    def __enter__(self):
        self.start = stamp(self.owner.device, self.owner.queue)

    def __exit__(self, *exc):
        events = self.owner.__dict__.setdefault("_stage_events", [])
        events.append((self.stage, self.start, stamp(self.owner.device, self.owner.queue)))


def view_defines(ortho: bool) -> dict:
    """Build options of a kernel that rasterizes the camera's view or rebuilds positions from its
    depth: ORTHO=1 for an orthographic camera, nothing for a perspective one (those programs are
    unchanged)."""
    return {"ORTHO": 1} if ortho else {}


# Fixed work-group shapes for the kernels whose results do not depend on the shape (no local
# memory, no barriers). PoCL compiles a kernel once per local size at its first launch with it;
# a None local size lets PoCL pick one from the global size, so every new image size (or
# triangle / light / tile count) would compile those kernels again (0.4-0.65 s each, cold).
# 64 work-items is within every targeted device's limit (PoCL, NVIDIA, Oclgrind).
WG_1D = 64
WG_2D = (8, 8)


def launch_1d(n: int, wg: int = WG_1D) -> tuple[tuple[int], tuple[int]]:
    """(global, local) sizes of a 1-D launch over n work-items: the fixed local size `wg` and the
    global size rounded up to it (at least one group). The kernel must return for ids >= n."""
    return (round_up(max(int(n), 1), wg),), (wg,)


def launch_2d(nx: int, ny: int, wg: tuple[int, int] = WG_2D) -> tuple[tuple[int, int], tuple[int, int]]:
    """(global, local) sizes of a 2-D launch over nx × ny work-items: the fixed shape `wg` and each
    global dimension rounded up to it. The kernel must return for ids outside nx × ny."""
    return (round_up(max(int(nx), 1), wg[0]), round_up(max(int(ny), 1), wg[1])), tuple(wg)


def scan_for(device):
    """The device's exclusive prefix sum with grand total (clrender/device/scan.py)."""
    return prefix_sum_for(device)
