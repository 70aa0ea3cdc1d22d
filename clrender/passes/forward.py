"""Arguments of kernels/forward.h's FORWARD_PARAMS (forward shading of transparent fragments),
shared by the A-buffer and depth-peeling passes."""
from __future__ import annotations

import numpy as np

from clrender.device import capabilities
from clrender.passes.ibl import ENV_OUTPUTS, env_kernel_args
from clrender.passes.base import SCENE_INPUTS, round_up, scene_args, view_defines

# The transparent layers' planes (forward.h store_layers): colour x3, transmittance, refraction
# offset x, y, the nearest fragment's triangle id (int bits; Frame.object_id)
LAYER_PLANES = 7
# The transmission planes of a scene with transmissive materials (forward.h TRANSMISSION=1;
# docs/transmission.md): T_r, T_g, T_b, lookup lod (-1 none, -2 legacy refraction, >= 0 mip level),
# offset R x, y, offset B x, y (G: the layers' offset planes), the nearest transmissive surface's
# view depth (-1 where the nearest fragment is not one; Frame.depth)
TX_PLANES = 9
FORWARD_INPUTS = ("prims",) + SCENE_INPUTS + ("camera_params", "ambient", "lights", "n_lights", "light_env") + ENV_OUTPUTS


def forward_vec(config, device) -> int:
    """Pixels per work-item of the forward kernels: a run must lie in one light tile."""
    return min(capabilities.pixel_vector_width(device.cl_device), config.light_tile_size)


def forward_defines(config, device, ortho: bool = False) -> dict:
    """ortho: an orthographic camera (lighting.h / forward.h rebuild positions with ORTHO)."""
    return {"VEC": forward_vec(config, device), "LIGHT_TILE": config.light_tile_size,
            "BRUTE_FORCE": int(config.light_culling == "brute_force"), **device_light_defines(config),
            **view_defines(ortho)}


def forward_grid(width: int, height: int, vec: int) -> tuple[tuple, tuple]:
    """(global, local) sizes of a forward kernel: VEC pixels of a row per work-item."""
    local = (max(32 // vec, 1), 4)
    return (round_up(-(-width // vec), local[0]), round_up(height, local[1])), local


def device_light_defines(config) -> dict:
    from clrender.passes.shade import SHADOW_FILTERS
    return {"SHADOWS": int(config.shadows), "SHADOW_FILTER": SHADOW_FILTERS[config.shadow_filter],
            "POISSON_RADIUS": f"{float(config.shadow_filter_radius)!r}f"}


def forward_args(res, prims) -> tuple:
    """FORWARD_PARAMS for a frame; `prims` is the transparent prim buffer. A scene with layered
    materials adds forward.h's SURFACE_LAYERS arguments, one with transmissive materials then its
    TRANSMISSION ones (variant_kernel's builds)."""
    env = res["light_env"]
    return (*scene_args(res, prims), res["camera_params"].data, np.int32(res["width"]), np.int32(res["height"]),
            np.float32(res["ambient"]), res["lights"].data, np.int32(res["n_lights"]), *env.lists,
            *env.shadow_and_sun, *env_kernel_args(res), *res.values.get("surface_layer_args", ()),
            *res.values.get("transmission_args", ()))


def scene_transmissive(scene) -> bool:
    """`scene` has transmissive materials: the buffers the passes declare for them (memory.estimate)."""
    return scene is not None and any(m.transmissive for m in scene.materials)


def transmissive(res) -> bool:
    """The frame's scene has transmissive materials (the upload's TRANSMISSION arguments)."""
    return "transmission_args" in res.values


def tx_args(res) -> tuple:
    """The TRANSMISSION variant's last argument of abuffer_resolve / peel_shade: the tx planes."""
    return (res.buffers["tx_planes"].data,) if transmissive(res) else ()


def variant_kernel(owner, attr: str, res):
    """owner.<attr> (a forward kernel) built for the scene's material features: SURFACE_LAYERS (and
    MULTISCATTER) for layered materials, TRANSMISSION for transmissive ones. Each variant is made the
    first time such a scene renders and kept on `owner`, so a scene with neither builds nothing new."""
    kernel = getattr(owner, attr)
    layers, tx = "surface_layer_args" in res.values, transmissive(res)
    if not (layers or tx):
        return kernel
    name = attr + ("_layered" if layers else "") + ("_transmission" if tx else "")
    variant = owner.__dict__.get(name)
    if variant is None:
        spec = kernel.spec
        defines = dict(spec.defines)
        if layers:
            defines.update(SURFACE_LAYERS=1, MULTISCATTER=int(owner.config.multiscatter))
        if tx:
            defines.update(TRANSMISSION=1)
        variant = owner.device.kernel(spec.filename, kernel.name, defines)
        setattr(owner, name, variant)
    return variant
