"""Frame.stats: the host's time per phase, each pass's device time (profiling events) and the
counters the passes keep (triangles, prims, tile entries, lights per tile, fragments, pairs)."""
from __future__ import annotations

from time import perf_counter as _perf_counter

import numpy as np

from clrender.device.timestamps import elapsed_ms

# Frame.stats["host"]: where render()'s wall time goes on the host, in order. upload: scene and
# light uploads (Renderer.render); prepare: per-scene pass setup; enqueue: launching the passes
# (Python and the driver's enqueue calls); overflow_wait: reading the overflow totals, which waits
# for the device to finish the frame; readback: copying the AOVs to numpy; stats: the counters
# read back for Frame.stats; other: the rest of render() (Frame assembly, checks). They add up
# to stats["wall_ms"]. Device time is in the per-pass *_ms (profiling events).
HOST_PHASES = ("upload_ms", "prepare_ms", "enqueue_ms", "overflow_wait_ms", "readback_ms", "stats_ms", "other_ms")
# *_ms keys of Frame.stats that are not a pass's own device time
NOT_PASS_MS = ("total_ms", "span_ms", "wall_ms")


def pass_ms(stats: dict) -> dict:
    """The device time of each pass (and stage breakdowns) in a Frame.stats dict."""
    return {k: v for k, v in stats.items() if k.endswith("_ms") and k not in NOT_PASS_MS}


class HostClock:
    """Accumulates host time per phase between `lap` calls."""

    def __init__(self):
        self.laps = {}
        self.last = _perf_counter()

    def lap(self, phase: str) -> None:
        now = _perf_counter()
        self.laps[phase] = self.laps.get(phase, 0.0) + (now - self.last) * 1e3
        self.last = now


def frame_stats(pipeline, res, timings, readback, transparent: bool, retries: int) -> dict:
    """The stats of a rendered frame; the passes are found by role (pipeline.setup, .binning,
    .light_cull, .shadow, .transparency), their counters read back here."""
    config, queue = pipeline.config, pipeline.queue
    stats = {f"{name}_ms": elapsed_ms(start, end) for name, start, end in timings}
    stats["total_ms"] = sum(stats.values())
    if timings:       # first pass's start to last pass's end: the passes plus any gap between them
        stats["span_ms"] = elapsed_ms(timings[0][1], timings[-1][2])
    stats.update(pipeline.setup.triangle_stats())
    stats["prims"] = int(pipeline.setup.prim_total.get(queue=queue)[0])
    stats["tile_entries"] = int(pipeline.binning.total.get(queue=queue)[0])
    stats["tile_size"] = pipeline.binning.tile          # config.tile_size None: the device's tuned tile
    stats["retries"] = retries
    stats["supersample"] = config.supersample
    stats["pipeline"] = config.pipeline
    # rasterizations of the scene: the second pass tests every msaa sample in one walk
    stats["geometry_passes"] = 1 if config.pipeline == "deferred" or config.reuse_visibility else 2
    from clrender.render.memory import pixel_buffers
    stats["bytes_per_pixel"] = pixel_buffers(config)
    stats.update(fragment_stats(config, readback, transparent))
    for p in pipeline.transparency if transparent else ():
        stats.update(p.stage_stats())         # breakdowns of their pass's ms, not added to total_ms
    if pipeline.shadow is not None and res["shadow_view_count"]:
        stats.update(pipeline.shadow.pass_stats())     # breakdown of shadow_ms, not added to total_ms
    stats["lights"] = res["n_lights"]
    if pipeline.light_cull is not None:
        stats.update(pipeline.light_cull.tile_stats())
    else:
        stats.update(lights_per_tile_avg=float(res["n_lights"]), lights_per_tile_max=res["n_lights"])
    for p in pipeline.passes:                      # (pixel, light) pairs the shading evaluated / needed
        if hasattr(p, "pair_stats"):
            stats.update(p.pair_stats())
    return stats


def fragment_stats(config, readback, transparent) -> dict:
    """Transparent fragments: total, per-pixel max, and those max_fragments_per_pixel dropped."""
    if not transparent:
        return {"fragments": 0, "fragments_max": 0, "fragments_dropped": 0}
    counts = readback.get("fragment_count")
    total = int(counts.sum(dtype=np.int64))
    cap = config.max_fragments_per_pixel
    kept = int(np.minimum(counts, cap).sum(dtype=np.int64)) if cap and config.transparency == "abuffer" else total
    return {"fragments": total, "fragments_max": int(counts.max()) if counts.size else 0,
            "fragments_dropped": total - kept}
