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
from clrender.device.limits import _gb, check_buffer, limits  # noqa: F401  (check_buffer: re-exported)
from clrender.errors import DeviceMemoryError  # noqa: F401  (re-exported)
from clrender.passes.base import RenderPass


def estimate(width: int, height: int, config, scene=None) -> dict:
    """{"total": bytes, "largest": bytes of the biggest single buffer, "largest_name": its name}
    for the per-resolution buffers of every pass, plus the scene upload when `scene` is given.
    Each pass declares its buffers (`buffer_bytes`, next to its allocate(); initial list
    capacities) and clrender/render/plan.py says which passes run. With supersample k the passes
    before the resolve hold k²-sized buffers, the resolve and post chain output-sized ones."""
    from clrender.render import plan
    from clrender.render.scene_upload import vertex_bytes
    k = getattr(config, "supersample", 1)
    out_w, out_h = int(width), int(height)
    width, height = k * out_w, k * out_h
    blend = scene is not None and any(m.see_through for m in scene.materials)    # BLEND or transmissive
    buffers = {"pipeline.constants": 4 * 64 + 8 * layout.SRGB_ENCODE_INTERVALS}   # matrices, sRGB encoder
    for cls in plan.pass_classes(config):
        where = plan.stage(cls)
        if where == "transparency" and not blend:
            continue                    # allocated only for a scene with BLEND triangles
        size = (out_w, out_h) if where == "output" else (width, height)
        buffers.update(cls.buffer_bytes(*size, config, scene))
    if k > 1 and not config.ldr_effects:
        # kept from before the passes declared their sizes: the image counted at the internal size
        # (an upper bound; tests/test_supersample.py counts on it)
        buffers["tonemap.image"] = 4 * width * height
    if scene is not None:
        v, n_lights = len(scene.positions), len(scene.lights)
        texels = sum(tex.rgba.shape[0] * tex.rgba.shape[1] for tex in scene.textures) * 4 // 3 + 1
        buffers.update({
            # tangents (16 bytes a vertex) were missing: Sponza x40 held 114 MiB over the estimate
            "scene.vertices": vertex_bytes(scene)
            + (12 * v if getattr(scene, "previous_positions", None) is not None else 0),
            "scene.triangles": 16 * scene.triangle_count,
            "scene.texels": 4 * texels,
            # the decoded pool (clrender/render/texture_pool.py linear_texels), when the budget takes it
            "scene.texels_linear": 16 * texels if 16 * texels <= getattr(config, "decoded_textures_mb", 0) * 2**20 else 0,
            "scene.lights": (structs.light_dtype.itemsize + 16) * n_lights,   # + culling spheres
        })
    name = max(buffers, key=buffers.get)
    return {"total": sum(buffers.values()), "largest": buffers[name], "largest_name": name}


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
