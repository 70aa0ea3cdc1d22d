"""Cold-start benchmark: what a new user waits for on the first `clrender render`, and after.

    python -m bench.cold_start [--configs pip,all] [--warm-runs 3] [--no-sponza]

Each configuration gets empty cache folders (CLRENDER_CACHE_DIR and POCL_CACHE_DIR in a fresh
temporary folder) and times, as whole processes, in one run: the demo CLI cold then warm
(medians of --warm-runs), Sponza at 1280x720 cold (fresh caches again) then warm. For every cold
run it records the longest silence on stderr (the time between two writes, counting the start
and the exit), the programs built and the seconds of each (top 10; from the CLI's debug log,
CLRENDER_LOG=debug), in the process and in its device probe's child (where a cold run compiles),
and the kernels PoCL compiled (files in its kernel cache).

Configurations: "pip": only pip's PoCL visible (OCL_ICD_VENDORS at an empty folder: pyopencl's
loader loads its bundled PoCL whatever the variable says); "intel": what `pip install
".[pocl,intel]"` gives, pip's PoCL and Intel's CPU runtime (OCL_ICD_VENDORS at a folder holding only
Intel's ICD file), the default device chosen as a user's would be;
"all": every installed implementation (e.g. Debian's PoCL beside pip's), as CI has them;
"noprobe": "all" with the device probe skipped (the probe child's own switch), for the probe's net
cost: its cold demo time minus this one's.
Targets (issue 35): demo cold <= 15 s, Sponza cold <= 25 s, no silence > 3 s, demo warm <= 1.5 s,
Sponza warm <= 3 s, on a 2-core machine. Every cold run also empties pyopencl's own binary cache
(XDG_CACHE_HOME: pyopencl caches programs for drivers other than PoCL, Intel's among them).
"""
from __future__ import annotations

import argparse
import os
import re
import selectors
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from bench.common import REPO, SPONZA, write_record

TARGETS = {"demo_cold_s": 15.0, "sponza_cold_s": 25.0, "longest_silence_s": 3.0, "demo_warm_s": 1.5,
           "sponza_warm_s": 3.0}
BUILT = re.compile(r"built (\S+.*?) in ([\d.]+) s")
FRAME = re.compile(r"\] \S+ -> \S+ \(([\d.]+) ms")      # the CLI's "[1/1] scene -> image (N ms, ..." line


def vendors_folder(config: str, tmp: Path) -> str:
    """The OCL_ICD_VENDORS folder of a configuration: empty ("pip": pip's PoCL, which pyopencl's
    loader always loads), or Intel's ICD file alone ("intel")."""
    folder = tmp / "vendors"
    folder.mkdir()
    if config == "intel":
        from clrender.device import icd
        intel = [p for p in icd.pip_implementations() if p.name == "intel"]
        if not intel:
            raise SystemExit("config intel: Intel's CPU runtime is not pip-installed (pip install opencl-rt)")
        (folder / "intel.icd").write_text(f"{intel[0].library}\n")
    return str(folder)


