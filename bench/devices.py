"""CPU OpenCL implementations side by side: every pass, the user frame and the cold first render.

    python -m bench.devices [--repeats 5] [--warmup 2] [--implementations pocl-pip,pocl-debian,intel]
                            [--cold demo,sponza] [--quick]

Implementations (each CPU one present; Oclgrind is a simulator and not timed): "intel" (Intel's
CPU runtime, platform "Intel(R) OpenCL"), "pocl-debian" (the PoCL whose platform version says
debian), "pocl-pip" (the other PoCL: pip's, bundled with pyopencl). Cases, clrender's defaults
otherwise:

* Sponza 1280x720 from the atrium camera (bench/common.py) at 0, 1024 and 4096 seeded point
  lights (bench.lights: seed 1, radius 0.05 of the bounds diagonal, intensity 1), load_scene's
  own environment;
* DamagedHelmet 1920x1080 with the built-in "studio" environment.

Each implementation renders in its own worker process (a driver that crashes takes only its own
column down, and only its own threads are alive while it renders). The parent drives the workers
one frame at a time, in turn, the order rotating every repetition, so machine noise hits every
implementation alike. Per case and implementation: the median ms of every pass (the *_ms keys of
Frame.stats: device profiling), of render(), and of the user frame (render() then Frame.image and
Frame.depth read to numpy), over --repeats frames after --warmup. A column whose pass times are
all zero while the frame took time is flagged (its profiling carries no time).

Then each implementation's cold first render: `python -m clrender render SCENE` in a subprocess
with empty CLRENDER_CACHE_DIR, POCL_CACHE_DIR and XDG_CACHE_HOME (pyopencl's binary cache) and
CLRENDER_DEVICE naming it (bench.cold_start's run_cli: wall time, the CLI's first-frame ms, longest
silence on stderr), for the demo scene and Sponza 1280x720.

Prints one table per case (rows: passes, total, render(), user frame; columns: implementations;
the winner and slowest/fastest of each row, * where that is >= 1.5) and one for the cold renders;
writes bench/results/devices-*.json. --quick: small frames, 2 repeats after 1 warm-up, the demo
cold only (a smoke test, not numbers to quote).
"""
from __future__ import annotations

import os

# The environment before clrender registers pip's OpenCL implementations for this process
# (clrender/device/icd.py sets $OCL_ICD_VENDORS at import): the cold renders must start from the user's.
ORIGINAL_ENV = dict(os.environ)

import argparse  # noqa: E402
import math  # noqa: E402
import multiprocessing  # noqa: E402
import shutil  # noqa: E402
import statistics  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Optional  # noqa: E402

from bench.common import HELMET, HELMET_CAMERA, REPO, SPONZA, SPONZA_CAMERA, require_scene, write_record  # noqa: E402

FAR_BEHIND = 1.5                 # slowest/fastest at which a row deserves a look (issue 35)
IMPLEMENTATIONS = ("pocl-pip", "pocl-debian", "intel")
LIGHT_COUNTS = (0, 1024, 4096)
RADIUS_FRAC = 0.05               # bench.lights' default: each light overlaps several light tiles
SETUP_TIMEOUT_S = 1800           # a worker's cold probe and program builds
FRAME_TIMEOUT_S = 600
RANK_FLOOR_MS = 0.05             # passes this short are not ranked: the ratio would be timer noise


# ---------------------------------------------------------------- pure logic (tests/test_bench_devices.py)

def implementation_key(platform: str, platform_version: str, origin: Optional[str]) -> Optional[str]:
    """"intel", "pocl-debian", "pocl-pip" (or "pocl-<origin>" for a PoCL from elsewhere, e.g.
    conda), None for what is not one of this benchmark's CPU implementations. By platform, not
    device name: PoCL's device names say "Intel(R) Xeon" too."""
    from clrender.device.capabilities import implementation_key as key_of
    key = key_of(platform)
    if key == "intel":
        return "intel"
    if key == "pocl":
        if "debian" in platform_version.lower():
            return "pocl-debian"
        return "pocl-pip" if origin in (None, "pip") else f"pocl-{origin}"
    return None


def _number(v) -> Optional[float]:
    return float(v) if isinstance(v, (int, float)) and math.isfinite(v) else None


def compare(values: dict) -> tuple[Optional[str], Optional[float]]:
    """(the implementation with the smallest value, slowest/fastest) over the values that are
    positive numbers: a zero is a time that was not measured, not a win. Ratio None with < 2."""
    valid = {k: v for k, v in ((k, _number(v)) for k, v in values.items()) if v is not None and v > 0}
    if not valid:
        return None, None
    winner = min(valid, key=valid.get)
    ratio = max(valid.values()) / valid[winner] if len(valid) > 1 else None
    return winner, ratio


