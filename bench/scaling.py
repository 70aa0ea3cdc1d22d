"""Scaling curves: clrender and the OpenGL/llvmpipe peer on the same axes, in one run.

    python -m bench.scaling [--axes resolution triangles lights instances] [--repeats 3] [--warmup 1]
                            [--device NAME] [--no-gl] [--gl-cap-s 120] [--instances 1 4 16 40]
                            [--config NAME=VALUE ...] [--plot docs/images/scaling.png]

Crytek Sponza from the fixed atrium camera (bench/common.py), random point lights made as
bench.lights makes them (seed 1, radius 0.05 of the bounds diagonal). The axes, the others
held at 1280×720, Sponza ×1 and 256 lights:

* resolution: 640×360, 1280×720, 1920×1080, 2560×1440, 3840×2160;
* triangles: Sponza ×1, ×2, ×4 -- copies of the whole scene at the same place (every copy is
  in view and rasterized, the picture is unchanged: both renderers keep the first of equal
  depths), so every stage handles k times the triangles;
* lights: 0, 256, 1024, 4096, 16384;
* instances (not in the default set; bench/big_scene.py): Sponza ×1, ×4, ×16, ×40 (40 × 262,087
  = 10.5M triangles) side by side on a grid in x and z, one bounds extent apart, the camera and
  the lights in the first copy: a big scene whose triangles are mostly behind walls or off screen.
  Measured interleaved (a Renderer per point), with the first frame's upload and retries, the
  device-memory estimate against what the frame holds, host RSS, and each pass's growth per
  million triangles.

The OpenGL peer is skipped (the reason printed) at a point whose upload and frames, extrapolated
from the previous point's, would take longer than --gl-cap-s. --config NAME=VALUE sets RenderConfig
fields for clrender.

Each point measures the frame a user waits for -- clrender: `render()` then `Frame.color` and
`Frame.depth` in numpy; the peer (bench/gl_lights.py, deferred shading with light volumes on
Mesa llvmpipe): the frame, glFinish and glReadPixels of the colour and the depth -- as medians
after warm-up, with clrender's pass sum (OpenCL profiling events) and render()'s wall time beside
it. Prints a table per axis with the cost per unit of each step (ms per megapixel, per million
triangles, per thousand lights), writes bench/results/scaling-*.json and the plot (matplotlib).
"""
from __future__ import annotations

import argparse
import statistics
import sys
import time

import numpy as np

from bench.big_scene import measure_instances, print_pass_growth, replicate
from bench.common import REPO, SPONZA, SPONZA_CAMERA, medians, require_scene, time_user_frames, write_record

RESOLUTIONS = ((640, 360), (1280, 720), (1920, 1080), (2560, 1440), (3840, 2160))
COPIES = (1, 2, 4)
LIGHTS = (0, 256, 1024, 4096, 16384)
INSTANCES = (1, 4, 16, 40)
BASE = dict(size=(1280, 720), copies=1, lights=256)
AXES = ("resolution", "triangles", "lights", "instances")
UNITS = {"resolution": ("megapixels", 1e-6), "triangles": ("million triangles", 1e-6),
         "lights": ("thousand lights", 1e-3), "instances": ("million triangles", 1e-6)}


