"""bench/roofline.py's arithmetic: Oclgrind's instruction counts of the roofline frame at a small
size (`collect_ops` runs under `oclgrind --inst-counts`), attributed to passes, classified
(float / int / atomic / load / store / free) and scaled to a measured frame (`ops_model`)."""
from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import time
from pathlib import Path

from bench.common import REPO, RESULTS

OPS_CACHE = RESULTS / "roofline_ops.json"

# kernel -> (pass, unit it scales with); scans and reductions go to the pass kernel launched just before them.
KERNELS = {"chunk_cull": ("setup", "chunks"), "setup_count": ("setup", "triangles"),
           "setup_emit": ("setup", "triangles"), "bin_count": ("binning", "prims"), "bin_fill": ("binning", "prims"),
           "raster_tiles": ("raster", "tile_entries"), "gbuffer_resolve": ("gbuffer", "pixels"),
           "light_view_bounds": ("light_cull", "lights"), "tile_depth_bounds": ("light_cull", "pixels"),
           "light_cull_count": ("light_cull", "tile_lights"), "light_cull_fill": ("light_cull", "tile_lights"),
           "shade": ("shade", "pixels")}
HELPER_UNIT = {"setup": "chunks", "binning": "tiles", "light_cull": "light_tiles", "shade": "pixels"}
HELPERS = ("scan_", "reduce")      # clrender's prefix sums, pyopencl's reductions (shade's pair sums)

FLOAT_OPS = {"fadd", "fsub", "fmul", "fdiv", "frem", "fneg", "fcmp"}
INT_OPS = {"add", "sub", "mul", "udiv", "sdiv", "urem", "srem", "shl", "lshr", "ashr", "and", "or", "xor",
           "icmp", "select", "sitofp", "uitofp", "fptosi", "fptoui", "fpext", "fptrunc"}
WORK_ITEM_CALLS = re.compile(r"get_(global|local|group)_(id|size)|get_num_groups|barrier|mem_fence|get_work_dim")


def classify(opcode: str) -> str:
    """float (incl. float math built-ins and intrinsics, each one op), int (incl. conversions and
    integer built-ins such as min, select), atomic, load, store, or free (control flow, phi,
    getelementptr, casts that move no bits, work-item queries, calls of the kernels' own functions,
    whose bodies are counted instruction by instruction)."""
    if opcode.startswith("load"):
        return "load"
    if opcode.startswith("store"):
        return "store"
    if opcode.startswith("call"):
        name = opcode[4:].strip()
        if "atomic" in name or "atom_" in name:
            return "atomic"
        if WORK_ITEM_CALLS.search(name) or "memcpy" in name or "memset" in name or "lifetime" in name:
            return "free"
        if name.startswith("llvm."):
            return "float" if re.search(r"\.f(32|64)|v\d+f32", name) else "int"
        m = re.match(r"_Z(\d+)", name)          # an OpenCL built-in (mangled): float if a parameter is
        if m:
            params = name[m.end() + int(m.group(1)):].split("(")[0]
            return "float" if "f" in params else "int"
        return "free"
    if opcode in FLOAT_OPS:
        return "float"
    if opcode in INT_OPS:
        return "int"
    if opcode.startswith(("atomicrmw", "cmpxchg")):
        return "atomic"
    return "free"


def parse_inst_counts(text: str) -> list[tuple[str, dict]]:
    """Oclgrind --inst-counts output -> [(kernel, {class: count})] in launch order."""
    launches = []
    for line in text.splitlines():
        m = re.match(r"Instructions executed for kernel '([^']+)':", line)
        if m:
            launches.append((m.group(1), {}))
            continue
        m = re.match(r"\s*(\d[\d,.' ]*) - (.+?)\s*$", line)      # (Oclgrind prints in the user's locale)
        if m and launches:
            cls = classify(m.group(2))
            launches[-1][1][cls] = launches[-1][1].get(cls, 0) + int(re.sub(r"\D", "", m.group(1)))
    return launches


def per_pass_counts(launches: list) -> dict:
    """The last frame's launches -> {pass: {unit: {class: count}}}. The last frame starts at the
    last launch of its first kernel (the chunk cull, else setup_count): Oclgrind writes its counts
    through C's stdout buffer, so no marker printed from Python between frames could be trusted
    to land in order."""
    names = [k for k, _ in launches]
    first = "chunk_cull" if "chunk_cull" in names else "setup_count"
    start = len(names) - 1 - names[::-1].index(first) if first in names else 0
    out: dict = {}
    current = None
    for kernel, cls in launches[start:]:
        if kernel in KERNELS:
            current, unit = KERNELS[kernel]
        elif kernel.startswith(HELPERS) and current in HELPER_UNIT:
            unit = HELPER_UNIT[current]
        elif kernel == "timestamp":    # profiling stamps (a kernel on some runtimes): not the pass's work
            continue
        else:
            current = None             # tonemap, fills, timestamps, per-scene work: not counted
            continue
        slot = out.setdefault(current, {}).setdefault(unit, {})
        for c, n in cls.items():
            slot[c] = slot.get(c, 0) + n
    return out


