"""Lighting benchmark: Crytek Sponza at 1280×720 from the fixed atrium camera, 0…4096 lights.

    python -m bench.lights [--counts 0 64 256 1024 4096] [--repeats 5] [--warmup 2]
                           [--tile-size 8] [--light-tile-size 16] [--radius-frac 0.05]
                           [--intensity 1.0] [--device NAME] [--no-gl] [--no-brute-force]
                           [--shading auto|blinn_phong]

For every light count the scene gets ``count`` seeded point lights
(``scene.add_random_lights(count, seed=1, radius=(r, r), intensity)``, r = ``radius-frac`` of the
scene's bounds diagonal, so each light overlaps several light tiles) and the benchmark prints:

* clrender (tiled light culling): the median ms of every pass (the ``*_ms`` keys of
  ``Frame.stats``: setup, binning, raster, gbuffer, light_cull, shade, tonemap, ...) and the
  total, plus ``lights_per_tile_avg`` / ``lights_per_tile_max``;
* clrender with ``light_culling="brute_force"`` (every pixel loops over every light) as the
  baseline;
* the OpenGL peer (bench/gl_lights.py: the research report's classic deferred shading --
  G-buffer MRTs, instanced sphere proxies with additive blending, global multiply -- on Mesa
  llvmpipe): median frame time (G-buffer + lights + combine + glFinish), the clrender/OpenGL
  ratio, the frame a user waits for on both sides, measured in the same run (clrender:
  ``render()`` then ``Frame.color`` and ``Frame.depth`` in numpy, with ``Frame.stats["host"]``'s
  breakdown of render()'s wall time; the peer: the frame, glFinish and glReadPixels of the colour
  and depth) and its ratio, and the PSNR of clrender's ``Frame.color`` against the peer's ``color`` (linear HDR;
  peak = max of the peer's color over foreground pixels with equal triangle ids; MSE over
  those pixels and the three channels).

Writes a JSON record (bench/results/lights-*.json), a plot of ms vs light count
(lights-ms-vs-count.png, needs matplotlib) and a side-by-side of clrender's ``Frame.image`` and
the peer's color tone-mapped the same way (Reinhard, sRGB) at 1024 lights
(lights-clrender-vs-opengl.png).
"""
from __future__ import annotations

import argparse
import statistics
import sys
import time

import numpy as np

from clrender.render.pipeline import pass_ms

from bench.common import (SPONZA, SPONZA_CAMERA, RESULTS, host_medians, medians, require_scene, time_renders,
                          time_user_frames, write_record)

PASS_ORDER = ("setup", "binning", "raster", "gbuffer", "particles", "light_cull", "shade", "tonemap")
SIDE_BY_SIDE_COUNT = 1024


def pass_keys(stats: dict) -> list[str]:
    """The ``*_ms`` keys of a stats dict (total last), known passes in pipeline order first."""
    keys = list(pass_ms(stats))
    order = {f"{p}_ms": i for i, p in enumerate(PASS_ORDER)}
    return sorted(keys, key=lambda k: (order.get(k, len(order)), k))


