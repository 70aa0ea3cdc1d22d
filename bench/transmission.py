"""See-through materials (issue 38): what transmission costs per pass and per user frame, per
transparency mode, and that a scene without it costs what it did.

    python -m bench.transmission [--width 1280] [--height 720] [--frames 7] [--warmup 2] [--lights 64]
                                 [--spheres 24] [--sphere-detail 24] [--peel-layers 8] [--device NAME]
                                 [--baseline DIR] [--quick]

Crytek Sponza (../shared/scenes, as every Sponza benchmark: bench.common.SPONZA) from the fixed atrium
camera with ``--lights`` seeded point lights made as bench.materials makes them (seed 1, radius 0.05 of
the bounds diagonal), the renderer's defaults otherwise. The glass: ``--spheres`` UV spheres of radius
``--radius`` (4·detail² triangles each: 24 spheres of detail 24 are 55,296 transmissive triangles),
seeded-random in the atrium in front of the camera, cycling through five transmissive materials
(GLASSES: clear volume, tinted volume with attenuation, frosted, dispersive, thin-walled).

Versions, rendered in one process and interleaved frame by frame (the order reversed every other
round, so drift of a shared machine falls on all alike):

* ``plain``: Sponza as loaded (no transmissive material), default Renderer (A-buffer);
* ``spheres_opaque``: plain + the spheres with transmission 0 (the same geometry drawn opaque: what
  the glass costs beyond its triangles);
* ``spheres_blend``: the spheres with transmission 0, alpha BLEND at opacity 0.5, A-buffer (the
  transparency of before issue 38: what transmission adds to alpha blending);
* ``abuffer``, ``depth_peeling`` (``--peel-layers``), ``screen_door``: plain + the glass spheres;
* ``before`` (with ``--baseline DIR``): the plain scene through another source tree's clrender (e.g.
  the commit before the change: ``git archive HEAD | tar -x -C DIR``) in a worker process (public API
  only), interleaved with the others; it also hashes its colour so that "plain renders bit for bit
  what before rendered" is checked, not only timed.

Per version: medians over ``--frames`` frames after ``--warmup`` of every pass's device ms (the
``*_ms`` of Frame.stats, OpenCL profiling events), their total, render()'s wall time and the user frame
(render() then Frame.color and Frame.depth read to numpy), the user frame's IQR (the noise band), and
for the glass versions the fragments per pixel. Writes bench/results/transmission-*.json.

``--quick``: 320x180, 1 warm-up and 2 frames, 8 spheres of detail 12 (a smoke run, not a measurement).
"""
from __future__ import annotations

import argparse
import dataclasses
import hashlib
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from clrender.render.stats import pass_ms

from bench.common import REPO, SPONZA, SPONZA_CAMERA, host_medians, medians, require_scene, write_record

# The atrium's open volume in front of the atrium camera (world units): where the spheres go.
GLASS_BOX = ((-12.5, 1.0, -3.2), (0.0, 8.5, 1.8))
GLASSES = (           # name, Material fields (thickness in units of the sphere's diameter)
    ("glass_clear", dict(base_color=(1.0, 1.0, 1.0, 1.0), roughness=0.0, thickness=1.0)),
    ("glass_tinted", dict(base_color=(1.0, 1.0, 1.0, 1.0), roughness=0.05, thickness=1.0,
                          attenuation_color=(0.95, 0.45, 0.15), attenuation_distance=0.6)),
    ("glass_frosted", dict(base_color=(0.9, 0.95, 1.0, 1.0), roughness=0.35, thickness=1.0)),
    ("glass_dispersive", dict(base_color=(1.0, 1.0, 1.0, 1.0), roughness=0.0, thickness=1.0, dispersion=1.0)),
    ("glass_thin", dict(base_color=(0.75, 0.9, 1.0, 1.0), roughness=0.1, thickness=0.0)),
)
BLEND_OPACITY = 0.5
MODES = (("abuffer", dict(transparency="abuffer")), ("depth_peeling", dict(transparency="depth_peeling")),
         ("screen_door", dict(transparency="screen_door")))
PASS_ORDER = ("setup", "binning", "raster", "gbuffer", "particles", "fragments", "light_cull", "ibl", "ssao",
              "ssao_blur", "shadow", "shade", "surface_layers", "transmission", "abuffer", "peel", "composite",
              "tonemap")
READ = ("color", "depth")


