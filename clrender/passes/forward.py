"""Arguments of kernels/forward.h's FORWARD_PARAMS (forward shading of transparent fragments),
shared by the A-buffer and depth-peeling passes."""
from __future__ import annotations

import numpy as np

FORWARD_INPUTS = ("prims", "positions", "normals", "uvs", "triangles", "materials", "texels", "srgb_lut",
                  "tex_infos", "tex_levels", "camera_params", "ambient", "lights", "n_lights", "light_env")


def forward_defines(config, device) -> dict:
    return {"VEC": 1, "LIGHT_TILE": config.light_tile_size,
            "BRUTE_FORCE": int(config.light_culling == "brute_force"), **device_light_defines(config)}


def device_light_defines(config) -> dict:
    from .shade import SHADOW_FILTERS
    return {"SHADOWS": int(config.shadows), "SHADOW_FILTER": SHADOW_FILTERS[config.shadow_filter],
            "POISSON_RADIUS": f"{float(config.shadow_filter_radius)!r}f"}


def forward_args(res, prims) -> tuple:
    """FORWARD_PARAMS for a frame; `prims` is the transparent prim buffer."""
    env = res["light_env"]
    return (prims.data, res["positions"].data, res["normals"].data, res["uvs"].data, res["triangles"].data,
            res["materials"].data, res["texels"].data, res["srgb_lut"].data, res["tex_infos"].data,
            res["tex_levels"].data, res["camera_params"].data, np.int32(res["width"]), np.int32(res["height"]),
            np.float32(res["ambient"]), res["lights"].data, np.int32(res["n_lights"]), *env.lists,
            *env.shadow_and_sun)
