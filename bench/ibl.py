"""Image-based lighting and the glTF BRDF: what they cost on Crytek Sponza at 1280×720.

    python -m bench.ibl [--counts 64 1024] [--repeats 5] [--warmup 2] [--environment PATH]
                        [--device NAME]

In one run, for each light count (seeded point lights as bench.lights: radius 0.05 of the bounds
diagonal), three configurations of the same frame:

* ``ambient``: the constant ambient term, `shading="auto"` (the glTF BRDF): the peer of
* ``environment``: the same with an HDR environment (default ../shared/environments/courtyard.exr)
  as the ambient light (kernels/ambient.h) and background;
* ``blinn_phong``: the constant ambient with `shading="blinn_phong"`: the peer of ``ambient``
  for the BRDF's cost.

Each prints the median ms of every pass (OpenCL profiling events) and of the frame a user waits
for (render() plus Frame.color and Frame.depth read to numpy), after warm-up frames. Then the
environment's precompute (kernels/ibl.cl: mip chain, GGX prefilter, SH; the device's DFG table
is cached apart) for 512×1024 and 1024×2048 (the environment resampled), median of 3 after a
warm-up. Writes bench/results/ibl-*.json.
"""
from __future__ import annotations

import argparse
import statistics
import sys
import time

import numpy as np

from clrender.render.pipeline import pass_ms

from .common import (
    REPO, SPONZA, SPONZA_CAMERA, host_medians, medians, require_scene, time_user_frames, write_record)

ENVIRONMENT = REPO.parent / "shared" / "environments" / "courtyard.exr"
CONFIGS = ("ambient", "environment", "blinn_phong")


def resampled(pixels: np.ndarray, height: int) -> np.ndarray:
    """Nearest-texel resampling to height × 2·height (a benchmark input, not a filter)."""
    h, w = pixels.shape[:2]
    rows = (np.arange(height) * h) // height
    cols = (np.arange(2 * height) * w) // (2 * height)
    return np.ascontiguousarray(pixels[rows][:, cols])


def prefilter_ms(device, pixels: np.ndarray, repeats: int = 3) -> dict:
    """Median wall ms of one environment's precompute (enqueue to finish), its phases' device ms."""
    from clrender.passes import ibl
    ibl.ibl_maps(device, device.queue, pixels, cache=False)          # builds the programs, the DFG table
    device.queue.finish()
    walls, phases = [], []
    for _ in range(repeats):
        t0 = time.perf_counter()
        maps = ibl.ibl_maps(device, device.queue, pixels, cache=False)
        device.queue.finish()
        walls.append((time.perf_counter() - t0) * 1e3)
        phases.append(maps.phase_ms())
    return {"wall_ms": statistics.median(walls),
            **{k: statistics.median(p[k] for p in phases) for k in phases[0]}}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--counts", type=int, nargs="+", default=[64, 1024])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--warmup", type=int, default=2)
    ap.add_argument("--environment", default=str(ENVIRONMENT))
    ap.add_argument("--device", default=None)
    ap.add_argument("--width", type=int, default=1280)
    ap.add_argument("--height", type=int, default=720)
    ap.add_argument("--radius-frac", type=float, default=0.05)
    args = ap.parse_args(argv)

    import clrender
    from clrender.scene.environment import load_environment
    scene = clrender.load_scene(require_scene(SPONZA))
    env = load_environment(args.environment)
    camera = clrender.Camera.look_at(**SPONZA_CAMERA)
    lo, hi = scene.bounds().astype(np.float64)
    radius = args.radius_frac * float(np.linalg.norm(hi - lo))
    renderers = {"auto": clrender.Renderer(args.width, args.height, device=args.device),
                 "blinn_phong": clrender.Renderer(args.width, args.height, device=args.device, shading="blinn_phong")}
    device = renderers["auto"].device
    print(f"Sponza {scene.triangle_count:,} triangles, {args.width}x{args.height}, {device.name}; environment "
          f"{env.source} ({env.width}x{env.height})")
    record = {"scene": SPONZA.name, "width": args.width, "height": args.height, "repeats": args.repeats,
              "warmup": args.warmup, "device": device.name, "environment": env.source, "counts": {}}
    for count in args.counts:
        scene.lights = scene.lights[:0]
        scene.add_random_lights(count, seed=1, radius=(radius, radius))
        rows = {}
        for name in CONFIGS:
            scene.environment = env if name == "environment" else None
            r = renderers["blinn_phong" if name == "blinn_phong" else "auto"]
            stats, walls, users, _ = time_user_frames(r, scene, camera, args.warmup, args.repeats)
            rows[name] = {"passes_ms": {k: v for k, v in medians([pass_ms(s) for s in stats]).items()},
                          "total_ms": statistics.median(s["total_ms"] for s in stats),
                          "render_wall_ms": statistics.median(walls), "user_frame_ms": statistics.median(users),
                          "host_ms": host_medians(stats)}
        record["counts"][count] = rows
        passes = sorted({k for row in rows.values() for k in row["passes_ms"]})
        print(f"\n{count} lights: median ms ({args.repeats} frames after {args.warmup} warm-up)")
        print(f"{'pass':<14}" + "".join(f"{n:>14}" for n in CONFIGS))
        for p in passes:
            print(f"{p:<14}" + "".join(f"{rows[n]['passes_ms'].get(p, 0.0):14.2f}" for n in CONFIGS))
        for key in ("total_ms", "render_wall_ms", "user_frame_ms"):
            print(f"{key:<14}" + "".join(f"{rows[n][key]:14.1f}" for n in CONFIGS))
        env_cost = rows["environment"]["user_frame_ms"] / rows["ambient"]["user_frame_ms"] - 1
        brdf_cost = rows["ambient"]["user_frame_ms"] / rows["blinn_phong"]["user_frame_ms"] - 1
        shade = {n: rows[n]["passes_ms"].get("shade_ms", 0.0) for n in CONFIGS}
        print(f"environment vs constant ambient: {env_cost:+.1%} user frame, shade {shade['environment']:.1f} vs "
              f"{shade['ambient']:.1f} ms; glTF BRDF vs Blinn-Phong: {brdf_cost:+.1%} user frame, shade "
              f"{shade['ambient']:.1f} vs {shade['blinn_phong']:.1f} ms")
        rows["environment_cost"], rows["brdf_cost"] = env_cost, brdf_cost

    record["prefilter"] = {}
    for h in (512, 1024):
        pixels = resampled(env.pixels, h)
        t = prefilter_ms(device, pixels)
        record["prefilter"][f"{h}x{2 * h}"] = t
        print(f"prefilter {2 * h}x{h}: {t['wall_ms']:.0f} ms wall (" +
              ", ".join(f"{k} {v:.0f}" for k, v in t.items() if k != "wall_ms") + ")")
    path = write_record("ibl", record)
    print(f"\nrecord: {path.relative_to(REPO)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
