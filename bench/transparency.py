"""Transparency benchmark: Crytek Sponza at 1280×720 with see-through curtains and a cloud of
2,000 transparent camera-facing quads, 64 point lights, shadows off.

    python -m bench.transparency [--width 1280] [--height 720] [--repeats 3] [--warmup 1]
                                 [--device NAME] [--no-gl] [--picture] [--picture-only]
                                 [--particles 2000] [--lights 64] [--seed 1]

The scene: every material whose name contains "curtain" or "fabric" (case-insensitive; in
Crytek Sponza the six Fabric* materials, the ground-floor hangings and the upper-floor drapes)
becomes ``alpha_mode="BLEND"`` with ``opacity=0.5``; ``--particles`` quads of ``--particle-size``
world units, facing the benchmark camera's eye, seeded-random in the atrium, are appended to the
scene's arrays with four new double-sided BLEND materials (four colours, alpha 0.3–0.6); 64
point lights from ``scene.add_random_lights(64, seed, radius=0.05 × bounds diagonal)``. The camera
is the fixed atrium camera every Sponza benchmark uses (bench.common.SPONZA_CAMERA).

Measured with ``clrender.Renderer(width, height, transparency=..., shadows=False)``, medians of
``--repeats`` frames after ``--warmup`` ones:

* ``opaque``: the same scene with everything opaque (original materials, the quads OPAQUE);
* ``abuffer``, ``peel4`` / ``peel8`` (``depth_peeling`` with ``peel_layers`` 4 / 8), ``screen_door``;

interleaved by default (all renderers built; after the warm-up, each round renders one frame
of every configuration, so load from other processes on a shared machine falls on all alike;
``--sequential`` measures one configuration after the other as bench.common.time_renders does);

for each: the wall time of ``render()`` (incl. readback), ``stats["total_ms"]`` (the sum of the
passes' OpenCL profiling events), every ``*_ms`` pass, and (A-buffer, peeling) the mean and max
of ``Frame.fragment_count``. Then the OpenGL peer (bench/gl_transparency.py: GLLightsPeer's
deferred opaque frame + classic depth peeling with the same lights, on Mesa llvmpipe) with 4
and 8 layers: median frame time incl. glFinish and readback of the colour. Prints the ratios
the transparency issue targets -- A-buffer / opaque frame (target <= 1.5) and depth peeling 8 /
A-buffer (target >= 4; the report claims 8) -- and writes bench/results/transparency-*.json.

``--picture`` also writes docs/images/transparency.png: the A-buffer render, the screen-door
render and the A-buffer's fragments per pixel, side by side (panels of --picture-width ×
--picture-height, rendered at that size), from a camera in the atrium looking at the curtains.
"""
from __future__ import annotations

import argparse
import dataclasses
import statistics
import sys
import time
from pathlib import Path

import numpy as np

from clrender.render.pipeline import pass_ms

from bench.common import REPO, SPONZA, SPONZA_CAMERA, medians, require_scene, time_renders, write_record

PASS_ORDER = ("setup", "binning", "raster", "gbuffer", "particles", "fragments", "light_cull", "ssao", "ssao_blur",
              "shadow", "shade", "abuffer", "peel", "composite", "tonemap")       # clrender/render/pipeline.py order
TRANSPARENT_WORDS = ("curtain", "fabric")
CURTAIN_OPACITY = 0.5
# The atrium's open volume between the two rows of columns (world units): where the quads go.
ATRIUM = ((-12.0, 4.6, -3.0), (10.0, 13.0, 1.4))
PARTICLE_COLORS = (            # linear RGB, alpha
    ("particle_amber", (1.00, 0.55, 0.12, 0.45)),
    ("particle_cyan", (0.10, 0.75, 1.00, 0.35)),
    ("particle_rose", (1.00, 0.20, 0.45, 0.60)),
    ("particle_lime", (0.45, 1.00, 0.15, 0.30)),
)
# The picture: from the west end of the atrium, turned towards the +z arcade: its green
# curtain (window and bricks behind it) on the right, the red one on the left, the cloud between.
PICTURE_CAMERA = dict(eye=(-15.0, 6.0, -1.5), target=(0.0, 6.0, 2.6), up=(0, 1, 0), fov_y_deg=60.0,
                      near=0.1, far=100.0)