def psnr_color(ours: np.ndarray, gl: dict) -> dict:
    """PSNR of ``ours`` against the peer's color over foreground pixels with equal triangle ids."""
    if ours is None:
        return {"psnr_db": float("nan"), "pixels": 0}
    same = gl["same_id"]
    a = np.asarray(ours, np.float64)[same]
    b = np.asarray(gl["color"], np.float64)[same]
    if not len(b):
        return {"psnr_db": float("nan"), "pixels": 0}
    peak = float(b.max())
    mse = float(np.mean((a - b) ** 2))
    if mse == 0.0:
        psnr = float("inf")
    elif peak <= 0.0:
        psnr = float("nan")
    else:
        psnr = float(10.0 * np.log10(peak ** 2 / mse))
    rel = np.abs(a - b).sum(-1) / np.maximum(b.sum(-1), 1e-6)
    return {"psnr_db": psnr, "peak": peak, "mse": mse, "pixels": int(same.sum()),
            "mean_abs_diff": float(np.mean(np.abs(a - b))), "rel_diff_p99": float(np.percentile(rel, 99))}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--counts", type=int, nargs="+", default=[0, 64, 256, 1024, 4096])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--warmup", type=int, default=2)
    ap.add_argument("--device", default=None)
    ap.add_argument("--tile-size", type=int, default=None, help="raster tile size (Renderer tile_size)")
    ap.add_argument("--light-tile-size", type=int, default=None, help="light-culling tile size")
    ap.add_argument("--shading", choices=("auto", "blinn_phong"), default="auto",
                    help="clrender's shading model (auto: Sponza's metallic-roughness materials with the glTF BRDF)")
    ap.add_argument("--radius-frac", type=float, default=0.05,
                    help="light radius as a fraction of the scene's bounds diagonal")
    ap.add_argument("--intensity", type=float, default=1.0)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--width", type=int, default=1280)
    ap.add_argument("--height", type=int, default=720)
    ap.add_argument("--no-gl", action="store_true", help="skip the OpenGL peer")
    ap.add_argument("--no-brute-force", action="store_true", help="skip the brute-force clrender baseline")
    ap.add_argument("--no-clrender", action="store_true", help="only the OpenGL peer")
    ap.add_argument("--gl-accum", choices=("f2", "f4"), default="f2",
                    help="OpenGL light accumulation format: RGBA16F (f2, default) or RGBA32F (f4)")
    args = ap.parse_args(argv)
    if any(c < 0 for c in args.counts):
        ap.error("--counts must be non-negative")

    import clrender
    t0 = time.perf_counter()
    scene = clrender.load_scene(require_scene(SPONZA))
    load_s = time.perf_counter() - t0
    camera = clrender.Camera.look_at(**SPONZA_CAMERA)
    lo, hi = scene.bounds().astype(np.float64)
    radius = args.radius_frac * float(np.linalg.norm(hi - lo))
    print(f"Sponza: {scene.triangle_count:,} triangles, loaded in {load_s:.1f} s; light radius "
          f"{radius:.3f} ({args.radius_frac:g} of the bounds diagonal), intensity {args.intensity:g}, "
          f"ambient {scene.ambient:g}, {args.width}x{args.height}")

    options = {"shading": args.shading}
    if args.tile_size is not None:
        options["tile_size"] = args.tile_size
    if args.light_tile_size is not None:
        options["light_tile_size"] = args.light_tile_size
    tiled = brute = None
    if not args.no_clrender:
        try:
            tiled = clrender.Renderer(args.width, args.height, device=args.device, **options)
            if not args.no_brute_force:
                brute = clrender.Renderer(args.width, args.height, device=args.device,
                                          light_culling="brute_force", **options)
        except (ValueError, TypeError) as exc:       # options this clrender does not know yet
            print(f"clrender lighting unavailable: {exc}")
            tiled = brute = None

    record = {"scene": SPONZA.name, "width": args.width, "height": args.height, "repeats": args.repeats,
              "warmup": args.warmup, "seed": args.seed, "radius": radius, "radius_frac": args.radius_frac,
              "intensity": args.intensity, "ambient": scene.ambient, "options": options, "counts": {}}
    if tiled is not None:
        record["device"] = tiled.device.name
        record["config"] = {k: getattr(tiled.config, k) for k in vars(tiled.config)}
    base_lights = scene.lights[:0].copy()
    side = None
    side_count = SIDE_BY_SIDE_COUNT if SIDE_BY_SIDE_COUNT in args.counts else max(args.counts)
    # clrender's frames for every count first, then the peer's: the peer (llvmpipe's threads, its
    # copy of the scene) is created only once clrender's frames are timed, so they never run
    # beside it.
    frames = {}
    for count in args.counts:
        set_lights(scene, base_lights, count, args, radius)
        entry = record["counts"].setdefault(str(count), {"lights": count})
        print(f"\n== {count} lights ==")
        frame = None
        if tiled is not None:
            stats, walls, users, frame = time_user_frames(tiled, scene, camera, args.warmup, args.repeats)
            med = medians(stats)
            entry["clrender"] = {"median": med, "wall_ms_median": statistics.median(walls),
                                 "user_frame_ms_median": statistics.median(users), "host_ms": host_medians(stats),
                                 "frames_ms": [s["total_ms"] for s in stats]}
            print(f"clrender (tiled light culling) on {tiled.device.name}, median of {args.repeats} frames (ms):")
            for k in pass_keys(med):
                print(f"  {k[:-3]:<11} {med[k]:9.2f}")
            print(f"  {'total':<11} {med['total_ms']:9.2f}   (passes); render() wall {statistics.median(walls):.1f}, "
                  f"+ colour and depth to numpy {statistics.median(users):.1f}")
            print("  host: " + ", ".join(f"{k[:-3]} {v:.1f}" for k, v in entry["clrender"]["host_ms"].items()))
            if "lights_per_tile_avg" in med:
                print(f"  lights per tile: avg {med['lights_per_tile_avg']:.2f}, max {int(med.get('lights_per_tile_max', 0))}")
        if brute is not None:
            stats_b, walls_b, _ = time_renders(brute, scene, camera, args.warmup, args.repeats)
            med_b = medians(stats_b)
            entry["clrender_brute_force"] = {"median": med_b, "wall_ms_median": statistics.median(walls_b),
                                             "frames_ms": [s["total_ms"] for s in stats_b]}
            line = f"clrender brute force: total {med_b['total_ms']:.2f} ms"
            if "shade_ms" in med_b:
                line += f" (shade {med_b['shade_ms']:.2f} ms)"
            if tiled is not None:
                line += f"; tiled speed-up {med_b['total_ms'] / entry['clrender']['median']['total_ms']:.2f}x"
            print(line)
        frames[count] = frame

    peer = None if args.no_gl else make_peer(scene, args)
    if peer is not None:
        record["opengl_info"] = peer.info()
        gb = peer.time_frame_gbuffer_only(camera, repeats=args.repeats, warmup=args.warmup)
        record["opengl_gbuffer_only_ms"] = statistics.median(gb)
        print(f"OpenGL peer ({peer.renderer}): G-buffer pass alone {statistics.median(gb):.1f} ms (median)")
    elif not args.no_gl:
        record["opengl_error"] = getattr(make_peer, "error", "unavailable")

    for count in args.counts if peer is not None else ():
        set_lights(scene, base_lights, count, args, radius)
        entry, frame = record["counts"][str(count)], frames[count]
        print(f"\n== {count} lights: OpenGL ==")
        peer.set_lights(scene.lights, scene.ambient)
        gl_times = peer.time_frame(camera, repeats=args.repeats, warmup=args.warmup)
        gl_ms = statistics.median(gl_times)
        gl_user = statistics.median(peer.time_frame_readback(camera, repeats=args.repeats, warmup=1))
        gl = peer.render(camera)
        entry["opengl"] = {"median_ms": gl_ms, "frames_ms": gl_times, "user_frame_ms_median": gl_user}
        print(f"OpenGL peer: median {gl_ms:.1f} ms per frame (G-buffer + lights + combine + glFinish), "
              f"{gl_user:.1f} with colour and depth read back")
        if frame is not None:
            gl["same_id"] = (gl["triangle_id"] >= 0) & (gl["triangle_id"] == frame.triangle_id)
            ratio = entry["clrender"]["median"]["total_ms"] / gl_ms
            user_ratio = entry["clrender"]["user_frame_ms_median"] / gl_user
            agreement = psnr_color(getattr(frame, "color", None), gl)
            entry["opengl"].update(ratio=ratio, user_frame_ratio=user_ratio, color_agreement=agreement)
            print(f"  clrender / OpenGL: passes vs frame {ratio:.2f}; the frame a user waits for "
                  f"(colour and depth in numpy) {user_ratio:.2f}")
            print(f"  color PSNR clrender vs OpenGL: {agreement['psnr_db']:.2f} dB over "
                  f"{agreement['pixels']:,} same-triangle pixels (peak {agreement.get('peak', float('nan')):.3f})")
        if count == side_count:
            side = (frame, gl, count)

    if side is not None:
        save_side_by_side(*side)
    path = write_record("lights", record)
    print(f"\nrecord: {path}")
    save_plot(record)
    return 0