def uv_sphere(detail: int, radius: float, center):
    """(positions, normals, faces) of a UV sphere with detail rings and 2·detail segments (4·detail²
    triangles), counter-clockwise seen from outside."""
    lat = np.linspace(0.0, np.pi, detail + 1)
    lon = np.linspace(0.0, 2 * np.pi, 2 * detail + 1)
    la, lo = np.meshgrid(lat, lon, indexing="ij")
    n = np.stack([np.sin(la) * np.cos(lo), np.cos(la), np.sin(la) * np.sin(lo)], -1).reshape(-1, 3)
    idx = np.arange(n.shape[0]).reshape(detail + 1, 2 * detail + 1)
    a, b, c, d = idx[:-1, :-1], idx[:-1, 1:], idx[1:, :-1], idx[1:, 1:]
    faces = np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3), np.stack([b, d, c], -1).reshape(-1, 3)])
    return n * radius + np.asarray(center, np.float64), n, faces


def glass_materials(radius: float, kind: str = "glass") -> list:
    """GLASSES as Materials (glTF BRDF, IOR 1.5); thickness in world units (the spheres' diameter).
    kind "opaque": the same with transmission 0 (drawn opaque); "blend": transmission 0 and alpha
    BLEND at opacity BLEND_OPACITY (the transparency of before issue 38: blended, not refracted)."""
    from clrender.scene.material import Material
    out = []
    for name, kw in GLASSES:
        kw = dict(kw, thickness=kw["thickness"] * 2 * radius)
        if kind != "glass":
            kw = {k: v for k, v in kw.items() if k in ("base_color", "roughness")}
            if kind == "blend":
                kw.update(alpha_mode="BLEND", opacity=BLEND_OPACITY)
        out.append(Material(name, metallic=0.0, ior=1.5, transmission=1.0 if kind == "glass" else 0.0, **kw))
    return out


def add_meshes(base, meshes, materials, mesh_name: str):
    """A new Scene: ``base`` plus ``meshes`` [(positions, normals, faces, material index into
    ``materials``)], ``materials`` appended to base's, one mesh (``mesh_name``)."""
    first = len(base.materials)
    v0 = len(base.positions)
    pos, nrm, tri, mat, off = [], [], [], [], v0
    for p, n, f, m in meshes:
        pos.append(p)
        nrm.append(n)
        tri.append(f + off)
        mat.append(np.full(len(f), first + m))
        off += len(p)
    pos, nrm = np.concatenate(pos).astype(np.float32), np.concatenate(nrm).astype(np.float32)
    tri, mat = np.concatenate(tri).astype(np.int32), np.concatenate(mat).astype(np.int32)
    extra = {}
    if base.colors is not None:
        extra["colors"] = np.concatenate([base.colors, np.ones((len(pos), 4), np.float32)])
    if base.tangents is not None:
        t = np.zeros((len(pos), 4), np.float32)
        t[:, 0], t[:, 3] = 1.0, 1.0
        extra["tangents"] = np.concatenate([base.tangents, t])
    if base.extra_uvs is not None:
        extra["extra_uvs"] = np.concatenate([base.extra_uvs, np.zeros((base.extra_uvs.shape[0], len(pos), 2),
                                                                      np.float32)], 1)
    n_tri = len(tri)
    scene = dataclasses.replace(
        base, positions=np.concatenate([base.positions, pos]), normals=np.concatenate([base.normals, nrm]),
        uvs=np.concatenate([base.uvs, np.zeros((len(pos), 2), np.float32)]),
        triangles=np.concatenate([base.triangles, tri]),
        triangle_material=np.concatenate([base.triangle_material, mat]),
        materials=list(base.materials) + list(materials), mesh_names=list(base.mesh_names) + [mesh_name],
        triangle_mesh=np.concatenate([base.triangle_mesh, np.full(n_tri, len(base.mesh_names), np.int32)]),
        triangle_face=np.concatenate([base.triangle_face, np.arange(n_tri, dtype=np.int32)]),
        lights=base.lights.copy(), particle_systems=list(base.particle_systems), objects=list(base.objects),
        mesh_object=base.mesh_object.copy(),
        **extra)
    return scene


def glass_scene(base, n: int, detail: int, radius: float, seed: int, kind: str = "glass"):
    """``base`` plus ``n`` spheres at seeded-random points of GLASS_BOX, cycling through GLASSES
    (glass_materials' `kind`)."""
    rng = np.random.default_rng(seed)
    lo, hi = (np.asarray(b, np.float64) for b in GLASS_BOX)
    centres = rng.uniform(lo, hi, (n, 3))
    meshes = [(*uv_sphere(detail, radius, c), k % len(GLASSES)) for k, c in enumerate(centres)]
    return add_meshes(base, meshes, glass_materials(radius, kind), "glass_spheres")