def collect_ops(width: int, height: int, lights: int) -> None:
    """Runs under `oclgrind --inst-counts`: one frame on the simulator (a frame whose buffers
    overflowed is redone inside render(): per_pass_counts keeps the last attempt), then its units
    (frame_counts) as one JSON line."""
    import clrender
    import clrender.render.memory as memory
    memory.check = lambda *a, **k: {}      # Oclgrind reports 128 MiB; Sponza's texels are 182 MB (host memory)
    # clrender builds for the simulator with -cl-opt-disable; without it Oclgrind 21.10 cannot run
    # raster.cl (llvm.experimental.noalias.scope.decl). -O0 code: see alu_ops for what that means.
    # Without the default environment: prefiltering it (thousands of GGX samples a texel) does not
    # finish under the simulator. Shade's count then lacks the per-pixel environment lookups.
    from bench.roofline import frame_counts, load_sponza
    scene, camera = load_sponza(lights, environment=False)
    r = clrender.Renderer(width, height, device=os.environ.get("ROOFLINE_OPS_DEVICE", "0:0"))
    frame = r.render(scene, camera)
    counts = frame_counts(r, r._scene_resources(scene), frame.stats)
    print("ROOFLINE_COUNTS " + json.dumps(counts), file=sys.stderr, flush=True)


def run_oclgrind(width: int, height: int, lights: int, log: Path | None = None) -> dict:
    """Count one frame's instructions under Oclgrind (minutes); the simulator's output goes to
    `log` (default: a temporary file), where its progress can be followed."""
    import tempfile
    cmd = ["oclgrind", "--inst-counts", sys.executable, "-m", "bench.roofline", "--collect-ops",
           str(width), str(height), str(lights)]
    env = {**os.environ, "PYTHONPATH": str(REPO), "CLRENDER_HOST_MIPS": "1"}   # mip chains on the host, not simulated
    log = log or Path(tempfile.gettempdir()) / f"roofline-oclgrind-{width}x{height}-{lights}.txt"
    t0 = time.perf_counter()
    with open(log, "w") as out:
        rc = subprocess.run(cmd, cwd=REPO, stdout=out, stderr=subprocess.STDOUT, env=env).returncode
    run = parse_run(log.read_text())
    if rc or run is None:
        raise RuntimeError(f"oclgrind run failed ({rc}), see {log}")
    return {**run, "seconds": time.perf_counter() - t0}


def parse_run(text: str) -> dict | None:
    """A `collect_ops` run's output -> {"counts": its frame's units, "passes": per_pass_counts}."""
    m = re.search(r"^ROOFLINE_COUNTS (.+)$", text, re.M)
    return None if m is None else {"counts": json.loads(m.group(1)), "passes": per_pass_counts(parse_inst_counts(text))}


def load_ops(size, lights: list, recount: bool) -> dict:
    """{str(lights): oclgrind run} from the cache, counting what is missing (or all with recount)."""
    cached = json.loads(OPS_CACHE.read_text()) if OPS_CACHE.is_file() and not recount else {}
    key = f"{size[0]}x{size[1]}"
    runs = cached.get(key, {})
    for n in {0, *lights}:
        if str(n) not in runs:
            print(f"counting instructions under Oclgrind: {key}, {n} lights ...", flush=True)
            runs[str(n)] = run_oclgrind(*size, n)
            print(f"  {runs[str(n)]['seconds']:.0f} s", flush=True)
    cached[key] = runs
    OPS_CACHE.parent.mkdir(parents=True, exist_ok=True)
    OPS_CACHE.write_text(json.dumps(cached, indent=1))
    return runs


def ops_model(runs: dict, lights: int, counts: dict) -> dict:
    """{pass: {class: ops}} at the measured frame: each kernel's small-frame counts per its unit
    times the frame's units. Shade with lights: the 0-light run's per-pixel ops plus, per
    evaluated light pair, the difference of the two small runs per their pairs. Light-culling
    loops over lights are per (light tile x light); with 0 lights they scale per light tile."""
    small = runs[str(lights)]
    sc = small["counts"]
    out = {}
    for name, units in small["passes"].items():
        total: dict = {}
        for unit, cls in units.items():
            if unit == "tile_lights" and not sc["tile_lights"]:
                unit = "light_tiles"
            if name == "shade" and lights:
                base = runs["0"]["passes"]["shade"]["pixels"]
                b0 = runs["0"]["counts"]
                for c in set(cls) | set(base):
                    per_px = base.get(c, 0) / b0["pixels"]
                    lit = cls.get(c, 0) - base.get(c, 0) * sc["pixels"] / b0["pixels"]
                    per_pair = lit / max(sc["light_pairs"], 1)
                    total[c] = total.get(c, 0) + per_px * counts["pixels"] + max(per_pair, 0) * counts["light_pairs"]
                continue
            scale = counts[unit] / max(sc[unit], 1)
            for c, n in cls.items():
                total[c] = total.get(c, 0) + n * scale
        out[name] = total
    return out


def alu_ops(cls: dict) -> float:
    """The ops the FLOP floor counts: float arithmetic and float built-ins only. The counts come
    from unoptimized (-O0) code, whose integer ops are mostly address and loop arithmetic that an
    optimizing compiler folds or hoists (reported, not counted); its float ops lack only common
    subexpression elimination and loop-invariant hoisting, which the floor's generosity (each
    scalar float op, even a division or sqrt, as one FLOP at the FMA peak) should cover."""
    return cls.get("float", 0)
