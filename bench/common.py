"""Shared benchmark plumbing: scene lookup, medians of per-pass timings, JSON records."""
from __future__ import annotations

import json
import platform
import statistics
import subprocess
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
SHARED_SCENES = REPO.parent / "shared" / "scenes"
RESULTS = REPO / "bench" / "results"

SPONZA = SHARED_SCENES / "sponza-crytek" / "Sponza.gltf"
# The fixed camera inside the atrium that every Sponza benchmark uses.
SPONZA_CAMERA = dict(eye=(-16.64, 5.48, -0.79), target=(13.97, 6.55, -0.79), up=(0, 1, 0),
                     fov_y_deg=60.0, near=0.1, far=100.0)


HELMET = SHARED_SCENES / "khronos-DamagedHelmet" / "DamagedHelmet.gltf"
# Upright (+y), facing +z: the view the material tests use, filling the frame.
HELMET_CAMERA = dict(eye=(1.2, 0.5, 2.9), target=(0.0, 0.0, 0.0), up=(0, 1, 0), fov_y_deg=40.0, near=0.05, far=20.0)


def require_scene(path: Path) -> Path:
    if not path.is_file():
        raise SystemExit(f"benchmark scene not found: {path} (the shared scenes live in ../shared/scenes "
                         f"next to the repository)")
    return path


def medians(samples: list[dict]) -> dict:
    """Median of every numeric key over frames."""
    keys = [k for k, v in samples[0].items() if isinstance(v, (int, float))]
    return {k: statistics.median(s[k] for s in samples) for k in keys}


def time_renders(renderer, scene, camera, warmup: int, repeats: int, **render_args):
    """Render warm-up frames, then `repeats` timed ones: (per-frame stats, wall ms, last frame)."""
    frame = None
    for _ in range(warmup):
        frame = renderer.render(scene, camera, **render_args)
    stats, walls = [], []
    for _ in range(repeats):
        t0 = time.perf_counter()
        frame = renderer.render(scene, camera, **render_args)
        walls.append((time.perf_counter() - t0) * 1e3)
        stats.append(frame.stats)
    return stats, walls, frame


def time_user_frames(renderer, scene, camera, warmup: int, repeats: int, read=("color", "depth"), **render_args):
    """Like time_renders, and the frame a user waits for: render() then reading `read` to numpy
    (clrender reads a Frame's arrays on first access). Returns (stats, render() wall ms, render()
    + reads wall ms, last frame)."""
    frame = None
    for _ in range(warmup):
        frame = renderer.render(scene, camera, **render_args)
        for name in read:
            getattr(frame, name)
    stats, walls, users = [], [], []
    for _ in range(repeats):
        t0 = time.perf_counter()
        frame = renderer.render(scene, camera, **render_args)
        t1 = time.perf_counter()
        for name in read:
            getattr(frame, name)
        users.append((time.perf_counter() - t0) * 1e3)
        walls.append((t1 - t0) * 1e3)
        stats.append(frame.stats)
    return stats, walls, users, frame


def host_medians(stats: list[dict]) -> dict:
    """Median of each Frame.stats["host"] phase (ms) over frames."""
    return {k: statistics.median(s["host"][k] for s in stats) for k in stats[0]["host"]}


def environment() -> dict:
    try:
        commit = subprocess.run(["git", "-C", str(REPO), "rev-parse", "--short", "HEAD"],
                                capture_output=True, text=True, timeout=10).stdout.strip()
    except Exception:
        commit = ""
    return {"machine": platform.machine(), "processor": platform.processor(), "python": platform.python_version(),
            "commit": commit, "time": time.strftime("%Y-%m-%dT%H:%M:%S")}


def write_record(name: str, record: dict) -> Path:
    RESULTS.mkdir(parents=True, exist_ok=True)
    path = RESULTS / f"{name}-{time.strftime('%Y%m%d-%H%M%S')}.json"
    path.write_text(json.dumps({**record, "environment": environment()}, indent=2, default=float))
    return path
