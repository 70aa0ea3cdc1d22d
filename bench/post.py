"""Post-processing benchmark: Crytek Sponza at 1280×720 with 256 point lights, the frame at
supersample 1, 2 and 4 and with each post effect on, ms of every pass (OpenCL profiling events)
and the wall time of render(), medians after warm-up (docs/post.md).

    python -m bench.post [--width 1280 --height 720 --repeats 5 --warmup 2 --device NAME]

Every frame moves the camera sideways (0.25 units since the previous frame) so motion blur has
work; `--picture` also writes docs/images/post.png (crops of none / edge AA / FXAA / 4x SSAA, and
bloom, motion blur, hatching). Records go to bench/results/post-*.json.
"""
from __future__ import annotations

import argparse
import statistics

import numpy as np

from .common import SPONZA, SPONZA_CAMERA, medians, require_scene, time_renders, write_record

CONFIGS = (
    ("plain", {}),
    ("ss2_box", dict(supersample=2)),
    ("ss2_lanczos2", dict(supersample=2, supersample_filter="lanczos2")),
    ("ss4_box", dict(supersample=4)),
    ("edge_aa", dict(edge_aa=True)),
    ("fxaa", dict(color_aa="fxaa")),
    ("edge_aa+fxaa", dict(edge_aa=True, color_aa="fxaa")),
    ("bloom", dict(bloom=True)),
    ("aa+bloom", dict(edge_aa=True, color_aa="fxaa", bloom=True)),
    ("motion_blur", dict(motion_blur=True, motion_blur_samples=8)),
    ("hatching", dict(hatching=True)),
    ("plain_again", {}),        # the plain frame once more, last: the first renders of a process run slower
)
POST_PASSES = ("resolve", "bloom", "motion_blur", "tonemap", "edge_aa", "fxaa", "hatching", "encode")
PAN = (0.0, 0.0, 0.25)          # the camera's motion since the previous frame (world units, sideways)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--width", type=int, default=1280)
    ap.add_argument("--height", type=int, default=720)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--warmup", type=int, default=2)
    ap.add_argument("--lights", type=int, default=256)
    ap.add_argument("--device", default=None)
    ap.add_argument("--only", nargs="+", choices=[c[0] for c in CONFIGS], default=None)
    ap.add_argument("--picture", action="store_true", help="also write docs/images/post.png")
    args = ap.parse_args(argv)

    import clrender
    scene = clrender.load_scene(require_scene(SPONZA))
    scene.add_random_lights(args.lights, seed=1, radius=(1.0, 3.0), intensity=1.0)
    camera = clrender.Camera.look_at(**SPONZA_CAMERA)
    prev = clrender.Camera.look_at(**{**SPONZA_CAMERA, "eye": tuple(np.subtract(SPONZA_CAMERA["eye"], PAN)),
                                      "target": tuple(np.subtract(SPONZA_CAMERA["target"], PAN))})
    record = {"scene": str(SPONZA.name), "width": args.width, "height": args.height, "lights": args.lights,
              "repeats": args.repeats, "warmup": args.warmup, "configs": {}}
    for name, opts in CONFIGS:
        if args.only and name not in args.only:
            continue
        r = clrender.Renderer(args.width, args.height, device=args.device, shadows=False, **opts)
        stats, walls, frame = time_renders(r, scene, camera, args.warmup, args.repeats, previous_camera=prev)
        record["device"] = frame.stats["device"]
        med = medians(stats)
        record["configs"][name] = {"options": opts, "median": med, "wall_ms_median": statistics.median(walls),
                                   "walls_ms": walls}
        post = {p: med.get(f"{p}_ms", 0.0) for p in POST_PASSES}
        print(f"{name:<14} wall {statistics.median(walls):8.1f} ms  passes {med['total_ms']:8.1f} ms  "
              + "  ".join(f"{p} {v:.1f}" for p, v in post.items() if v), flush=True)
    plain = [record["configs"][n]["median"]["total_ms"] for n in ("plain", "plain_again") if n in record["configs"]]
    if plain:
        base = min(plain)
        record["ratios"] = {name: c["median"]["total_ms"] / base for name, c in record["configs"].items()}
        print("pass time / plain frame: " + ", ".join(f"{k} {v:.2f}" for k, v in record["ratios"].items()))
    if "plain" in record["configs"]:
        # An effect's cost: the ms of the passes it adds (with the LDR effects, encoding the image
        # becomes a pass of its own), over the plain frame's passes. Differencing whole frames
        # instead would add the frame-to-frame noise of the unchanged passes (several ms here).
        plain_ms = min(record["configs"][n]["median"]["total_ms"] for n in ("plain", "plain_again")
                       if n in record["configs"])
        targets = {"aa+bloom over the frame": ("aa+bloom", ("edge_aa", "fxaa", "bloom", "encode"), 0.15),
                   "motion blur (8 samples) over the frame": ("motion_blur", ("motion_blur",), 0.10)}
        record["targets"] = {}
        for label, (name, passes, limit) in targets.items():
            if name in record["configs"]:
                med = record["configs"][name]["median"]
                extra = sum(med.get(f"{p}_ms", 0.0) for p in passes) / plain_ms
                record["targets"][label] = {"passes": passes, "fraction": extra, "limit": limit}
                print(f"{label}: {' + '.join(passes)} = {extra:.1%} of the plain frame's {plain_ms:.1f} ms "
                      f"(target <= {limit:.0%})")
        if "ss2_box" in record["configs"]:
            print(f"supersample 2 over 1: {record['ratios']['ss2_box']:.2f}x (target <= 4.5x)")
    print(f"record: {write_record('post', record)}")
    if args.picture:
        print(f"picture: {make_picture(args, scene, camera, prev)}")
    return 0