# -- the `before` version: another tree's clrender in a worker process (public API only) -----------
BASELINE_WORKER = r"""
import hashlib, json, sys, time
import numpy as np
import clrender
a = json.loads(sys.argv[1])
scene = clrender.load_scene(a["path"])
lo, hi = scene.bounds().astype(np.float64)
r = a["radius_frac"] * float(np.linalg.norm(hi - lo))
scene.lights = scene.lights[:0]
scene.add_random_lights(a["lights"], seed=1, radius=(r, r))
camera = clrender.Camera.look_at(**a["camera"])
renderer = clrender.Renderer(a["width"], a["height"], device=a["device"])
print(json.dumps({"device": renderer.device.name, "file": clrender.__file__}), flush=True)
for line in sys.stdin:
    t0 = time.perf_counter()
    frame = renderer.render(scene, camera)
    t1 = time.perf_counter()
    color, _ = frame.color, frame.depth
    t2 = time.perf_counter()
    st = {k: v for k, v in frame.stats.items() if isinstance(v, (int, float)) or k == "host"}
    print(json.dumps({"stats": st, "wall": (t1 - t0) * 1e3, "user": (t2 - t0) * 1e3,
                      "sha1": hashlib.sha1(np.ascontiguousarray(color).tobytes()).hexdigest()}, default=float), flush=True)
"""


