"""The raster's vector width and tile sizes measured per device (issue 40 item 3): which VEC and tile
are fastest depends on the CPU and its OpenCL compiler, not only on the vendor.

When a Renderer opens a CPU device whose choice is not cached yet (clrender/device/tuning.py), a short
tune times setup + binning + raster -- what the tile size and raster VEC change -- on a built-in
workload made to Sponza's statistics (tune_workload.py), and keeps today's default unless a candidate
is faster by MARGIN: one step per candidate, the default and the candidate in ROUNDS interleaved
rounds, judged by the median of per-round ratios (a shared machine's load hits both alike). A win is
measured again and judged on both sets.

    steps:   VEC 4 at the default tile; tile 16 at the default VEC; VEC 16 on tile 16 where the
             compiler has 512-bit vectors (capabilities.compiler_has_512bit_vectors); the shadow
             maps' tile, 16 against 32, on a depth-only SHADOW_SIZE² view of the same workload

Each candidate is a program build (~1-3 s cold on PoCL on 2 cores; Intel's runtime ~0.3 s). A cold
start (the process that probed the device: new machine or kernels) does not tune -- it builds for
seconds already, and a new user judges it (pip-only demo: 17.1 s, 22.0 with the tune) -- and a later
process starts no step after BUDGET_S of tuning, so the cost is spread over a device's next runs.
The steps measured, their timings and the choice are cached (tuning.entry_name); once complete a
start pays nothing.
"""
from __future__ import annotations

import os
import statistics
import time
from dataclasses import asdict
from typing import Optional

import numpy as np

from clrender.device import cache, capabilities, tuning
from clrender.device.tuning import Choice, default_choice

MARGIN = 0.05                    # a candidate replaces the default only when this much faster
ROUNDS = 9
BUDGET_S = 2.0                   # a process starts no further step after this much tuning
SIZE = (640, 360)                # the camera workload (tune_workload.py: ~16-22 ms a run on 2 cores)
SHADOW_SIZE = 1024               # a depth-only map, the size of a spot light's
_tuning = False                  # set while the tune renders (its passes read tuning.choice)


def decide(timings: dict, default, margin: float = MARGIN):
    """The candidate to use given {candidate: [ms per round, ...]} (rounds interleaved: entry i of
    every list ran in round i): the candidate whose median ratio to the default's time in the
    same round is lowest, if below 1 - `margin`, else the default (ties and noise keep it).
    Ratios within a round cancel a shared machine's load drift. A default not measured wins."""
    base = timings.get(default) or []
    if not base:
        return default
    ratios = {}
    for c, ts in timings.items():
        pairs = [(t, b) for t, b in zip(ts, base) if b > 0]
        if pairs:
            ratios[c] = statistics.median(t / b for t, b in pairs)
    best = min(ratios, key=lambda c: (ratios[c], c != default))
    return best if ratios[best] < 1.0 - margin else default


def camera_candidates(dev) -> list[tuple[int, int]]:
    """(VEC, tile) pairs worth timing, the default first: each width at the default tile, each
    tile at the default width (not the whole grid: every pair is a program build), and 16 wide on
    16-pixel tiles (a run must fit its tile row) only where the compiler has 512-bit vectors."""
    d = default_choice(dev)
    wide = capabilities.compiler_has_512bit_vectors(dev)
    pairs = [(d.vec, d.tile), (4, d.tile), (8, d.tile), (d.vec, 16)] + ([(16, 16)] if wide else [])
    out = []
    for vec, tile in pairs:
        vec = min(vec, tile)
        if (vec, tile) not in out and capabilities.tile_size_for_ok(dev, tile):
            out.append((vec, tile))
    return out


def shadow_candidates(dev) -> list[int]:
    return [t for t in (16, 32) if capabilities.tile_size_for_ok(dev, t)]


def steps(dev) -> list[tuple[str, str, list]]:
    """The tune's steps, in order: (name, "camera" or "shadow", candidates, the default first)."""
    d = default_choice(dev)
    cams = camera_candidates(dev)
    out = [(f"vec{v}_tile{t}", "camera", [cams[0], (v, t)]) for v, t in cams[1:]]
    shadows = shadow_candidates(dev)
    if d.shadow_tile in shadows and len(shadows) > 1:
        out.append(("shadow", "shadow", [d.shadow_tile] + [t for t in shadows if t != d.shadow_tile]))
    return out


