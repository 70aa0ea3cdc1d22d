"""Scaling curves: clrender and the OpenGL/llvmpipe peer on the same axes, in one run.

    python -m bench.scaling [--axes resolution triangles lights] [--repeats 3] [--warmup 1]
                            [--device NAME] [--no-gl] [--plot docs/images/scaling.png]

Crytek Sponza from the fixed atrium camera (bench/common.py), random point lights made as
bench.lights makes them (seed 1, radius 0.05 of the bounds diagonal). Three axes, the others
held at 1280×720, Sponza ×1 and 256 lights:

* resolution: 640×360, 1280×720, 1920×1080, 2560×1440, 3840×2160;
* triangles: Sponza ×1, ×2, ×4 -- copies of the whole scene at the same place (every copy is
  in view and rasterized, the picture is unchanged: both renderers keep the first of equal
  depths), so every stage handles k times the triangles;
* lights: 0, 256, 1024, 4096, 16384.

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

from bench.common import REPO, SPONZA, SPONZA_CAMERA, medians, require_scene, time_user_frames, write_record

RESOLUTIONS = ((640, 360), (1280, 720), (1920, 1080), (2560, 1440), (3840, 2160))
COPIES = (1, 2, 4)
LIGHTS = (0, 256, 1024, 4096, 16384)
BASE = dict(size=(1280, 720), copies=1, lights=256)
UNITS = {"resolution": ("megapixels", 1e-6), "triangles": ("million triangles", 1e-6),
         "lights": ("thousand lights", 1e-3)}


def replicate(scene, copies: int):
    """`copies` instances of the scene's geometry at the same place (materials and textures shared)."""
    if copies == 1:
        return scene
    import dataclasses
    v, t = len(scene.positions), len(scene.triangles)

    def tile(a):
        return None if a is None else np.concatenate([a] * copies, axis=-2 if a.ndim == 3 else 0)
    return dataclasses.replace(
        scene, positions=tile(scene.positions), normals=tile(scene.normals), uvs=tile(scene.uvs),
        triangles=np.concatenate([scene.triangles + np.int32(k * v) for k in range(copies)]),
        triangle_material=tile(scene.triangle_material), triangle_mesh=tile(scene.triangle_mesh),
        triangle_face=tile(scene.triangle_face), colors=tile(scene.colors), tangents=tile(scene.tangents),
        extra_uvs=tile(scene.extra_uvs), previous_positions=None, animation=None) if t else scene


def points(axes) -> list[tuple[str, float, dict]]:
    """(axis, x, setting) for every measurement; the shared base point is measured once per axis."""
    out = []
    for axis in axes:
        if axis == "resolution":
            out += [(axis, w * h, dict(BASE, size=(w, h))) for w, h in RESOLUTIONS]
        elif axis == "triangles":
            out += [(axis, k, dict(BASE, copies=k)) for k in COPIES]
        else:
            out += [(axis, n, dict(BASE, lights=n)) for n in LIGHTS]
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--axes", nargs="+", choices=("resolution", "triangles", "lights"),
                    default=["resolution", "triangles", "lights"])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--warmup", type=int, default=1)
    ap.add_argument("--device", default=None)
    ap.add_argument("--no-gl", action="store_true", help="skip the OpenGL peer")
    ap.add_argument("--plot", default=str(REPO / "docs" / "images" / "scaling.png"))
    args = ap.parse_args(argv)

    import clrender
    base = clrender.load_scene(require_scene(SPONZA))
    camera = clrender.Camera.look_at(**SPONZA_CAMERA)
    lo, hi = base.bounds().astype(np.float64)
    radius = 0.05 * float(np.linalg.norm(hi - lo))
    light_sets = {}
    for n in sorted({s["lights"] for _, _, s in points(args.axes)}):
        base.lights = base.lights[:0].copy()
        base.add_random_lights(n, seed=1, radius=(radius, radius), intensity=1.0)
        light_sets[n] = base.lights.copy()
    scenes = {k: replicate(base, k) for k in sorted({s["copies"] for _, _, s in points(args.axes)})}

    record = {"scene": SPONZA.name, "repeats": args.repeats, "warmup": args.warmup, "base": BASE,
              "light_radius": radius, "axes": {a: [] for a in args.axes}}
    renderers, peers = {}, {}
    for axis, x, setting in points(args.axes):
        size, scene = setting["size"], scenes[setting["copies"]]
        scene.lights = light_sets[setting["lights"]]
        if size not in renderers:
            renderers.clear()                    # one resolution's buffers at a time
            renderers[size] = clrender.Renderer(*size, device=args.device)
        r = renderers[size]
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
    record["device"] = next(iter(renderers.values())).device.name if renderers else None
    for axis in args.axes:
        print_growth(axis, record["axes"][axis])
    path = write_record("scaling", record)
    print(f"\nrecord: {path}")
    save_plot(record, args.plot)
    return 0


def peer_point(peers, size, scene, camera, args) -> dict:
    """The peer's frame with colour and depth read back, or why there is none."""
    try:
        from bench.gl_lights import GLLightsPeer
        key = (size, id(scene))
        if key not in peers:
            for p in peers.values():
                p.release()
            peers.clear()
            peers[key] = GLLightsPeer(*size)
            peers[key].upload(scene)
        peer = peers[key]
        peer.set_lights(scene.lights, scene.ambient)
        times = peer.time_frame_readback(camera, repeats=args.repeats, warmup=args.warmup)
        return {"user_frame_ms": statistics.median(times), "frames_ms": times, "renderer": peer.renderer}
    except Exception as exc:                      # no EGL / moderngl: keep clrender's numbers
        print(f"OpenGL peer unavailable: {exc}")
        args.no_gl = True
        return {"error": str(exc)}


def unit_x(axis, entry) -> float:
    """The axis value in the unit the growth table uses."""
    if axis == "resolution":
        return entry["x"] * UNITS[axis][1]
    if axis == "triangles":
        return entry["triangles"] * UNITS[axis][1]
    return entry["x"] * UNITS[axis][1]


def print_growth(axis, entries) -> None:
    """ms added per unit between consecutive points: where each renderer's cost grows."""
    unit = UNITS[axis][0]
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
    labels = {"resolution": "pixels (millions)", "triangles": "triangles (millions)", "lights": "point lights"}
    for ax, axis in zip(subplots[0], axes):
        entries = record["axes"][axis]
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