def points(axes, instances=INSTANCES) -> list[tuple[str, float, dict]]:
    """(axis, x, setting) for every measurement; the shared base point is measured once per axis."""
    out = []
    for axis in axes:
        if axis == "resolution":
            out += [(axis, w * h, dict(BASE, size=(w, h))) for w, h in RESOLUTIONS]
        elif axis == "triangles":
            out += [(axis, k, dict(BASE, copies=k)) for k in COPIES]
        elif axis == "instances":
            out += [(axis, k, dict(BASE, copies=k, grid=True)) for k in instances]
        else:
            out += [(axis, n, dict(BASE, lights=n)) for n in LIGHTS]
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--axes", nargs="+", choices=AXES, default=["resolution", "triangles", "lights"])
    ap.add_argument("--instances", nargs="+", type=int, default=list(INSTANCES),
                    help="copy counts of the instances axis")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--warmup", type=int, default=1)
    ap.add_argument("--device", default=None)
    ap.add_argument("--no-gl", action="store_true", help="skip the OpenGL peer")
    ap.add_argument("--gl-cap-s", type=float, default=120.0,
                    help="skip a peer point whose upload and frames would take longer (extrapolated)")
    ap.add_argument("--config", nargs="+", default=[], metavar="NAME=VALUE",
                    help="RenderConfig fields for clrender, e.g. decoded_textures_mb=0")
    ap.add_argument("--plot", default=str(REPO / "docs" / "images" / "scaling.png"))
    args = ap.parse_args(argv)

    import clrender
    from clrender.budget import memory_limit
    t0 = time.perf_counter()
    base = clrender.load_scene(require_scene(SPONZA))
    load_ms = (time.perf_counter() - t0) * 1e3
    camera = clrender.Camera.look_at(**SPONZA_CAMERA)
    lo, hi = base.bounds().astype(np.float64)
    radius = 0.05 * float(np.linalg.norm(hi - lo))
    todo = points(args.axes, tuple(args.instances))
    light_sets = {}
    for n in sorted({s["lights"] for _, _, s in todo}):
        base.lights = base.lights[:0].copy()
        base.add_random_lights(n, seed=1, radius=(radius, radius), intensity=1.0)
        light_sets[n] = base.lights.copy()

    def make_renderer(size):
        return clrender.Renderer(*size, device=args.device, config=render_config(args.config))

    record = {"scene": SPONZA.name, "config": args.config, "repeats": args.repeats, "warmup": args.warmup,
              "base": BASE, "light_radius": radius, "scene_load_ms": load_ms, "grid_extent": (hi - lo).tolist(),
              "memory_budget_bytes": memory_limit(), "axes": {a: [] for a in args.axes}}
    renderers, peers, scenes = {}, {}, {}
    for axis, x, setting in todo:
        if axis == "instances":
            continue                              # measured interleaved below (bench/big_scene.py)
        size = setting["size"]
        if setting["copies"] not in scenes:
            scenes.clear()                        # one scene (and its device upload) at a time
            peers_release(peers)
            scenes[setting["copies"]] = replicate(base, setting["copies"])
        scene = scenes[setting["copies"]]
        scene.lights = light_sets[setting["lights"]]
        if size not in renderers:
            renderers.clear()                    # one resolution's buffers at a time
            renderers[size] = make_renderer(size)
        r = renderers[size]
        record["device"] = r.device.name
        stats, walls, users, _ = time_user_frames(r, scene, camera, args.warmup, args.repeats)
        med = medians(stats)
        entry = {"x": x, "setting": {**setting, "size": list(size)}, "triangles": scene.triangle_count,
                 "clrender": {"passes_ms": med["total_ms"], "render_wall_ms": statistics.median(walls),
                              "user_frame_ms": statistics.median(users),
                              "pass_ms": {k: v for k, v in med.items() if k.endswith("_ms")}}}
        if not args.no_gl:
            entry["opengl"] = peer_point(peers, size, scene, camera, args)
        record["axes"][axis].append(entry)
        gl = entry.get("opengl", {}).get("user_frame_ms")
        print(f"{axis:<10} {str(x):>8}: clrender passes {med['total_ms']:8.1f}  render() {statistics.median(walls):8.1f}"
              f"  + colour, depth {statistics.median(users):8.1f} ms" + (f"   OpenGL {gl:8.1f} ms, ratio "
                                                                          f"{statistics.median(users) / gl:.2f}"
                                                                          if gl else ""), flush=True)
    peers_release(peers)
    renderers.clear()
    scenes.clear()
    if "instances" in args.axes:
        entries, device = measure_instances([t for t in todo if t[0] == "instances"], base, hi - lo, camera,
                                            light_sets, args, make_renderer, peer_point)
        record["axes"]["instances"] = entries
        record["device"] = record.get("device") or device
    for axis in args.axes:
        print_growth(axis, record["axes"][axis])
    if "instances" in args.axes:
        record["pass_growth"] = print_pass_growth(record["axes"]["instances"])
    path = write_record("scaling", record)
    print(f"\nrecord: {path}")
    save_plot(record, args.plot)
    return 0


def render_config(items):
    """RenderConfig with NAME=VALUE fields, each VALUE parsed as the field's default's type."""
    import dataclasses
    from clrender import RenderConfig
    config = RenderConfig()
    changes = {}
    for item in items:
        name, _, text = item.partition("=")
        if not hasattr(config, name):
            raise SystemExit(f"--config {item}: RenderConfig has no field {name!r}")
        kind = type(getattr(config, name))
        changes[name] = (text.lower() in ("1", "true", "yes")) if kind is bool else \
            text if kind is str or getattr(config, name) is None else kind(text)
    return dataclasses.replace(config, **changes)


def peers_release(peers) -> None:
    for p in peers.values():
        p.release()
    peers.clear()