def make_picture(args, scene, camera, prev):
    """docs/images/post.png: a crop of Sponza (columns, arches) without AA, with edge AA, FXAA and
    4x over-sampling, then the full frame with bloom, with motion blur, hatched, and edge AA's mask
    (ambient raised to 0.35 so the picture is not dark)."""
    import imageio.v3 as iio
    from PIL import Image, ImageDraw

    import clrender
    from .common import REPO
    w, h = 640, 360
    scene.ambient = 0.35                          # brighter than the benchmark's frame, for the eye
    frames = {}
    for name, opts in (("no AA", {}), ("edge AA", dict(edge_aa=True)), ("FXAA", dict(color_aa="fxaa")),
                       ("4x SSAA", dict(supersample=4)), ("bloom", dict(bloom=True, bloom_threshold=0.5,
                                                                         bloom_strength=0.6, bloom_radius=32)),
                       ("motion blur", dict(motion_blur=True, shutter=1.0)), ("hatching", dict(hatching=True))):
        r = clrender.Renderer(w, h, device=args.device, shadows=False, **opts)
        frame = r.render(scene, camera, previous_camera=prev)
        frames[name] = frame.image
        if name == "edge AA":
            frames["edges"] = np.repeat(frame.edges[..., None] * np.uint8(255), 3, axis=2)
    x0, y0, cw, ch = 250, 60, 160, 90            # the crop, magnified 4x without filtering
    crops = [np.kron(frames[n][y0:y0 + ch, x0:x0 + cw], np.ones((2, 2, 1), np.uint8)) for n in
             ("no AA", "edge AA", "FXAA", "4x SSAA")]
    top = np.concatenate(crops, 1)
    bottom = np.concatenate([frames[n][::2, ::2] for n in ("bloom", "motion blur", "hatching", "edges")], 1)
    img = Image.fromarray(np.concatenate([top, bottom], 0))
    draw = ImageDraw.Draw(img)
    for i, n in enumerate(("no AA", "edge AA", "FXAA", "4x SSAA")):
        draw.text((i * 2 * cw + 6, 4), n, fill=(255, 255, 0))
    for i, n in enumerate(("bloom", "motion blur", "hatching", "edge AA's mask")):
        draw.text((i * w // 2 + 6, 2 * ch + 4), n, fill=(255, 255, 0))
    path = REPO / "docs" / "images" / "post.png"
    iio.imwrite(path, np.asarray(img))
    return path


if __name__ == "__main__":
    raise SystemExit(main())
