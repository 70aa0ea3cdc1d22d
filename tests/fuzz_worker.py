"""The fuzzing tier's worker process (tests/test_fuzz.py starts one and keeps it for the module).

It makes a 16x12 Renderer once, renders every seed once (so the kernels a case needs are built
before the cases are timed), then caps its own address space (RLIMIT_AS: what it has now plus
HEADROOM) and serves cases: one JSON request per line on stdin ({"path", "render"}), one JSON
answer per line on the protocol pipe (the original stdout; anything the code under test prints
goes to stderr, which the test sends to a log file). Per case it reports the outcome (loaded /
rendered, or the exception's type and message), the warnings raised, the load and render
seconds, the peak RSS growth (VmHWM reset through /proc/self/clear_refs before the case), and
every file opened under the OUTSIDE folder (an audit hook sees Python-level opens; the test also
watches the files' access times for reads by C code).

Replay a saved case by hand:  python3 tests/fuzz_worker.py --replay CASE_FOLDER/SCENE_FILE
"""
from __future__ import annotations

import json
import os
import resource
import sys
import time
import traceback
import warnings

HEADROOM = 3 << 30          # address space a case may add on top of the warmed-up worker's
WIDTH, HEIGHT = 16, 12


def _status(key: str) -> int:
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith(key + ":"):
                return int(line.split()[1]) * 1024
    return 0


def _reset_peak() -> bool:
    try:
        with open("/proc/self/clear_refs", "w") as f:
            f.write("5")
        return True
    except OSError:
        return False


class Worker:
    def __init__(self, device: str | None, outside: str, render: bool):
        import clrender
        self.clrender = clrender
        self.outside = os.path.realpath(outside)
        self.opened: list[str] = []
        self.renderer = clrender.Renderer(WIDTH, HEIGHT, device=device) if render else None
        sys.addaudithook(self._audit)

    def _audit(self, event, args):
        if event == "open" and args and isinstance(args[0], (str, bytes, os.PathLike)):
            try:
                path = os.fsdecode(args[0])
                if path.startswith(self.outside) or os.path.realpath(path).startswith(self.outside):
                    self.opened.append(path)
            except Exception:       # noqa: BLE001: an audit hook must never raise into the caller
                pass

    def case(self, path: str, render: bool) -> dict:
        import numpy as np
        from clrender import SceneError
        self.opened = []
        out: dict = {"warnings": []}
        peak_ok = _reset_peak()
        base_rss = _status("VmRSS")
        base_max = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024
        t0 = time.perf_counter()
        stage = "load"
        caught: list = []
        try:
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                scene = self.clrender.load_scene(path)
                out["load_s"] = time.perf_counter() - t0
                if render and self.renderer is not None:
                    stage = "render"
                    t1 = time.perf_counter()
                    frame = self.renderer.render(scene)
                    color, image = frame.color, frame.image
                    out["render_s"] = time.perf_counter() - t1
                    out["finite"] = bool(np.isfinite(color).all())
                    out["image_shape"] = list(image.shape)
                    out["triangles"] = int(len(scene.triangles))
            out["outcome"] = "ok"
        except BaseException as exc:        # noqa: BLE001: the test decides what is acceptable
            if isinstance(exc, KeyboardInterrupt):
                raise
            out["outcome"] = "error"
            out["stage"] = stage
            out["type"] = type(exc).__module__ + "." + type(exc).__qualname__
            out["scene_error"] = isinstance(exc, SceneError)
            out["value_error"] = isinstance(exc, ValueError)
            out["message"] = str(exc)
            # what a catch-all SceneError wrapped, if any ("raise ... from None" hides its context on purpose)
            cause = exc.__cause__ or (None if exc.__suppress_context__ else exc.__context__)
            if cause is not None:
                out["cause"] = type(cause).__module__ + "." + type(cause).__qualname__
                out["cause_memory"] = isinstance(cause, MemoryError)
                out["cause_recursion"] = isinstance(cause, RecursionError)
            out["traceback"] = "".join(traceback.format_exception(exc)[-12:])
        out["warnings"] = [f"{w.category.__name__}: {w.message}" for w in caught]
        out["seconds"] = time.perf_counter() - t0
        # without clear_refs, ru_maxrss only shows growth beyond the worker's earlier peak
        out["rss_growth"] = (_status("VmHWM") - base_rss) if peak_ok else \
            resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024 - base_max
        out["opened_outside"] = self.opened
        return out


def main(argv) -> int:
    config = json.loads(argv[1])
    proto = os.fdopen(os.dup(1), "w", buffering=1)
    os.dup2(2, 1)                       # prints of the code under test go to the log, not the protocol
    if config.get("max_memory"):
        os.environ["CLRENDER_MAX_MEMORY"] = str(config["max_memory"])
    worker = Worker(config.get("device"), config["outside"], config.get("render", True))
    for path in config.get("warm", []):             # build every kernel the seeds need, untimed
        result = worker.case(path, True)
        if result["outcome"] != "ok":
            proto.write(json.dumps({"fatal": f"seed {path} failed: {result.get('type')}: "
                                             f"{result.get('message')}"}) + "\n")
            return 1
    limit = _status("VmSize") + HEADROOM
    resource.setrlimit(resource.RLIMIT_AS, (limit, resource.getrlimit(resource.RLIMIT_AS)[1]))
    proto.write(json.dumps({"ready": True, "rss": _status("VmRSS"), "as_limit": limit,
                            "peak_reset": _reset_peak()}) + "\n")
    for line in sys.stdin:
        request = json.loads(line)
        proto.write(json.dumps(worker.case(request["path"], request.get("render", True))) + "\n")
    return 0


if __name__ == "__main__":
    if len(sys.argv) == 3 and sys.argv[1] == "--replay":
        print(json.dumps(Worker(None, "/nonexistent", True).case(sys.argv[2], True), indent=1))
        sys.exit(0)
    sys.exit(main(sys.argv))
