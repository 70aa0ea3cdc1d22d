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
    materials adds forward.h's SURFACE_LAYERS arguments (layered_kernel's build)."""
    env = res["light_env"]
    return (*scene_args(res, prims), res["camera_params"].data, np.int32(res["width"]), np.int32(res["height"]),
            np.float32(res["ambient"]), res["lights"].data, np.int32(res["n_lights"]), *env.lists,
            *env.shadow_and_sun, *env_kernel_args(res), *res.values.get("surface_layer_args", ()))


def layered_kernel(owner, attr: str, res):
    """owner.<attr> (a forward kernel), or for a scene with layered materials its SURFACE_LAYERS
    build, made the first time one is rendered (so a scene without layers never builds it)."""
    kernel = getattr(owner, attr)
    if "surface_layer_args" not in res.values:
        return kernel
    layered = owner.__dict__.get(attr + "_layered")
    if layered is None:
        spec = kernel.spec
        defines = {**dict(spec.defines), "SURFACE_LAYERS": 1, "MULTISCATTER": int(owner.config.multiscatter)}
        layered = owner.device.kernel(spec.filename, kernel.name, defines)
        setattr(owner, attr + "_layered", layered)
    return layered
