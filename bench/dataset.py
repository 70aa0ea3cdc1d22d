"""Dataset export benchmark: `clrender dataset` on Crytek Sponza against the same renders without it.

    python -m bench.dataset [--views 48] [--width 640] [--height 480] [--device NAME]

Three timings of the same N views (the `sphere` layout around Sponza's bounds), in this process
after a warm-up render:

* export: `clrender.cli.main(["dataset", ...])` writing images, depth (.npy and 16-bit PNG, cm),
  masks and transforms.json through the batch machinery (manifest, progress off); its wall time
  includes loading the scene file once (the batch worker's own scene cache);
* peer: a plain loop over the export's cameras doing the frame a user waits for (render() plus
  image, depth and object_id read to numpy), writing nothing;
* the peer plus writing the same image PNG and depth .npy with imageio/NumPy.

It prints ms per view (medians of per-view times for the loops; the export's wall / N) and the
derived AOVs' host cost (object_id, material_id, position) on one frame, and writes
bench/results/dataset-*.json.
"""
from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np

from bench.common import SPONZA, require_scene, write_record


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--views", type=int, default=48)
    ap.add_argument("--width", type=int, default=640)
    ap.add_argument("--height", type=int, default=480)
    ap.add_argument("--device", default=None)
    args = ap.parse_args(argv)

    import imageio.v3 as iio

    import clrender
    from clrender.cli.app import main as cli
    from clrender.dataset.views import load_dataset

    scene_path = require_scene(SPONZA)
    scene = clrender.load_scene(scene_path)
    renderer = clrender.Renderer(args.width, args.height, device=args.device)
    renderer.render(scene).image                                  # programs built, scene uploaded
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "export"
        cmd = ["dataset", str(scene_path), "-o", str(out), "--views", str(args.views), "--layout", "sphere",
               "--width", str(args.width), "--height", str(args.height), "--depth-scale", "100", "-q"]
        if args.device:
            cmd += ["--device", args.device]
        start = time.perf_counter()
        assert cli(cmd) == 0
        export_s = time.perf_counter() - start
        views = load_dataset(out)
        peer, peer_write, derived = [], [], []
        for v in views:
            t0 = time.perf_counter()
            f = renderer.render(scene, v.camera)
            f.image, f.depth, f.object_id
            peer.append(time.perf_counter() - t0)
            t0 = time.perf_counter()
            f = renderer.render(scene, v.camera)
            iio.imwrite(Path(tmp) / "x.png", f.image)
            np.save(Path(tmp) / "x.npy", f.depth)
            f.object_id
            peer_write.append(time.perf_counter() - t0)
        identical = all(np.array_equal(iio.imread(v.image), renderer.render(scene, v.camera).image)
                        for v in views[:4])
        for _ in range(5):
            f = renderer.render(scene, views[0].camera)
            f.triangle_id
            times = {}
            for name in ("object_id", "material_id", "position"):
                t0 = time.perf_counter()
                getattr(f, name)
                times[name] = (time.perf_counter() - t0) * 1e3
            derived.append(times)
        files = sum(1 for p in out.rglob("*") if p.is_file())
        size = sum(p.stat().st_size for p in out.rglob("*") if p.is_file())

    ms = lambda xs: 1e3 * statistics.median(xs)  # noqa: E731
    record = {
        "scene": str(scene_path), "views": args.views, "size": [args.width, args.height],
        "export_wall_s": export_s, "export_ms_per_view": 1e3 * export_s / args.views,
        "peer_ms_per_view": ms(peer), "peer_with_writes_ms_per_view": ms(peer_write),
        "export_files": files, "export_bytes": size, "reexport_images_identical": identical,
        "derived_aov_ms": {k: statistics.median(d[k] for d in derived) for k in derived[0]},
    }
    print(f"{args.views} views of Sponza at {args.width}x{args.height}:")
    print(f"  clrender dataset (images, depth npy+png, masks, transforms.json): "
          f"{record['export_ms_per_view']:.1f} ms/view ({export_s:.2f} s, {files} files, {size / 1e6:.1f} MB)")
    print(f"  peer: render() + image, depth, object_id to numpy:               {record['peer_ms_per_view']:.1f} ms/view")
    print(f"  peer + image PNG and depth .npy writes:                         "
          f"{record['peer_with_writes_ms_per_view']:.1f} ms/view")
    print("  derived AOVs on the host (ms): " + ", ".join(f"{k} {v:.2f}" for k, v in record["derived_aov_ms"].items()))
    print(f"  re-rendered images identical to the export: {identical}")
    print(f"wrote {write_record('dataset', record)}")


if __name__ == "__main__":
    main()
