"""G-buffer benchmark: Crytek Sponza at 1280×720 from the fixed atrium camera.

    python -m bench.gbuffer [--repeats 10] [--warmup 3] [--device NAME] [--tile-size 8 16 32] [--no-gl]
                            [--no-materials]

Prints the median milliseconds per pass from OpenCL profiling events (setup = transform,
clipping and triangle setup; binning; raster = fine rasterization into the visibility
buffer; gbuffer = the G-buffer resolve), triangles per second, and — in the same run — the
same G-buffer drawn by OpenGL (moderngl on Mesa llvmpipe through EGL, bench/gl_peer.py):
the clrender/OpenGL time ratio and how closely the two G-buffers agree. Writes a JSON
record and a side-by-side PNG under bench/results/.

Materials (docs/materials.md): the G-buffer resolve of DamagedHelmet and Sponza at the same size
with their glTF textures as loaded, without normal and metallic-roughness maps, and with the base
colour texture alone (what the resolve sampled before per-pixel materials): the target is all
textures at most 1.5× the base colour alone.
"""
from __future__ import annotations

import argparse
import statistics
import sys
import time

import numpy as np

from bench.common import (HELMET, HELMET_CAMERA, RESULTS, SPONZA, SPONZA_CAMERA, host_medians, medians,
                          require_scene, time_renders, time_user_frames, write_record)

PASSES = ("setup", "binning", "raster", "gbuffer")
GBUFFER_READ = ("depth", "normal", "albedo", "triangle_id")     # what the OpenGL peer reads back


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeats", type=int, default=10)
    ap.add_argument("--warmup", type=int, default=3)
    ap.add_argument("--device", default=None)
    ap.add_argument("--tile-size", type=int, nargs="+", default=[16])
    ap.add_argument("--width", type=int, default=1280)
    ap.add_argument("--height", type=int, default=720)
    ap.add_argument("--no-gl", action="store_true", help="skip the OpenGL peer")
    ap.add_argument("--no-materials", action="store_true", help="skip the per-pixel material measurements")
    args = ap.parse_args(argv)

    import clrender
    t0 = time.perf_counter()
    scene = clrender.load_scene(require_scene(SPONZA))
    load_s = time.perf_counter() - t0
    camera = clrender.Camera.look_at(**SPONZA_CAMERA)
    print(f"Sponza: {scene.triangle_count:,} triangles, {len(scene.textures)} textures, loaded in {load_s:.1f} s")

    record = {"scene": str(SPONZA.name), "width": args.width, "height": args.height, "repeats": args.repeats,
              "warmup": args.warmup, "clrender": {}}
    frames = {}
    for tile in args.tile_size:
        renderer = clrender.Renderer(args.width, args.height, device=args.device, tile_size=tile)
        stats, walls, users, frame = time_user_frames(renderer, scene, camera, args.warmup, args.repeats,
                                                      read=GBUFFER_READ)
        med = medians(stats)
        frames[tile] = frame
        tris_per_s = scene.triangle_count / (sum(med[p + "_ms"] for p in PASSES) * 1e-3)
        record["clrender"][str(tile)] = {"device": renderer.device.name, "median_ms": med,
                                         "wall_ms_median": statistics.median(walls),
                                         "user_frame_ms_median": statistics.median(users),
                                         "host_ms": host_medians(stats),
                                         "triangles_per_s": tris_per_s, "frames_ms": [s["total_ms"] for s in stats]}
        print(f"\nclrender on {renderer.device.name}, tile {tile}×{tile} — median of {args.repeats} frames (ms):")
        for p in PASSES:
            print(f"  {p:<9} {med[p + '_ms']:8.2f}")
        gbuffer_ms = sum(med[p + "_ms"] for p in PASSES)
        record["clrender"][str(tile)]["gbuffer_passes_ms"] = gbuffer_ms
        print(f"  {'G-buffer':<9} {gbuffer_ms:8.2f}   (the passes above; the whole frame with shading and tone "
              f"mapping: {med['total_ms']:.1f} ms; render() wall {statistics.median(walls):.1f} ms, with depth, "
              f"normal, albedo and triangle id in numpy {statistics.median(users):.1f} ms)")
        print("  host: " + ", ".join(f"{k[:-3]} {v:.1f}" for k, v in record["clrender"][str(tile)]["host_ms"].items()))
        print(f"  {tris_per_s / 1e6:.1f} M triangles/s; prims {int(med['prims']):,}; tile entries "
              f"{int(med['tile_entries']):,}; culled: backface {int(med['culled_backface']):,}, offscreen "
              f"{int(med['culled_offscreen']):,}, near {int(med['culled_near']):,}; clipped {int(med['clipped']):,}")

    best_tile = min(record["clrender"], key=lambda t: record["clrender"][t]["gbuffer_passes_ms"])
    clr_ms = record["clrender"][best_tile]["gbuffer_passes_ms"]
    frame = frames[int(best_tile)]
    if not args.no_gl:
        record["opengl"] = run_gl_peer(scene, camera, args, frame, clr_ms, record["clrender"])
    if not args.no_materials:
        record["materials"] = {"DamagedHelmet": run_materials(clrender.load_scene(require_scene(HELMET)),
                                                              clrender.Camera.look_at(**HELMET_CAMERA), args),
                               "Sponza": run_materials(scene, camera, args)}
    path = write_record("gbuffer", record)
    print(f"\nrecord: {path}")
    return 0


