"""First-frame benchmark: what a fresh process pays before its first Sponza image.

    python -m bench.first_frame [--runs 5] [--scene PATH] [--baseline DIR]

Each run is a fresh Python process (the PoCL kernel cache, clrender's program binaries and device
probe are warm after a first, uncounted run) that times, in order: importing clrender, the scene
load (`load_scene`), `Renderer(1280, 720)`, the first render() (its Frame.stats["host"] phases and
retries) and a second render() (a warm frame) with the scene's default camera, as the CLI renders
it. Then the whole command `python -m clrender render SCENE -o out.png` is timed from outside
(interpreter start to exit). Medians over the runs are printed and written to
bench/results/first_frame-*.json.

--baseline DIR: a second checkout (e.g. `git archive HEAD | tar -x -C DIR`) measured the same
way, its runs interleaved with this tree's (A/B/A/B), so that a shared machine's load falls on
both alike.
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from bench.common import REPO, SPONZA, require_scene, write_record

CHILD = r"""
import json, sys, time
t0 = time.perf_counter()
import clrender
from clrender import Renderer, load_scene
t1 = time.perf_counter()
scene = load_scene(sys.argv[1])
t2 = time.perf_counter()
renderer = Renderer(1280, 720)
t3 = time.perf_counter()
camera = scene.default_camera()
frame = renderer.render(scene, camera)
t4 = time.perf_counter()
second = renderer.render(scene, camera)
t5 = time.perf_counter()
host = frame.stats.get("host", {})
print("RESULT " + json.dumps({"import_s": t1 - t0, "load_s": t2 - t1, "renderer_s": t3 - t2,
                              "first_render_s": t4 - t3, "second_render_s": t5 - t4,
                              "retries": frame.stats.get("retries"), "host_ms": host,
                              "module": clrender.__file__}))
"""


def child_env(tree: Path) -> dict:
    env = dict(os.environ)
    env["PYTHONPATH"] = str(tree)          # before the editable install's path: this tree's clrender
    return env


def run_child(tree: Path, scene: Path) -> dict:
    out = subprocess.run([sys.executable, "-c", CHILD, str(scene)], cwd=tree, env=child_env(tree),
                         capture_output=True, text=True, timeout=900)
    lines = [line for line in out.stdout.splitlines() if line.startswith("RESULT ")]
    if out.returncode or not lines:
        raise SystemExit(f"benchmark child failed in {tree}:\n{out.stderr[-3000:]}")
    record = json.loads(lines[-1][7:])
    if not record["module"].startswith(str(tree)):
        raise SystemExit(f"the child imported {record['module']}, not the tree {tree}")
    return record


def run_cli(tree: Path, scene: Path, image: Path) -> float:
    t = time.perf_counter()
    out = subprocess.run([sys.executable, "-m", "clrender", "render", str(scene), "-o", str(image)], cwd=tree,
                         env=child_env(tree), capture_output=True, text=True, timeout=900)
    wall = time.perf_counter() - t
    if out.returncode:
        raise SystemExit(f"clrender render failed in {tree}:\n{out.stderr[-3000:]}")
    return wall


def summary(records: list[dict], cli: list[float]) -> dict:
    keys = ("import_s", "load_s", "renderer_s", "first_render_s", "second_render_s")
    row = {k: statistics.median(r[k] for r in records) for k in keys}
    phases = sorted({p for r in records for p in r["host_ms"]})
    row["first_render_host_ms"] = {p: statistics.median(r["host_ms"].get(p, 0.0) for r in records) for p in phases}
    row["retries"] = [r["retries"] for r in records]
    row["first_over_warm"] = row["first_render_s"] / row["second_render_s"]
    row["cli_s"] = statistics.median(cli)
    row["runs"] = len(records)
    return row


def show(name: str, row: dict) -> None:
    host = ", ".join(f"{k[:-3]} {v:.0f}" for k, v in row["first_render_host_ms"].items())
    print(f"{name}: import {row['import_s']:.2f} s, load {row['load_s']:.2f} s, Renderer() {row['renderer_s']:.2f} s, "
          f"first render() {row['first_render_s']:.2f} s ({row['first_over_warm']:.1f}x the warm "
          f"{row['second_render_s']:.2f} s; host ms: {host}; retries {row['retries']}), "
          f"CLI {row['cli_s']:.2f} s  [median of {row['runs']}]")


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--scene", type=Path, default=SPONZA)
    ap.add_argument("--baseline", type=Path, default=None, help="another checkout, measured interleaved")
    args = ap.parse_args(argv)
    scene = require_scene(args.scene.resolve())
    trees = {"current": REPO}
    if args.baseline is not None:
        trees["baseline"] = args.baseline.resolve()
    results = {name: ([], []) for name in trees}
    with tempfile.TemporaryDirectory() as tmp:
        for name, tree in trees.items():          # warm-up: kernel caches, program binaries, device probe
            run_child(tree, scene)
            run_cli(tree, scene, Path(tmp) / f"{name}.png")
        for _ in range(args.runs):
            for name, tree in trees.items():
                results[name][0].append(run_child(tree, scene))
                results[name][1].append(run_cli(tree, scene, Path(tmp) / f"{name}.png"))
    rows = {name: summary(*results[name]) for name in trees}
    for name, row in rows.items():
        show(name, row)
    path = write_record("first_frame", {"scene": str(scene), "size": [1280, 720], "cpus": os.cpu_count(),
                                        "load_average": os.getloadavg(), "trees": {k: str(v) for k, v in trees.items()},
                                        "results": rows})
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