def run_cli(args: list[str], env: dict, timeout: float = 1800) -> dict:
    """Run `python -m clrender ARGS`; wall time, exit status, stderr, and the longest gap between
    stderr writes (start and exit included)."""
    start = time.perf_counter()
    proc = subprocess.Popen([sys.executable, "-m", "clrender", *args], env=env, cwd=REPO,
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    sel = selectors.DefaultSelector()
    sel.register(proc.stderr, selectors.EVENT_READ)
    last, longest, chunks = start, 0.0, []
    while True:
        if time.perf_counter() - start > timeout:
            proc.kill()
        events = sel.select(timeout=1.0)
        if events:
            data = os.read(proc.stderr.fileno(), 65536)
            if not data:
                break
            now = time.perf_counter()
            longest, last = max(longest, now - last), now
            chunks.append(data)
    proc.wait()
    end = time.perf_counter()
    longest = max(longest, end - last)
    text = b"".join(chunks).decode(errors="replace")
    builds, probe_builds = [], []
    for line in text.splitlines():
        m = BUILT.search(line)
        if m:
            (probe_builds if "(probe child)" in line else builds).append((m.group(1), float(m.group(2))))
    builds.sort(key=lambda b: -b[1])
    probe_builds.sort(key=lambda b: -b[1])
    errors = [ln for ln in text.splitlines() if "error" in ln.lower()]
    frame = FRAME.search(text)
    return {"seconds": end - start, "rc": proc.returncode, "longest_silence_s": longest,
            "programs_built": len(builds), "build_seconds_top10": builds[:10],
            "probe_programs_built": len(probe_builds), "probe_build_seconds_top10": probe_builds[:10],
            "first_frame_ms": float(frame.group(1)) if frame else None,
            "error": errors[-1][:300] if proc.returncode else None}


def pocl_kernels(folder: Path) -> int:
    return sum(1 for _ in folder.rglob("*.so")) if folder.is_dir() else 0


def measure(config: str, scene: Path, size: list[str], warm_runs: int, label: str) -> dict:
    tmp = Path(tempfile.mkdtemp(prefix=f"cold-{config}-{label}-"))
    env = dict(os.environ, CLRENDER_CACHE_DIR=str(tmp / "clrender"), POCL_CACHE_DIR=str(tmp / "pocl"),
               XDG_CACHE_HOME=str(tmp / "xdg"), CLRENDER_LOG="debug")
    for name in ("CLRENDER_DEVICE", "OCL_ICD_VENDORS", "CLRENDER_ICD_VENDORS"):
        env.pop(name, None)
    if config in ("pip", "intel"):
        env["OCL_ICD_VENDORS"] = vendors_folder(config, tmp)
    if config == "noprobe":
        env["CLRENDER_PROBE_CHILD"] = "1"
    out = tmp / "out.png"
    try:
        cold = run_cli(["render", str(scene), "-o", str(out), *size], env)
        cold["pocl_kernels_compiled"] = pocl_kernels(tmp / "pocl")
        print(f"  {config} {label} cold: {cold['seconds']:.1f} s (exit {cold['rc']}; first frame "
              f"{cold['first_frame_ms'] or 0:.0f} ms), longest silence "
              f"{cold['longest_silence_s']:.1f} s, {cold['programs_built']} programs "
              f"(+{cold['probe_programs_built']} in the probe, slowest "
              f"{', '.join('%s %.2f s' % (n.split(' ')[0], t) for n, t in cold['probe_build_seconds_top10'][:3])}), "
              f"{cold['pocl_kernels_compiled']} PoCL kernels" + (f"; {cold['error']}" if cold["error"] else ""),
              flush=True)
        warm = []
        if cold["rc"] == 0:
            for _ in range(warm_runs):
                warm.append(run_cli(["render", str(scene), "-o", str(out), *size], env))
            print(f"  {config} {label} warm: median {statistics.median(w['seconds'] for w in warm):.2f} s "
                  f"({', '.join('%.2f' % w['seconds'] for w in warm)})", flush=True)
        return {"cold": cold, "warm": warm,
                "warm_median_s": statistics.median(w["seconds"] for w in warm) if warm else None}
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--configs", default="pip,intel,all", help="comma-separated: pip, intel, all, noprobe")
    ap.add_argument("--warm-runs", type=int, default=3)
    ap.add_argument("--no-sponza", action="store_true")
    args = ap.parse_args(argv)
    record: dict = {"targets": TARGETS, "configs": {}}
    for config in args.configs.split(","):
        print(f"{config}:", flush=True)
        result = {"demo": measure(config, REPO / "scenes" / "demo.toml", [], args.warm_runs, "demo")}
        if config == "noprobe":
            record["configs"][config] = result
            continue
        if not args.no_sponza and SPONZA.is_file():
            result["sponza"] = measure(config, SPONZA, ["--width", "1280", "--height", "720"], args.warm_runs,
                                       "sponza")
        elif not args.no_sponza:
            print(f"  Sponza skipped: {SPONZA} not found (needs ../shared/scenes)", flush=True)
        record["configs"][config] = result
    path = write_record("cold_start", record)
    print(f"record: {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
