"""Shadow benchmark: Crytek Sponza at 1280×720 from the fixed atrium camera with the sun
(cascaded shadow maps) + 16 shadowed spot lights + 1024 unshadowed point lights.

    python -m bench.shadows [--repeats 3] [--warmup 1] [--device NAME] [--filter pcf3x3]
                            [--cascades 3] [--sun-size 2048] [--spot-size 1024] [--spots 16]
                            [--lights 1024] [--picture docs/images/sponza-shadows.png]

Prints the median ms of every pass from OpenCL profiling events (the ``*_ms`` keys of
``Frame.stats``; ``shadow`` is every shadow map's setup + binning + raster, broken down as
``shadow_setup`` / ``shadow_binning`` / ``shadow_raster``, which are not added again to the
total), the same scene with ``shadows=False`` (the sun and spots unshadowed) as the baseline,
and writes a JSON record (bench/results/shadows-*.json) and the picture (tone-mapped image of
the shadowed frame). Exits with a message when the scene is absent.

The shadowed frame is timed with the chunk cull (RenderConfig.chunk_cull, the default) and
without, frames interleaved (on, off, on, off...) in one process; the record's ``chunk_cull``
entry has both medians of the camera's setup and the maps' setup / binning / raster, and
whether the shadow atlas and the G-buffer are bit-identical (``--no-ab``: the cull only).
"""
from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import numpy as np

from clrender.render.pipeline import pass_ms

from bench.common import REPO, SPONZA, SPONZA_CAMERA, medians, require_scene, time_renders, write_record

PASS_ORDER = ("setup", "binning", "raster", "gbuffer", "particles", "light_cull", "shadow", "shadow_setup",
              "shadow_binning", "shadow_raster", "ssao", "ssao_blur", "shade", "tonemap")
SUN_DIR = (0.35, -1.0, 0.12)        # high sun through the open atrium: the far floor lit, the roof's shadow edge
FLOOR_Y = 3.98                      # Sponza's ground floor (world units)


def pass_keys(stats: dict) -> list[str]:
    keys = list(pass_ms(stats))
    order = {f"{p}_ms": i for i, p in enumerate(PASS_ORDER)}
    return sorted(keys, key=lambda k: (order.get(k, len(order)), k))


