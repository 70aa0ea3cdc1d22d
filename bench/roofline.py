"""Roofline: how far each pass of a Sponza frame is from this machine's floor (issue 40, item 1).

    python -m bench.roofline [--devices 1:0 2:0 3:0] [--repeats 5] [--size 1280 720]
                             [--lights 0 1024] [--recount-ops] [--ops-size 160 90]

Per CPU OpenCL implementation (never the Oclgrind simulator, which only counts instructions):

* **Copy bandwidth**: an OpenCL float4 copy over 256 MiB buffers (>> every cache), GB/s counting
  the bytes read plus the bytes written; numpy's memcpy (np.copyto) of the same size as a reference.
* **FLOP rate**: FMA_CHAINS independent chains of float8 steps per work-item (enough to hide the
  FMA latency), 2 FLOP per lane per step, the faster of fma() and x*m + a (PoCL 3.0's generic
  target has no FMA instruction: its fma() is a library call); GFLOP/s total and per compute unit.
  Both are sampled once after each timed frame (after a warm-up) and their medians taken: on a
  shared machine the load moves the rates and the frames alike.
* **Each pass** of the bench/lights.py frame (Sponza, SPONZA_CAMERA, 0 and 1024 random lights):
  its median ms (pass_ms of Frame.stats), the bytes it must move (`bytes_model`: each declared
  input read once and each output written once, from the sizes of the device buffers the
  frame actually used -- see the notes there for what is left out) and the arithmetic it must do
  (`ops_model`: Oclgrind's instruction counts of the same frame at --ops-size, normalised per
  triangle / prim / tile entry / pixel / light pair, scaled to the measured frame's counts; that
  frame has no default environment, whose prefiltering does not finish under the simulator).

The floor of a pass is max(bytes / copy bandwidth, ops / FLOP rate): a lower bound under
generous assumptions (each byte moved once at streaming speed; each scalar float op, a division
or sqrt too, as one FLOP at the FMA peak; integer, address and control-flow work free: alu_ops).
ms / floor says how far the pass is from it; "bound" which of the two terms is larger.
Writes bench/results/roofline-*.json. The Oclgrind counts (bench/roofline_ops.py) do not depend on
the CPU: they are kept in bench/results/roofline_ops.json (--recount-ops redoes them: 15-30 minutes on 2 busy cores)."""
from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from pathlib import Path

import numpy as np

from bench.common import SPONZA, SPONZA_CAMERA, environment, require_scene, write_record
from bench.roofline_ops import alu_ops, collect_ops, load_ops, ops_model

COPY_MIB = 256
FMA_CHAINS = 8          # independent float8 chains per work-item: > FMA latency x pipes (4 x 2 on Zen/Haswell)
FMA_ITERS = 512
FMA_ITEMS_PER_CU = 2048
PASSES = ("setup", "binning", "raster", "gbuffer", "light_cull", "shade")

# Micro-kernels of this benchmark only (not a render stage): a streaming copy and FMA chains.
PROBE_SOURCE = r"""
#ifndef FMA_CHAINS
#define FMA_CHAINS 8
#endif
#ifdef MUL_ADD
#define STEP(x, m, a) ((x) * (m) + (a))
#else
#define STEP(x, m, a) fma((x), (m), (a))
#endif

kernel void copy4(global const float4 *src, global float4 *dst) {
    const size_t i = get_global_id(0);
    dst[i] = src[i];
}

/* FMA_CHAINS float8 chains x = STEP(x, m, a) per work-item (fma(), or mul then add: MUL_ADD);
   seeds depend on the id so nothing folds; the chains' sum is written so nothing is dead. */
kernel void fma_chains(global float8 *out, const float8 m, const float8 a, const int iters) {
    const float base = (float)get_global_id(0) * 1e-4f;
    float8 x[FMA_CHAINS];
    for (int c = 0; c < FMA_CHAINS; ++c)
        x[c] = (float8)(base) + (float)c * 0.125f + (float8)(0.f, 1.f, 2.f, 3.f, 4.f, 5.f, 6.f, 7.f) * 0.01f;
    for (int k = 0; k < iters; ++k) {
        #pragma unroll
        for (int c = 0; c < FMA_CHAINS; ++c)
            x[c] = STEP(x[c], m, a);
    }
    float8 s = x[0];
    for (int c = 1; c < FMA_CHAINS; ++c)
        s += x[c];
    out[get_global_id(0)] = s;
}
"""
FMA_M, FMA_A = 0.999, 0.001          # x -> m x + a converges to 1: no overflow whatever iters


