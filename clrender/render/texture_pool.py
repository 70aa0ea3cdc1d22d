"""The texture pool: every device texture's RGBA8 mip chain in one texel buffer.

`mip_chain` is the definition (and the host path): levels halve with floor down to 1x1 as in GL;
each level is PIL's BOX resize, channel by channel in float32 linear space (sRGB colour channels
decoded through `srgb_to_linear_lut`, alpha and linear textures as byte / 255), of the previous
level's float values (not of its 8-bit codes), then encoded to 8 bits (`encode8`).

`linear_texels` keeps, beside it, every texel decoded to float4 linear RGBA (kernels/texel_decode.cl),
4× the bytes, when the render options' `decoded_textures_mb` allows: the G-buffer's samples then
load floats instead of decoding each texel every time it is sampled (kernels/texture_vec.h
TEXELS_LINEAR), for the same bits.

`upload_pool` builds the pool on the device when it has doubles (kernels/mipmap.cl): level 0 is
copied in and every further level computed there, bit-identical to `mip_chain`, because the kernel
repeats PIL's arithmetic (`box_taps`: taps and double weights per output row / column, doubles
summed in order, rounded to float after each pass, passes in PIL's order: `pil_vertical_first`) and encodes by comparing with thresholds taken
from `encode8` itself (`code_thresholds`). Without doubles the host chain is uploaded.
"""
from __future__ import annotations

import weakref
from functools import lru_cache

import numpy as np

from clrender.abi import structs
from clrender.abi.gbuffer import linear_to_srgb8, srgb_to_linear_lut
from clrender.scene.model import Texture

_MIP_CACHE: "weakref.WeakKeyDictionary[Texture, list[np.ndarray]]" = weakref.WeakKeyDictionary()
ENV_HOST_MIPS = "CLRENDER_HOST_MIPS"      # "1": build mip chains on the host even on a device with doubles


def encode8(linear: np.ndarray, srgb: bool) -> np.ndarray:
    """float32 linear values -> 8-bit codes: sRGB-encoded, or round(clip(x) * 255) in float32."""
    if srgb:
        return linear_to_srgb8(linear)
    return np.floor(np.clip(linear, 0, 1) * 255 + 0.5).astype(np.uint8)


