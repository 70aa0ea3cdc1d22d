"""Surface layers (the glTF material extensions, issue 37): what they cost per pass and per user frame.

    python -m bench.materials [--repeats 11] [--warmup 2] [--lights 1024] [--device NAME]
                              [--scenes sponza helmet] [--baseline DIR] [--per-layer] [--quick]

Two scenes, each in two (with --baseline three) versions rendered in the same run, interleaved frame
by frame (plain, layered, layered, plain, ...) so that drift of a shared machine falls on all alike:

* Crytek Sponza at 1280x720 from the fixed atrium camera with 1024 seeded point lights made as
  bench.lights makes them (radius 0.05 of the bounds diagonal, seed 1), constant ambient;
* DamagedHelmet at 1280x720 from HELMET_CAMERA under the built-in studio environment (load_scene's
  default for a file without lights, as bench.ibl_gallery's default column), no point lights.

``plain``: the materials as loaded (no extension). ``layered``: every glTF-BRDF material (metallic
not None) given clearcoat 1, clearcoat_roughness 0.1, sheen_color (0.5, 0.5, 0.5), sheen_roughness
0.5, anisotropy_strength 0.6 and iridescence 1 (dataclasses.replace; the two versions are shallow
copies of one loaded scene sharing its arrays, so each keeps its own cached device upload).

Per version: the median of every pass's device ms (the ``*_ms`` keys of Frame.stats, including
``surface_layers_ms``), of the passes' total, of render()'s wall time and of the frame a user waits
for (render() then Frame.color and Frame.depth read to numpy), over ``repeats`` frames after
``warmup`` frames. The issue's targets, printed per scene:

* no extension: the plain frames run no surface_layers pass; their spread (IQR of the user frame)
  is the noise band to compare other records with;
* all extensions on: ``layered shading`` = (gbuffer + shade + surface_layers) of the layered frames
  over (gbuffer + shade) of the plain frames -- the G-buffer pass is the visibility buffer's
  resolve -- target <= 1.5; also surface_layers alone relative to the plain gbuffer + shade.

``--baseline DIR``: a third version, ``before``: the plain scene rendered by the clrender of another
source tree (e.g. the commit before the extensions: ``git archive HEAD | tar -x -C DIR``) in a worker
process (BASELINE_WORKER: public API only), interleaved with the other two frame by frame: the
"no change when no extension is used" target measured in one run. ``--per-layer``: one more
version per extension alone (clearcoat, sheen, anisotropy, iridescence), to see which layer costs what.

``--quick``: 640x360, 1 warm-up and 2 frames each (a smoke run, not a measurement).
Writes bench/results/materials-*.json.
"""
from __future__ import annotations

import argparse
import copy
import dataclasses
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from clrender.render.stats import pass_ms

from bench.common import (HELMET, HELMET_CAMERA, SPONZA, SPONZA_CAMERA, REPO, host_medians, medians, require_scene,
                          write_record)

# Every surface extension switched on (issue 37's benchmark): clearcoat + sheen + anisotropy + iridescence.
ALL_ON = dict(clearcoat=1.0, clearcoat_roughness=0.1, sheen_color=(0.5, 0.5, 0.5), sheen_roughness=0.5,
              anisotropy_strength=0.6, iridescence=1.0)
# --per-layer: one more version per extension, alone (which layer costs what)
SINGLE = {"clearcoat": ("clearcoat", "clearcoat_roughness"), "sheen": ("sheen_color", "sheen_roughness"),
          "anisotropy": ("anisotropy_strength",), "iridescence": ("iridescence",)}
PASS_ORDER = ("setup", "binning", "raster", "gbuffer", "particles", "light_cull", "ibl", "shade", "surface_layers",
              "tonemap")
RESOLVE_SHADE = ("gbuffer_ms", "shade_ms")       # the plain frame's shading work the target is relative to
TARGET = 1.5