CONFIGS = (            # name, Renderer options, scene variant
    ("opaque", dict(transparency="abuffer"), "opaque"),
    ("abuffer", dict(transparency="abuffer"), "transparent"),
    ("peel4", dict(transparency="depth_peeling", peel_layers=4), "transparent"),
    ("peel8", dict(transparency="depth_peeling", peel_layers=8), "transparent"),
    ("screen_door", dict(transparency="screen_door"), "transparent"),
)


def pass_keys(stats: dict) -> list[str]:
    """The ``*_ms`` keys of a stats dict (total left out), known passes in pipeline order first."""
    keys = list(pass_ms(stats))
    order = {f"{p}_ms": i for i, p in enumerate(PASS_ORDER)}
    return sorted(keys, key=lambda k: (order.get(k, len(order)), k))


# -- scene ---------------------------------------------------------------------------------------
def particle_quads(n: int, seed: int, eye, size: float, box=ATRIUM):
    """``n`` squares of side ``size`` centred at seeded-random points of ``box``, each facing
    ``eye`` (front face, CCW, towards it). Returns positions (4n, 3), normals, uvs, triangles
    (2n, 3) local to these vertices, and the colour index (0..len(PARTICLE_COLORS)-1) per quad."""
    rng = np.random.default_rng(seed)
    lo, hi = (np.asarray(b, np.float64) for b in box)
    centres = rng.uniform(lo, hi, (n, 3))
    colour = rng.integers(0, len(PARTICLE_COLORS), n)
    nrm = np.asarray(eye, np.float64) - centres
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    right = np.cross((0.0, 1.0, 0.0), nrm)
    bad = np.linalg.norm(right, axis=1) < 1e-6
    right[bad] = np.cross((1.0, 0.0, 0.0), nrm[bad])
    right /= np.linalg.norm(right, axis=1, keepdims=True)
    up = np.cross(nrm, right)
    h = size / 2
    corners = ((-1, -1), (1, -1), (1, 1), (-1, 1))            # CCW seen from +normal
    pos = np.stack([centres + h * (sx * right + sy * up) for sx, sy in corners], 1).reshape(-1, 3)
    normals = np.repeat(nrm, 4, axis=0)
    uvs = np.tile(np.array([(0, 1), (1, 1), (1, 0), (0, 0)], np.float64), (n, 1))
    base = 4 * np.arange(n)[:, None]
    tris = np.concatenate([base + (0, 1, 2), base + (0, 2, 3)], 1).reshape(-1, 3)
    return pos, normals, uvs, tris, colour


def build_scene(base, *, transparent: bool, eye, n_particles: int, particle_size: float, seed: int):
    """A new Scene: ``base`` (lights included) with its curtains/fabrics BLEND at opacity 0.5 and
    the particle quads BLEND (``transparent``), or everything OPAQUE (curtains as loaded, quads
    OPAQUE with the same colours). Returns (scene, names of the switched materials)."""
    from clrender.scene.model import Material
    materials, switched = [], []
    for m in base.materials:
        if any(w in m.name.lower() for w in TRANSPARENT_WORDS):
            switched.append(m.name)
            if transparent:
                m = dataclasses.replace(m, alpha_mode="BLEND", opacity=CURTAIN_OPACITY)
        materials.append(m)
    first_mat = len(materials)
    for name, rgba in PARTICLE_COLORS:
        materials.append(Material(name=name, base_color=rgba if transparent else rgba[:3] + (1.0,),
                                  specular_intensity=0.1, specular_power=16.0, double_sided=True,
                                  alpha_mode="BLEND" if transparent else "OPAQUE"))
    pos, nrm, uv, tri, colour = particle_quads(n_particles, seed, eye, particle_size)
    v0 = len(base.positions)
    n_tri = 2 * n_particles
    scene = dataclasses.replace(
        base,
        positions=np.concatenate([base.positions, pos.astype(np.float32)]),
        normals=np.concatenate([base.normals, nrm.astype(np.float32)]),
        uvs=np.concatenate([base.uvs, uv.astype(np.float32)]),
        triangles=np.concatenate([base.triangles, (tri + v0).astype(np.int32)]),
        triangle_material=np.concatenate([base.triangle_material,
                                          (first_mat + np.repeat(colour, 2)).astype(np.int32)]),
        materials=materials,
        mesh_names=list(base.mesh_names) + ["particle_cloud"],
        triangle_mesh=np.concatenate([base.triangle_mesh, np.full(n_tri, len(base.mesh_names), np.int32)]),
        triangle_face=np.concatenate([base.triangle_face, np.arange(n_tri, dtype=np.int32)]),
        lights=base.lights.copy(),
        particle_systems=list(base.particle_systems))
    return scene, switched