# -- the measurement --------------------------------------------------------------------------------

class _Runner:
    """Setup, binning and raster for one (tile, VEC), wired as the pipeline wires them."""

    def __init__(self, device, scene_res, camera, size, tile: int, vec: int, depth_only: bool = False):
        from clrender.config import RenderConfig
        from clrender.passes.base import Resources, empty
        from clrender.passes.binning import BinningPass
        from clrender.passes.raster import RasterPass
        from clrender.passes.setup import SetupPass
        from clrender.render.camera_upload import camera_buffers, upload_camera
        q = device.queue
        self.queue, (w, h) = q, size
        config = RenderConfig(tile_size=tile, shadow_tile_size=tile)
        self.passes = [SetupPass(device, config, select="opaque", status=not depth_only),
                       BinningPass(device, config, tile),
                       RasterPass(device, config, depth_only=depth_only, tile=tile, vec=vec)]
        matrices = camera_buffers(q)
        values = upload_camera(q, matrices, camera, w, h, None, False)
        self.res = Resources(buffers={**scene_res.buffers, **matrices},
                             values={**scene_res.values, **values, "width": w, "height": h})
        if depth_only:
            self.target = empty(q, w * h, np.float32)
            self.res.buffers["raster_target"] = self.target
            self.res.values.update(raster_offset=0, raster_stride=w)
        for p in self.passes:
            p.allocate(w, h)
            p.prepare_scene(scene_res)

    def run(self) -> float:
        """One frame of the three passes (grown and redone if a list overflowed); its wall ms."""
        for _ in range(4):
            start = time.perf_counter()
            for p in self.passes:
                p.publish(self.res)
                p.run(self.res)
            self.queue.finish()
            ms = 1e3 * (time.perf_counter() - start)
            grown = False
            for p in self.passes:
                for ov in p.overflows():
                    total = int(ov.total.get(queue=self.queue)[0])
                    if total > ov.capacity:
                        p.grow(ov.name, total)
                        grown = True
            if not grown:
                return ms
        raise RuntimeError("the tune's workload kept overflowing its buffers")


def measure(device, step=None, rounds: int = ROUNDS, scene=None, camera=None, size=SIZE,
            shadow_size=SHADOW_SIZE, vec: Optional[int] = None) -> dict:
    """{candidate: [ms per round]} for one step, ("camera", [(vec, tile)...]) or ("shadow",
    [tile...]) (default: every camera candidate), after a warm-up run each (builds, first
    launches). Shadow candidates run at `vec` (default: the default choice's)."""
    from clrender.render import scene_upload
    from clrender.render.tune_workload import workload
    dev = device.cl_device
    if scene is None:
        scene, camera = workload(size)
    scene_res = scene_upload.upload(scene, device)
    kind, cands = ("camera", camera_candidates(dev)) if step is None else step
    if kind == "camera":
        runners = {c: _Runner(device, scene_res, camera, size, c[1], c[0]) for c in cands}
    else:
        vec = vec or default_choice(dev).vec
        runners = {t: _Runner(device, scene_res, camera, (shadow_size, shadow_size), t, min(vec, t), depth_only=True)
                   for t in cands}
    for r in runners.values():
        r.run()                                  # builds and first launches
    times = {c: [] for c in runners}
    for _ in range(rounds):
        for c, r in runners.items():
            times[c].append(r.run())
    return times


def _ratios(ms: dict, default) -> dict:
    """A step's timings as ratios to its default's in the same round (the default: all 1)."""
    base = ms.get(default) or []
    return {c: [t / b for t, b in zip(ts, base) if b > 0] for c, ts in ms.items()}


