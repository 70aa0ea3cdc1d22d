"""Post-processing benchmark: Crytek Sponza at 1280×720 with 256 point lights, the frame at
supersample 1, 2 and 4 and with each post effect on, ms of every pass (OpenCL profiling events)
and the wall time of render(), medians after warm-up (docs/post.md).

    python -m bench.post [--width 1280 --height 720 --repeats 3 --warmup 1 --device NAME]

Post effects measured so far: over-sampling (box, Lanczos-2), edge AA and FXAA (issue 11 adds
bloom, motion blur and hatching to the same table). Records go to bench/results/post-*.json.
"""
from __future__ import annotations

import argparse
import statistics

from .common import SPONZA, SPONZA_CAMERA, medians, require_scene, time_renders, write_record

CONFIGS = (
    ("plain", {}),
    ("ss2_box", dict(supersample=2)),
    ("ss2_lanczos2", dict(supersample=2, supersample_filter="lanczos2")),
    ("ss4_box", dict(supersample=4)),
    ("edge_aa", dict(edge_aa=True)),
    ("fxaa", dict(color_aa="fxaa")),
    ("edge_aa+fxaa", dict(edge_aa=True, color_aa="fxaa")),
)
POST_PASSES = ("resolve", "tonemap", "edge_aa", "fxaa", "encode")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--width", type=int, default=1280)
    ap.add_argument("--height", type=int, default=720)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--warmup", type=int, default=1)
    ap.add_argument("--lights", type=int, default=256)
    ap.add_argument("--device", default=None)
    ap.add_argument("--only", nargs="+", choices=[c[0] for c in CONFIGS], default=None)
    args = ap.parse_args(argv)

    import clrender
    scene = clrender.load_scene(require_scene(SPONZA))
    scene.add_random_lights(args.lights, seed=1, radius=(1.0, 3.0), intensity=1.0)
    camera = clrender.Camera.look_at(**SPONZA_CAMERA)
    record = {"scene": str(SPONZA.name), "width": args.width, "height": args.height, "lights": args.lights,
              "repeats": args.repeats, "warmup": args.warmup, "configs": {}}
    for name, opts in CONFIGS:
        if args.only and name not in args.only:
            continue
        r = clrender.Renderer(args.width, args.height, device=args.device, shadows=False, **opts)
        stats, walls, frame = time_renders(r, scene, camera, args.warmup, args.repeats)
        record["device"] = frame.stats["device"]
        med = medians(stats)
        record["configs"][name] = {"options": opts, "median": med, "wall_ms_median": statistics.median(walls),
                                   "walls_ms": walls}
        post = {p: med.get(f"{p}_ms", 0.0) for p in POST_PASSES}
        print(f"{name:<14} wall {statistics.median(walls):8.1f} ms  passes {med['total_ms']:8.1f} ms  "
              + "  ".join(f"{p} {v:.1f}" for p, v in post.items() if v), flush=True)
    plain = record["configs"].get("plain")
    if plain:
        base = plain["median"]["total_ms"]
        record["ratios"] = {name: c["median"]["total_ms"] / base for name, c in record["configs"].items()}
        print("pass time / plain frame: " + ", ".join(f"{k} {v:.2f}" for k, v in record["ratios"].items()))
    print(f"record: {write_record('post', record)}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