def set_lights(scene, base_lights, count: int, args, radius: float) -> None:
    """The scene's lights: its own (none for Sponza) and `count` random ones (seed args.seed)."""
    scene.lights = base_lights.copy()
    scene.add_random_lights(count, seed=args.seed, radius=(radius, radius), intensity=args.intensity)


def make_peer(scene, args):
    try:
        from bench.gl_lights import GLLightsPeer
        peer = GLLightsPeer(args.width, args.height, accum_dtype=args.gl_accum)
    except Exception as exc:                     # no EGL / moderngl: say so, keep the clrender numbers
        print(f"OpenGL peer unavailable: {exc}")
        make_peer.error = str(exc)
        return None
    peer.upload(scene)
    return peer


def tonemap_reinhard(color: np.ndarray) -> np.ndarray:
    """clrender's default display transform (exposure 1): Reinhard c/(1+c), then sRGB to uint8."""
    from clrender.abi.gbuffer import linear_to_srgb8
    c = np.maximum(np.asarray(color, np.float64), 0.0)
    return linear_to_srgb8(c / (1.0 + c))


def save_side_by_side(frame, gl, count) -> None:
    import imageio.v3 as iio
    right = tonemap_reinhard(gl["color"])
    if frame is not None:
        left = getattr(frame, "image", None)
        if left is None or left.shape != right.shape:
            left = tonemap_reinhard(frame.color)
        img = np.concatenate([left, right], 1)
        label, name = "clrender (left) vs OpenGL (right)", "lights-clrender-vs-opengl.png"
    else:                                        # --no-clrender: keep the last side-by-side
        img, label, name = right, "OpenGL only", "lights-opengl.png"
    RESULTS.mkdir(parents=True, exist_ok=True)
    path = RESULTS / name
    iio.imwrite(path, img)
    print(f"side by side at {count} lights, {label}: {path}")


