"""Ctrl-C that always ends a job: when the last SIGINT arrived, and imports that cannot swallow one.

A SIGINT becomes KeyboardInterrupt on the main thread, but what it interrupts elsewhere can turn
it into an ordinary error first: a kernel build whose compiler child process died of the same
Ctrl-C (the terminal signals the whole process group) fails with BUILD_PROGRAM_FAILURE on the
warm-up thread, and trimesh's import wraps its optional imports in `except BaseException`, so a
Ctrl-C there is swallowed and the job runs on. `install()` (the CLI) records each SIGINT, so code
that catches errors can ask `interrupted_since(start)` and re-raise KeyboardInterrupt instead of
reporting a failure; `import_deferring_interrupts(name)` holds a SIGINT back until an import is
done and then raises it.
"""
from __future__ import annotations

import importlib
import signal
import sys
import threading
import time
from typing import Optional

_STATE = {"last": None}          # time.monotonic() of the last SIGINT seen by `install`'s handler


def _handler(signum, frame):
    _STATE["last"] = time.monotonic()
    raise KeyboardInterrupt


def install() -> None:
    """Record every SIGINT (and still raise KeyboardInterrupt on the main thread, as Python does).
    Only from the main thread, and only over Python's own default handler."""
    if threading.current_thread() is not threading.main_thread():
        return
    if signal.getsignal(signal.SIGINT) is signal.default_int_handler:
        signal.signal(signal.SIGINT, _handler)


def interrupted_since(start: float) -> bool:
    """Whether a SIGINT arrived at or after `start` (a time.monotonic() value)."""
    last = _STATE["last"]
    return last is not None and last >= start


def raise_if_interrupted(start: float) -> None:
    """Raise KeyboardInterrupt when a SIGINT arrived since `start`: call it in an `except` clause
    so a failure caused by the interrupt ends the job as an interrupt, not as an error."""
    if interrupted_since(start):
        raise KeyboardInterrupt


def import_deferring_interrupts(name: str) -> Optional[object]:
    """Import module `name` with SIGINT held back until it is done, then raise KeyboardInterrupt
    if one came. On another thread (no SIGINT is delivered there) or when already imported: a
    plain import."""
    module = sys.modules.get(name)
    if module is not None:
        return module
    if threading.current_thread() is not threading.main_thread():
        return importlib.import_module(name)
    got = []
    previous = signal.signal(signal.SIGINT, lambda signum, frame: got.append(time.monotonic()))
    try:
        module = importlib.import_module(name)
    finally:
        signal.signal(signal.SIGINT, previous)
    if got:
        _STATE["last"] = got[-1]
        # the module may hold stand-ins for what the Ctrl-C cut short (trimesh's ExceptionWrapper):
        # a caller that goes on after the interrupt imports it afresh
        for key in [k for k in sys.modules if k == name or k.startswith(name + ".")]:
            del sys.modules[key]
        raise KeyboardInterrupt
    return module