def format_table(title: str, rows: list, impls: list, unit: str = "ms", floor: float = 0.0) -> list[str]:
    """Lines of a table: `rows` are (name, {impl: number | None | reason}); a column per
    implementation, then the row's winner and slowest/fastest, * where that is >= FAR_BEHIND.
    A row whose values are all under `floor` is not ranked (a ratio of microseconds is noise)."""
    name_w = max([len(unit)] + [len(name) for name, _ in rows])
    col_w = max([9] + [len(i) for i in impls])

    def cell(v) -> str:
        n = _number(v)
        return f"{n:.2f}" if n is not None else ("-" if v is None else str(v))

    cells = {name: [cell(values.get(i)) for i in impls] for name, values in rows}
    col_w = max([col_w] + [len(c) for cs in cells.values() for c in cs])
    lines = [title, f"{unit:<{name_w}}" + "".join(f" {i:>{col_w}}" for i in impls) + f" {'winner':>{col_w}}  ratio"]
    for name, values in rows:
        winner, ratio = compare({i: values.get(i) for i in impls})
        if all(n is None or n < floor for n in (_number(values.get(i)) for i in impls)):
            winner = ratio = None
        line = (f"{name:<{name_w}}" + "".join(f" {c:>{col_w}}" for c in cells[name])
                + f" {winner or '-':>{col_w}}  " + (f"{ratio:.2f}x" if ratio is not None else "-"))
        if ratio is not None and ratio >= FAR_BEHIND:
            line += " *"
        lines.append(line)
    lines.append(f"(winner: the fastest; ratio: slowest / fastest; * slowest >= {FAR_BEHIND:g}x the fastest"
                 + (f"; rows under {floor:g} {unit} not ranked)" if floor > 0 else ")"))
    return lines


# ---------------------------------------------------------------- devices

def device_key(info) -> Optional[str]:
    """implementation_key of a clrender DeviceInfo; None for GPUs and simulators."""
    from clrender.device import capabilities
    if info.is_simulator or not capabilities.is_cpu(info.cl_device):
        return None
    try:
        origin = info.origin
    except Exception:                      # a driver that cannot say where it came from
        origin = None
    return implementation_key(info.platform, info.cl_device.platform.version, origin)


def present_implementations() -> dict:
    """{key: DeviceInfo} of the CPU implementations the OpenCL loader lists (the first device of each)."""
    from clrender.device.core import list_devices
    found: dict = {}
    for info in list_devices():
        key = device_key(info)
        if key is not None and key not in found:
            found[key] = info
    return found


def device_spec(key: str, info) -> str:
    """A CLRENDER_DEVICE value picking exactly `info`, not its "P:D": a cold run with a fresh cache
    writes its own ICD folder, and the loader may list the implementations in another order there."""
    from clrender.device.core import DeviceError, match_devices
    candidates = {"intel": ["intel"], "pocl-debian": ["pocl debian", "debian"],
                  "pocl-pip": ["pocl pip"]}.get(key, [])
    for spec in candidates:
        try:
            if [d.id for d in match_devices(spec)] == [info.id]:
                return spec
        except DeviceError:
            pass
    print(f"note: no name picks {key} alone; its cold run names it by id {info.id} (valid while the "
          f"loader lists the implementations in the same order)", flush=True)
    return info.id


def describe(info) -> dict:
    from clrender.device import capabilities
    d = info.cl_device
    out = {"label": info.label, "description": info.description, "driver_version": d.driver_version,
           "compute_units": int(d.max_compute_units), "max_work_group_size": int(d.max_work_group_size)}
    try:
        out["vector_widths"] = capabilities.vector_widths(d)
    except Exception as exc:
        out["vector_widths"] = f"unknown ({exc})"
    return out


# ---------------------------------------------------------------- cases

def cases(quick: bool) -> list[dict]:
    sponza = (320, 180) if quick else (1280, 720)
    helmet = (480, 270) if quick else (1920, 1080)
    out = [{"name": f"sponza-{n}", "scene": "sponza", "size": sponza, "lights": n, "environment": None,
            "title": f"Sponza {sponza[0]}x{sponza[1]}, {n} lights"} for n in LIGHT_COUNTS]
    out.append({"name": "helmet-studio", "scene": "helmet", "size": helmet, "lights": 0, "environment": "studio",
                "title": f"DamagedHelmet {helmet[0]}x{helmet[1]}, studio environment"})
    return out