def save_plot(record) -> None:
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("matplotlib not importable: skipping the ms-vs-lights plot (pip install matplotlib)")
        return
    counts = sorted(record["counts"], key=int)
    x = np.arange(len(counts))
    series = {}
    for c in counts:
        e = record["counts"][c]
        if "clrender" in e:
            series.setdefault("clrender tiled (total)", []).append(e["clrender"]["median"]["total_ms"])
            if "shade_ms" in e["clrender"]["median"]:
                series.setdefault("clrender tiled: light_cull + shade",
                                  []).append(e["clrender"]["median"]["shade_ms"]
                                             + e["clrender"]["median"].get("light_cull_ms", 0.0))
        if "clrender_brute_force" in e:
            series.setdefault("clrender brute force (total)", []).append(e["clrender_brute_force"]["median"]["total_ms"])
        if "opengl" in e:
            series.setdefault("OpenGL llvmpipe deferred (total)", []).append(e["opengl"]["median_ms"])
            if "opengl_gbuffer_only_ms" in record:
                series.setdefault("OpenGL: lights + combine (total - G-buffer pass)", []).append(
                    max(e["opengl"]["median_ms"] - record["opengl_gbuffer_only_ms"], 1e-3))
    fig, ax = plt.subplots(figsize=(7, 4.5))
    for name, ys in series.items():
        if len(ys) == len(counts):
            ax.plot(x, ys, marker="o", label=name)
    ax.set_xticks(x, counts)
    ax.set_xlabel("lights")
    ax.set_ylabel("median ms per frame")
    ax.set_yscale("log")
    ax.set_title(f"Sponza {record['width']}x{record['height']}, light radius {record['radius']:.2f}")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    fig.tight_layout()
    RESULTS.mkdir(parents=True, exist_ok=True)
    path = RESULTS / "lights-ms-vs-count.png"
    fig.savefig(path, dpi=120)
    plt.close(fig)
    print(f"plot: {path}")


if __name__ == "__main__":
    sys.exit(main())