def choose(dev, measured: dict) -> Choice:
    """The choice from the steps measured so far ({step name: {candidate: [ms]}}): each step's
    candidate against that step's default, by decide()'s rule; unmeasured steps keep defaults."""
    d = default_choice(dev)
    cam, shadow = {(d.vec, d.tile): [1.0]}, {d.shadow_tile: [1.0]}
    for name, kind, cands in steps(dev):
        if name in measured:
            target = cam if kind == "camera" else shadow
            for c, r in _ratios(measured[name], cands[0]).items():
                if c != cands[0] and r:
                    target[c] = r
    # decide() pairs entry i of each list with the default's: ratios are already per round
    pad = max(len(v) for v in (*cam.values(), *shadow.values()))
    vec, tile = decide({c: v if c != (d.vec, d.tile) else [1.0] * pad for c, v in cam.items()}, (d.vec, d.tile))
    shadow_tile = decide({c: v if c != d.shadow_tile else [1.0] * pad for c, v in shadow.items()}, d.shadow_tile)
    return Choice(vec, tile, shadow_tile)


def tune(device, record: Optional[dict] = None, budget_s: Optional[float] = None) -> tuple[Choice, dict]:
    """Run the tune's next steps on a clrender Device, as many as start within `budget_s` (at
    least one): the cold cost is spread over a device's first runs, a few seconds each, instead of
    all at once. Returns the choice so far and the cache record."""
    from clrender import progress
    global _tuning
    dev = device.cl_device
    d = default_choice(dev)
    budget_s = BUDGET_S if budget_s is None else budget_s
    record = dict(record or {})
    measured = {k: {_parse(c): v for c, v in ms.items()} for k, ms in (record.get("measured_ms") or {}).items()}
    pending = [st for st in steps(dev) if st[0] not in measured]
    start = time.perf_counter()
    _tuning = True
    try:
        with progress.stage("measuring the raster's vector width and tile sizes", len(pending),
                            device.info.label) as stage:
            for i, (name, kind, cands) in enumerate(pending):
                if i and time.perf_counter() - start > budget_s:
                    break                # the rest in the device's next runs
                so_far = choose(dev, measured)
                ms = measure(device, (kind, cands), vec=so_far.vec)
                if decide(ms, cands[0]) != cands[0]:
                    # a win is measured again (programs built: ~ROUNDS runs) and judged on both
                    # sets: one burst of load on the default's runs must not switch a device
                    again = measure(device, (kind, cands), vec=so_far.vec)
                    ms = {c: ms[c] + again[c] for c in ms}
                measured[name] = ms
                stage.advance(name)
    finally:
        _tuning = False
    c = choose(dev, measured)
    done = all(n in measured for n, _, _ in steps(dev))
    record.update({"device": device.info.label, "version": tuning.VERSION, "choice": asdict(c), "default": asdict(d),
                   "complete": done, "margin": MARGIN, "rounds": ROUNDS, "size": list(SIZE),
                   "shadow_size": SHADOW_SIZE,
                   "seconds": round(float(record.get("seconds", 0)) + time.perf_counter() - start, 3),
                   "runs": int(record.get("runs", 0)) + 1,
                   "measured_ms": {k: {_name(c): [round(x, 3) for x in v] for c, v in ms.items()}
                                   for k, ms in measured.items()}})
    return c, record


def _name(c) -> str:
    return f"vec{c[0]}_tile{c[1]}" if isinstance(c, tuple) else f"tile{c}"


def _parse(name: str):
    if name.startswith("vec"):
        v, t = name[3:].split("_tile")
        return int(v), int(t)
    return int(name[4:])


def ensure(device) -> Optional[Choice]:
    """The device's choice, tuning it (and caching the answer) over its first runs on this machine;
    None where the device is not tuned (tuning.enabled)."""
    dev = device.cl_device
    if _tuning or not tuning.enabled(dev) or os.environ.get("CLRENDER_PROBE_CHILD"):
        return None                   # (the probe child checks the defaults' kernels only)
    if tuning.complete(dev):
        return tuning.choice(dev)
    from clrender.device import probe
    if probe.probed_in_this_process(device.info):
        return tuning.choice(dev)     # a cold start already builds for seconds: the tune waits for the next run
    name = tuning.entry_name(dev)
    record = cache.read_json(name)
    record = record if isinstance(record, dict) and tuning.from_record(record) is not None else None
    if record is not None and record.get("complete"):
        c = tuning.from_record(record)
    else:
        with device.lock:
            c, record = tune(device, record)
        cache.write_json(name, record)
    tuning.remember(dev, c, bool(record.get("complete")))
    return c