MATERIAL_VARIANTS = {
    "all textures": {},
    "no normal/MR maps": dict(normal_texture=-1, metallic_roughness_texture=-1),
    "base colour only": dict(normal_texture=-1, metallic_roughness_texture=-1, occlusion_texture=-1,
                             emissive_texture=-1, emissive=(0.0, 0.0, 0.0)),
}


def run_materials(scene, camera, args) -> dict:
    """G-buffer resolve ms (and the frame's wall time) of `scene` under MATERIAL_VARIANTS."""
    import dataclasses

    import clrender
    renderer = clrender.Renderer(args.width, args.height, device=args.device)
    loaded = scene.materials
    out = {}
    print(f"\nmaterials, {scene.source.rsplit('/', 1)[-1]} at {args.width}×{args.height}, median of {args.repeats} (ms):")
    try:
        for name, change in MATERIAL_VARIANTS.items():
            scene.materials = [dataclasses.replace(m, **change) for m in loaded]
            stats, walls, _ = time_renders(renderer, scene, camera, args.warmup, args.repeats)
            med = medians(stats)
            out[name] = {"gbuffer_ms": med["gbuffer_ms"], "shade_ms": med["shade_ms"],
                         "frame_ms": med["total_ms"], "wall_ms": statistics.median(walls)}
            print(f"  {name:<18} resolve {med['gbuffer_ms']:7.2f}   shade {med['shade_ms']:7.2f}   "
                  f"passes {med['total_ms']:7.1f}   render() wall {statistics.median(walls):7.1f}")
    finally:
        scene.materials = loaded
    ratio = out["all textures"]["gbuffer_ms"] / out["base colour only"]["gbuffer_ms"]
    out["resolve_ratio_all_vs_base"] = ratio
    print(f"  resolve with every texture / base colour only: {ratio:.2f}× (target <= 1.5×)")
    return out


def run_gl_peer(scene, camera, args, frame, clr_ms, record_clr) -> dict:
    try:
        from bench.gl_peer import GLPeer, compare_gbuffers
        peer = GLPeer(args.width, args.height)
    except Exception as exc:                     # no EGL / moderngl: say so, keep the clrender numbers
        print(f"\nOpenGL peer unavailable: {exc}")
        return {"error": str(exc)}
    peer.upload(scene)
    gl_times = peer.time_frame(camera, repeats=args.repeats, warmup=args.warmup)
    gl_ms = statistics.median(gl_times)
    gl_user = statistics.median(peer.time_frame_with_readback(camera, repeats=args.repeats, warmup=1))
    user_ms = statistics.median(f["user_frame_ms_median"] for f in record_clr.values())
    gl = peer.render(camera)
    ours = {"depth": frame.depth, "normal": frame.normal, "albedo": frame.albedo, "triangle_id": frame.triangle_id}
    agreement = compare_gbuffers(ours, gl)
    print(f"\nOpenGL peer ({peer.renderer}): median {gl_ms:.1f} ms per frame (draw + glFinish)")
    print(f"  clrender G-buffer / OpenGL G-buffer time ratio: {clr_ms / gl_ms:.2f}")
    print(f"  with the G-buffer read back to numpy: OpenGL {gl_user:.1f} ms, clrender's whole frame {user_ms:.1f} ms "
          f"(ratio {user_ms / gl_user:.2f})")
    for key in sorted(agreement):
        value = agreement[key]
        print(f"  {key:<34} {value:.4f}" if isinstance(value, float) else f"  {key:<34} {value}")
    save_side_by_side(frame, gl)
    return {"renderer": peer.renderer, "median_ms": gl_ms, "frames_ms": gl_times, "ratio": clr_ms / gl_ms,
            "user_frame_ms_median": gl_user, "user_frame_ratio": user_ms / gl_user, "agreement": agreement}


def save_side_by_side(frame, gl) -> None:
    import imageio.v3 as iio
    from clrender.abi.gbuffer import linear_to_srgb8
    top = np.concatenate([frame.image, linear_to_srgb8(gl["albedo"])], 1)
    bottom = np.concatenate([((frame.normal * 0.5 + 0.5) * 255).astype(np.uint8),
                             ((np.nan_to_num(gl["normal"]) * 0.5 + 0.5) * 255).astype(np.uint8)], 1)
    RESULTS.mkdir(parents=True, exist_ok=True)
    iio.imwrite(RESULTS / "gbuffer-clrender-vs-opengl.png", np.concatenate([top, bottom], 0)[::2, ::2])


if __name__ == "__main__":
    sys.exit(main())