def _median_event_s(queue, launch, warmup: int, repeats: int) -> float:
    """Median seconds of `launch()` (returns an event) by OpenCL profiling, after `warmup` runs."""
    for _ in range(warmup):
        launch().wait()
    times = []
    for _ in range(repeats):
        ev = launch()
        ev.wait()
        times.append((ev.profile.end - ev.profile.start) * 1e-9)
    return statistics.median(times)


class Probe:
    """The copy and FMA micro-kernels on one clrender Device (its context and profiling queue)."""

    def __init__(self, device):
        import pyopencl as cl
        self.cl = cl
        self.device = device
        self.queue = device.queue
        opts = [f"-DFMA_CHAINS={FMA_CHAINS}"]
        program = cl.Program(device.context, PROBE_SOURCE).build(options=opts)
        mul_add = cl.Program(device.context, PROBE_SOURCE).build(options=opts + ["-DMUL_ADD"])
        self.copy4 = cl.Kernel(program, "copy4")
        # fma() and x*m + a (which the compiler may contract to an FMA, or not: an implementation
        # without FMA code generation calls a soft fma())
        self.chains = {"fma": cl.Kernel(program, "fma_chains"), "mul_add": cl.Kernel(mul_add, "fma_chains")}
        self.compute_units = int(device.cl_device.max_compute_units)

    def copy(self, src: np.ndarray) -> np.ndarray:
        """The copy kernel over a float32 array (length a multiple of 4), result read back."""
        cl, ctx, mf = self.cl, self.device.context, self.cl.mem_flags
        a, b = cl.Buffer(ctx, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=src), cl.Buffer(ctx, mf.WRITE_ONLY, src.nbytes)
        self.copy4(self.queue, (src.size // 4,), None, a, b)
        out = np.empty_like(src)
        cl.enqueue_copy(self.queue, out, b)
        return out

    def copy_gbs(self, mib: int = COPY_MIB, warmup: int = 2, repeats: int = 5) -> float:
        """GB/s (1e9 bytes) of the copy kernel, counting bytes read + written (buffers kept for
        the next call: bench runs interleave it with frames)."""
        cl, ctx = self.cl, self.device.context
        n = mib * (1 << 20)
        if getattr(self, "_copy_bytes", 0) != n:
            self._copy_bufs = [cl.Buffer(ctx, cl.mem_flags.READ_WRITE, n) for _ in range(2)]
            for buf, v in zip(self._copy_bufs, (1.0, 0.0)):
                cl.enqueue_fill_buffer(self.queue, buf, np.float32(v), 0, n).wait()
            self._copy_bytes = n
        a, b = self._copy_bufs
        s = _median_event_s(self.queue, lambda: self.copy4(self.queue, (n // 16,), None, a, b), warmup, repeats)
        return 2 * n / s / 1e9

    def fma(self, items: int, iters: int, kind: str = "fma") -> np.ndarray:
        """The FMA kernel's output (kind: "fma" or "mul_add"): (items, 8) float32."""
        out = self.cl.Buffer(self.device.context, self.cl.mem_flags.WRITE_ONLY, items * 32)
        host = np.empty((items, 8), np.float32)
        self._fma_launch(out, items, iters, kind).wait()
        self.cl.enqueue_copy(self.queue, host, out)
        return host

    def _fma_launch(self, out, items, iters, kind):
        vec = lambda v: np.full(8, v, np.float32).view(self.cl.cltypes.float8)[0]   # noqa: E731
        return self.chains[kind](self.queue, (items,), None, out, vec(FMA_M), vec(FMA_A), np.int32(iters))

    def gflops(self, warmup: int = 2, repeats: int = 5) -> dict:
        """GFLOP/s of each chain kernel: 2 FLOP per lane per step (the final sums not counted)."""
        items = FMA_ITEMS_PER_CU * self.compute_units
        if getattr(self, "_fma_out", None) is None:
            self._fma_out = self.cl.Buffer(self.device.context, self.cl.mem_flags.WRITE_ONLY, items * 32)
        rates = {}
        for kind in self.chains:
            s = _median_event_s(self.queue, lambda: self._fma_launch(self._fma_out, items, FMA_ITERS, kind),
                                warmup, repeats)
            rates[kind] = items * FMA_ITERS * FMA_CHAINS * 8 * 2 / s / 1e9
        return rates


def fma_reference(items: int, iters: int) -> np.ndarray:
    """NumPy of fma_chains: each step rounded to float32 once, as fma() does (from float64, where
    x*m is exact and only the add rounds: a double rounding that may differ in the last bit)."""
    base = np.arange(items, dtype=np.float32)[:, None] * np.float32(1e-4)
    lanes = np.arange(8, dtype=np.float32) * np.float32(0.01)
    m, a = np.float64(np.float32(FMA_M)), np.float64(np.float32(FMA_A))
    total = None
    for c in range(FMA_CHAINS):
        x = (base + np.float32(c * 0.125)) + lanes
        for _ in range(iters):
            x = (x.astype(np.float64) * m + a).astype(np.float32)
        total = x if total is None else total + x
    return total


def numpy_copy_gbs(mib: int = COPY_MIB, repeats: int = 5) -> float:
    src = np.ones(mib * (1 << 18), np.float32)
    dst, times = src.copy(), []
    for _ in range(repeats):
        t0 = time.perf_counter()
        np.copyto(dst, src)
        times.append(time.perf_counter() - t0)
    return 2 * src.nbytes / statistics.median(times) / 1e9


# ---------------------------------------------------------------------------------------------
# Bytes: each declared input read once, each output written once (a lower bound).


def frame_counts(renderer, scene_res, stats: dict) -> dict:
    """What the bytes and ops models scale with, from a rendered frame (reads back vis_prim)."""
    p = renderer.pipeline
    vis = p.raster.vis_prim.get(queue=renderer.device.queue)
    lc = p.light_cull
    visible = stats["chunks"] - stats["culled_chunks"]
    return {"pixels": renderer.width * renderer.height, "triangles": int(stats["triangles_in"]),
            "chunks": int(stats["chunks"]), "visible_triangles": min(visible * 128, int(stats["triangles_in"])),
            "prims": int(stats["prims"]), "tiles": int(p.binning.tiles_x * p.binning.tiles_y),
            "tile_entries": int(stats["tile_entries"]), "visible_prims": int(np.unique(vis[vis >= 0]).size),
            "lights": int(stats["lights"]), "light_tiles": int(lc.tiles_x * lc.tiles_y),
            "light_entries": int(stats["light_list_entries"]),
            "tile_lights": int(lc.tiles_x * lc.tiles_y * stats["lights"]),
            "light_pairs": int(stats["light_pairs_evaluated"])}


def bytes_model(renderer, scene_res, counts: dict) -> dict:
    """{pass: {term: bytes}}: the buffers each pass reads (its `inputs`) and writes (its
    `outputs`), counted once each, at the sizes the frame used: variable-length buffers (prims,
    tile lists, light lists) at their filled length, not their capacity. Left out: a pass's own
    intermediates (setup's staged prims and counts, light_cull's tile depths and spheres, scan
    scratch), buffers of a few hundred bytes (matrices, LUTs, materials) and, in raster, gbuffer and
    shade, the texels (which and how many a pixel samples is not known cheaply), which keeps it a
    lower bound. Per-pixel records (gbuffer: the prim and its 3 vertices' attributes; shade: the
    triangle's material index) are counted once per distinct visible prim: an estimate."""
    from clrender.abi import structs
    b, v, p = scene_res.buffers, scene_res.values, renderer.pipeline
    px, prim = counts["pixels"], structs.prim_dtype.itemsize
    nt = max(int(v["n_tris"]), 1)
    frac = counts["visible_triangles"] / nt                     # the chunk cull skips the rest
    vertex = sum(b[k].nbytes for k in ("positions", "normals", "uvs", "tangents")) / max(int(v["n_vertices"]), 1)
    lights = v["lights"].nbytes * (counts["lights"] > 0)
    gbuffer, shade = (next(q for q in p.passes if q.name == n) for n in ("gbuffer", "shade"))
    shade_planes = 4 + int(bool(v["surface_extras"]))        # triangle_id, normal, depth, albedo (+ emissive)
    return {
        "setup": {"triangles+tri_material (visible chunks)":
                  int((b["triangles"].nbytes + b["tri_material"].nbytes) * frac),
                  "positions (visible chunks)": int(b["positions"].nbytes * frac),
                  "chunk boxes": 32 * counts["chunks"],
                  "prims written": prim * counts["prims"], "tri_status written": counts["triangles"]},
        "binning": {"prims": prim * counts["prims"], "tile counts+offsets": 8 * counts["tiles"],
                    "tile_prims written": 4 * counts["tile_entries"]},
        "raster": {"tile counts+offsets": 8 * counts["tiles"], "tile_prims": 4 * counts["tile_entries"],
                   "prims": prim * counts["prims"], "vis_depth+vis_prim written": p.raster.vis_depth.nbytes
                   + p.raster.vis_prim.nbytes},
        "gbuffer": {"vis_depth+vis_prim": p.raster.vis_depth.nbytes + p.raster.vis_prim.nbytes,
                    "visible prims + 3 vertices (estimate)": int(counts["visible_prims"] * (prim + 16 + 3 * vertex)),
                    "gbuffer written": 4 * len(gbuffer.planes) * px},
        "light_cull": {"depth plane": 4 * px, "lights": lights, "light counts+offsets": 8 * counts["light_tiles"],
                       "tile_lights written": 4 * counts["light_entries"]},
        "shade": {"gbuffer planes read": 4 * shade_planes * px, "light counts+offsets": 8 * counts["light_tiles"],
                  "tile_lights": 4 * counts["light_entries"], "lights": lights,
                  "tri_material (visible prims)": 4 * counts["visible_prims"],
                  "color+light_count+light_pairs written": shade.color.nbytes + shade.light_count.nbytes
                  + shade.light_pairs.nbytes},
    }


# ---------------------------------------------------------------------------------------------


def load_sponza(lights: int, environment: bool = True):
    import clrender
    scene = clrender.load_scene(require_scene(SPONZA), default_environment=environment)
    lo, hi = scene.bounds().astype(np.float64)
    r = 0.05 * float(np.linalg.norm(hi - lo))
    scene.add_random_lights(lights, seed=1, radius=(r, r), intensity=1.0)
    return scene, clrender.Camera.look_at(**SPONZA_CAMERA)


def measure_device(spec: str, size, lights: list, repeats: int, runs: dict, scene_lights: dict) -> dict:
    import clrender
    from clrender.render.pipeline import pass_ms
    r = clrender.Renderer(*size, device=spec)
    probe = Probe(r.device)
    probe.copy_gbs(warmup=2, repeats=1), probe.gflops(warmup=2, repeats=1)                 # warm-up
    rec = {"device": r.device.name, "implementation": r.device.cl_device.platform.name,
           "compute_units": probe.compute_units, "lights": {}}
    copies, flops, np_copies = [], [], []

    def probes():
        """One copy, FMA and numpy copy sample after each frame: this shared machine's load moves
        them and the frames alike, and their medians are taken over the same stretch of time."""
        copies.append(probe.copy_gbs(warmup=0, repeats=1))
        flops.append(probe.gflops(warmup=0, repeats=1))
        np_copies.append(numpy_copy_gbs(repeats=1))

    for n in lights:
        scene, camera = scene_lights[n]
        r.render(scene, camera)                                        # warm-up (builds)
        samples, frame = [], None
        for _ in range(repeats):
            frame = r.render(scene, camera)
            samples.append(pass_ms(frame.stats))
            probes()
        ms = {k[:-3]: statistics.median(s[k] for s in samples) for k in samples[0]}
        counts = frame_counts(r, r._scene_resources(scene), frame.stats)
        rec["lights"][str(n)] = {"counts": counts, "ms": ms, "bytes": bytes_model(r, r._scene_resources(scene), counts),
                                 "ops": ops_model(runs, n, counts) if runs else {}}
    rec["copy_gbs"] = statistics.median(copies)
    rec["numpy_copy_gbs"] = statistics.median(np_copies)
    rec["gflops_by_kernel"] = {k: statistics.median(f[k] for f in flops) for k in flops[0]}
    rec["gflops"] = max(rec["gflops_by_kernel"].values())          # the faster of fma() and x*m + a
    rec["gflops_per_cu"] = rec["gflops"] / probe.compute_units
    for entry in rec["lights"].values():
        entry["passes"] = floors(entry.pop("ms"), entry.pop("bytes"), entry.pop("ops"), rec)
        entry["total_ms"] = entry["passes"].pop("total", {}).get("ms")
    return rec


def floors(ms: dict, nbytes: dict, ops: dict, rec: dict) -> dict:
    """Per pass: ms, bytes, ops, the time each takes at the measured rates, the floor (the larger)."""
    rows = {}
    for p in PASSES:
        b, o = sum(nbytes[p].values()), alu_ops(ops.get(p, {}))
        t_bw, t_fl = b / rec["copy_gbs"] / 1e6, o / rec["gflops"] / 1e6          # ms
        floor = max(t_bw, t_fl)
        t = ms.get(p, float("nan"))
        rows[p] = {"ms": t, "bytes": b, "bytes_terms": nbytes[p], "ops": o, "int_ops": ops.get(p, {}).get("int", 0),
                   "ops_classes": ops.get(p, {}),
                   "bw_floor_ms": t_bw, "flop_floor_ms": t_fl, "floor_ms": floor,
                   "x_floor": t / floor if floor else float("nan"), "bound": "memory" if t_bw >= t_fl else "compute"}
    rows["total"] = {"ms": ms.get("total")}
    return rows


def print_device(rec: dict) -> None:
    print(f"\n{rec['device']} ({rec['implementation']}): copy {rec['copy_gbs']:.1f} GB/s (numpy "
          f"{rec['numpy_copy_gbs']:.1f}), FMA {rec['gflops']:.1f} GFLOP/s ({rec['gflops_per_cu']:.1f} per "
          f"core, {rec['compute_units']} cores)")
    for n, entry in rec["lights"].items():
        print(f"  {n} lights: {'pass':<11}{'ms':>8}{'MB':>8}{'bw ms':>8}{'Mflop':>9}{'Mint':>8}{'flop ms':>9}"
              f"{'floor':>8}{'x floor':>9}  bound")
        for p, row in entry["passes"].items():
            print(f"  {'':10}{p:<11}{row['ms']:8.2f}{row['bytes'] / 1e6:8.1f}{row['bw_floor_ms']:8.2f}"
                  f"{row['ops'] / 1e6:9.1f}{row['int_ops'] / 1e6:8.1f}{row['flop_floor_ms']:9.2f}{row['floor_ms']:8.2f}"
                  f"{row['x_floor']:9.1f}  {row['bound']}")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--devices", nargs="+", default=None, help="P:D specs (default: every CPU device but Oclgrind)")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--size", type=int, nargs=2, default=(1280, 720))
    ap.add_argument("--lights", type=int, nargs="+", default=[0, 1024])
    ap.add_argument("--ops-size", type=int, nargs=2, default=(160, 90))
    ap.add_argument("--recount-ops", action="store_true", help="redo the Oclgrind instruction counts")
    ap.add_argument("--no-ops", action="store_true", help="bandwidth floor only (no Oclgrind counts)")
    ap.add_argument("--rescore", type=Path, default=None,
                    help="a roofline record: recompute its floors with the current op counts, measure nothing")
    ap.add_argument("--collect-ops", type=int, nargs=3, default=None, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.collect_ops:
        collect_ops(*args.collect_ops)
        return 0
    if args.rescore:
        return rescore(args.rescore, args.recount_ops)
    devices = args.devices
    if devices is None:
        from clrender.device.probe import select_devices
        devices = [d.id for d in select_devices("all")]
    runs = None if args.no_ops else load_ops(args.ops_size, args.lights, args.recount_ops)
    scene_lights = {n: load_sponza(n) for n in args.lights}
    record = {"size": list(args.size), "repeats": args.repeats, "ops_size": list(args.ops_size),
              "copy_mib": COPY_MIB, "fma": {"chains": FMA_CHAINS, "iters": FMA_ITERS}, "devices": {}}
    if runs:
        record["ops_runs"] = {k: {"counts": v["counts"]} for k, v in runs.items()}
    for spec in devices:
        rec = measure_device(spec, args.size, args.lights, args.repeats, runs, scene_lights)
        record["devices"][spec] = rec
        print_device(rec)
    env = environment()
    record["cpu"] = _cpu_model() or env.get("processor")
    print(f"\nwrote {write_record('roofline', record)}")
    return 0


def rescore(path: Path, recount: bool) -> int:
    """A record's floors again, from its stored ms, bytes and frame counts and the (cached) ops."""
    record = json.loads(path.read_text())
    record.pop("environment", None)
    runs = load_ops(record["ops_size"], [int(n) for d in record["devices"].values() for n in d["lights"]], recount)
    record["ops_runs"] = {k: {"counts": v["counts"]} for k, v in runs.items()}
    for rec in record["devices"].values():
        for n, entry in rec["lights"].items():
            rows = entry["passes"]
            ops = ops_model(runs, int(n), entry["counts"])
            entry["passes"] = floors({p: r["ms"] for p, r in rows.items()},
                                     {p: r["bytes_terms"] for p, r in rows.items()}, ops, rec)
            entry["passes"].pop("total")
        print_device(rec)
    record["rescored_from"] = path.name
    print(f"\nwrote {write_record('roofline', record)}")
    return 0


def _cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return ""


if __name__ == "__main__":
    sys.exit(main())