# The `before` version's process: the same plain scene through another tree's clrender (public API
# only, so that any version of it runs this). Reads one line per frame, answers one JSON line.
BASELINE_WORKER = r"""
import json, sys, time
import numpy as np
import clrender
a = json.loads(sys.argv[1])
scene = clrender.load_scene(a["path"])
if a["lights"] is not None:
    lo, hi = scene.bounds().astype(np.float64)
    r = a["radius_frac"] * float(np.linalg.norm(hi - lo))
    scene.lights = scene.lights[:0]
    scene.add_random_lights(a["lights"], seed=1, radius=(r, r))
elif scene.environment is None:
    scene.set_environment("studio")
camera = clrender.Camera.look_at(**a["camera"])
renderer = clrender.Renderer(a["width"], a["height"], device=a["device"])
print(json.dumps({"device": renderer.device.name, "file": clrender.__file__}), flush=True)
for line in sys.stdin:
    t0 = time.perf_counter()
    frame = renderer.render(scene, camera)
    t1 = time.perf_counter()
    frame.color, frame.depth
    t2 = time.perf_counter()
    st = {k: v for k, v in frame.stats.items() if isinstance(v, (int, float)) or k == "host"}
    print(json.dumps({"stats": st, "wall": (t1 - t0) * 1e3, "user": (t2 - t0) * 1e3}, default=float), flush=True)
"""


