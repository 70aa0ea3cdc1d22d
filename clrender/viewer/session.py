"""The viewer's render loop: one thread owns the renderers and the scene; the newest view wins.

Browser events (camera moves, panel changes, clicks) arrive on viser's threads and only *submit*
a `ViewState`; nothing queues: a submit replaces the state not yet taken, so a camera that moved
five times while a frame rendered is rendered once, where it is now. The loop then renders

* a **preview** (`PREVIEW_SCALE`² of the pixels, anti-aliasing off: msaa 1, supersample 1, no
  edge AA or FXAA) for a state submitted while the camera moves, and
* the **full** frame (the configured size and anti-aliasing) once no newer state came for
  `settle_s`, or at once for a state that is not a camera move (a panel change, a pinned camera).

A frame is published with what it showed (`Shown`); the server turns it into the page's picture.
Panel changes that only change how a frame is drawn (the AOV shown, the highlight) re-publish the
last frame (`republish`) without rendering. The loop has no viser in it: tests drive it directly.
"""
from __future__ import annotations

import dataclasses
import threading
import time
from time import monotonic
from collections import OrderedDict, deque
from dataclasses import dataclass, field
from typing import Callable, Optional

from clrender.config import RenderConfig
from clrender.scene.camera import Camera

PREVIEW_SCALE = 0.5            # a preview frame is (W/2) x (H/2): a quarter of the pixels
SETTLE_S = 0.12                # no camera move for this long: the full frame follows ...
SETTLE_MAX_S = 0.5             # ... or 1.5x the recent gap between moves (a slow page), up to this
HISTORY = 256                  # frames whose timings RenderLoop.history keeps
RENDERERS_KEPT = 4             # (size, config) renderers kept warm (a preview and a full one, twice)
# What a preview leaves out: anti-aliasing, the part of the cost that scales with samples.
PREVIEW_OPTIONS = {"msaa": 1, "supersample": 1, "edge_aa": False, "color_aa": "none"}


@dataclass(frozen=True)
class ViewState:
    """Everything a frame depends on. `environment` is the Environment to light with (None: none),
    `environment_key` what names it (compared instead of the arrays)."""
    camera: Camera
    width: int
    height: int
    config: RenderConfig
    time: float = 0.0
    environment_key: object = "scene"
    environment: object = field(default=None, compare=False)
    moving: bool = False              # submitted while the camera moves: a preview first
    submitted: float = field(default_factory=monotonic, compare=False)    # when the change arrived


@dataclass(frozen=True)
class Shown:
    """A published frame: the state it rendered, full or preview, and its Frame."""
    state: ViewState
    full: bool
    frame: object                     # clrender Frame
    seconds: float                    # render() wall time
    started: float = 0.0              # time.monotonic() when its render began
    published: float = 0.0            # ... and when its picture was handed to the page