# ---------------------------------------------------------------- worker process (one per implementation)

class _Worker:
    """The renderer side: its implementation's device, the scenes loaded once, a Renderer per size."""

    def __init__(self, key: str):
        found = present_implementations()
        if key not in found:
            raise RuntimeError(f"the worker's OpenCL loader lists no {key} device")
        self.info = found[key]
        self.scenes: dict = {}
        self.renderers: dict = {}
        self.renderer = self.scene = self.camera = None

    def setup(self, case: dict) -> dict:
        import clrender
        import numpy as np
        name = case["scene"]
        if name not in self.scenes:
            path, camera = (SPONZA, SPONZA_CAMERA) if name == "sponza" else (HELMET, HELMET_CAMERA)
            scene = clrender.load_scene(require_scene(path))
            self.scenes[name] = (scene, scene.lights.copy(), clrender.Camera.look_at(**camera))
        scene, base_lights, self.camera = self.scenes[name]
        scene.lights = base_lights.copy()
        if case["lights"]:
            lo, hi = scene.bounds().astype(np.float64)
            r = RADIUS_FRAC * float(np.linalg.norm(hi - lo))
            scene.add_random_lights(case["lights"], seed=1, radius=(r, r), intensity=1.0)
        if case["environment"]:
            scene.set_environment(case["environment"])
        size = tuple(case["size"])
        if size not in self.renderers:
            self.renderers[size] = clrender.Renderer(*size, device=self.info)
        self.renderer, self.scene = self.renderers[size], scene
        env = getattr(scene, "environment", None)
        return {"triangles": int(scene.triangle_count), "lights": int(len(scene.lights)),
                "environment": getattr(env, "source", None) if env is not None else None,
                "device": self.renderer.device.name}

    def frame(self) -> dict:
        from clrender.render.pipeline import pass_ms
        t0 = time.perf_counter()
        frame = self.renderer.render(self.scene, self.camera)
        t1 = time.perf_counter()
        frame.image, frame.depth                      # noqa: B018 -- the reads a user waits for
        t2 = time.perf_counter()
        stats = frame.stats
        return {"passes": {k: float(v) for k, v in pass_ms(stats).items() if isinstance(v, (int, float))},
                "total_ms": float(stats.get("total_ms", 0.0)),
                "render_ms": (t1 - t0) * 1e3, "user_ms": (t2 - t0) * 1e3}


def _serve(conn, key: str) -> None:
    """Worker process: answers ("ok", value) or ("error", one line) to each request."""
    try:
        worker = _Worker(key)
        conn.send(("ok", describe(worker.info)))
    except Exception as exc:
        conn.send(("error", f"{type(exc).__name__}: {exc}".splitlines()[0]))
        return
    while True:
        msg = conn.recv()
        if msg[0] == "quit":
            return
        try:
            conn.send(("ok", worker.setup(msg[1]) if msg[0] == "setup" else worker.frame()))
        except Exception as exc:
            conn.send(("error", f"{type(exc).__name__}: {exc}".splitlines()[0]))


class Remote:
    """The parent's handle on one worker process."""

    def __init__(self, key: str):
        ctx = multiprocessing.get_context("spawn")   # no fork: the parent has OpenCL loaded
        self.key = key
        self.conn, child = ctx.Pipe()
        self.proc = ctx.Process(target=_serve, args=(child, key), name=f"bench-{key}", daemon=True)
        self.proc.start()
        child.close()
        self.error: Optional[str] = None
        self.info = self._answer(SETUP_TIMEOUT_S)

    def _answer(self, timeout: float):
        if self.error:
            return None
        try:
            if not self.conn.poll(timeout):
                self.error = f"no answer in {timeout:.0f} s"
                self.proc.kill()
                return None
            status, value = self.conn.recv()
        except (EOFError, OSError):
            self.proc.join(5)
            self.error = f"worker died (exit {self.proc.exitcode})"
            return None
        if status == "error":
            self.error = value
            return None
        return value

    def ask(self, msg: tuple, timeout: float):
        if self.error:
            return None
        try:
            self.conn.send(msg)
        except (BrokenPipeError, OSError):
            self.proc.join(5)
            self.error = f"worker died (exit {self.proc.exitcode})"
            return None
        return self._answer(timeout)

    def close(self) -> None:
        if self.proc.is_alive():
            try:
                self.conn.send(("quit",))
            except OSError:
                pass
            self.proc.join(30)
            if self.proc.is_alive():
                self.proc.kill()
                self.proc.join(5)