class Baseline:
    """The `before` version: a BASELINE_WORKER process on `tree`'s clrender, one frame per request."""

    def __init__(self, tree: Path, args: dict):
        env = {**os.environ, "PYTHONPATH": str(tree)}       # ahead of the editable install's finder
        self.proc = subprocess.Popen([sys.executable, "-c", BASELINE_WORKER, json.dumps(args)], cwd=str(tree),
                                     env=env, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
        self.info = self._answer()
        if not self.info.get("file", "").startswith(str(tree)):
            raise SystemExit(f"--baseline {tree}: the worker imported {self.info.get('file')}, not that tree's clrender")

    def _answer(self) -> dict:
        line = self.proc.stdout.readline()
        if not line:
            raise SystemExit(f"--baseline worker exited (status {self.proc.wait()}): see its error above")
        return json.loads(line)

    def frame(self) -> tuple:
        self.proc.stdin.write("frame\n")
        self.proc.stdin.flush()
        a = self._answer()
        return a["stats"], a["wall"], a["user"]

    def close(self) -> None:
        self.proc.stdin.close()
        self.proc.wait(timeout=60)


def layered_copy(scene, keys=tuple(ALL_ON)):
    """A shallow copy of `scene` whose glTF-BRDF materials have the extension values ALL_ON[keys]."""
    values = {k: ALL_ON[k] for k in keys}
    out = copy.copy(scene)
    out.materials = [dataclasses.replace(m, **values) if m.metallic is not None else m for m in scene.materials]
    return out


def layered_count(scene) -> int:
    return sum(1 for m in scene.materials if getattr(m, "layers", ()))


def user_frame(renderer, scene, camera, read=("color", "depth")) -> tuple:
    """(Frame.stats, render() wall ms, render() + reading `read` to numpy ms) of one frame."""
    t0 = time.perf_counter()
    frame = renderer.render(scene, camera)
    t1 = time.perf_counter()
    for a in read:
        getattr(frame, a)
    return frame.stats, (t1 - t0) * 1e3, (time.perf_counter() - t0) * 1e3


def interleaved(renderer, versions: dict, camera, warmup: int, repeats: int) -> dict:
    """Warm-up frames of every version, then `repeats` rounds of one user frame per version (the
    order reversed every other round). A version is a Scene or a Baseline.
    {version: (stats list, render() wall ms list, user frame ms list)}."""
    def one(v):
        return v.frame() if isinstance(v, Baseline) else user_frame(renderer, v, camera)

    for _ in range(warmup):
        for v in versions.values():
            one(v)
    out = {name: ([], [], []) for name in versions}
    names = list(versions)
    for r in range(repeats):
        for name in (names if r % 2 == 0 else names[::-1]):
            for acc, x in zip(out[name], one(versions[name])):
                acc.append(x)
    return out


def summarize(stats: list, walls: list, users: list) -> dict:
    q = np.percentile(users, [25, 75]) if len(users) > 1 else (users[0], users[0])
    return {"passes_ms": medians([pass_ms(s) for s in stats]),
            "total_ms": statistics.median(s["total_ms"] for s in stats),
            "render_wall_ms": statistics.median(walls), "user_frame_ms": statistics.median(users),
            "user_frame_iqr_ms": float(q[1] - q[0]), "user_frames_ms": users,
            "totals_ms": [s["total_ms"] for s in stats], "host_ms": host_medians(stats)}


def ordered_passes(rows: dict) -> list:
    keys = {k for row in rows.values() for k in row["passes_ms"]}
    order = {f"{p}_ms": i for i, p in enumerate(PASS_ORDER)}
    return sorted(keys, key=lambda k: (order.get(k, len(order)), k))


def targets(rows: dict) -> dict:
    plain, layered = rows["plain"]["passes_ms"], rows["layered"]["passes_ms"]
    base = sum(plain.get(k, 0.0) for k in RESOLVE_SHADE)
    layers = layered.get("surface_layers_ms", 0.0)
    shading = sum(layered.get(k, 0.0) for k in RESOLVE_SHADE) + layers
    return {"plain_gbuffer_shade_ms": base, "layered_gbuffer_shade_layers_ms": shading,
            "layered_shading_ratio": shading / base if base else float("nan"),
            "surface_layers_ms": layers, "surface_layers_over_plain_shading": layers / base if base else float("nan"),
            "plain_runs_surface_layers": "surface_layers_ms" in plain,
            "user_frame_ratio": rows["layered"]["user_frame_ms"] / rows["plain"]["user_frame_ms"],
            "user_frame_paired_ratio": paired(rows["layered"], rows["plain"]),
            "target_met": bool(base) and shading / base <= TARGET, **no_change(rows)}


def paired(a: dict, b: dict) -> float:
    """Median over rounds of a's user frame / b's user frame of the same round (drift cancels)."""
    return statistics.median(x / y for x, y in zip(a["user_frames_ms"], b["user_frames_ms"]))


def no_change(rows: dict) -> dict:
    """plain (this tree) against before (--baseline's tree): the difference of the medians and whether
    it is within the noise (at most the larger of the two user frames' interquartile ranges)."""
    if "before" not in rows:
        return {}
    p, b = rows["plain"], rows["before"]
    diff = p["user_frame_ms"] - b["user_frame_ms"]
    noise = max(p["user_frame_iqr_ms"], b["user_frame_iqr_ms"])
    return {"plain_over_before_paired_ratio": paired(p, b), "plain_minus_before_user_ms": diff, "plain_minus_before_total_ms": p["total_ms"] - b["total_ms"],
            "noise_ms": noise, "no_change_within_noise": abs(diff) <= noise}


def print_table(title: str, rows: dict, t: dict) -> None:
    print(f"\n{title}: median ms")
    print(f"{'pass':<16}" + "".join(f"{n:>12}" for n in rows))
    for k in ordered_passes(rows):
        print(f"{k[:-3]:<16}" + "".join(f"{rows[n]['passes_ms'][k]:12.2f}" if k in rows[n]["passes_ms"]
                                        else f"{'-':>12}" for n in rows))
    for key, label in (("total_ms", "passes total"), ("render_wall_ms", "render() wall"),
                       ("user_frame_ms", "user frame"), ("user_frame_iqr_ms", "user frame IQR")):
        print(f"{label:<16}" + "".join(f"{rows[n][key]:12.1f}" for n in rows))
    print(f"plain frames run surface_layers: {'yes' if t['plain_runs_surface_layers'] else 'no'}; layered "
          f"(gbuffer + shade + surface_layers) / plain (gbuffer + shade) = {t['layered_gbuffer_shade_layers_ms']:.1f} / "
          f"{t['plain_gbuffer_shade_ms']:.1f} = {t['layered_shading_ratio']:.2f}x (target <= {TARGET}x: "
          f"{'met' if t['target_met'] else 'NOT met'}); surface_layers alone {t['surface_layers_ms']:.1f} ms = "
          f"{t['surface_layers_over_plain_shading']:.2f}x plain gbuffer + shade; user frame "
          f"{t['user_frame_ratio']:.2f}x (paired by round {t['user_frame_paired_ratio']:.2f}x)")
    if "noise_ms" in t:
        print(f"plain - before: user frame {t['plain_minus_before_user_ms']:+.1f} ms, passes "
              f"{t['plain_minus_before_total_ms']:+.1f} ms, paired by round {t['plain_over_before_paired_ratio']:.3f}x; noise (larger IQR) {t['noise_ms']:.1f} ms: "
              f"{'no change within noise' if t['no_change_within_noise'] else 'OUTSIDE the noise'}")


def load(which: str, lights: int, radius_frac: float):
    """(plain scene, camera, description) of 'sponza' or 'helmet'."""
    import clrender
    if which == "sponza":
        scene = clrender.load_scene(require_scene(SPONZA))
        lo, hi = scene.bounds().astype(np.float64)
        radius = radius_frac * float(np.linalg.norm(hi - lo))
        scene.lights = scene.lights[:0]
        scene.add_random_lights(lights, seed=1, radius=(radius, radius))     # as bench.lights
        return scene, clrender.Camera.look_at(**SPONZA_CAMERA), f"Sponza, {lights} lights (radius {radius:.3f})"
    scene = clrender.load_scene(require_scene(HELMET))
    if scene.environment is None:               # a file with lights would not get the default one
        scene.set_environment("studio")
    return scene, clrender.Camera.look_at(**HELMET_CAMERA), f"DamagedHelmet, studio environment ({scene.environment.source})"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeats", type=int, default=11)
    ap.add_argument("--warmup", type=int, default=2)
    ap.add_argument("--lights", type=int, default=1024)
    ap.add_argument("--radius-frac", type=float, default=0.05)
    ap.add_argument("--width", type=int, default=1280)
    ap.add_argument("--height", type=int, default=720)
    ap.add_argument("--scenes", nargs="+", choices=("sponza", "helmet"), default=["sponza", "helmet"])
    ap.add_argument("--device", default=None)
    ap.add_argument("--quick", action="store_true", help="640x360, 1 warm-up, 2 frames: a smoke run")
    ap.add_argument("--per-layer", action="store_true",
                    help="also each extension alone (clearcoat, sheen, anisotropy, iridescence): one version each")
    ap.add_argument("--baseline", type=Path, default=None,
                    help="another source tree (e.g. `git archive HEAD | tar -x -C DIR`): its plain frames as 'before'")
    args = ap.parse_args(argv)
    if args.quick:
        args.width, args.height, args.warmup, args.repeats = 640, 360, 1, 2
    if args.repeats < 1 or args.warmup < 0:
        ap.error("--repeats must be >= 1 and --warmup >= 0")

    import clrender
    renderer = clrender.Renderer(args.width, args.height, device=args.device)
    print(f"{renderer.device.name}, {args.width}x{args.height}, median of {args.repeats} interleaved frames "
          f"after {args.warmup} warm-up")
    record = {"width": args.width, "height": args.height, "repeats": args.repeats, "warmup": args.warmup,
              "quick": args.quick, "device": renderer.device.name, "all_on": ALL_ON, "target": TARGET,
              "config": {k: getattr(renderer.config, k) for k in vars(renderer.config)}, "scenes": {}}
    for which in args.scenes:
        t0 = time.perf_counter()
        plain, camera, what = load(which, args.lights, args.radius_frac)
        layered = layered_copy(plain)
        n = layered_count(layered)
        print(f"\n{what}: {plain.triangle_count:,} triangles, loaded in {time.perf_counter() - t0:.1f} s; "
              f"{n} of {len(layered.materials)} materials layered")
        if n == 0:
            raise SystemExit(f"{which}: no material has layers after switching the extensions on "
                             f"(Material.layers empty): nothing to measure")
        versions = {"plain": plain, "layered": layered}
        if args.per_layer:
            versions.update({name: layered_copy(plain, keys) for name, keys in SINGLE.items()})
        before = None
        if args.baseline is not None:
            before = Baseline(args.baseline.resolve(), {
                "path": str(SPONZA if which == "sponza" else HELMET), "width": args.width, "height": args.height,
                "device": args.device, "radius_frac": args.radius_frac,
                "lights": args.lights if which == "sponza" else None,
                "camera": SPONZA_CAMERA if which == "sponza" else HELMET_CAMERA})
            versions = {"before": before, **versions}
            record["baseline"] = {"tree": str(args.baseline), **before.info}
        try:
            runs = interleaved(renderer, versions, camera, args.warmup, args.repeats)
        finally:
            if before is not None:
                before.close()
        rows = {name: summarize(*runs[name]) for name in versions}
        t = targets(rows)
        print_table(what, rows, t)
        for name in SINGLE if args.per_layer else ():
            t[f"{name}_surface_layers_ms"] = rows[name]["passes_ms"].get("surface_layers_ms", 0.0)
        if args.per_layer:
            print("surface_layers ms with one extension alone: " + ", ".join(
                f"{name} {t[f'{name}_surface_layers_ms']:.1f}" for name in SINGLE))
        record["scenes"][which] = {"description": what, "triangles": plain.triangle_count,
                                   "layered_materials": n, "materials": len(layered.materials),
                                   "lights": len(plain.lights), **rows, "targets": t}
        del plain, layered, versions            # free the uploads before the next scene
    path = write_record("materials", record)
    print(f"\nrecord: {path.relative_to(REPO)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