class RenderLoop:
    """`render(state, full) -> Frame` on the loop's thread; `publish(Shown)` after each frame;
    `on_error(exc, state)` for a frame that failed (the loop keeps running)."""

    def __init__(self, render: Callable, publish: Callable, on_error: Callable, settle_s: float = SETTLE_S):
        self._render, self._publish, self._on_error = render, publish, on_error
        self.settle_s = float(settle_s)
        self._cond = threading.Condition()
        self._pending: Optional[ViewState] = None
        self._needs_full: Optional[ViewState] = None      # a preview was shown; its full frame is owed
        self._last_move = 0.0
        self._move_gap: Optional[float] = None             # recent gap between camera moves (EMA)
        self._stop = False
        self.busy = False                                  # a frame is rendering (the status line reads it)
        self.last: Optional[Shown] = None
        self.last_full: Optional[Shown] = None
        self.counts = {"preview": 0, "full": 0, "dropped": 0}
        self.history: deque = deque(maxlen=HISTORY)        # the last frames' Shown (bench/viewer.py reads it)
        self._thread = threading.Thread(target=self._run, name="clrender-view-render", daemon=True)
        self._thread.start()

    def submit(self, state: ViewState) -> None:
        with self._cond:
            if self._pending is not None:
                self.counts["dropped"] += 1                # replaced before it was taken: never rendered
            self._pending = state
            if state.moving:
                now = time.monotonic()
                gap = now - self._last_move
                if gap < SETTLE_MAX_S:                     # a page that sends its camera slowly
                    self._move_gap = gap if self._move_gap is None else 0.7 * self._move_gap + 0.3 * gap
                self._last_move = now
            self._cond.notify_all()

    def republish(self) -> None:
        """Publish the last frame again (the AOV shown or the highlight changed)."""
        shown = self.last
        if shown is not None:
            self._publish(shown)

    def wait_idle(self, timeout: float = 60.0) -> bool:
        """Block until nothing is pending, owed or rendering (tests, the handle): True if so."""
        deadline = time.monotonic() + timeout
        with self._cond:
            while self._pending is not None or self._needs_full is not None or self.busy:
                left = deadline - time.monotonic()
                if left <= 0:
                    return False
                self._cond.wait(min(left, 0.05))
        return True

    def close(self, timeout: float = 30.0) -> None:
        with self._cond:
            self._stop = True
            self._cond.notify_all()
        if self._thread is not threading.current_thread():
            self._thread.join(timeout)

    # -- the loop ----------------------------------------------------------------------------
    def _next(self) -> Optional[tuple[ViewState, bool]]:
        """(state, full) to render next, waiting as needed; None when stopping."""
        with self._cond:
            while not self._stop:
                if self._pending is not None:
                    state, self._pending = self._pending, None
                    full = not state.moving
                    self._needs_full = None if full else state
                    self.busy = True
                    return state, full
                if self._needs_full is not None:
                    settle = min(SETTLE_MAX_S, max(self.settle_s, 1.5 * (self._move_gap or 0.0)))
                    left = settle - (time.monotonic() - self._last_move)
                    if left <= 0:
                        state, self._needs_full = self._needs_full, None
                        self.busy = True
                        return dataclasses.replace(state, moving=False), True
                    self._cond.wait(left)
                else:
                    self._cond.wait()
            return None

    def _run(self) -> None:
        while True:
            job = self._next()
            if job is None:
                return
            state, full = job
            try:
                started = time.monotonic()
                frame = self._render(state, full)
                shown = Shown(state, full, frame, time.monotonic() - started, started)
                self.last = shown
                if full:
                    self.last_full = shown
                self.counts["full" if full else "preview"] += 1
                self._publish(shown)
                self.history.append(dataclasses.replace(shown, published=time.monotonic()))
            except Exception as exc:                       # one bad frame must not end the viewer
                self._on_error(exc, state)
            finally:
                with self._cond:
                    self.busy = False
                    self._cond.notify_all()


class Renderers:
    """The Renderer of each (width, height, config), the last RENDERERS_KEPT kept (programs are
    shared by the device's cache: a new one only allocates its buffers)."""

    def __init__(self, device, first=None):
        self.device = device
        self._kept: OrderedDict = OrderedDict()
        if first is not None:
            self._kept[(first.width, first.height, first.config)] = first

    def get(self, width: int, height: int, config: RenderConfig):
        key = (width, height, config)
        renderer = self._kept.get(key)
        if renderer is None:
            from clrender.render.renderer import Renderer
            renderer = Renderer(width, height, device=self.device.info, config=config)
            self._kept[key] = renderer
            while len(self._kept) > RENDERERS_KEPT:
                self._kept.popitem(last=False)
        self._kept.move_to_end(key)
        return renderer

    def clear(self) -> None:
        self._kept.clear()


def preview_config(config: RenderConfig) -> RenderConfig:
    return dataclasses.replace(config, **PREVIEW_OPTIONS)


def preview_size(width: int, height: int, scale: float = PREVIEW_SCALE) -> tuple[int, int]:
    return max(1, int(width * scale)), max(1, int(height * scale))
