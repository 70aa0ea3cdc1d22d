"""What the raster runs with on a device once measured: its pixels per work-item (VEC), camera tile
and shadow-map tile (issue 40 item 3). The device layer only keeps and answers the choice; the
measurement, which renders, lives in the render layer (clrender/render/autotune.py).

A choice is cached like the probe's answer (clrender/device/cache.py: probe/tune-<key>.json, keyed by
driver identity, CPU, kernel sources and VERSION: a kernel or workload change retunes). Devices that
are never tuned keep today's per-vendor defaults (capabilities): GPUs and Oclgrind (a pixel per
work-item), CLRENDER_VEC set (tests force a width), CLRENDER_TUNE=0. An explicit
RenderConfig.tile_size / shadow_tile_size always wins. No choice changes a pixel
(tests/test_autotune.py renders every check case with each).
"""
from __future__ import annotations

import os
from dataclasses import asdict, dataclass
from typing import Optional

from clrender.device import cache, capabilities

ENV_TUNE = "CLRENDER_TUNE"
VERSION = 2                      # the workload and candidates (render/autotune.py): a change retunes
_choices: dict = {}              # cl_device.int_ptr -> Choice or None (not tuned: defaults)
_complete: set = set()           # devices whose tune has no step left


@dataclass(frozen=True)
class Choice:
    vec: int                     # the camera raster's (and fragments') pixels per work-item
    tile: int                    # the camera's raster tile, when RenderConfig.tile_size is None
    shadow_tile: int             # the shadow maps' tile, when RenderConfig.shadow_tile_size is None


def enabled(dev) -> bool:
    """Whether `dev` is tuned at all: a CPU path (VEC > 1) and neither CLRENDER_TUNE=0 nor CLRENDER_VEC."""
    if os.environ.get(ENV_TUNE, "1").strip().lower() in ("0", "off", "no", "false"):
        return False
    if os.environ.get("CLRENDER_VEC"):
        return False
    return capabilities.pixel_vector_width(dev) > 1


def default_choice(dev) -> Choice:
    """Today's per-vendor choice (what an untuned device runs; GPUs: the camera's tile for shadows)."""
    vec = capabilities.pixel_vector_width(dev)
    return Choice(vec, capabilities.DEFAULT_TILE,
                  capabilities.DEFAULT_SHADOW_TILE_CPU if vec > 1 else capabilities.DEFAULT_TILE)


def choice(dev) -> Optional[Choice]:
    """The tuned choice for a cl.Device: this process's, else the cached one; None when the device
    is not tuned (capabilities then uses its defaults). Never measures."""
    import pyopencl as cl
    if not isinstance(dev, cl.Device) or not enabled(dev):    # (tests' stand-ins are not tuned)
        return None
    key = dev.int_ptr
    if key not in _choices:
        _choices[key] = from_record(cache.read_json(entry_name(dev)))
    return _choices[key]


def complete(dev) -> bool:
    """Whether this process knows `dev`'s tune to have no step left."""
    return dev.int_ptr in _complete


def remember(dev, c: Choice, is_complete: bool) -> None:
    """This process's choice for `dev` (the render layer's tune, or a test planting one)."""
    _choices[dev.int_ptr] = c
    if is_complete:
        _complete.add(dev.int_ptr)


def from_record(record) -> Optional[Choice]:
    try:
        c = record["choice"]
        return Choice(int(c["vec"]), int(c["tile"]), int(c["shadow_tile"]))
    except (TypeError, KeyError, ValueError):
        return None


def entry_name(dev) -> str:
    """probe/tune-<key>.json, keyed like the probe's answer (probe.kernels_key) and by VERSION."""
    from clrender.device.probe import kernels_key
    return f"probe/tune-{kernels_key(dev, f'tune {VERSION}'.encode() + bytes(1))}.json"


def cached_record(dev) -> Optional[dict]:
    """The cache entry of `dev`'s tune (what was measured), or None."""
    record = cache.read_json(entry_name(dev))
    return record if isinstance(record, dict) else None


def summary(dev) -> Optional[dict]:
    """What the raster runs with on `dev` for `clrender devices`: {"vec", "tile", "shadow_tile",
    "tuned"} (tuned: False for today's defaults, on a device not tuned yet or never tuned), the
    cache entry's measurements under "measured"; None where it cannot be told. Never raises."""
    try:
        import pyopencl as cl
        if not isinstance(dev, cl.Device):
            return None
        c = choice(dev)
        record = cached_record(dev) if c is not None else None
        out = {**asdict(c or default_choice(dev)), "tuned": record is not None}
        if record is not None:
            out["complete"] = bool(record.get("complete"))
            out["measured"] = {k: record.get(k) for k in ("measured_ms", "seconds", "runs", "size", "shadow_size")}
        return out
    except Exception:
        return None


# -- what a pass runs with: config first, then the tuned choice, then today's defaults --------------

def camera_tile_size(dev, config) -> int:
    """The camera raster's tile: config.tile_size, else the device's tuned one, else
    capabilities.DEFAULT_TILE; it must fit a work-group (capabilities.tile_size_for)."""
    if config.tile_size is not None:
        return capabilities.tile_size_for(dev, config.tile_size)
    tuned = choice(dev)
    return capabilities.tile_size_for(dev, tuned.tile if tuned is not None else capabilities.DEFAULT_TILE)


def shadow_tile_size(dev, config) -> int:
    """Raster tile of the shadow maps: config.shadow_tile_size, else on CPUs the tuned one, else 32
    (a work-group of 32/VEC x 1 work-items walking whole tile columns: a 2048² map bins 16x fewer
    tile entries than with 8-pixel tiles), and the camera's tile on GPUs (a pixel per work-item:
    32² would exceed most work-group limits)."""
    if config.shadow_tile_size is not None:
        return capabilities.tile_size_for(dev, config.shadow_tile_size)
    if capabilities.pixel_vector_width(dev) == 1:
        return camera_tile_size(dev, config)
    tuned = choice(dev)
    return tuned.shadow_tile if tuned is not None else capabilities.DEFAULT_SHADOW_TILE_CPU


def resolved_tiles(dev, config):
    """`config` with tile_size and shadow_tile_size None (chosen per device) replaced by what this
    device runs: a Renderer's config then says what ran, and memory estimates are exact."""
    import dataclasses
    if config.tile_size is not None and config.shadow_tile_size is not None:
        return config
    tile = camera_tile_size(dev, config)
    return dataclasses.replace(config, tile_size=tile,
                               shadow_tile_size=shadow_tile_size(dev, dataclasses.replace(config, tile_size=tile)))


def raster_vector_width(dev, tile: int) -> int:
    """Pixels per raster work-item (camera, shadow maps, transparent fragments): the tuned width
    where the device was tuned (CLRENDER_VEC and VEC-1 devices are not), else
    capabilities.pixel_vector_width; a work-item's pixel run must fit in its tile row."""
    tuned = choice(dev)
    return min(tuned.vec if tuned is not None else capabilities.pixel_vector_width(dev), tile)