def add_lights(scene, args) -> None:
    """Sun, `spots` shadowed spots hanging above the two rows of columns (aimed at the floor
    beside them, so the columns, vases and plants cast shadows), `lights` random point lights."""
    scene.set_sun(SUN_DIR, (9.0, 8.4, 7.2), shadow=True, shadow_map_size=args.sun_size)
    per_row = max(args.spots // 2, 1)
    k = 0
    for z, aim in ((-3.3, 0.45), (1.7, -0.45)):
        for x in np.linspace(-13.0, 10.0, per_row):
            if k == args.spots:
                break
            scene.add_spot_light((float(x), FLOOR_Y + 5.5, z), (0.1, -1.0, aim), (3.5, 2.6, 1.65), 10.0, 15.0, 32.0,
                                 shadow=True, shadow_map_size=args.spot_size)
            k += 1
    lo, hi = scene.bounds().astype(np.float64)
    radius = 0.05 * float(np.linalg.norm(hi - lo))
    scene.add_random_lights(args.lights, seed=1, radius=(radius, radius), intensity=args.intensity)


def time_moving_camera(args, scene, camera) -> dict:
    """A short camera pan with map reuse on: the sun's cascades are redrawn, the spots' kept."""
    import clrender
    r = clrender.Renderer(args.width, args.height, device=args.device, shadow_filter=args.filter,
                          sun_cascades=args.cascades)
    stats = []
    for k in range(args.warmup + args.repeats):
        step = np.array([0.0, 0.0, 0.15 * k])
        cam = clrender.Camera.look_at(np.add(camera.eye, step), np.add(camera.target, step), camera.up,
                                      fov_y_deg=camera.fov_y_deg, near=camera.near, far=camera.far)
        stats.append(r.render(scene, cam).stats)
    med = medians(stats[args.warmup:])
    print(f"\nmoving camera, static spots' maps kept, median of {args.repeats} frames (ms):")
    print(f"  shadow          {med['shadow_ms']:9.2f}   ({int(med['shadow_maps_reused'])} of "
          f"{int(med['shadow_maps'])} maps kept)")
    print(f"  {'total':<15} {med['total_ms']:9.2f}")
    return {"median": med}


def time_interleaved(renderers: dict, scene, camera, warmup: int, repeats: int) -> dict:
    """Frames of each renderer in turn (A, B, A, B...): name -> (stats, wall ms, last frame,
    (shadow atlas maps, G-buffer) of the last frame)."""
    for _ in range(warmup):
        for r in renderers.values():
            r.render(scene, camera)
    stats, walls, last = ({name: [] for name in renderers} for _ in range(3))
    for _ in range(repeats):
        for name, r in renderers.items():
            t0 = time.perf_counter()
            frame = r.render(scene, camera)
            walls[name].append((time.perf_counter() - t0) * 1e3)
            stats[name].append(frame.stats)
            last[name] = frame
    return {name: (stats[name], walls[name], last[name], (shadow_maps(r), np.array(last[name].gbuffer)))
            for name, r in renderers.items()}


def shadow_maps(renderer) -> list:
    """Each map's square of the shadow atlas (the atlas between squares is never written)."""
    shadow = renderer.pipeline.shadow
    lay = shadow.layout
    atlas = shadow.atlas.get()[: lay.atlas_width * lay.atlas_height].reshape(lay.atlas_height, lay.atlas_width)
    return [atlas[v.y0:v.y0 + v.size, v.x0:v.x0 + v.size].copy() for v in lay.views]


CULL_KEYS = ("setup_ms", "shadow_ms", "shadow_setup_ms", "shadow_binning_ms", "shadow_raster_ms", "total_ms")


def compare_chunk_cull(on, off) -> dict:
    """Medians with and without the chunk cull, their ratio, and bit-identity of maps and G-buffer."""
    med_on, med_off = medians(on[0]), medians(off[0])
    maps_same = len(on[3][0]) == len(off[3][0]) and all(np.array_equal(a, b) for a, b in zip(on[3][0], off[3][0]))
    out = {"on": {k: med_on[k] for k in CULL_KEYS}, "off": {k: med_off[k] for k in CULL_KEYS},
           "ratio": {k: med_on[k] / med_off[k] for k in CULL_KEYS if med_off[k]},
           "maps_identical": bool(maps_same), "gbuffer_identical": bool(np.array_equal(on[3][1], off[3][1])),
           "chunks": int(on[2].stats["chunks"]), "camera_culled_chunks": int(on[2].stats["culled_chunks"])}
    print(f"\nchunk cull, medians over {len(on[0])} interleaved frames each (ms):   on       off    on/off")
    for k in CULL_KEYS:
        print(f"  {k[:-3]:<22} {med_on[k]:9.2f} {med_off[k]:9.2f}   {out['ratio'].get(k, float('nan')):5.2f}")
    print(f"  camera: {out['camera_culled_chunks']} of {out['chunks']} chunks culled; shadow maps bit-identical: "
          f"{maps_same}, G-buffer bit-identical: {out['gbuffer_identical']}")
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--warmup", type=int, default=1)
    ap.add_argument("--device", default=None)
    ap.add_argument("--width", type=int, default=1280)
    ap.add_argument("--height", type=int, default=720)
    ap.add_argument("--filter", default="pcf3x3", choices=("pcf3x3", "poisson", "hard"))
    ap.add_argument("--cascades", type=int, default=3)
    ap.add_argument("--sun-size", type=int, default=2048)
    ap.add_argument("--spot-size", type=int, default=1024)
    ap.add_argument("--spots", type=int, default=16)
    ap.add_argument("--lights", type=int, default=1024)
    ap.add_argument("--intensity", type=float, default=0.15, help="of the random point lights")
    ap.add_argument("--no-baseline", action="store_true", help="skip the shadows=False baseline")
    ap.add_argument("--no-ab", action="store_true", help="skip the frames without the chunk cull")
    ap.add_argument("--picture", default=str(REPO / "docs" / "images" / "sponza-shadows.png"),
                    help="where to save the shadowed frame's image ('' to skip)")
    args = ap.parse_args(argv)

    import clrender
    t0 = time.perf_counter()
    scene = clrender.load_scene(require_scene(SPONZA))
    print(f"Sponza: {scene.triangle_count:,} triangles, loaded in {time.perf_counter() - t0:.1f} s")
    scene.ambient = 0.06
    add_lights(scene, args)
    camera = clrender.Camera.look_at(**SPONZA_CAMERA)
    n_shadowed = int((scene.lights["shadow_size"] > 0).sum())
    print(f"lights: sun ({args.cascades} cascades of {args.sun_size}²), {n_shadowed} shadowed spots "
          f"({args.spot_size}²), {len(scene.lights) - n_shadowed} unshadowed point lights; "
          f"{args.width}x{args.height}, filter {args.filter}")

    record = {"scene": SPONZA.name, "width": args.width, "height": args.height, "repeats": args.repeats,
              "warmup": args.warmup, "filter": args.filter, "cascades": args.cascades, "sun_size": args.sun_size,
              "spot_size": args.spot_size, "spots": n_shadowed, "lights": args.lights, "sun_direction": SUN_DIR}
    # Every map rendered every frame (the cost of a frame whose lights or camera all move), with
    # the chunk cull and without (interleaved), then no shadows; `reuse_static_spots` below times a
    # moving camera with the static spots' maps kept.
    shadowed = dict(shadows=True, shadow_map_reuse=False)
    ab = {"shadows": clrender.Renderer(args.width, args.height, device=args.device, shadow_filter=args.filter,
                                       sun_cascades=args.cascades, chunk_cull=True, **shadowed)}
    if not args.no_ab:
        ab["shadows_no_chunk_cull"] = clrender.Renderer(args.width, args.height, device=args.device,
                                                        shadow_filter=args.filter, sun_cascades=args.cascades,
                                                        chunk_cull=False, **shadowed)
    results = time_interleaved(ab, scene, camera, args.warmup, args.repeats)
    if not args.no_baseline:
        r = clrender.Renderer(args.width, args.height, device=args.device, shadow_filter=args.filter,
                              sun_cascades=args.cascades, shadows=False)
        results["no_shadows"] = time_renders(r, scene, camera, args.warmup, args.repeats) + (None,)
    frame = None
    for name, (stats, walls, last, _) in results.items():
        med = medians(stats)
        record.setdefault("device", last.stats["device"])
        record[name] = {"median": med, "wall_ms_median": statistics.median(walls),
                        "frames_ms": [s["total_ms"] for s in stats]}
        print(f"\n{name} on {last.stats['device']}, median of {args.repeats} frames after {args.warmup} warm-up (ms):")
        for k in pass_keys(med):
            print(f"  {k[:-3]:<15} {med[k]:9.2f}")
        print(f"  {'total':<15} {med['total_ms']:9.2f}   (wall incl. readback: {statistics.median(walls):.1f})")
        if "shadow_maps" in med:
            print(f"  {int(med['shadow_maps'])} shadow maps, atlas {int(med['shadow_atlas_texels']):,} texels; "
                  f"lights per tile avg {med.get('lights_per_tile_avg', 0):.1f}")
        if name == "shadows":
            frame = last
            vis = last.shadow[last.triangle_id >= 0]
            record["shadowed_fraction_per_light"] = [float((vis[:, k] < 0.5).mean()) for k in range(vis.shape[1])]
    if "shadows_no_chunk_cull" in results:
        record["chunk_cull"] = compare_chunk_cull(results["shadows"], results["shadows_no_chunk_cull"])

    if not args.no_baseline:
        record["reuse_static_spots"] = time_moving_camera(args, scene, camera)
    path = write_record("shadows", record)
    print(f"\nrecord: {path}")
    if args.picture and frame is not None:
        import imageio.v3 as iio
        pic = Path(args.picture)
        pic.parent.mkdir(parents=True, exist_ok=True)
        iio.imwrite(pic, frame.image)
        print(f"picture: {pic}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
