"""Renderer variants side by side (docs/variants.md): Crytek Sponza at 1280×720 with 64, 1024
and 4096 point lights, every pipeline × light-accumulation mode in one run, one table: ms per
pass and whole frame (OpenCL profiling events; render() wall time), bytes per pixel of the
per-pixel buffers, (pixel, light) pairs evaluated vs inside the radius; and the report's own
comparison point, the OpenGL light-volume peer (bench/gl_lights.py) on llvmpipe.

    python -m bench.variants [--counts 64 1024 4096 --repeats 3 --warmup 1 --device NAME --no-gl]

Lights as bench.lights: random points in the scene's bounds (seed 1), radius 0.05 of the bounds
diagonal, intensity 1. Records go to bench/results/variants-*.json.
"""
from __future__ import annotations

import argparse
import statistics

import numpy as np

from clrender.render.pipeline import pass_ms

from .common import SPONZA, SPONZA_CAMERA, medians, require_scene, time_renders, write_record

VARIANTS = (
    ("deferred", {}),
    ("deferred quads", dict(light_culling="quads")),
    ("deferred stencil", dict(light_culling="stencil")),
    ("light_prepass", dict(pipeline="light_prepass")),
    ("light_prepass lum f16", dict(pipeline="light_prepass", light_buffer_specular="luminance",
                                   light_buffer_precision="float16")),
    ("light_prepass msaa4", dict(pipeline="light_prepass", msaa=4)),
    ("light_indexed", dict(pipeline="light_indexed")),
    # pass 1's visibility instead of the second raster (not the report's algorithm; same pixels)
    ("light_prepass reuse", dict(pipeline="light_prepass", reuse_visibility=True)),
    ("light_indexed reuse", dict(pipeline="light_indexed", reuse_visibility=True)),
)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--counts", type=int, nargs="+", default=[64, 1024, 4096])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--warmup", type=int, default=1)
    ap.add_argument("--width", type=int, default=1280)
    ap.add_argument("--height", type=int, default=720)
    ap.add_argument("--device", default=None)
    ap.add_argument("--radius-frac", type=float, default=0.05)
    ap.add_argument("--only", nargs="+", choices=[v[0] for v in VARIANTS], default=None)
    ap.add_argument("--no-gl", action="store_true", help="skip the OpenGL light-volume peer")
    args = ap.parse_args(argv)

    import clrender
    scene = clrender.load_scene(require_scene(SPONZA))
    camera = clrender.Camera.look_at(**SPONZA_CAMERA)
    lo, hi = scene.bounds().astype(np.float64)
    radius = args.radius_frac * float(np.linalg.norm(hi - lo))
    variants = [(n, o) for n, o in VARIANTS if not args.only or n in args.only]
    renderers = {n: clrender.Renderer(args.width, args.height, device=args.device, shadows=False, **o)
                 for n, o in variants}
    peer = None
    if not args.no_gl:
        try:
            from .gl_lights import GLLightsPeer
            peer = GLLightsPeer(args.width, args.height)
            peer.upload(scene)
        except Exception as exc:                  # no EGL / moderngl: keep the clrender numbers
            print(f"OpenGL peer unavailable: {exc}")
    record = {"scene": SPONZA.name, "width": args.width, "height": args.height, "repeats": args.repeats,
              "warmup": args.warmup, "radius": radius, "variants": dict(variants), "counts": {}}
    base = scene.lights[:0].copy()
    for count in args.counts:
        scene.lights = base.copy()
        scene.add_random_lights(count, seed=1, radius=(radius, radius), intensity=1.0)
        entry = {}
        # Rounds of one frame per variant, interleaved: this machine drifts by 15 % over a minute,
        # which blocks of repeats per variant turned into ratios that swapped between runs.
        for name, _ in variants:
            time_renders(renderers[name], scene, camera, args.warmup, 0)
        runs = {name: ([], []) for name, _ in variants}
        for _ in range(args.repeats):
            for name, _ in variants:
                stats, walls, frame = time_renders(renderers[name], scene, camera, 0, 1)
                runs[name][0].extend(stats)
                runs[name][1].extend(walls)
        for name, (stats, walls) in runs.items():
            entry[name] = {"median": medians(stats), "wall_ms_median": statistics.median(walls), "walls_ms": walls,
                           "bytes_per_pixel": stats[-1]["bytes_per_pixel"]}
            record["device"] = stats[-1]["device"]
        if peer is not None:
            peer.set_lights(scene.lights, scene.ambient)
            entry["opengl"] = {"median_ms": statistics.median(peer.time_frame(camera, repeats=args.repeats,
                                                                               warmup=args.warmup))}
        record["counts"][str(count)] = entry
        print_table(count, entry)
    print(f"record: {write_record('variants', record)}")
    return 0


def print_table(count: int, entry: dict) -> None:
    ref = entry.get("deferred")
    print(f"\n== {count} lights == (ms; medians)")
    print(f"{'variant':<22} {'wall':>7} {'passes':>7} {'x def':>6} {'B/px':>5} {'evaluated':>11} {'useful':>11}  "
          "passes (ms)")
    for name, e in entry.items():
        if name == "opengl":
            continue
        m = e["median"]
        ratio = m["total_ms"] / ref["median"]["total_ms"] if ref else float("nan")
        passes = " ".join(f"{k[:-3]} {v:.1f}" for k, v in pass_ms(m).items()
                          if v >= 0.05 and k.count("_") <= 2)
        print(f"{name:<22} {e['wall_ms_median']:7.1f} {m['total_ms']:7.1f} {ratio:6.2f} "
              f"{e['bytes_per_pixel']['total']:5d} {int(m.get('light_pairs_evaluated', 0)):11,d} "
              f"{int(m.get('light_pairs_useful', 0)):11,d}  {passes}")
    if "opengl" in entry:
        print(f"{'OpenGL light volumes':<22} {entry['opengl']['median_ms']:7.1f}  (llvmpipe, G-buffer + lights + "
              "combine + glFinish)")


if __name__ == "__main__":
    raise SystemExit(main())
