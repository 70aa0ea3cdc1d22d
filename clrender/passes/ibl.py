"""Image-based lighting: the per-environment precomputation on the device (kernels/ibl.cl) and
the maps the shading kernels read through kernels/environment.h (docs/ibl.md).

    maps = ibl_maps(device, device.queue, pixels, key="sky.exr")    # (H, W, 3) float32 linear RGB
    kernel(queue, gsize, lsize, ..., *maps.args(intensity=1.0, rotation_deg=30.0))   # ENV_PARAMS

Once per environment (per device and key; the last CACHE_ENVIRONMENTS are kept):
  - level 0: the environment itself (what the background shows);
  - the specular chain, K = specular_levels levels: level 0 the environment box-downsampled to at
    most max_width wide (the environment itself when it is no wider and 2:1), level k = 1..K-1 half
    the width of level k-1 (at least MIN_LEVEL_WIDTH), GGX-prefiltered for roughness k / (K - 1)
    from a box mip chain of level 0 (filtered importance sampling, PREFILTER_SAMPLES per level);
  - order-2 spherical harmonics of the irradiance E(n) / pi (27 floats).
Once per device (cached, whatever the environment): the split-sum DFG table (A, B, C).

The results depend only on the pixels and the options: two precomputes give the same bits (fixed
sample sequences, fixed-order sums).
"""
from __future__ import annotations

import hashlib
import math
import threading
from collections import OrderedDict
from dataclasses import dataclass, field
from typing import Hashable, Optional

import numpy as np
import pyopencl as cl

from clrender.device import capabilities
from clrender import progress
from clrender.device.core import ProgramSpec
from clrender.passes.base import RenderPass, launch_1d, launch_2d, zeros

SOURCE = "ibl.cl"
DEFAULT_SPECULAR_LEVELS = 6
DEFAULT_MAX_WIDTH = 512
MIN_LEVEL_WIDTH = 8
# GGX samples per texel of specular level k (k = 1..K-1; the last entry for any further level).
# Chosen so the prefilter of a 1024 x 2048 environment takes well under 1 s on a 2-core PoCL CPU
# (docs/ibl.md has the measurements).
PREFILTER_SAMPLES = (512, 1024, 2048, 4096, 4096)
DFG_SIZE = 64
DFG_SAMPLES = (64, 16)      # Gauss-Legendre nodes: 64 along theta_h, 16 per half of phi in [0, pi]: 2048 per texel
CACHE_ENVIRONMENTS = 2          # environments kept per device

# env_params layout (kernels/environment.h ENV_P_*)
P_INTENSITY, P_ROTATION_U, P_SPEC_LEVELS, P_DFG_SIZE, P_ROT_COS, P_ROT_SIN, P_LEVELS, P_COUNT = 0, 1, 2, 3, 4, 5, 6, 8
LEVEL_STRIDE = 4

# Real SH basis constants, the order of environment.h (1, y, z, x, xy, yz, 3z^2 - 1, xz, x^2 - y^2).
SH_K = (0.282094791773878, 0.488602511902920, 0.488602511902920, 0.488602511902920, 1.092548430592079,
        1.092548430592079, 0.315391565252520, 1.092548430592079, 0.546274215296040)