def load_base(args):
    """Sponza with ``--lights`` seeded random point lights (radius 0.05 of the bounds diagonal)."""
    import clrender
    t0 = time.perf_counter()
    base = clrender.load_scene(require_scene(SPONZA))
    load_s = time.perf_counter() - t0
    lo, hi = base.bounds().astype(np.float64)
    radius = args.radius_frac * float(np.linalg.norm(hi - lo))
    base.add_random_lights(args.lights, seed=args.seed, radius=(radius, radius), intensity=args.intensity)
    return base, load_s, radius


# -- measuring -----------------------------------------------------------------------------------
def fragment_stats(frame) -> dict:
    fc = np.asarray(frame.fragment_count)
    covered = fc > 0
    return {"mean": float(fc.mean()), "max": int(fc.max()) if fc.size else 0,
            "mean_covered": float(fc[covered].mean()) if covered.any() else 0.0,
            "covered_frac": float(covered.mean()), "total": int(fc.sum()),
            "p99": float(np.percentile(fc, 99)) if fc.size else 0.0,
            "transmittance_mean": float(np.mean(frame.transmittance))}


def run_clrender(args, scenes, camera, record) -> dict:
    """Every configuration's median frame. By default the configurations are interleaved: all
    renderers are built, each renders ``warmup`` frames, then ``repeats`` rounds render one frame
    of each in turn, so that load from other processes on the machine falls on all of them alike.
    ``--sequential`` times one configuration after the other (bench.common.time_renders)."""
    import clrender
    configs = [c for c in CONFIGS if not args.only or c[0] in args.only]
    samples = {name: ([], []) for name, _, _ in configs}
    frames, elapsed = {}, {}
    if args.sequential:
        for name, opts, variant in configs:
            r = clrender.Renderer(args.width, args.height, device=args.device, shadows=False, **opts)
            record.setdefault("device", r.device.name)
            t0 = time.perf_counter()
            stats, walls, frames[name] = time_renders(r, scenes[variant], camera, args.warmup, args.repeats)
            samples[name] = (stats, walls)
            elapsed[name] = time.perf_counter() - t0
            del r
    else:
        renderers = {name: clrender.Renderer(args.width, args.height, device=args.device, shadows=False, **opts)
                     for name, opts, _ in configs}
        record.setdefault("device", next(iter(renderers.values())).device.name)
        for name, _, variant in configs:
            t0 = time.perf_counter()
            for _ in range(args.warmup):
                frames[name] = renderers[name].render(scenes[variant], camera)
            elapsed[name] = time.perf_counter() - t0
        for _ in range(args.repeats):
            for name, _, variant in configs:
                t0 = time.perf_counter()
                frame = renderers[name].render(scenes[variant], camera)
                wall = (time.perf_counter() - t0) * 1e3
                samples[name][0].append(frame.stats)
                samples[name][1].append(wall)
                frames[name] = frame
                elapsed[name] += wall / 1e3
    for name, opts, variant in configs:
        stats, walls = samples[name]
        med = medians(stats)
        entry = {"options": opts, "scene": variant, "median": med, "wall_ms_median": statistics.median(walls),
                 "frames_ms": [s["total_ms"] for s in stats], "walls_ms": walls, "elapsed_s": elapsed[name]}
        if name in ("abuffer", "peel4", "peel8"):
            entry["fragments"] = fragment_stats(frames[name])
        record["clrender"][name] = entry
        line = (f"  {name:<12} wall {entry['wall_ms_median']:9.1f} ms   total {med['total_ms']:9.1f} ms")
        if "fragments" in entry:
            line += f"   fragments/pixel mean {entry['fragments']['mean']:.2f} max {entry['fragments']['max']}"
        print(line, flush=True)
    return frames