class Baseline:
    """The `before` version: BASELINE_WORKER on `tree`'s clrender, one frame per request."""

    def __init__(self, tree: Path, args: dict):
        env = {**os.environ, "PYTHONPATH": str(tree)}       # ahead of the editable install's finder
        self.proc = subprocess.Popen([sys.executable, "-c", BASELINE_WORKER, json.dumps(args)], cwd=str(tree),
                                     env=env, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
        self.info = self._answer()
        self.hashes: list = []
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
        self.hashes.append(a["sha1"])
        return a["stats"], a["wall"], a["user"]

    def close(self) -> None:
        self.proc.stdin.close()
        self.proc.wait(timeout=120)


# -- measuring --------------------------------------------------------------------------------------
def user_frame(renderer, scene, camera, keep: dict, name: str) -> tuple:
    """(Frame.stats, render() wall ms, render() + reading READ ms) of one frame; the frame in keep[name]."""
    t0 = time.perf_counter()
    frame = renderer.render(scene, camera)
    t1 = time.perf_counter()
    for a in READ:
        getattr(frame, a)
    user = (time.perf_counter() - t0) * 1e3
    keep[name] = frame
    return frame.stats, (t1 - t0) * 1e3, user


def interleaved(versions: dict, camera, warmup: int, frames: int, keep: dict) -> dict:
    """versions: name -> (renderer, scene) or a Baseline. Warm-up rounds, then `frames` rounds of one
    user frame per version (order reversed every other round). {name: (stats, walls, users)}."""
    def one(name):
        v = versions[name]
        return v.frame() if isinstance(v, Baseline) else user_frame(*v, camera, keep, name)

    names = list(versions)
    for _ in range(warmup):
        for name in names:
            one(name)
    out = {name: ([], [], []) for name in names}
    for r in range(frames):
        for name in (names if r % 2 == 0 else names[::-1]):
            for acc, x in zip(out[name], one(name)):
                acc.append(x)
    return out


def summarize(stats: list, walls: list, users: list) -> dict:
    q = np.percentile(users, [25, 75]) if len(users) > 1 else (users[0], users[0])
    return {"passes_ms": medians([pass_ms(s) for s in stats]), "total_ms": statistics.median(s["total_ms"] for s in stats),
            "render_wall_ms": statistics.median(walls), "user_frame_ms": statistics.median(users),
            "user_frame_iqr_ms": float(q[1] - q[0]), "user_frames_ms": users, "totals_ms": [s["total_ms"] for s in stats],
            "host_ms": host_medians(stats) if "host" in stats[0] else {}}


def fragments(frame) -> dict:
    fc = np.asarray(frame.fragment_count)
    return {"mean": float(fc.mean()), "max": int(fc.max()), "covered_frac": float((fc > 0).mean()),
            "transmittance_mean": float(np.mean(frame.transmittance))}


def paired(a: dict, b: dict) -> float:
    """Median over rounds of a's user frame / b's of the same round (drift cancels)."""
    return statistics.median(x / y for x, y in zip(a["user_frames_ms"], b["user_frames_ms"]))


def ordered_passes(rows: dict) -> list:
    keys = {k for row in rows.values() for k in row["passes_ms"]}
    order = {f"{p}_ms": i for i, p in enumerate(PASS_ORDER)}
    return sorted(keys, key=lambda k: (order.get(k, len(order)), k))


def print_table(rows: dict) -> None:
    print(f"\n{'median ms':<18}" + "".join(f"{n:>15}" for n in rows))
    for k in ordered_passes(rows):
        print(f"{k[:-3]:<18}" + "".join(f"{rows[n]['passes_ms'][k]:15.2f}" if k in rows[n]["passes_ms"]
                                        else f"{'-':>15}" for n in rows))
    for key, label in (("total_ms", "passes total"), ("render_wall_ms", "render() wall"),
                       ("user_frame_ms", "user frame"), ("user_frame_iqr_ms", "user frame IQR")):
        print(f"{label:<18}" + "".join(f"{rows[n][key]:15.1f}" for n in rows))
    frag = [n for n in rows if "fragments" in rows[n]]
    if frag:
        print(f"{'fragments/px':<18}" + "".join(
            f"{rows[n]['fragments']['mean']:9.2f} ({rows[n]['fragments']['max']:>2})" if n in frag else f"{'-':>15}"
            for n in rows))


def comparisons(rows: dict, new_passes: list) -> dict:
    out = {"plain_runs_new_passes": new_passes}
    for ref in ("spheres_opaque", "spheres_blend"):
        if ref in rows:
            base = rows[ref]
            for mode, _ in MODES:
                if mode in rows:
                    out[f"{mode}_over_{ref}"] = {"total_ms": rows[mode]["total_ms"] / base["total_ms"],
                                                 "user_frame_paired": paired(rows[mode], base)}
    if "before" in rows:
        p, b = rows["plain"], rows["before"]
        diff = p["user_frame_ms"] - b["user_frame_ms"]
        noise = max(p["user_frame_iqr_ms"], b["user_frame_iqr_ms"])
        out.update({"plain_over_before_paired": paired(p, b), "plain_minus_before_user_ms": diff,
                    "plain_minus_before_total_ms": p["total_ms"] - b["total_ms"], "noise_ms": noise,
                    "no_change_within_noise": abs(diff) <= noise})
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--width", type=int, default=1280)
    ap.add_argument("--height", type=int, default=720)
    ap.add_argument("--frames", type=int, default=7, help="timed frames per version (after the warm-up)")
    ap.add_argument("--warmup", type=int, default=2)
    ap.add_argument("--lights", type=int, default=64)
    ap.add_argument("--radius-frac", type=float, default=0.05, help="light radius / the scene's bounds diagonal")
    ap.add_argument("--spheres", type=int, default=24)
    ap.add_argument("--sphere-detail", type=int, default=24, help="rings per sphere (4·detail² triangles each)")
    ap.add_argument("--radius", type=float, default=0.8, help="sphere radius (world units)")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--peel-layers", type=int, default=8)
    ap.add_argument("--modes", nargs="+", choices=[m for m, _ in MODES], default=[m for m, _ in MODES])
    ap.add_argument("--no-opaque-spheres", action="store_true",
                    help="leave out the spheres_opaque and spheres_blend versions")
    ap.add_argument("--device", default=None)
    ap.add_argument("--baseline", type=Path, default=None,
                    help="another source tree (e.g. `git archive HEAD | tar -x -C DIR`): its plain frames as 'before'")
    ap.add_argument("--quick", action="store_true", help="320x180, 1 warm-up, 2 frames, 8 spheres of detail 12")
    args = ap.parse_args(argv)
    if args.quick:
        args.width, args.height, args.warmup, args.frames, args.spheres, args.sphere_detail = 320, 180, 1, 2, 8, 12
    if args.frames < 1 or args.warmup < 0:
        ap.error("--frames must be >= 1 and --warmup >= 0")
    if not SPONZA.is_file():
        print(f"skipping: benchmark scene not found: {SPONZA} (the shared scenes live in ../shared/scenes)")
        return 0

    import clrender
    t0 = time.perf_counter()
    plain = clrender.load_scene(require_scene(SPONZA))
    lo, hi = plain.bounds().astype(np.float64)
    light_radius = args.radius_frac * float(np.linalg.norm(hi - lo))
    plain.lights = plain.lights[:0]
    plain.add_random_lights(args.lights, seed=1, radius=(light_radius, light_radius))     # as bench.materials
    load_s = time.perf_counter() - t0
    glass = glass_scene(plain, args.spheres, args.sphere_detail, args.radius, args.seed)
    n_tx = int(sum(np.count_nonzero(glass.triangle_material == i) for i, m in enumerate(glass.materials)
                   if getattr(m, "transmissive", False)))
    camera = clrender.Camera.look_at(**SPONZA_CAMERA)
    renderers = {"abuffer": clrender.Renderer(args.width, args.height, device=args.device)}   # the defaults
    for mode, opts in MODES:
        if mode != "abuffer" and mode in args.modes:
            extra = {"peel_layers": args.peel_layers} if mode == "depth_peeling" else {}
            renderers[mode] = clrender.Renderer(args.width, args.height, device=args.device, **opts, **extra)
    device = renderers["abuffer"].device.name
    print(f"{device}, {args.width}x{args.height}, median of {args.frames} interleaved frames after {args.warmup} warm-up")
    print(f"Sponza: {plain.triangle_count:,} triangles (loaded in {load_s:.1f} s), {args.lights} point lights "
          f"(radius {light_radius:.3f}); glass: {args.spheres} spheres of radius {args.radius:g}, "
          f"{n_tx:,} transmissive triangles ({', '.join(n for n, _ in GLASSES)})", flush=True)
    if n_tx == 0:
        raise SystemExit("no transmissive triangle in the glass scene (Material.transmissive false): nothing to measure")

    versions: dict = {}
    before = None
    if args.baseline is not None:
        before = Baseline(args.baseline.resolve(), {
            "path": str(SPONZA), "width": args.width, "height": args.height, "device": args.device,
            "radius_frac": args.radius_frac, "lights": args.lights, "camera": SPONZA_CAMERA})
        versions["before"] = before
    versions["plain"] = (renderers["abuffer"], plain)
    if not args.no_opaque_spheres:
        for kind in ("opaque", "blend"):
            versions[f"spheres_{kind}"] = (renderers["abuffer"], glass_scene(plain, args.spheres, args.sphere_detail,
                                                                            args.radius, args.seed, kind))
    for mode, _ in MODES:
        if mode in args.modes:
            versions[mode] = (renderers[mode], glass)
    keep: dict = {}
    try:
        runs = interleaved(versions, camera, args.warmup, args.frames, keep)
    finally:
        if before is not None:
            before.close()
    rows = {name: summarize(*runs[name]) for name in versions}
    for name in ("spheres_blend", "abuffer", "depth_peeling"):
        if name in keep:
            rows[name]["fragments"] = fragments(keep[name])
    new_passes = sorted(set(rows["plain"]["passes_ms"]) & {"transmission_ms"})
    print_table(rows)
    cmp = comparisons(rows, new_passes)
    if before is not None:
        ours = hashlib.sha1(np.ascontiguousarray(keep["plain"].color).tobytes()).hexdigest()
        cmp["plain_bit_identical_to_before"] = bool(before.hashes) and all(h == ours for h in before.hashes)
        cmp["before"] = {"tree": str(args.baseline), **before.info}
    print(f"\nplain (no transmissive material) runs a transmission pass: {'yes' if new_passes else 'no'}")
    for mode, _ in MODES:
        for ref in ("spheres_opaque", "spheres_blend"):
            key = f"{mode}_over_{ref}"
            if key in cmp:
                print(f"{mode}: passes {cmp[key]['total_ms']:.2f}x {ref}', user frame "
                      f"{cmp[key]['user_frame_paired']:.2f}x (paired by round)")
    if "noise_ms" in cmp:
        print(f"plain - before: user frame {cmp['plain_minus_before_user_ms']:+.1f} ms, passes "
              f"{cmp['plain_minus_before_total_ms']:+.1f} ms, paired {cmp['plain_over_before_paired']:.3f}x; noise "
              f"(larger IQR) {cmp['noise_ms']:.1f} ms: "
              f"{'no change within noise' if cmp['no_change_within_noise'] else 'OUTSIDE the noise'}; colour "
              f"{'bit-identical' if cmp['plain_bit_identical_to_before'] else 'DIFFERS'}")
    record = {"width": args.width, "height": args.height, "frames": args.frames, "warmup": args.warmup,
              "quick": args.quick, "device": device, "lights": args.lights, "light_radius": light_radius,
              "camera": SPONZA_CAMERA, "scene": SPONZA.name, "triangles": glass.triangle_count,
              "transmissive_triangles": n_tx, "spheres": {"count": args.spheres, "detail": args.sphere_detail,
                                                         "radius": args.radius, "box": GLASS_BOX, "seed": args.seed},
              "glasses": {n: {k: (list(v) if isinstance(v, tuple) else v) for k, v in kw.items()} for n, kw in GLASSES},
              "peel_layers": args.peel_layers, "load_average": list(os.getloadavg()), "versions": rows,
              "comparisons": cmp}
    path = write_record("transmission", record)
    print(f"\nrecord: {path.relative_to(REPO)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
