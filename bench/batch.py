"""Batch benchmark: a 48-frame camera fly-through of Crytek Sponza at 640×360 with 256 lights.

    python -m bench.batch [--frames 48] [--width 640] [--height 360] [--lights 256] [--workers 1 2]
                          [--device NAME] [--gif docs/images/batch-flythrough.gif]

The fly-through is a TOML scene written to a temporary folder: Sponza by absolute path, camera
keyframes down the atrium (clrender/scene/keyframes.py), 256 seeded point lights of radius 0.05 × the
scene's diagonal. It is rendered with `clrender.batch.jobs.render_frames`:

* in this process (no Dask);
* on a LocalCluster of 1 worker, then of 2 workers, each worker with POCL_CPU_MAX_CU_NUM =
  cores / workers (PoCL's thread pool per process; the default would give every worker all cores).

For each mode it prints frames per second over the whole job, the first frame's cost per process
(scene load, upload, program builds: the per-process overhead) against the median of the other
frames, the median render() wall time and pass sum (Frame.stats total_ms), and whether every PNG
is byte-identical to the single-process run. Cluster start-up is timed separately. Writes
bench/results/batch-*.json and, with --gif, the fly-through as a GIF for docs/batch.md.
"""
from __future__ import annotations

import argparse
import json
import logging
import os
import statistics
import tempfile
import time
from pathlib import Path

from bench.common import SPONZA, require_scene, write_record

# Down the atrium's long axis (x) at gallery height, drifting across it, then turning back.
KEYS = [(0.0, (-15.0, 4.0, -0.8), (10.0, 5.0, -0.8)),
        (0.7, (-6.0, 5.0, 0.5), (12.0, 6.0, -2.0)),
        (1.4, (4.0, 7.0, -0.5), (14.0, 4.0, 2.0)),
        (2.0, (12.0, 8.0, -0.8), (-10.0, 3.0, -0.8))]


def flythrough_toml(sponza: Path, lights: int, light_radius: float, width: int, height: int) -> str:
    keys = "\n".join(f"[[camera.keys]]\ntime = {t}\neye = {list(e)}\ntarget = {list(g)}\n" for t, e, g in KEYS)
    return (f'ambient = 0.08\n\n[[mesh]]\npath = "{sponza.as_posix()}"\n\n[camera]\nfov_y_deg = 60\nnear = 0.1\nfar = 100\n\n{keys}\n'
            f"[render]\nwidth = {width}\nheight = {height}\n\n"
            f"[lights]\nrandom = {{ count = {lights}, seed = 1, radius = [{light_radius}, {light_radius}], "
            f"intensity = 2.0 }}\n")


def summarize(name: str, result, out: Path, reference: Path | None, frames: int, startup_s: float = 0.0) -> dict:
    records = json.loads((out / "manifest.json").read_text())["frames"]
    by_worker: dict = {}
    for r in sorted(records, key=lambda r: r["frame"]):
        by_worker.setdefault(r["worker"], []).append(r)
    first = [rs[0]["wall_ms"] for rs in by_worker.values()]
    rest = [r["wall_ms"] for rs in by_worker.values() for r in rs[1:]]
    identical = None
    if reference is not None:
        identical = sum((out / f"f_{f:03d}.png").read_bytes() == (reference / f"f_{f:03d}.png").read_bytes()
                        for f in range(frames))
    row = {"mode": name, "workers": len(by_worker), "frames": len(records), "failed": len(result.failed),
           "job_s": result.wall_s, "fps": len(result.rendered) / result.wall_s, "cluster_start_s": startup_s,
           "first_frame_ms": statistics.median(first), "frame_ms_median": statistics.median(rest) if rest else None,
           "render_ms_median": statistics.median(r["render_ms"] for r in records),
           "passes_ms_median": statistics.median(r["stats"]["total_ms"] for r in records),
           "identical_to_single_process": identical}
    print(f"{name:>22}: {row['fps']:5.2f} frames/s ({row['job_s']:.1f} s, {row['frames']} frames"
          + (f", cluster start {startup_s:.1f} s" if startup_s else "") + f"); first frame per process "
          f"{row['first_frame_ms']:.0f} ms, then {row['frame_ms_median'] or 0:.0f} ms/frame (render() "
          f"{row['render_ms_median']:.0f} ms, passes {row['passes_ms_median']:.0f} ms)"
          + ("" if identical is None else f"; {identical}/{frames} PNGs identical"), flush=True)
    return row


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=48)
    ap.add_argument("--width", type=int, default=640)
    ap.add_argument("--height", type=int, default=360)
    ap.add_argument("--lights", type=int, default=256)
    ap.add_argument("--workers", type=int, nargs="*", default=[1, 2])
    ap.add_argument("--device", default=None)
    ap.add_argument("--gif", default=None, help="also write the single-process frames as a GIF here")
    args = ap.parse_args(argv)

    from distributed import Client, LocalCluster

    import clrender
    from clrender.outputs.aov_io import write_video
    from clrender.batch.jobs import render_frames

    sponza = require_scene(SPONZA)
    t0 = time.perf_counter()
    lo, hi = clrender.load_scene(str(sponza)).bounds()
    load_s = time.perf_counter() - t0
    radius = 0.05 * float(((hi - lo) ** 2).sum() ** 0.5)
    fps = args.frames / KEYS[-1][0]                   # the whole path in --frames frames
    rows = []
    with tempfile.TemporaryDirectory(prefix="clrender-batch-bench-") as tmp:
        tmp = Path(tmp)
        scene = tmp / "flythrough.toml"
        scene.write_text(flythrough_toml(sponza, args.lights, radius, args.width, args.height))
        job = dict(fps=fps, device=args.device)
        frames = range(args.frames)
        single = tmp / "single"
        result = render_frames(scene, frames, single / "f_{frame:03d}.png", quiet=False, **job)
        rows.append(summarize("single process", result, single, None, args.frames))
        cores = os.cpu_count() or 1
        for n in args.workers:
            env = {"POCL_CPU_MAX_CU_NUM": str(max(1, cores // n)), "PYTHONWARNINGS": "ignore"}
            start = time.perf_counter()
            with LocalCluster(n_workers=n, threads_per_worker=1, processes=True, dashboard_address=None,
                              silence_logs=logging.ERROR, env=env) as cluster, Client(cluster) as client:
                client.wait_for_workers(n)
                startup = time.perf_counter() - start
                out = tmp / f"dask{n}"
                result = render_frames(scene, frames, out / "f_{frame:03d}.png", client=client, quiet=False, **job)
                rows.append(summarize(f"LocalCluster {n} worker" + "s" * (n > 1), result, out, single, args.frames,
                                      startup))
        if args.gif:
            import numpy as np
            from PIL import Image
            size = (args.width // 2, args.height // 2)       # half size, every other frame: a docs-page-sized file
            small = [np.asarray(Image.open(single / f"f_{f:03d}.png").convert("RGB").resize(size, Image.LANCZOS))
                     for f in frames[::2]]
            write_video(args.gif, small, fps / 2)
            print(f"wrote {args.gif}")
    path = write_record("batch", {"scene": str(sponza), "frames": args.frames, "width": args.width,
                                  "height": args.height, "lights": args.lights, "fps": fps, "cores": cores,
                                  "scene_load_s": load_s, "modes": rows})
    print(f"scene load (this process) {load_s:.2f} s; record {path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