# ---------------------------------------------------------------- parent

def summarize(frames: list[dict]) -> dict:
    keys = list(dict.fromkeys(k for f in frames for k in f["passes"]))
    passes = {k: statistics.median(f["passes"].get(k, 0.0) for f in frames) for k in keys}
    user = statistics.median(f["user_ms"] for f in frames)
    return {"passes_ms": passes, "total_ms": statistics.median(f["total_ms"] for f in frames),
            "render_ms": statistics.median(f["render_ms"] for f in frames), "user_frame_ms": user,
            "user_frames_ms": [f["user_ms"] for f in frames],
            # profiling that carries no time (e.g. marker events without timestamps)
            "pass_times_all_zero": user > 0 and not any(v > 0 for v in passes.values())}


def case_rows(results: dict, impls: list) -> list:
    """Table rows of one case: passes (in the order the pipeline reports them), then the totals."""
    pass_names = list(dict.fromkeys(k for i in impls if i in results for k in results[i]["passes_ms"]))
    rows = []
    for k in pass_names:
        rows.append((k[:-3] if k.endswith("_ms") else k,
                     {i: results[i]["passes_ms"].get(k) if i in results else None for i in impls}))
    for label, key in (("passes total", "total_ms"), ("render()", "render_ms"),
                       ("user frame", "user_frame_ms")):
        rows.append((label, {i: results[i][key] if i in results else None for i in impls}))
    return rows


def time_case(case: dict, remotes: dict, warmup: int, repeats: int) -> dict:
    """Set the case up on every worker, then render warm-up + timed frames in turn."""
    setup = {}
    for key, r in remotes.items():
        setup[key] = r.ask(("setup", case), SETUP_TIMEOUT_S)
        if setup[key] is None:
            print(f"  {key}: {r.error}", flush=True)
    alive = [k for k, r in remotes.items() if not r.error]
    frames: dict = {k: [] for k in alive}
    for rep in range(warmup + repeats):
        shift = rep % len(alive) if alive else 0
        for key in alive[shift:] + alive[:shift]:
            frame = remotes[key].ask(("frame",), FRAME_TIMEOUT_S)
            if frame is not None and rep >= warmup:
                frames[key].append(frame)
    results = {}
    for key in alive:
        if remotes[key].error:
            print(f"  {key}: {remotes[key].error}", flush=True)
        elif frames[key]:
            results[key] = {**summarize(frames[key]), "setup": setup[key]}
    return results