def run_gl(args, scene, camera, record, frames) -> None:
    try:
        from bench.gl_transparency import GLTransparencyPeer, split_scene
        peer = GLTransparencyPeer(args.width, args.height, peel_layers=4)
    except Exception as exc:                   # no EGL / moderngl: say so, keep the clrender numbers
        print(f"OpenGL peer unavailable: {exc}")
        record["opengl_error"] = str(exc)
        return
    peer.upload(scene)
    info = peer.info()
    record["opengl"] = {"info": info}
    print(f"\nOpenGL depth-peeling peer ({peer.renderer}): {info['triangles']:,} opaque + "
          f"{info['transparent_triangles']:,} transparent triangles, {info['forward_lights']} lights", flush=True)
    opaque = peer.time_frame_opaque_only(camera, repeats=args.repeats, warmup=args.warmup)
    record["opengl"]["opaque_only_ms"] = statistics.median(opaque)
    print(f"  {'opaque pass':<12} {statistics.median(opaque):9.1f} ms (G-buffer + lights + combine + glFinish)")
    fc = peer.fragment_count(camera)
    record["opengl"]["fragments"] = {"mean": float(fc.mean()), "max": int(fc.max())}
    if "abuffer" in frames:
        ours = frames["abuffer"].fragment_count
        record["opengl"]["fragments"]["equal_to_clrender_frac"] = float(np.mean(fc == ours))
    opaque_keep = np.flatnonzero(~np.isin(np.arange(scene.triangle_count), split_scene(scene)[1]))
    for layers in args.gl_layers:
        peer.peel_layers = int(layers)
        times = peer.time_frame(camera, repeats=args.repeats, warmup=args.warmup)
        entry = {"peel_layers": layers, "median_ms": statistics.median(times), "frames_ms": times}
        ours = frames.get(f"peel{layers}")
        if ours is not None:
            gl = peer.render(camera)
            tid = np.where(gl["triangle_id"] >= 0, opaque_keep[np.maximum(gl["triangle_id"], 0)], -1)
            same = (tid >= 0) & (tid == ours.triangle_id)
            entry["color_agreement"] = psnr(ours.color, gl["color"], same)
            entry["clrender_over_opengl"] = record["clrender"][f"peel{layers}"]["median"]["total_ms"] / entry["median_ms"]
        record["opengl"][f"peel{layers}"] = entry
        line = f"  {f'peel{layers}':<12} {entry['median_ms']:9.1f} ms (opaque + {layers} peels + composite + glFinish + readback)"
        if "color_agreement" in entry:
            line += f"; colour PSNR vs clrender peel{layers} {entry['color_agreement']['psnr_db']:.1f} dB"
        print(line, flush=True)
    peer.release()


def psnr(ours, theirs, mask) -> dict:
    a = np.asarray(ours, np.float64)[mask]
    b = np.asarray(theirs, np.float64)[mask]
    if not len(b):
        return {"psnr_db": float("nan"), "pixels": 0}
    peak, mse = float(b.max()), float(np.mean((a - b) ** 2))
    value = float("inf") if mse == 0 else (float(10 * np.log10(peak ** 2 / mse)) if peak > 0 else float("nan"))
    return {"psnr_db": value, "peak": peak, "mse": mse, "pixels": int(mask.sum()),
            "mean_abs_diff": float(np.mean(np.abs(a - b)))}


def print_tables(record) -> None:
    cl = record["clrender"]
    if not cl:
        return
    names = list(cl)
    passes = []
    for n in names:
        for k in pass_keys(cl[n]["median"]):
            if k not in passes:
                passes.append(k)
    order = {f"{p}_ms": i for i, p in enumerate(PASS_ORDER)}
    passes.sort(key=lambda k: (order.get(k, len(order)), k))
    print(f"\nclrender on {record.get('device', '?')}, median of {record['repeats']} frames after "
          f"{record['warmup']} warm-up (ms; passes from OpenCL profiling events):")
    print(f"  {'':<16}" + "".join(f"{n:>12}" for n in names))
    for k in passes:
        print(f"  {k[:-3]:<16}" + "".join(
            f"{cl[n]['median'][k]:12.1f}" if k in cl[n]["median"] else f"{'-':>12}" for n in names))
    print(f"  {'total':<16}" + "".join(f"{cl[n]['median']['total_ms']:12.1f}" for n in names))
    print(f"  {'wall (render())':<16}" + "".join(f"{cl[n]['wall_ms_median']:12.1f}" for n in names))
    print(f"  {'frags/px mean':<16}" + "".join(
        f"{cl[n]['fragments']['mean']:12.2f}" if "fragments" in cl[n] else f"{'-':>12}" for n in names))
    print(f"  {'frags/px max':<16}" + "".join(
        f"{cl[n]['fragments']['max']:12d}" if "fragments" in cl[n] else f"{'-':>12}" for n in names))


