"""Device memory: what a frame will need (checked before allocating) and what clrender holds.

`estimate()` predicts the bytes of the buffers the passes allocate per resolution (and, given a
scene, of its upload), `check()` compares that with the device's global memory and its largest
single allocation (CL_DEVICE_MAX_MEM_ALLOC_SIZE) and raises `DeviceMemoryError` naming both.
`held_bytes()` sums the device buffers actually owned (passes, pipeline constants, scene upload);
`Frame.stats["device_bytes"]` reports it. tests/test_memory.py keeps the estimate honest.
The shadow atlas and its per-size raster stages depend on the frame's lights, not only on the
resolution: ShadowPass checks the atlas against the device's limits before allocating it.
"""
from __future__ import annotations

from collections.abc import Mapping

import pyopencl as cl
import pyopencl.array as cla

from clrender.abi import gbuffer as layout
from clrender.abi import structs
from clrender.passes.base import RenderPass
from clrender.passes.binning import initial_list_capacity


class DeviceMemoryError(ValueError):
    """The requested frame or scene does not fit the device's memory."""


def _gb(n: int) -> str:
    return f"{n / 2**30:.2f} GiB"


def limits(cl_device) -> tuple[int, int]:
    """(global memory bytes, largest single allocation bytes) of a pyopencl device."""
    return int(cl_device.global_mem_size), int(cl_device.max_mem_alloc_size)


def check_buffer(device, what: str, entries: int, bytes_per_entry: int, capacity: int) -> None:
    """DeviceMemoryError unless `capacity` entries of `bytes_per_entry` (in 4-byte arrays) fit
    the device; raised before allocating, naming what needs the memory."""
    need = int(capacity) * bytes_per_entry
    total, max_alloc = limits(device.cl_device)
    if need > total or 4 * int(capacity) > max_alloc:
        raise DeviceMemoryError(
            f"{what} need {need} bytes ({_gb(need)}) of device memory for {entries} entries but {device.name} "
            f"has {total} bytes ({_gb(total)}), at most {max_alloc} bytes ({_gb(max_alloc)}) per allocation; "
            f"render at a smaller size or set max_fragments_per_pixel")