def peer_point(peers, size, scene, camera, args, done=()) -> dict:
    """The peer's frame with colour and depth read back, or why there is none. Skipped when the
    previous point of the axis (`done`), scaled by the triangles, says its upload and frames would
    take longer than args.gl_cap_s (llvmpipe rasterizes every triangle on the CPU)."""
    prev = next((e for e in reversed(done) if "opengl" in e), None)
    if prev is not None:
        gl = prev["opengl"]
        if "user_frame_ms" not in gl:
            return {"skipped": gl.get("skipped") or gl.get("error")}
        scale = scene.triangle_count / prev["triangles"]
        predicted = scale * (gl["upload_s"] + gl["user_frame_ms"] * (args.warmup + args.repeats) / 1e3)
        if predicted > args.gl_cap_s:
            why = (f"about {predicted:.0f} s for upload and {args.warmup + args.repeats} frames, extrapolated from "
                   f"{prev['triangles']:,} triangles, over --gl-cap-s {args.gl_cap_s:.0f}")
            print(f"OpenGL peer skipped at {scene.triangle_count:,} triangles: {why}")
            return {"skipped": why}
    try:
        from bench.gl_lights import GLLightsPeer
        key = (size, id(scene))
        if key not in peers:
            peers_release(peers)
            peers[key] = GLLightsPeer(*size)
            peers[key].upload(scene)
        peer = peers[key]
        peer.set_lights(scene.lights, scene.ambient)
        times = peer.time_frame_readback(camera, repeats=args.repeats, warmup=args.warmup)
        return {"user_frame_ms": statistics.median(times), "frames_ms": times, "renderer": peer.renderer,
                "upload_s": float(peer.upload_s)}
    except Exception as exc:                      # no EGL / moderngl: keep clrender's numbers
        print(f"OpenGL peer unavailable: {exc}")
        args.no_gl = True
        return {"error": str(exc)}


def unit_x(axis, entry) -> float:
    """The axis value in the unit the growth table uses."""
    if axis == "resolution":
        return entry["x"] * UNITS[axis][1]
    if axis in ("triangles", "instances"):
        return entry["triangles"] * UNITS[axis][1]
    return entry["x"] * UNITS[axis][1]


def print_growth(axis, entries) -> None:
    """ms added per unit between consecutive points: where each renderer's cost grows."""
    unit = UNITS[axis][0]
    entries = [e for e in entries if "user_frame_ms" in e["clrender"]]
    print(f"\n{axis}: ms per {unit} between consecutive points (the frame a user waits for)")
    for a, b in zip(entries, entries[1:]):
        dx = unit_x(axis, b) - unit_x(axis, a)
        ours = (b["clrender"]["user_frame_ms"] - a["clrender"]["user_frame_ms"]) / dx
        line = f"  {a['x']} -> {b['x']}: clrender {ours:9.2f}"
        if "user_frame_ms" in a.get("opengl", {}) and "user_frame_ms" in b.get("opengl", {}):
            line += f"   OpenGL {(b['opengl']['user_frame_ms'] - a['opengl']['user_frame_ms']) / dx:9.2f}"
        print(line)


def save_plot(record, path) -> None:
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("matplotlib not importable: no plot (pip install matplotlib)")
        return
    axes = list(record["axes"])
    fig, subplots = plt.subplots(1, len(axes), figsize=(5 * len(axes), 4.2), squeeze=False)
    labels = {"resolution": "pixels (millions)", "triangles": "triangles (millions)", "lights": "point lights",
              "instances": "triangles (millions), copies on a grid"}
    for ax, axis in zip(subplots[0], axes):
        entries = [e for e in record["axes"][axis] if "user_frame_ms" in e["clrender"]]
        xs = [unit_x(axis, e) / (1e-3 if axis == "lights" else 1) for e in entries]
        ax.plot(xs, [e["clrender"]["user_frame_ms"] for e in entries], "o-", label="clrender: render() + colour, depth")
        ax.plot(xs, [e["clrender"]["passes_ms"] for e in entries], "o--", alpha=0.6, label="clrender: pass sum")
        gl = [e.get("opengl", {}).get("user_frame_ms") for e in entries]
        if all(g is not None for g in gl):
            ax.plot(xs, gl, "s-", label="OpenGL llvmpipe: frame + readback")
        if axis == "lights":
            ax.set_xscale("symlog", linthresh=256)
        ax.set_yscale("log")
        ax.set_xlabel(labels[axis])
        ax.set_ylabel("ms per frame")
        ax.set_title(f"Sponza, {axis}")
        ax.grid(True, which="both", alpha=0.3)
    subplots[0][0].legend(fontsize=8)
    fig.suptitle(f"clrender vs OpenGL (llvmpipe), same machine, same run ({time.strftime('%Y-%m-%d')})", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    print(f"plot: {path}")


if __name__ == "__main__":
    sys.exit(main())