def ratios(record) -> dict:
    cl, out = record["clrender"], {}
    for key, num, den, target in (("abuffer_over_opaque", "abuffer", "opaque", "<= 1.5"),
                                  ("peel8_over_abuffer", "peel8", "abuffer", ">= 4 (report: 8)"),
                                  ("peel4_over_abuffer", "peel4", "abuffer", None),
                                  ("screen_door_over_opaque", "screen_door", "opaque", None)):
        if num in cl and den in cl:
            out[key] = {"total_ms": cl[num]["median"]["total_ms"] / cl[den]["median"]["total_ms"],
                        "wall_ms": cl[num]["wall_ms_median"] / cl[den]["wall_ms_median"], "target": target}
    gl = record.get("opengl", {})
    if "peel8" in gl and "abuffer" in cl:
        out["opengl_peel8_over_clrender_abuffer_wall"] = {
            "wall_ms": gl["peel8"]["median_ms"] / cl["abuffer"]["wall_ms_median"], "target": None}
    return out


# -- picture -------------------------------------------------------------------------------------
def heat_map(count: np.ndarray, vmax: int) -> np.ndarray:
    """Fragments per pixel -> RGB uint8 (0 black, then a magma-like ramp up to vmax)."""
    stops = np.array([(0, 0, 0), (40, 11, 84), (140, 41, 129), (222, 73, 104), (254, 159, 109), (252, 253, 191)],
                     np.float64)
    t = np.clip(np.asarray(count, np.float64) / max(vmax, 1), 0.0, 1.0) * (len(stops) - 1)
    i = np.minimum(t.astype(int), len(stops) - 2)
    f = (t - i)[..., None]
    return np.rint(stops[i] * (1 - f) + stops[i + 1] * f).astype(np.uint8)


def label(img: np.ndarray, text: str) -> np.ndarray:
    try:
        from PIL import Image, ImageDraw
    except ImportError:
        return img
    from PIL import ImageFont
    try:
        font = ImageFont.load_default(size=15)         # Pillow >= 10.1: a scalable default font
    except TypeError:
        font = ImageFont.load_default()
    im = Image.fromarray(img)
    d = ImageDraw.Draw(im)
    box = d.textbbox((8, 6), text, font=font)
    d.rectangle((4, 4, box[2] + 4, box[3] + 4), fill=(0, 0, 0))
    d.text((8, 6), text, fill=(255, 255, 255), font=font)
    return np.asarray(im)


def make_picture(args, base) -> Path:
    import clrender
    import imageio.v3 as iio
    cam_args = dict(PICTURE_CAMERA)
    camera = clrender.Camera.look_at(**cam_args)
    scene, _ = build_scene(base, transparent=True, eye=cam_args["eye"], n_particles=args.particles,
                           particle_size=args.particle_size, seed=args.seed)
    scene.ambient = args.picture_ambient
    w, h = args.picture_width, args.picture_height
    panels = []
    ab = clrender.Renderer(w, h, device=args.device, shadows=False, transparency="abuffer",
                           exposure=args.picture_exposure).render(scene, camera)
    sd = clrender.Renderer(w, h, device=args.device, shadows=False, transparency="screen_door",
                           exposure=args.picture_exposure).render(scene, camera)
    vmax = max(int(np.percentile(ab.fragment_count, 99.9)), 1)
    panels.append(label(ab.image, "A-buffer"))
    panels.append(label(sd.image, "screen door (4x4 dither)"))
    panels.append(label(heat_map(ab.fragment_count, vmax),
                        f"A-buffer fragments/pixel (black 0 .. white >= {vmax}, max {int(ab.fragment_count.max())})"))
    img = np.concatenate(panels, 1)
    pic = Path(args.picture_path)
    pic.parent.mkdir(parents=True, exist_ok=True)
    iio.imwrite(pic, img)
    print(f"picture: {pic} ({pic.stat().st_size / 1e6:.2f} MB, {img.shape[1]}x{img.shape[0]}; camera {cam_args}; "
          f"fragments/pixel mean {ab.fragment_count.mean():.2f} max {int(ab.fragment_count.max())})")
    return pic