def cold_render(key: str, spec: str, scene: Path, size: list, label: str) -> dict:
    from bench.cold_start import run_cli
    tmp = Path(tempfile.mkdtemp(prefix=f"devices-cold-{key}-{label}-"))
    # XDG_CACHE_HOME too: pyopencl keeps built binaries of every implementation but PoCL in its own
    # cache (~/.cache/pyopencl), which would make Intel's "cold" builds cache hits.
    env = dict(ORIGINAL_ENV, CLRENDER_CACHE_DIR=str(tmp / "clrender"), POCL_CACHE_DIR=str(tmp / "pocl"),
               XDG_CACHE_HOME=str(tmp / "xdg"), CLRENDER_DEVICE=spec, CLRENDER_LOG="debug")
    env.pop("CLRENDER_PROBE_CHILD", None)
    try:
        return run_cli(["render", str(scene), "-o", str(tmp / "out.png"), *size], env)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeats", type=int, default=None, help="timed frames per case (default 5, --quick 2)")
    ap.add_argument("--warmup", type=int, default=None, help="warm-up frames per case (default 2, --quick 1)")
    ap.add_argument("--implementations", default=None,
                    help=f"comma-separated, of {', '.join(IMPLEMENTATIONS)} (default: every one present)")
    ap.add_argument("--cold", default=None,
                    help="comma-separated cold-render scenes: demo, sponza, or none (default demo,sponza; "
                         "--quick demo)")
    ap.add_argument("--quick", action="store_true", help="small frames, few repeats, demo cold only: a smoke test")
    args = ap.parse_args(argv)
    repeats = args.repeats if args.repeats is not None else (2 if args.quick else 5)
    warmup = args.warmup if args.warmup is not None else (1 if args.quick else 2)
    if repeats < 1 or warmup < 0:
        ap.error("--repeats must be >= 1 and --warmup >= 0")
    cold_names = [c for c in (args.cold or ("demo" if args.quick else "demo,sponza")).split(",") if c]
    if cold_names == ["none"]:
        cold_names = []
    bad = [c for c in cold_names if c not in ("demo", "sponza")]
    if bad:
        ap.error(f"--cold: unknown scene(s) {', '.join(bad)}; choose from demo, sponza, none")
    require_scene(SPONZA)
    require_scene(HELMET)

    present = present_implementations()
    if args.implementations:
        wanted = [w.strip() for w in args.implementations.split(",") if w.strip()]
        missing = [w for w in wanted if w not in present]
        if missing:
            ap.error(f"--implementations: {', '.join(missing)} not present; present: "
                     f"{', '.join(present) or 'none'} (known: {', '.join(IMPLEMENTATIONS)})")
    else:
        wanted = [k for k in IMPLEMENTATIONS if k in present] + [k for k in present if k not in IMPLEMENTATIONS]
    if not wanted:
        print("no CPU OpenCL implementation present (pip install pocl-binary-distribution / opencl-rt)")
        return 1
    specs = {k: device_spec(k, present[k]) for k in wanted}
    print("implementations: " + "; ".join(f"{k} = {present[k].description} ({present[k].label})" for k in wanted),
          flush=True)

    record: dict = {"quick": args.quick, "repeats": repeats, "warmup": warmup, "far_behind": FAR_BEHIND,
                    "implementations": {}, "failed": {}, "cases": {}, "cold": {}}
    remotes: dict = {}
    tables: list[str] = []
    try:
        for key in wanted:                  # one at a time: their cold builds must not overlap
            print(f"starting the {key} worker (probe, program builds on a cold cache) ...", flush=True)
            remote = Remote(key)
            if remote.error:
                print(f"  {key}: {remote.error}", flush=True)
                record["failed"][key] = remote.error
                remote.close()
                continue
            remotes[key] = remote
            record["implementations"][key] = {**remote.info, "device_spec": specs[key]}
        for case in cases(args.quick):
            live = {k: r for k, r in remotes.items() if not r.error}
            print(f"\n{case['title']}: {warmup} warm-up + {repeats} timed frames on {', '.join(live)} in turn",
                  flush=True)
            results = time_case(case, live, warmup, repeats)
            for key, r in live.items():
                if r.error:
                    record["failed"].setdefault(key, f"{case['name']}: {r.error}")
            rows = case_rows(results, wanted)
            table = format_table(f"{case['title']} (median ms)", rows, wanted, floor=RANK_FLOOR_MS)
            for key, res in results.items():
                if res["pass_times_all_zero"]:
                    table.append(f"WARNING {key}: every pass reads 0 ms while the frame took "
                                 f"{res['user_frame_ms']:.1f} ms (its profiling events carry no time)")
            print("\n".join(table), flush=True)
            tables += table + [""]
            record["cases"][case["name"]] = {
                "title": case["title"], "size": case["size"], "lights": case["lights"],
                "environment": case["environment"], "results": results,
                "rows": [{"row": name, "values": values, "winner": compare(values)[0], "ratio": compare(values)[1]}
                         for name, values in rows]}
    finally:
        for r in remotes.values():
            r.close()

    cold_rows = []
    cold_scenes = {"demo": (REPO / "scenes" / "demo.toml", ["--width", "320", "--height", "180"] if args.quick else []),
                   "sponza": (SPONZA, ["--width", "1280", "--height", "720"])}
    for name in cold_names:
        scene, size = cold_scenes[name]
        seconds, silence, first = {}, {}, {}
        for key in wanted:
            if key in record["failed"] and key not in remotes:
                seconds[key] = "failed"
                continue
            print(f"cold {name} on {key} (CLRENDER_DEVICE={specs[key]!r}, empty caches) ...", flush=True)
            run = cold_render(key, specs[key], scene, size, name)
            record["cold"].setdefault(name, {})[key] = run
            seconds[key] = run["seconds"] if run["rc"] == 0 else f"exit {run['rc']}"
            silence[key] = run["longest_silence_s"]
            first[key] = run["first_frame_ms"] / 1e3 if run["first_frame_ms"] is not None else None
            if run["rc"]:
                print(f"  exit {run['rc']}: {run['error']}", flush=True)
        cold_rows += [(f"{name} cold render", seconds), (f"{name} first frame", first),
                      (f"{name} longest silence", silence)]
    if cold_rows:
        table = format_table("cold first render (empty caches, whole `python -m clrender render` process)",
                             cold_rows, wanted, unit="s")
        print("\n" + "\n".join(table))
        tables += table
    record["tables"] = tables
    path = write_record("devices", record)
    print(f"\nrecord: {path.relative_to(REPO)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
