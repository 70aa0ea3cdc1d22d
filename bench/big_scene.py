"""Big scenes for bench/scaling.py's instances axis: copies of a scene side by side on a grid,
measured interleaved (one Renderer per point, the points' frames in turn, round after round: a
shared machine's load then falls on every point alike), with what a big scene costs besides time.

Per point: the scene build (host copies), the first frame (upload, and the buffers that overflowed
and grew: its retries), the device-memory estimate (clrender.render.memory.check, as render()
checks it) against the device's limits and what the frame holds (Frame.stats device_bytes), this
process's RSS after the point was set up, per-pass medians and each pass's growth per million
triangles between points (`pass_growth`).
"""
from __future__ import annotations

import dataclasses
import gc
import math
import statistics
import time

import numpy as np

from bench.common import host_medians, medians, time_user_frames


# Frame.stats' per-reason triangle counts (setup.triangle_stats): where a big scene's triangles go
TRIANGLE_STATUS = ("culled_near", "degenerate", "culled_backface", "culled_offscreen", "transparent",
                   "chunks", "culled_chunks")


def grid_offsets(copies: int, extent) -> np.ndarray:
    """(copies, 3) float32 translations: copy k in column k % cols and row k // cols of a grid on
    the x-z plane, cols = ceil(sqrt(copies)), one bounds extent (x, z of `extent`) apart, so the
    copies touch and never overlap. Copy 0 stays in place (the camera and lights are in it)."""
    if copies < 1:
        raise ValueError(f"copies must be at least 1, got {copies}")
    cols = math.isqrt(copies - 1) + 1
    k = np.arange(copies)
    ex, ez = float(extent[0]), float(extent[2])
    return np.stack([(k % cols) * ex, np.zeros(copies), (k // cols) * ez], axis=1).astype(np.float32)


def replicate(scene, copies: int, offsets=None):
    """`copies` instances of the scene's geometry (materials and textures shared), copy k moved by
    offsets[k] (default: all at the same place)."""
    if copies == 1:
        return scene
    v, t = len(scene.positions), len(scene.triangles)

    def tile(a):
        return None if a is None else np.concatenate([a] * copies, axis=-2 if a.ndim == 3 else 0)
    positions = tile(scene.positions) if offsets is None else \
        np.concatenate([scene.positions + np.asarray(o, np.float32) for o in offsets[:copies]])
    if len(positions) != copies * v:
        raise ValueError(f"{len(offsets)} offsets for {copies} copies")
    return dataclasses.replace(
        scene, positions=positions, normals=tile(scene.normals), uvs=tile(scene.uvs),
        triangles=np.concatenate([scene.triangles + np.int32(k * v) for k in range(copies)]),
        triangle_material=tile(scene.triangle_material), triangle_mesh=tile(scene.triangle_mesh),
        triangle_face=tile(scene.triangle_face), colors=tile(scene.colors), tangents=tile(scene.tangents),
        extra_uvs=tile(scene.extra_uvs), previous_positions=None, animation=None) if t else scene


def measure_instances(todo, base, extent, camera, light_sets, args, make_renderer, peer_point) -> tuple:
    """Entries of the instances axis for `todo` ((axis, copies, setting) of bench.scaling.points),
    and the device's name. `make_renderer(size)` makes a Renderer; `peer_point(peers, size, scene,
    camera, args, done)` measures the OpenGL peer (after clrender's renderers are released)."""
    from clrender.render.pipeline import pass_ms
    states, entries, device = [], [], None
    for axis, x, setting in todo:
        size = tuple(setting["size"])
        t0 = time.perf_counter()
        scene = replicate(base, x, grid_offsets(x, extent))
        scene.lights = light_sets[setting["lights"]]
        entry = {"x": x, "setting": {**setting, "size": list(size)}, "triangles": scene.triangle_count,
                 "scene_build_ms": (time.perf_counter() - t0) * 1e3}
        entries.append(entry)
        rss0 = host_memory()["rss_bytes"]
        try:
            r = make_renderer(size)
            device = r.device.name
            entry["memory"] = memory_point(r, scene)
            grown = []
            t0 = time.perf_counter()
            first = first_render(r, scene, camera, grown)
            first_ms = (time.perf_counter() - t0) * 1e3
        except Exception as exc:                  # an estimate that refuses, a buffer that cannot grow
            print(f"{axis:<10} {x:>8}: clrender failed: {type(exc).__name__}: {exc}", flush=True)
            entry["clrender"] = {"error": f"{type(exc).__name__}: {exc}"}
            continue
        entry["clrender"] = {
            "first_frame": {"wall_ms": first_ms, "upload_ms": first.stats["host"]["upload_ms"],
                            "retries": first.stats["retries"], "tile_entries": first.stats["tile_entries"],
                            "grown": [{"buffer": n, "entries": t, "capacity": c} for n, t, c in grown]},
            "rss_added_bytes": host_memory()["rss_bytes"] - rss0}
        del first
        states.append((entry, r, scene, {"stats": [], "walls": [], "users": []}))
    warm = max(args.warmup - 1, 0)               # the first frame was the first warm-up
    for rnd in range(warm + args.repeats):
        for entry, r, scene, got in (states if rnd % 2 == 0 else states[::-1]):
            stats, walls, users, _ = time_user_frames(r, scene, camera, 0, 1)
            if rnd >= warm:
                got["stats"] += stats
                got["walls"] += walls
                got["users"] += users
    for entry, r, scene, got in states:
        stats, c = got["stats"], entry["clrender"]
        med = medians(stats)
        last = stats[-1]
        c.update({"passes_ms": med["total_ms"], "render_wall_ms": statistics.median(got["walls"]),
                  "user_frame_ms": statistics.median(got["users"]),
                  "pass_ms": {k: statistics.median(pass_ms(s)[k] for s in stats) for k in pass_ms(stats[0])},
                  "host_ms": host_medians(stats), "retries": [s["retries"] for s in stats],
                  "prims": last["prims"], "tile_entries": last["tile_entries"],
                  "triangle_status": {k: last[k] for k in TRIANGLE_STATUS if k in last},
                  "device_bytes": last["device_bytes"], "device_bytes_by_owner": last["device_bytes_by_owner"]})
        entry["memory"]["held_over_estimate"] = last["device_bytes"] / entry["memory"]["estimate_bytes"]
    c = None
    states = [(e, s) for e, _, s, _ in states]   # release the renderers before the peer runs
    gc.collect()
    peers = {}
    for entry, scene in states:
        if not args.no_gl:
            entry["opengl"] = peer_point(peers, tuple(entry["setting"]["size"]), scene, camera, args,
                                         [e for e in entries if e is not entry and "opengl" in e])
        print_point(entry)
    for p in peers.values():
        p.release()
    return entries, device


def print_point(entry) -> None:
    c, m = entry["clrender"], entry["memory"]
    gl = entry.get("opengl", {}).get("user_frame_ms")
    print(f"instances {entry['x']:>8}: clrender passes {c['passes_ms']:8.1f}  render() {c['render_wall_ms']:8.1f}"
          f"  + colour, depth {c['user_frame_ms']:8.1f} ms"
          + (f"   OpenGL {gl:8.1f} ms, ratio {c['user_frame_ms'] / gl:.2f}" if gl else ""))
    f = c["first_frame"]
    print(f"{'':<20}{entry['triangles']:,} triangles; build {entry['scene_build_ms']:.0f} ms, first frame "
          f"{f['wall_ms']:.0f} ms (upload {f['upload_ms']:.0f}, retries {f['retries']}"
          + "".join(f", {g['buffer']} {g['capacity']:,} -> {g['entries']:,}" for g in f["grown"])
          + f"); device {c['device_bytes'] / 2**20:.0f} MiB held, {m['estimate_bytes'] / 2**20:.0f} MiB estimated;"
          f" RSS +{c['rss_added_bytes'] / 2**20:.0f} MiB", flush=True)


def first_render(renderer, scene, camera, grown: list):
    """renderer.render, noting in `grown` each (buffer, entries needed, capacity) that overflowed and
    grew (the frame's retries; Pipeline._grow_overflowing, wrapped for this one call)."""
    pipeline = renderer.pipeline
    grow = pipeline._grow_overflowing

    def noted():
        out = grow()
        grown.extend(out)
        return out
    pipeline._grow_overflowing = noted
    try:
        return renderer.render(scene, camera)
    finally:
        del pipeline._grow_overflowing


def memory_point(renderer, scene) -> dict:
    """The device-memory estimate for this scene and size (clrender.render.memory), checked against
    the device's limits as render() checks it (DeviceMemoryError when it refuses)."""
    from clrender.device.limits import limits
    from clrender.render import memory
    need = memory.check(renderer.device, renderer.width, renderer.height, renderer.config, scene)
    total, max_alloc = limits(renderer.device.cl_device)
    return {"estimate_bytes": need["total"], "largest_bytes": need["largest"], "largest_name": need["largest_name"],
            "device_global_bytes": total, "device_max_alloc_bytes": max_alloc}


def host_memory() -> dict:
    """This process's resident set now and its peak (Linux /proc; zeros elsewhere)."""
    out = {"rss_bytes": 0, "rss_peak_bytes": 0}
    try:
        for line in open("/proc/self/status"):
            if line.startswith(("VmRSS:", "VmHWM:")):
                out["rss_bytes" if line.startswith("VmRSS") else "rss_peak_bytes"] = int(line.split()[1]) * 1024
    except OSError:
        pass
    return out


def pass_growth(entries) -> list[dict]:
    """Per pass (and the pass sum, render() and the user's frame): ms added per million triangles
    between consecutive points that rendered."""
    entries = [e for e in entries if "pass_ms" in e["clrender"]]
    out = []
    for a, b in zip(entries, entries[1:]):
        dx = (b["triangles"] - a["triangles"]) * 1e-6
        ca, cb = a["clrender"], b["clrender"]
        per = {k: (cb["pass_ms"][k] - ca["pass_ms"][k]) / dx for k in cb["pass_ms"] if k in ca["pass_ms"]}
        for k in ("passes_ms", "render_wall_ms", "user_frame_ms"):
            per[k] = (cb[k] - ca[k]) / dx
        out.append({"from": a["x"], "to": b["x"], "ms_per_million_triangles": per})
    return out


def print_pass_growth(entries) -> list[dict]:
    """Print pass_growth as a table (one row per pass, one column per step) and return it."""
    growth = pass_growth(entries)
    if not growth:
        return growth
    done = [e for e in entries if "pass_ms" in e["clrender"]]
    print("\ninstances: per pass, ms at each point and ms per million triangles between points")
    print(f"  {'pass':<26}" + "".join(f"{'x' + str(e['x']):>9}" for e in done)
          + "".join(f"{str(g['from']) + '->' + str(g['to']):>10}" for g in growth))
    for k in growth[-1]["ms_per_million_triangles"]:
        vals = [e["clrender"]["pass_ms"].get(k, e["clrender"].get(k)) for e in done]
        print(f"  {k:<26}" + "".join(f"{v:9.1f}" if v is not None else f"{'-':>9}" for v in vals)
              + "".join(f"{g['ms_per_million_triangles'].get(k, float('nan')):10.2f}" for g in growth))
    return growth