def estimate(width: int, height: int, config, scene=None) -> dict:
    """{"total": bytes, "largest": bytes of the biggest single buffer, "largest_name": its name}
    for the per-resolution buffers of every pass, plus the scene upload when `scene` is given.
    Mirrors the allocate()/prepare_scene() sizes in clrender/passes/ (initial list capacities).
    With supersample k the passes before the resolve hold k²-sized buffers (counted at the
    internal size, which covers the post chain's smaller ones), plus the resolve's own."""
    k = getattr(config, "supersample", 1)
    out_w, out_h = int(width), int(height)
    width, height = k * out_w, k * out_h
    px = int(width) * int(height)
    tiles = -(-width // config.tile_size) * -(-height // config.tile_size)
    buffers = {
        "raster.vis_depth+vis_prim": 8 * px,
        "gbuffer": 4 * len(layout.PLANES) * px,
        "shade.color": 12 * px,
        "shade.light_count": 4 * px,
        "shade.light_pairs": 8 * px + 16,     # evaluated + useful per pixel, their 64-bit sums
        "tonemap.image": 4 * px,
        "binning.tiles": 12 * tiles,
        "binning.tile_prims": 4 * 8 * tiles,
        "pipeline.constants": 4 * 64 + 8 * layout.SRGB_ENCODE_INTERVALS,   # matrices, sRGB encoder
        "setup.prims": structs.prim_dtype.itemsize * 1024,
    }
    buffers.update(_pipeline_buffers(px, tiles, config, scene))
    if getattr(config, "ssao", False):
        buffers["ssao.ao"] = 4 * px
        if config.ssao_blur:
            buffers["ssao_blur.along_x+ao"] = 8 * px
    ltiles = -(-width // config.light_tile_size) * -(-height // config.light_tile_size)
    if config.light_culling in ("tiled", "stencil"):
        buffers["light_cull.tiles"] = 24 * ltiles
        buffers["light_cull.tile_lights"] = 4 * 16 * ltiles
    if config.light_culling == "stencil":        # initial words per pixel (docs/light_accumulation.md)
        from clrender.passes.light_stencil import INITIAL_WORDS
        buffers["light_stencil.words"] = 4 * INITIAL_WORDS * px
    if config.light_culling == "quads":
        buffers["light_quads.tiles"] = 8 * ltiles
        buffers["light_quads.tile_lights"] = 4 * 16 * ltiles
    if scene is not None:
        v, t, n_lights = len(scene.positions), scene.triangle_count, len(scene.lights)
        texels = sum(tex.rgba.shape[0] * tex.rgba.shape[1] for tex in scene.textures) * 4 // 3 + 1
        buffers.update({
            "scene.vertices": 32 * v + (12 * v if getattr(scene, "previous_positions", None) is not None else 0),
            "scene.triangles": 16 * t,
            "scene.texels": 4 * texels,
            "scene.lights": (structs.light_dtype.itemsize + 16) * n_lights,   # + culling spheres
            "setup.per_triangle": _setup_per_triangle(t, config),
            "setup.prims": structs.prim_dtype.itemsize * max(1024, t + t // 8),
            "binning.tile_prims": 4 * initial_list_capacity(tiles, t),
        })
        if getattr(config, "chunk_cull", False):
            from clrender.passes.chunk_cull import n_chunks
            buffers["chunk_cull.bounds"] = 32 * n_chunks(t)
        if config.light_culling == "quads":               # + pixel and tile rectangles
            buffers["light_quads.rects"] = 32 * n_lights
        if getattr(config, "transparency", "screen_door") != "screen_door" and any(
                m.alpha_mode == "BLEND" for m in scene.materials):
            from clrender.render.scene_upload import transparent_triangle_count
            buffers.update(_transparency(px, tiles, t, transparent_triangle_count(scene), config))
    if getattr(config, "bloom", False):                  # at the output size (after the resolve)
        from clrender.passes.bloom import bloom_levels, level_sizes
        levels, _, taps = bloom_levels(config.bloom_radius)
        sizes = level_sizes(out_w, out_h, levels)
        buffers["bloom.pyramid+tmp+color+taps"] = (12 * out_w * out_h + 12 * sum(w * h for w, h in sizes)
                                                   + 12 * sizes[0][0] * sizes[0][1] + 4 * (2 * taps + 1))
    if getattr(config, "ldr_effects", False):            # tonemap writes LDR planes, encode the image
        buffers["tonemap.image"] = 12 * out_w * out_h
        buffers["encode.image"] = 4 * out_w * out_h
        if config.edge_aa:
            buffers["edge_aa.ldr+edges+flags"] = 14 * out_w * out_h
        if config.color_aa == "fxaa":
            buffers["fxaa.ldr+luma"] = 16 * out_w * out_h
    if getattr(config, "motion_blur", False):
        from clrender.passes.motion_blur import MAX_RADIUS
        tiles_y = -(-out_h // MAX_RADIUS)
        tiles = -(-out_w // MAX_RADIUS) * tiles_y
        runs = out_w                                     # VEC = 1 at most: one partial max per pixel column
        buffers["motion_blur.inv_len+color+tiles"] = 16 * out_w * out_h + 16 * runs * tiles_y + 8 * tiles
    if getattr(config, "hatching", False):
        from clrender.passes import tam
        buffers["hatching.out+tam"] = 12 * out_w * out_h + tam.DEVICE_BYTES
    if k > 1:
        buffers["resolve.rows+color+gbuffer"] = 12 * out_w * height + (12 + 4 * len(layout.PLANES)) * out_w * out_h
    name = max(buffers, key=buffers.get)
    return {"total": sum(buffers.values()), "largest": buffers[name], "largest_name": name}


def _setup_per_triangle(t: int, config) -> int:
    """setup's per-triangle buffers (passes/setup.py): counts, offsets, statuses and staged prims;
    with the chunk cull they are per chunk slot, plus the cull's chunk lists (the chunk boxes,
    shared by every view, are counted once: "chunk_cull.bounds")."""
    prim = structs.prim_dtype.itemsize
    if not getattr(config, "chunk_cull", False):
        return (9 + prim) * t
    from clrender.passes.chunk_cull import CHUNK, n_chunks
    c = n_chunks(t)
    return (8 + prim) * c * CHUNK + t + 8 * c + (5 * c + 4)


def _transparency(px: int, tiles: int, n_tris: int, n_blend: int, config) -> dict:
    """Buffers of the transparency passes (allocated when a scene has BLEND triangles)."""
    out = {"fragments.counts+range": 16 * px, "fragments.binning": 44 * tiles,
           "fragments.setup": _setup_per_triangle(n_tris, config)
           + structs.prim_dtype.itemsize * max(1024, n_blend + n_blend // 8),
           "composite.color": 12 * px}
    if config.transparency == "abuffer":
        out["abuffer.offsets+layers"] = 32 * px
        out["abuffer.frag_depth+frag_prim"] = 8 * 2 * px      # initial capacity: 2 fragments per pixel
    else:
        out["peel.layer+layers"] = 36 * px
    return out


def check(device, width: int, height: int, config, scene=None) -> dict:
    """`estimate()`, raising DeviceMemoryError when it exceeds the device's limits."""
    need = estimate(width, height, config, scene)
    total, max_alloc = limits(device.cl_device)
    k = getattr(config, "supersample", 1)
    what = f"{width}x{height}" + (f" at supersample {k} ({k * width}x{k * height} internally)" if k > 1 else "") \
        + ("" if scene is None else f" with {scene.triangle_count} triangles")
    if need["total"] > total:
        raise DeviceMemoryError(
            f"{what} needs about {need['total']} bytes ({_gb(need['total'])}) of device memory but "
            f"{device.name} has {total} bytes ({_gb(total)}); render at a smaller size")
    if need["largest"] > max_alloc:
        raise DeviceMemoryError(
            f"{what} needs a {need['largest']}-byte ({_gb(need['largest'])}) buffer ({need['largest_name']}) "
            f"but {device.name} allows at most {max_alloc} bytes ({_gb(max_alloc)}) per allocation "
            f"(CL_DEVICE_MAX_MEM_ALLOC_SIZE); render at a smaller size")
    return need


def _buffers(value, out: dict) -> None:
    """Collect {buffer pointer: bytes} from a cla.Array / cl.Buffer or containers of them."""
    if isinstance(value, cla.Array):
        buf = value.base_data
        if buf is not None:
            out[buf.int_ptr] = int(buf.size)
    elif isinstance(value, cl.Buffer):
        out[value.int_ptr] = int(value.size)
    elif isinstance(value, Mapping):            # dicts, and weak-keyed caches (the pose pass's bind data)
        for v in list(value.values()):
            _buffers(v, out)
    elif isinstance(value, (list, tuple)):
        for v in value:
            _buffers(v, out)
    elif isinstance(value, RenderPass):          # a pass's inner stages (fragments: setup, binning)
        _buffers(vars(value), out)


def held_bytes(pipeline, scene_res) -> dict:
    """Bytes of device buffers held for a frame, by owner: each pass (its attributes), "pipeline"
    (camera matrices, constant tables) and "scene" (the upload and lights). Shared buffers are
    counted once, under the first owner."""
    seen: dict = {}
    by_owner = {}
    owners = [("scene", scene_res.buffers), ("pipeline", (pipeline.matrices, pipeline.constants))]
    owners += [(p.name, vars(p)) for p in pipeline.passes]
    if pipeline.pose_pass is not None:          # skins and morph targets (bind data, palette, previous positions)
        owners.append(("pose", vars(pipeline.pose_pass)))
    for name, value in owners:
        found: dict = {}
        _buffers(value, found)
        fresh = {k: v for k, v in found.items() if k not in seen}
        seen.update(fresh)
        by_owner[name] = by_owner.get(name, 0) + sum(fresh.values())
    return {"device_bytes": int(sum(seen.values())), "device_bytes_by_owner": by_owner}



def _pipeline_buffers(px: int, tiles: int, config, scene) -> dict:
    """The light pre-pass's and light-indexed's own buffers (docs/variants.md), on top of the
    deferred pipeline's (which keeps its G-buffer as the AOV output in every pipeline)."""
    pipeline = getattr(config, "pipeline", "deferred")
    if pipeline == "deferred":
        return {}
    out = {}
    if pipeline == "light_prepass":
        from clrender.passes.light_buffer import PRECISIONS, light_buffer_planes
        out["shade.color"] = 0                              # the material pass owns the colour
        out["light_buffer"] = light_buffer_planes(config) * PRECISIONS[config.light_buffer_precision][0](
            0).itemsize * px
        out["material.color+spread+deltas"] = 12 * px + (12 * px if config.msaa > 1 else 4) + \
            max(12 * (config.msaa - 2) * px, 4)
        if config.msaa > 1:              # one setup and binning, a visibility buffer per sub-sample
            t = scene.triangle_count if scene is not None else 0
            prims = structs.prim_dtype.itemsize * max(1024, t + t // 8)
            out["msaa_geometry"] = (4 * px * (config.msaa + 1) + 12 * tiles + 4 * initial_list_capacity(tiles, t)
                                    + prims + _setup_per_triangle(t, config))
    return out


def pixel_buffers(config) -> dict:
    """Bytes per pixel of every per-pixel buffer a frame goes through, by role (Frame.stats
    "bytes_per_pixel"; docs/variants.md): what the pipeline variants trade against each other."""
    pipeline = getattr(config, "pipeline", "deferred")
    planes = layout.geometry_planes(config)
    out = {"visibility": 8, "gbuffer_geometry_pass": 4 * len(planes)}
    if pipeline == "light_prepass":
        from clrender.passes.light_buffer import PRECISIONS, light_buffer_planes
        out["light_buffer"] = light_buffer_planes(config) * PRECISIONS[config.light_buffer_precision][0](0).itemsize
        if config.msaa > 1:
            out["msaa_visibility"] = 4 * config.msaa + 4     # a prim index per sample, one depth scratch
            out["msaa_resolve"] = 12 + 12 * (config.msaa - 2)   # running sum, kept deltas (material.cl)
    out["gbuffer_aov_planes"] = 4 * (len(layout.PLANES) - len(planes))
    out["color"] = 12
    out["total"] = sum(out.values())
    return out