def specular_sizes(width: int, height: int, levels: int = DEFAULT_SPECULAR_LEVELS,
                   max_width: int = DEFAULT_MAX_WIDTH) -> list[tuple[int, int]]:
    """[(w, h)] of the specular chain's levels for a width x height environment."""
    w0 = max(min(int(width), int(max_width)), 2)
    sizes = [(w0, max(w0 // 2, 1))]
    for _ in range(1, levels):
        w = max(sizes[-1][0] // 2, MIN_LEVEL_WIDTH)
        sizes.append((w, max(w // 2, 1)))
    return sizes


def mip_sizes(w0: int, h0: int) -> list[tuple[int, int]]:
    """The prefilter's source chain: (w0, h0), then halvings (at least 1) down to one row."""
    sizes = [(w0, h0)]
    while sizes[-1][1] > 1 or sizes[-1][0] > 2:
        w, h = sizes[-1]
        sizes.append((max(w // 2, 1), max(h // 2, 1)))
        if sizes[-1] == (w, h):
            break
    return sizes


def level_samples(k: int, samples: Optional[tuple] = None) -> int:
    table = tuple(samples or PREFILTER_SAMPLES)
    return int(table[min(k - 1, len(table) - 1)])


def env_params(intensity: float = 1.0, rotation_deg: float = 0.0, specular_levels: int = DEFAULT_SPECULAR_LEVELS,
               dfg_size: int = DFG_SIZE) -> np.ndarray:
    """The env_params floats (environment.h ENV_P_*)."""
    rot = (float(rotation_deg) / 360.0) % 1.0
    p = np.zeros(P_COUNT, np.float32)
    p[P_INTENSITY] = intensity
    p[P_ROTATION_U] = rot
    p[P_SPEC_LEVELS] = specular_levels
    p[P_DFG_SIZE] = dfg_size
    p[P_ROT_COS] = math.cos(2.0 * math.pi * rot)
    p[P_ROT_SIN] = math.sin(2.0 * math.pi * rot)
    p[P_LEVELS] = specular_levels + 1
    return p


@dataclass(frozen=True, eq=False)
class IblMaps:
    """One environment's maps on one device (and the device's DFG table). `args()` gives the
    kernel arguments of environment.h's ENV_PARAMS."""
    texels: cl.Buffer           # float RGB, every level (level_table offsets, in texels)
    levels: cl.Buffer           # int32 (K + 1, 4): (offset, width, height, 0); 0 = full resolution
    sh: cl.Buffer               # float32 (9, 3): E(n)/pi coefficients, basis constants and A_l/pi included
    dfg: cl.Buffer              # float32 (n, n, 3): A, B, C; row = roughness, column = n.v
    level_table: np.ndarray     # the levels buffer's contents
    width: int                  # the environment's
    height: int
    specular_levels: int        # K
    dfg_size: int               # n
    samples: tuple              # GGX samples per texel of specular levels 1..K-1
    key: Hashable = None
    events: dict = field(default_factory=dict, compare=False, repr=False)    # phase -> [cl.Event]
    _params: dict = field(default_factory=dict, compare=False, repr=False)

    def params(self, intensity: float = 1.0, rotation_deg: float = 0.0) -> np.ndarray:
        return env_params(intensity, rotation_deg, self.specular_levels, self.dfg_size)

    def args(self, intensity: float = 1.0, rotation_deg: float = 0.0) -> tuple:
        """(env_texels, env_levels, env_sh, env_dfg, env_params): the ENV_PARAMS arguments, with a
        params buffer per (intensity, rotation) (a few are kept)."""
        key = (float(intensity), float(rotation_deg))
        with _lock:
            buf = self._params.get(key)
            if buf is None:
                if len(self._params) >= 8:
                    self._params.pop(next(iter(self._params)))
                buf = cl.Buffer(self.texels.context, cl.mem_flags.READ_ONLY | cl.mem_flags.COPY_HOST_PTR,
                                hostbuf=self.params(intensity, rotation_deg))
                self._params[key] = buf
        return (self.texels, self.levels, self.sh, self.dfg, buf)

    def level(self, queue, index: int) -> np.ndarray:
        """Level `index` (0: full resolution, 1 + k: specular level k) as (h, w, 3) float32 (waits)."""
        off, w, h, _ = (int(v) for v in self.level_table[index])
        out = np.empty((h, w, 3), np.float32)
        cl.enqueue_copy(queue, out, self.texels, src_offset=off * 12, is_blocking=True)
        return out

    def sh_coefficients(self, queue) -> np.ndarray:
        """(9, 3) float32: E(n)/pi = sum_k c_k SH_K[k] poly_k(n) (waits)."""
        out = np.empty((9, 3), np.float32)
        cl.enqueue_copy(queue, out, self.sh, is_blocking=True)
        return out

    def dfg_table(self, queue) -> np.ndarray:
        """(n, n, 3) float32 (roughness row, n.v column; A, B, C) (waits)."""
        out = np.empty((self.dfg_size, self.dfg_size, 3), np.float32)
        cl.enqueue_copy(queue, out, self.dfg, is_blocking=True)
        return out

    def phase_ms(self) -> dict:
        """Device milliseconds per precompute phase from the profiling events (waits for them)."""
        out = {}
        for phase, evs in self.events.items():
            if evs:
                cl.wait_for_events(evs)
                out[phase] = sum((e.profile.end - e.profile.start) for e in evs) * 1e-6
        return out


_lock = threading.RLock()
_env_cache: dict = {}       # Device -> OrderedDict(key -> IblMaps)
_dfg_cache: dict = {}       # (Device, size, samples) -> cl.Buffer


def clear_cache() -> None:
    with _lock:
        _env_cache.clear()
        _dfg_cache.clear()


def _kernels(device):
    vec = capabilities.pixel_vector_width(device.cl_device)
    defines = {"VEC": vec}
    names = ("ibl_box", "ibl_copy", "ibl_sh_rows", "ibl_sh_reduce", "ibl_sample_table", "ibl_prefilter", "ibl_dfg")
    return vec, ProgramSpec.of(SOURCE, defines), {n: device.kernel(SOURCE, n, defines) for n in names}


def gauss_legendre01(k: int) -> np.ndarray:
    """float32 (k, 2): Gauss-Legendre nodes and weights on [0, 1]."""
    x, w = np.polynomial.legendre.leggauss(int(k))
    return np.ascontiguousarray(np.stack([0.5 * (x + 1.0), 0.5 * w], 1), np.float32)


def dfg_table(device, queue=None, size: int = DFG_SIZE, samples: tuple = DFG_SAMPLES,
              cache: bool = True) -> cl.Buffer:
    """The split-sum table on `device` (float32 (size, size, 3): row j at roughness j / (size - 1), column i
    at n.v = (i + 0.5) / size; A, B, C),
    computed once per device. samples = (Gauss-Legendre nodes along theta, nodes per half of phi)."""
    queue = queue or device.queue
    ks, kp = (int(v) for v in samples)
    key = (device, int(size), ks, kp)
    with _lock:
        buf = _dfg_cache.get(key) if cache else None
        if buf is None:
            vec, _, k = _kernels(device)
            mf = cl.mem_flags
            buf = cl.Buffer(device.context, mf.READ_WRITE, size * size * 3 * 4)
            gs = cl.Buffer(device.context, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=gauss_legendre01(ks))
            gp = cl.Buffer(device.context, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=gauss_legendre01(kp))
            g, l = launch_2d(-(-size // vec), size)
            k["ibl_dfg"](queue, g, l, buf, np.int32(size), gs, np.int32(ks), gp, np.int32(kp))
            if cache:
                _dfg_cache[key] = buf
        return buf


def pixels_key(pixels: np.ndarray) -> str:
    """A content key for an environment (when the caller has none)."""
    a = np.ascontiguousarray(pixels, np.float32)
    return "sha1:" + hashlib.sha1(a.view(np.uint8).reshape(-1)).hexdigest() + f":{a.shape}"


def ibl_maps(device, queue, pixels: np.ndarray, key: Hashable = None, *,
             specular_levels: int = DEFAULT_SPECULAR_LEVELS, max_width: int = DEFAULT_MAX_WIDTH,
             samples: Optional[tuple] = None, dfg_size: int = DFG_SIZE, dfg_samples: tuple = DFG_SAMPLES,
             cache: bool = True) -> IblMaps:
    """The IBL maps of the equirectangular environment `pixels` ((H, W, 3) float32 linear RGB,
    finite, >= 0) on `device` (a clrender.device.Device), enqueued on `queue` (None: the device's).
    Precomputed once per (device, key, options); key None: the pixels' content hash. Returns without
    waiting for the device."""
    queue = queue or device.queue
    samples = tuple(int(s) for s in (samples or PREFILTER_SAMPLES))
    if specular_levels < 1:
        raise ValueError("specular_levels must be >= 1")
    if key is None:
        key = pixels_key(pixels)
    full_key = (key, int(specular_levels), int(max_width), samples, int(dfg_size), tuple(dfg_samples))
    with _lock:
        per_device = _env_cache.setdefault(device, OrderedDict())
        if cache and full_key in per_device:
            per_device.move_to_end(full_key)
            return per_device[full_key]
        maps = _precompute(device, queue, pixels, key, specular_levels, max_width, samples, dfg_size, dfg_samples)
        if cache:
            per_device[full_key] = maps
            while len(per_device) > CACHE_ENVIRONMENTS:
                per_device.popitem(last=False)
        return maps


def _precompute(device, queue, pixels, key, K, max_width, samples, dfg_size, dfg_samples) -> IblMaps:
    pixels = np.ascontiguousarray(pixels, dtype=np.float32)
    if pixels.ndim != 3 or pixels.shape[2] != 3 or pixels.shape[0] < 1 or pixels.shape[1] < 2:
        raise ValueError(f"an environment is (H, W, 3) float32, got shape {pixels.shape}")
    H, W = int(pixels.shape[0]), int(pixels.shape[1])
    if W * H * 3 >= 2 ** 31 // 4:
        raise ValueError(f"environment too large ({W}x{H})")
    vec, spec, k = _kernels(device)
    spec_sizes = specular_sizes(W, H, K, max_width)
    w0, h0 = spec_sizes[0]
    alias = (w0, h0) == (W, H)            # the specular chain's level 0 is the environment itself
    table = np.zeros((K + 1, LEVEL_STRIDE), np.int32)
    table[0] = (0, W, H, 0)
    offset = W * H
    for i, (w, h) in enumerate(spec_sizes):
        if i == 0 and alias:
            table[1] = (0, w, h, 0)
            continue
        table[1 + i] = (offset, w, h, 0)
        offset += w * h
    total = offset
    msizes = mip_sizes(w0, h0)
    mtable = np.zeros((len(msizes), LEVEL_STRIDE), np.int32)
    moff = 0
    for i, (w, h) in enumerate(msizes):
        mtable[i] = (moff, w, h, 0)
        moff += w * h

    ctx = device.context
    mf = cl.mem_flags
    events: dict = {}
    with progress.stage("precomputing image-based lighting", 4, device.name) as stage:
        device.build([spec])
        texels = cl.Buffer(ctx, mf.READ_WRITE, total * 12)
        mips = cl.Buffer(ctx, mf.READ_WRITE, moff * 12)
        levels = cl.Buffer(ctx, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=table)
        mip_levels = cl.Buffer(ctx, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=mtable)
        sh = cl.Buffer(ctx, mf.READ_WRITE, 27 * 4)
        partial = cl.Buffer(ctx, mf.READ_WRITE, 27 * H * 4)
        # The environment goes to its own buffer, then a kernel copies it into level 0: Oclgrind 21.10's
        # checker reports reads of a buffer the host wrote as uninitialized once a kernel has used it
        # as both source and destination (the box resize into the chain's level 0 does).
        env = cl.Buffer(ctx, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=pixels)
        g, l = launch_1d(W * H * 3)
        events["upload"] = [k["ibl_copy"](queue, g, l, env, np.int32(0), texels, np.int32(0), np.int32(W * H * 3))]
        stage.advance("upload")

        # the specular chain's level 0 and the prefilter's source chain
        ev = []
        if not alias:
            g, l = launch_2d(w0, h0)
            ev.append(k["ibl_box"](queue, g, l, env, np.int32(0), np.int32(W), np.int32(H),
                                   texels, np.int32(table[1][0]), np.int32(w0), np.int32(h0)))
        g, l = launch_1d(w0 * h0 * 3)
        ev.append(k["ibl_copy"](queue, g, l, env if alias else texels, np.int32(3 * table[1][0]), mips, np.int32(0),
                                np.int32(w0 * h0 * 3)))
        for m in range(1, len(msizes)):
            (sw, sh_), (dw, dh) = msizes[m - 1], msizes[m]
            g, l = launch_2d(dw, dh)
            ev.append(k["ibl_box"](queue, g, l, mips, np.int32(mtable[m - 1][0]), np.int32(sw), np.int32(sh_),
                                   mips, np.int32(mtable[m][0]), np.int32(dw), np.int32(dh)))
        events["downsample"] = ev
        stage.advance("downsample")

        ev = []
        rows = max((spec_sizes[i][1] * level_samples(i, samples) for i in range(1, K)), default=1)
        sample_table = cl.Buffer(ctx, mf.READ_WRITE, max(rows, 1) * 16)
        for i in range(1, K):
            off, w, h, _ = (int(v) for v in table[1 + i])
            rough = i / (K - 1)
            n = level_samples(i, samples)
            g, l = launch_1d(h * n)
            ev.append(k["ibl_sample_table"](queue, g, l, sample_table, np.int32(h), np.int32(n), np.float32(rough * rough),
                                            np.int32(w0), np.int32(h0), np.int32(len(msizes))))
            g, l = launch_2d(-(-w // vec), h)
            ev.append(k["ibl_prefilter"](queue, g, l, mips, mip_levels, np.int32(len(msizes)), sample_table, np.int32(n),
                                         texels, np.int32(off), np.int32(w), np.int32(h)))
        events["prefilter"] = ev
        stage.advance("prefilter")

        g, l = launch_1d(H)
        ev = [k["ibl_sh_rows"](queue, g, l, env, np.int32(W), np.int32(H), partial)]
        g, l = launch_1d(27)
        ev.append(k["ibl_sh_reduce"](queue, g, l, partial, np.int32(H), sh))
        events["sh"] = ev
        stage.advance("irradiance")

        dfg = dfg_table(device, queue, dfg_size, dfg_samples)
    # the scratch buffers (env, mips, mip_levels, partial, sample_table) are released by the runtime
    # once the kernels queued on them are done
    return IblMaps(texels=texels, levels=levels, sh=sh, dfg=dfg, level_table=table, width=W, height=H,
                   specular_levels=K, dfg_size=int(dfg_size), samples=samples, key=key, events=events)


# -- the pass --------------------------------------------------------------------------------------
# The scene's environment (Scene.set_environment) made ready for the lighting passes: its maps
# precomputed once per environment (ibl_maps, cached), then every frame only the ENV_PARAMS
# arguments with its intensity and rotation. A scene without an environment launches no kernel:
# the lighting passes get 1-element placeholders and has_env = 0 (the constant `scene.ambient`).

ENV_OUTPUTS = ("env_args", "has_env", "env_background")


class IblPass(RenderPass):
    name = "ibl"
    inputs = ("environment",)
    outputs = ENV_OUTPUTS

    def active(self, res):
        return res["environment"] is not None    # no environment: the constant ambient, no kernel

    def __init__(self, device, config):
        super().__init__(device, config)
        self.placeholder = tuple(zeros(self.queue, 8, dt).data for dt in
                                 (np.float32, np.int32, np.float32, np.float32, np.float32))

    def publish(self, res):
        env = res["environment"]
        if env is None:
            res.values.update(env_args=self.placeholder, has_env=0, env_background=0)

    def run(self, res):
        env = res["environment"]
        maps = ibl_maps(self.device, self.queue, env.pixels, key=env.key, dfg_size=DFG_SIZE, dfg_samples=DFG_SAMPLES)
        res.values.update(env_args=maps.args(env.intensity, env.rotation_deg), has_env=1,
                          env_background=int(env.background))


def env_kernel_args(res) -> tuple:
    """(has_env, env_background, *ENV_PARAMS) for a lighting kernel."""
    return (np.int32(res["has_env"]), np.int32(res["env_background"]), *res["env_args"])