# -- main ----------------------------------------------------------------------------------------
def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--width", type=int, default=1280)
    ap.add_argument("--height", type=int, default=720)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--warmup", type=int, default=1)
    ap.add_argument("--device", default=None)
    ap.add_argument("--no-gl", action="store_true", help="skip the OpenGL depth-peeling peer")
    ap.add_argument("--gl-layers", type=int, nargs="+", default=[4, 8])
    ap.add_argument("--sequential", action="store_true",
                    help="time the clrender configurations one after the other instead of interleaved")
    ap.add_argument("--only", nargs="+", choices=[c[0] for c in CONFIGS], default=None,
                    help="measure only these clrender configurations")
    ap.add_argument("--particles", type=int, default=2000)
    ap.add_argument("--particle-size", type=float, default=0.3)
    ap.add_argument("--lights", type=int, default=64)
    ap.add_argument("--radius-frac", type=float, default=0.05,
                    help="light radius as a fraction of the scene's bounds diagonal")
    ap.add_argument("--intensity", type=float, default=1.0)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--picture", action="store_true", help="also write docs/images/transparency.png")
    ap.add_argument("--picture-only", action="store_true", help="write the picture, measure nothing")
    ap.add_argument("--picture-path", default=str(REPO / "docs" / "images" / "transparency.png"))
    ap.add_argument("--picture-width", type=int, default=640)
    ap.add_argument("--picture-height", type=int, default=360)
    ap.add_argument("--picture-ambient", type=float, default=0.25)
    ap.add_argument("--picture-exposure", type=float, default=1.0)
    args = ap.parse_args(argv)

    if not SPONZA.is_file():
        print(f"skipping: benchmark scene not found: {SPONZA} (the shared scenes live in ../shared/scenes "
              f"next to the repository)")
        return 0
    import clrender
    base, load_s, radius = load_base(args)
    if args.picture_only:
        make_picture(args, base)
        return 0
    camera = clrender.Camera.look_at(**SPONZA_CAMERA)
    scenes, switched = {}, []
    for variant in ("opaque", "transparent"):
        scenes[variant], switched = build_scene(base, transparent=variant == "transparent",
                                                eye=SPONZA_CAMERA["eye"], n_particles=args.particles,
                                                particle_size=args.particle_size, seed=args.seed)
    tr = scenes["transparent"]
    n_blend = int(np.isin(tr.triangle_material,
                          [i for i, m in enumerate(tr.materials) if m.alpha_mode == "BLEND"]).sum())
    print(f"Sponza: {base.triangle_count:,} triangles, loaded in {load_s:.1f} s; {args.width}x{args.height}")
    print(f"transparent: {', '.join(switched)} (BLEND, opacity {CURTAIN_OPACITY}) + {args.particles:,} quads of "
          f"{args.particle_size:g} (BLEND, alpha {min(c[1][3] for c in PARTICLE_COLORS):g}-"
          f"{max(c[1][3] for c in PARTICLE_COLORS):g}): {n_blend:,} of {tr.triangle_count:,} triangles")
    print(f"lights: {args.lights} random point lights (seed {args.seed}, radius {radius:.2f}), ambient "
          f"{base.ambient:g}, shadows off", flush=True)

    import os
    record = {"scene": SPONZA.name, "interleaved": not args.sequential,
              "load_average_before": list(os.getloadavg()), "width": args.width, "height": args.height, "repeats": args.repeats,
              "warmup": args.warmup, "seed": args.seed, "lights": args.lights, "light_radius": radius,
              "intensity": args.intensity, "ambient": base.ambient, "camera": SPONZA_CAMERA,
              "switched_materials": switched, "curtain_opacity": CURTAIN_OPACITY,
              "particles": {"count": args.particles, "size": args.particle_size, "box": ATRIUM,
                            "materials": {n: c for n, c in PARTICLE_COLORS}},
              "triangles": tr.triangle_count, "transparent_triangles": n_blend, "clrender": {}}
    print("\nclrender:")
    frames = run_clrender(args, scenes, camera, record)
    if not args.no_gl:
        run_gl(args, tr, camera, record, frames)
    record["load_average_after"] = list(os.getloadavg())
    print_tables(record)
    record["ratios"] = ratios(record)
    if record["ratios"]:
        print("\nratios (median total_ms from profiling events; wall time of render() in brackets):")
        for k, v in record["ratios"].items():
            tgt = f"   target {v['target']}" if v.get("target") else ""
            if "total_ms" in v:
                print(f"  {k:<40} {v['total_ms']:7.2f}  ({v['wall_ms']:.2f}){tgt}")
            else:
                print(f"  {k:<40} wall {v['wall_ms']:7.2f}{tgt}")
    path = write_record("transparency", record)
    print(f"\nrecord: {path}")
    if args.picture:
        make_picture(args, base)
    return 0


if __name__ == "__main__":
    sys.exit(main())