def mip_chain(tex: Texture) -> list[np.ndarray]:
    """RGBA8 levels, level 0 first, down to 1×1; sizes halve with floor as in GL."""
    from PIL import Image

    cached = _MIP_CACHE.get(tex)
    if cached is not None:
        return cached
    levels = [tex.rgba]
    lut = srgb_to_linear_lut()
    h, w = tex.rgba.shape[:2]
    if max(h, w) > 1:
        linear = [lut[tex.rgba[..., c]] if (tex.srgb and c < 3) else tex.rgba[..., c].astype(np.float32) / 255.0
                  for c in range(4)]
        while max(h, w) > 1:
            h, w = max(h // 2, 1), max(w // 2, 1)
            linear = [np.asarray(Image.fromarray(ch, mode="F").resize((w, h), Image.BOX)) for ch in linear]
            level = np.empty((h, w, 4), np.uint8)
            for c in range(4):
                level[..., c] = encode8(linear[c], tex.srgb and c < 3)
            levels.append(level)
    _MIP_CACHE[tex] = levels
    return levels


def level_sizes(h: int, w: int) -> list[tuple[int, int]]:
    """(h, w) of every level of an h x w texture, level 0 first (mip_chain's sizes)."""
    sizes = [(h, w)]
    while max(h, w) > 1:
        h, w = max(h // 2, 1), max(w // 2, 1)
        sizes.append((h, w))
    return sizes


def pool_layout(textures: list[Texture]):
    """(TexInfo[T], TexLevel[L], texel count): where every level of every texture lies in the pool."""
    infos = np.zeros(max(len(textures), 1), structs.texinfo_dtype)
    level_records, offset = [], 0
    for t, tex in enumerate(textures):
        sizes = level_sizes(*tex.rgba.shape[:2])
        infos[t] = (len(level_records), len(sizes), structs.WRAP[tex.wrap_s], structs.WRAP[tex.wrap_t],
                    structs.LUT_SRGB if tex.srgb else structs.LUT_LINEAR, (0, 0, 0))
        for h, w in sizes:
            level_records.append((offset, w, h, 0))
            offset += w * h
    if offset >= 2**31:
        raise ValueError(f"textures need {offset} texels; more than 2^31 is not supported")
    levels = np.array(level_records or [(0, 1, 1, 0)], structs.texlevel_dtype)
    return infos, levels, offset


def texture_pool(textures: list[Texture]):
    """(texels uint32[N], TexInfo[T], TexLevel[L]) for all textures, built on the host."""
    infos, levels, total = pool_layout(textures)
    texels = np.zeros(max(total, 1), np.uint32)
    for t, tex in enumerate(textures):
        first = int(infos[t]["first_level"])
        for k, level in enumerate(mip_chain(tex)):
            offset = int(levels[first + k]["offset"])
            texels[offset:offset + level.shape[0] * level.shape[1]] = \
                np.ascontiguousarray(level).view(np.uint32).reshape(-1)
    return texels, infos, levels


def decode_tables() -> np.ndarray:
    """float32[512]: the sRGB decode table (LUT_SRGB) then c / 255 (LUT_LINEAR)."""
    return np.concatenate([srgb_to_linear_lut(), np.arange(256, dtype=np.float32) / np.float32(255.0)])


# -- the device path ---------------------------------------------------------------------------------
def box_taps(n_in: int, n_out: int) -> list[tuple[int, list[float]]]:
    """Per output index: (first input index, weights), PIL's BOX filter coefficients for resizing
    n_in samples to n_out (Pillow's precompute_coeffs in doubles, as the C code computes them)."""
    scale = filterscale = float(n_in) / n_out
    filterscale = max(filterscale, 1.0)
    support = 0.5 * filterscale
    ss = 1.0 / filterscale
    out = []
    for xx in range(n_out):
        center = (xx + 0.5) * scale
        xmin = max(int(center - support + 0.5), 0)
        xmax = min(int(center + support + 0.5), n_in) - xmin
        ws = [1.0 if -0.5 < ((x + xmin) - center + 0.5) * ss <= 0.5 else 0.0 for x in range(xmax)]
        total = 0.0
        for w in ws:
            total += w
        out.append((xmin, [w / total for w in ws] if total != 0.0 else ws))
    return out


def pil_vertical_first(h: int, w: int) -> bool:
    """Whether PIL (13.0) resizes an h x w float image to half size columns first: it does when
    h > 4 * ceil(w / 2), found by comparing with both orders (the order changes the float rounding;
    tests/test_texture_pool.py checks the rule against PIL on many sizes)."""
    return h > 4 * ((w + 1) // 2)


@lru_cache(maxsize=None)
def code_thresholds() -> np.ndarray:
    """float32[2][256]: per encoding (sRGB, then linear) t[k] = the smallest float32 x in [0, 1]
    with encode8(x) >= k (t[0] = 0): encode8(x) = #{k >= 1: t[k] <= x} for every float32 x in
    [0, 1] (the encoders are monotonic; tests/test_texture_pool.py checks it). Bisection over
    float32 bit patterns, which order like the values for x >= 0."""
    one = int(np.float32(1.0).view(np.uint32))
    k = np.arange(256, dtype=np.int64)
    out = np.zeros((2, 256), np.float32)
    for row, srgb in enumerate((True, False)):
        lo, hi = np.zeros(256, np.int64), np.full(256, one + 1, np.int64)
        while np.any(lo < hi):
            mid = (lo + hi) // 2
            x = np.minimum(mid, one).astype(np.uint32).view(np.float32)
            ok = encode8(x, srgb).astype(np.int64) >= k
            hi, lo = np.where(ok, mid, hi), np.where(ok, lo, mid + 1)
        out[row] = np.minimum(lo, one).astype(np.uint32).view(np.float32)
    return out


ENCODE_INTERVALS = 4096


@lru_cache(maxsize=None)
def encode_table(n: int = ENCODE_INTERVALS) -> np.ndarray:
    """float32 (n, 2) for mipmap.cl's sRGB encoder: [0, 1) in n equal intervals, entry k = (threshold,
    base): encode8(x, True) = base + (x >= threshold) for x in interval k (exact, from
    code_thresholds; AssertionError if an interval held two code boundaries)."""
    t = code_thresholds()[0].astype(np.float64)
    lo = np.arange(n, dtype=np.float64) / n                 # exact in float32 for n a power of 2
    base = encode8(lo.astype(np.float32), True).astype(np.int64)
    nxt = np.append(t, 2.0)[np.minimum(base + 1, 256)]      # the next code's threshold (none past 255)
    if np.any(np.append(t, 2.0)[np.minimum(base + 2, 256)] < lo + 1.0 / n):
        raise AssertionError("two sRGB code boundaries in one interval")
    thr = np.where(nxt < lo + 1.0 / n, nxt, 2.0)
    return np.stack([thr, base], 1).astype(np.float32)


def _has_doubles(device) -> bool:
    return "cl_khr_fp64" in device.cl_device.extensions


def device_builds_mips(device) -> bool:
    import os
    return _has_doubles(device) and os.environ.get(ENV_HOST_MIPS, "0") != "1"


def upload_pool(device, textures: list[Texture]) -> dict:
    """{"texels", "tex_infos", "tex_levels", "srgb_lut"} device arrays for `textures`."""
    import pyopencl.array as cla

    q = device.queue
    if not device_builds_mips(device):
        texels, infos, levels = texture_pool(textures)
        texels_buf = cla.to_device(q, texels)
    else:
        infos, levels, total = pool_layout(textures)
        texels_buf = cla.empty(q, max(total, 1), np.uint32)
        _build_on_device(device, textures, infos, levels, texels_buf)
    return {"texels": texels_buf, "tex_infos": cla.to_device(q, infos), "tex_levels": cla.to_device(q, levels),
            "srgb_lut": cla.to_device(q, decode_tables())}


def _axis_tables(textures: list[Texture]):
    """(taps int32[N][4] = (first, count, weight index, 0), weights float64[M], {(n_in, n_out): row})."""
    rows: dict = {}
    taps, weights = [], []
    for tex in textures:
        sizes = level_sizes(*tex.rgba.shape[:2])
        for (h0, w0), (h1, w1) in zip(sizes, sizes[1:]):
            for pair in ((w0, w1), (h0, h1)):
                if pair in rows:
                    continue
                rows[pair] = len(taps)
                for first, ws in box_taps(*pair):
                    taps.append((first, len(ws), len(weights), 0))
                    weights.extend(ws)
    return (np.array(taps or [(0, 0, 0, 0)], np.int32), np.array(weights or [0.0], np.float64), rows)


def _halves(n: int) -> bool:
    """An axis mip_half handles: halved from an even size, or 1 that stays 1."""
    return n == 1 or n % 2 == 0


_WG = (32, 4)     # work-group shape; rounding odd sizes up to it beats PoCL's own pick


def _build_on_device(device, textures, infos, levels, texels_buf) -> None:
    import pyopencl as cl
    import pyopencl.array as cla

    q = device.queue
    offsets = [int(levels[int(infos[t]["first_level"])]["offset"]) for t in range(len(textures))]
    level0 = [np.ascontiguousarray(tex.rgba).view(np.uint32).reshape(-1) for tex in textures]
    if device.info.is_simulator:
        # Oclgrind's uninitialized-value checker misses writes at an offset (it reports reads of
        # level 0 copied that way): one whole-buffer write there; in place elsewhere (no staging copy)
        staged = np.zeros(texels_buf.size, np.uint32)
        for offset, texels in zip(offsets, level0):
            staged[offset:offset + texels.size] = texels
        texels_buf.set(staged, queue=q)
    else:
        for offset, texels in zip(offsets, level0):      # level 0, straight into its place in the pool
            cl.enqueue_copy(q, texels_buf.data, texels, dst_offset=4 * offset)
    sizes = [level_sizes(*tex.rgba.shape[:2]) for tex in textures]
    if all(len(s) == 1 for s in sizes):
        return
    scratch = [max([s[k][0] * s[k][1] for s in sizes if len(s) > k] or [1]) for k in (1, 2)]
    taps, weights, rows = _axis_tables(textures)
    taps_buf, weights_buf = cla.to_device(q, taps), cla.to_device(q, weights)
    decode, encode = cla.to_device(q, decode_tables()), cla.to_device(q, encode_table())
    linear = [cla.empty(q, 4 * n, np.float32) for n in scratch]     # float4 ping-pong, levels 1, 3.. / 2, 4..
    kernels = {name: device.kernel("mipmap.cl", name, {"ENCODE_INTERVALS": ENCODE_INTERVALS})
               for name in ("mip_level", "mip_half")}
    for t, tex in enumerate(textures):
        first = int(infos[t]["first_level"])
        for k in range(1, len(sizes[t])):
            (h0, w0), (h1, w1) = sizes[t][k - 1], sizes[t][k]
            src, dst = linear[k % 2], linear[(k + 1) % 2]
            gsize = (-(-w1 // _WG[0]) * _WG[0], -(-h1 // _WG[1]) * _WG[1])
            head = (texels_buf.data, src.data, np.int32(tex.srgb), np.int32(levels[first + k - 1]["offset"]),
                    np.int32(w0), dst.data, np.int32(levels[first + k]["offset"]), np.int32(w1), np.int32(h1))
            order = np.int32(pil_vertical_first(h0, w0))
            if _halves(w0) and _halves(h0):
                kernels["mip_half"](q, gsize, _WG, *head, np.int32(min(w0, 2)), np.int32(min(h0, 2)),
                                    order, decode.data, encode.data, np.int32(k == 1))
            else:
                kernels["mip_level"](q, gsize, _WG, *head, taps_buf.data, np.int32(rows[(w0, w1)]),
                                     np.int32(rows[(h0, h1)]), order, weights_buf.data, decode.data,
                                     encode.data, np.int32(k == 1))
    # No finish: the scratch arrays are released on return, and OpenCL keeps a released buffer until
    # the enqueued commands that use it complete; the in-order queue runs the frame after the levels.


# -- the decoded pool -----------------------------------------------------------------------------------
LINEAR_TEXEL_BYTES = 16          # float4 per texel (the RGBA8 pool: 4)


def linear_texels(device, res, budget_mb: int) -> bool:
    """Whether the scene `res` (clrender/render/scene_upload.py) has its decoded pool,
    res.buffers["texels_linear"], making it now when its bytes fit `budget_mb` MiB and one device
    allocation; False (samples decode the RGBA8 pool) when they do not, the budget is 0, the scene
    has no texture or the device runs a pixel per work-item (GPUs: no lane-by-lane gathers to
    save, 4x the bytes to read). Made once per scene upload: textures do not change between frames."""
    from clrender.device import capabilities
    if budget_mb <= 0 or capabilities.pixel_vector_width(device.cl_device) == 1:
        return False            # GPUs, Oclgrind: a pixel per work-item reads the words (a quarter of the bytes)
    if not res.values.get("n_textures"):
        return False            # nothing to sample: no decode, no program
    texels = res["texels"]
    nbytes = LINEAR_TEXEL_BYTES * texels.size
    if nbytes > budget_mb * 2**20 or nbytes > int(device.cl_device.max_mem_alloc_size):
        return False
    if "texels_linear" in res.buffers:
        return True
    import pyopencl.array as cla

    q = device.queue
    infos, levels = res["tex_infos"].get(queue=q), res["tex_levels"].get(queue=q)
    out = cla.empty(q, 4 * texels.size, np.float32)
    kernel = device.kernel("texel_decode.cl", "decode_texels")
    for info in infos:
        first = int(levels[int(info["first_level"])]["offset"])
        last = levels[int(info["first_level"]) + int(info["levels"]) - 1]
        count = int(last["offset"]) + int(last["width"]) * int(last["height"]) - first
        if count <= 0:
            continue
        kernel(q, (-(-count // 64) * 64,), (64,), texels.data, np.int32(first), np.int32(count),
               res["srgb_lut"].data, np.int32(info["lut"]), out.data)
    res.buffers["texels_linear"] = out
    return True
