"""`clrender view`: the scene rendered by clrender, streamed into a web page by viser.

viser (the library nerfstudio's viewer is built on) serves the page (its three.js client ships in
its wheel), sends the camera back over its websocket as the mouse or a finger orbits, pans and
zooms, and shows our picture as the scene's background image. This module turns its camera into
clrender Cameras, owns the render loop (clrender/viewer/session.py: previews while moving, the full
frame once still, the newest camera wins) and the panels (clrender/viewer/panels.py), and answers
clicks from the frame's id buffers (clrender/viewer/pick.py).

Exactness: a camera from the page is put through the camera file's own conversion
(`camera_entry` then `entry_camera`, clrender/dataset/camera_file.py) before it is rendered, so
the frame shown at full resolution is bit for bit the one `clrender render --camera FILE` makes
from a saved view. Listed cameras (the scene file's, the camera file's) are rendered as they are,
until the page's camera leaves them.

Safety: the server binds to 127.0.0.1 unless told otherwise; a path typed in the page (an
environment) must lie in the scene's folder or one the command line allowed.
"""
from __future__ import annotations

import contextlib
import errno
import io
import math
import socket
import threading
import time
from pathlib import Path
from typing import Optional, Sequence

import numpy as np

from clrender.config import RenderConfig, check_int
from clrender.dataset.camera_file import (
    DEFAULT_FOV_DEG, append_camera, bounding_sphere, camera_entry, entry_camera, near_far, read_camera_file)
from clrender.dataset.views import rotation_from_quaternion
from clrender.scene.camera import Camera
from clrender.viewer.pick import highlight, pick, pick_markdown
from clrender.viewer.session import PREVIEW_SCALE, RenderLoop, Renderers, ViewState, preview_config, preview_size

LOCAL_HOSTS = ("127.0.0.1", "localhost", "::1")      # no warning for these (clrender/cli/view.py)
FOLLOW_MAX = (3840, 2160)       # the page's own size is followed up to this (a larger window: scaled down)
ENVIRONMENT_SUFFIXES = (".exr", ".hdr", ".pic")
PLAY_RATE_S = 0.1               # the animation's time advances this often while playing
JPEG_QUALITY = 90
FREE = "free (the page's)"      # the camera list's entry for a camera the page moved
FREE_CAMERA = object()          # camera_label(FREE_CAMERA) is FREE


class PortInUse(ValueError):
    pass


def check_port(host: str, port: int) -> None:
    """ValueError unless (host, port) can be listened on now (the server would pick another
    port silently; a user who asked for this one must hear that it is taken)."""
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    with socket.socket(family, socket.SOCK_STREAM) as s:
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)      # as the server does: TIME_WAIT is free
        try:
            s.bind((host, port))
        except OSError as exc:
            reason = "in use" if exc.errno == errno.EADDRINUSE else (exc.strerror or str(exc))
            raise PortInUse(f"port {port} on {host} is {reason} (choose another with --port)") from None


def _close(a, b, scale: float) -> bool:
    return bool(np.all(np.abs(np.subtract(a, b)) <= 1e-6 * scale))


class Viewer:
    """A running viewer. `scene`: a loaded Scene; `renderer`: a Renderer to start from (its device
    and config; its size unless width/height are given), else `device`/`config`."""

    def __init__(self, scene, *, renderer=None, device=None, config: Optional[RenderConfig] = None,
                 host: str = "127.0.0.1", port: int = 8080, width: Optional[int] = None,
                 height: Optional[int] = None, camera_file: Optional[str] = None, allow: Sequence = (),
                 transport: str = "jpeg", label: Optional[str] = None, preview_scale: float = PREVIEW_SCALE):
        if transport not in ("jpeg", "png"):
            raise ValueError(f"transport must be 'jpeg' or 'png', got {transport!r}")
        if not (isinstance(preview_scale, (int, float)) and 0.0 < preview_scale <= 1.0):
            raise ValueError(f"preview_scale must be in (0, 1], got {preview_scale!r}")
        self.scene, self.transport, self.preview_scale = scene, transport, float(preview_scale)
        source = Path(scene.source)
        self.folders = tuple(Path(f).resolve() for f in ((source.parent,) if source.exists() else ()) + tuple(allow))
        if renderer is not None:
            config = config or renderer.config
            if width is None and height is None:
                width, height = renderer.width, renderer.height
        self.config = config or RenderConfig()
        if (width is None) != (height is None):
            raise ValueError("give both width and height, or neither (then the page's size is followed)")
        self.fixed_size = None if width is None else (check_int("width", width, 1, 16384),
                                                      check_int("height", height, 1, 16384))
        self.centre, self.radius = bounding_sphere(scene.bounds())
        self.camera_file = Path(camera_file) if camera_file else Path(f"{source.stem or 'scene'}.cameras.json")
        self.listed = self._listed_cameras()
        self.animated = scene.animation is not None
        self.duration = float(scene.animation.duration) if self.animated else 0.0
        self.time = 0.0
        self._scene_environment = getattr(scene, "environment", None)
        self._lock = threading.RLock()
        self._state: Optional[ViewState] = None
        self._pinned: Optional[Camera] = scene.default_camera()     # the page starts at `clrender render`'s camera
        self._picked: Optional[int] = None        # object id highlighted
        self._highlight = True
        self._aov = "image"
        self._posed_time: Optional[float] = None
        self._playing = False
        self._closed = False
        self._environment = ("scene", self._scene_environment)     # (what names it, the Environment)
        self.last_pick = None
        self.errors: list[str] = []

        check_port(host, port)
        from clrender.device.probe import open_device
        self.device = renderer.device if renderer is not None else open_device(device)
        self.renderers = Renderers(self.device, renderer)
        if self.fixed_size is not None:          # a size the device cannot hold fails here, before the server
            self.renderers.get(*self.fixed_size, self.config)
        import viser
        with contextlib.redirect_stdout(io.StringIO()):          # its banner: the CLI prints the URL itself
            self.server = viser.ViserServer(host=host, port=port, label=label or f"clrender · {source.name}",
                                            verbose=False)
        if self.server.get_port() != port:
            self.server.stop()
            raise PortInUse(f"port {port} on {host} is in use (choose another with --port)")
        self.host, self.port = host, port
        self.server.scene.set_up_direction("+y")
        self._set_initial_camera(self._pinned)
        from clrender.viewer.panels import Panels
        self.panels = Panels(self)
        self.loop = RenderLoop(self._render, self._publish, self._on_error)
        self.server.on_client_connect(self._client_connected)
        self.server.scene.on_click()(self._clicked)
        self._ticker = threading.Thread(target=self._tick, name="clrender-view-status", daemon=True)
        self._ticker.start()
        if self.fixed_size is not None:          # the first frame renders before any page connects
            self._submit(camera=self._pinned, moving=False)

    # -- cameras -----------------------------------------------------------------------------
    def _listed_cameras(self) -> list[tuple[str, Camera]]:
        """(label, Camera): the camera file's views first (reopening a shot list), then the scene's."""
        out = []
        if self.camera_file.is_file():
            cf = read_camera_file(self.camera_file)
            w, h = self.fixed_size or (cf.width or 1280, cf.height or 720)
            for i, entry in enumerate(cf.entries):
                cam = entry_camera(entry, self.scene.bounds(), w, h, DEFAULT_FOV_DEG, cf.width, cf.height)
                out.append((f"file: {entry.get('name', f'view {i}')}", cam))
        for name, cam in getattr(self.scene, "cameras", None) or ():
            out.append((f"scene: {name}", cam))
        return out

    def camera_labels(self) -> list[str]:
        return [FREE] + [label for label, _ in self.listed]

    def camera_label(self, camera: Optional[Camera] = None) -> str:
        """The list's label of `camera` (default: the pinned one), FREE when it is not listed."""
        camera = camera or self._pinned
        return next((label for label, cam in self.listed if cam == camera), FREE)

    def _set_initial_camera(self, cam: Camera) -> None:
        ic = self.server.initial_camera
        ic.position, ic.look_at, ic.up = cam.eye, cam.target, cam.up
        ic.fov = math.radians(cam.fov_y_deg)

    def _move_clients(self, cam: Camera) -> None:
        for client in self.server.get_clients().values():
            with client.atomic():
                client.camera.position = cam.eye
                client.camera.look_at = cam.target
                client.camera.up_direction = cam.up
                client.camera.fov = math.radians(cam.fov_y_deg)

    def _page_camera(self, handle) -> Optional[Camera]:
        """The clrender Camera of the page's camera (viser: OpenCV axes in wxyz, vertical fov in
        radians): the pinned camera while the page shows it, else a perspective camera with near/far
        around the scene's bounds, put through the camera file's conversion."""
        eye = np.asarray(handle.position, np.float64)
        target = np.asarray(handle.look_at, np.float64)
        pinned = self._pinned
        scale = max(self.radius, float(np.linalg.norm(eye - self.centre)))
        if (pinned is not None and _close(eye, pinned.eye, scale) and _close(target, pinned.target, scale)
                and abs(math.degrees(float(handle.fov)) - pinned.fov_y_deg) < 1e-6):
            return pinned                                   # the page shows the listed camera (it stays pinned)
        up = -rotation_from_quaternion(handle.wxyz)[:, 1]  # OpenCV axes: y is down
        near, far = near_far(eye, self.centre, self.radius)
        w, h = self._size(handle)
        try:
            cam = Camera.look_at(tuple(eye), tuple(target), tuple(up), math.degrees(float(handle.fov)), near, far)
            return entry_camera(camera_entry(cam, w, h), self.scene.bounds(), w, h)
        except ValueError:                                  # eye on target, up along the view: keep the last
            return None

    def _size(self, handle=None) -> tuple[int, int]:
        if self.fixed_size is not None:
            return self.fixed_size
        if handle is None:
            state = self._state
            return (state.width, state.height) if state is not None else (1280, 720)
        w, h = max(int(handle.image_width), 16), max(int(handle.image_height), 16)
        k = min(1.0, FOLLOW_MAX[0] / w, FOLLOW_MAX[1] / h)
        return max(16, int(w * k)), max(16, int(h * k))

    def _client_connected(self, client) -> None:
        """A page connected (after its first camera message, which may still be viser's default
        view): it is moved to the pinned camera, or its own camera is rendered."""
        client.camera.on_update(self._camera_moved)
        if self._pinned is not None:
            self._move_clients(self._pinned)
            size, state = self._size(client.camera), self._state
            if state is None or state.camera != self._pinned or (state.width, state.height) != size:
                self._submit(camera=self._pinned, size=size, moving=False)   # else: already rendered
        else:
            self._camera_moved(client.camera, moving=False)

    def _camera_moved(self, handle, moving: bool = True) -> None:
        if self._closed:
            return
        with self._lock:
            size = self._size(handle)
            cam = self._page_camera(handle)
            if cam is None:
                return
            state = self._state
            if state is not None and state.camera == cam and (state.width, state.height) == size:
                return                                       # an echo of what is shown
            self._submit(camera=cam, size=size, moving=moving and cam is not self._pinned)
        label = self.camera_label(cam if cam is self._pinned else FREE_CAMERA)
        if self.panels.cameras.value != label:
            self.panels.cameras.value = label

    def select_camera(self, label: str) -> None:
        """Show a listed camera as it is (its projection, near/far; pinned until another is chosen)."""
        for name, cam in self.listed:
            if name == label:
                with self._lock:
                    self._pinned = cam
                    self._submit(camera=cam, moving=False)
                self._move_clients(cam)
                return

    def save_view(self) -> Optional[str]:
        """Append the full frame's camera (and time) to the camera file; the page lists it."""
        state = self._state
        if state is None:
            return None
        name = f"view {sum(label.startswith('file: ') for label, _ in self.listed) + 1}"
        entry = camera_entry(state.camera, state.width, state.height, time=state.time, name=name)
        try:
            count = append_camera(self.camera_file, entry, state.width, state.height)
        except (ValueError, OSError) as exc:
            self._notify("save view failed", str(exc), error=True)
            return None
        cam = entry_camera(entry, self.scene.bounds(), state.width, state.height)
        label = f"file: {name}"
        self.listed.insert(sum(label.startswith("file: ") for label, _ in self.listed), (label, cam))
        self._pinned = cam
        self.panels.set_camera_labels(self.camera_labels(), label)
        self._notify("view saved", f"{name}: camera {count} of {self.camera_file}")
        return label

    # -- panel setters -----------------------------------------------------------------------
    def set_option(self, name: str, value) -> bool:
        import dataclasses
        try:
            config = dataclasses.replace(self.config, **{name: value})
        except (ValueError, TypeError) as exc:
            self._notify(f"{name}: not applied", str(exc).splitlines()[0], error=True)
            return False
        with self._lock:
            self.config = config
            self._submit(moving=False)
        return True

    def set_aov(self, name: str) -> None:
        self._aov = name
        self.loop.republish()

    def set_highlight(self, on: bool) -> None:
        self._highlight = bool(on)
        self.loop.republish()

    def set_time(self, t: float, from_slider: bool = False) -> None:
        with self._lock:
            self.time = float(min(max(t, 0.0), self.duration))
            self._submit(moving=self._playing or from_slider)

    def set_playing(self, on: bool) -> None:
        self._playing = bool(on)
        if self._playing:
            threading.Thread(target=self._play, name="clrender-view-play", daemon=True).start()
        else:
            self.set_time(self.time)

    def _play(self) -> None:
        last = time.monotonic()
        while self._playing and not self._closed:
            time.sleep(PLAY_RATE_S)
            now = time.monotonic()
            t = self.time + (now - last)
            last = now
            if t > self.duration:
                t = 0.0 if self.duration > 0 else t
            with self._lock:
                self.time = t
                self._submit(moving=True)
            if self.panels.time is not None:
                self.panels.time.value = round(t, 4)

    def set_environment(self, kind: str, path: str, intensity: float, rotation: float) -> str:
        """Light with the scene's environment, none, studio or a file (confined to the allowed
        folders); returns the line the panel shows (an error keeps the viewer and its frame)."""
        from clrender.scene.environment import load_environment
        try:
            if not (math.isfinite(intensity) and intensity >= 0 and math.isfinite(rotation)):
                raise ValueError(f"intensity must be a finite number >= 0, got {intensity}")
            if kind == "scene":
                env = self._scene_environment
                if env is not None and (intensity != 1.0 or rotation != 0.0):
                    env = env.with_params(intensity=intensity, rotation_deg=rotation)
                key = ("scene", intensity, rotation)
            elif kind == "none":
                env, key = None, "none"
            elif kind == "studio":
                env, key = load_environment("studio", intensity, rotation), ("studio", intensity, rotation)
            else:
                if not path:
                    return "type the path of an .exr or .hdr file"
                file = self.confined(path)
                env, key = load_environment(str(file), intensity, rotation), (str(file), intensity, rotation)
        except (ValueError, OSError) as exc:
            message = str(exc).splitlines()[0]
            # no notification: the file field reports every keystroke, and error notifications
            # stay until closed (they pile up over the picture); the panel line shows it
            self.panels.message.content = f"**environment not changed:** {message}"
            return f"**error:** {message}"
        with self._lock:
            self._environment = (key, env)
            self._submit(moving=False)
        return f"lighting: {kind if kind != 'file' else path}"

    def confined(self, text: str) -> Path:
        """The file `text` names (relative to the scene's folder), if it lies in an allowed folder
        and exists; else ValueError (the path is not opened)."""
        base = self.folders[0] if self.folders else Path.cwd()
        path = (base / text).resolve()
        if not any(path == f or f in path.parents for f in self.folders):
            raise ValueError(f"{text}: outside the scene's folder (start the viewer with --allow-outside FOLDER to "
                             f"allow another folder)")
        if path.suffix.lower() not in ENVIRONMENT_SUFFIXES:
            raise ValueError(f"{text}: not an environment image (use {', '.join(ENVIRONMENT_SUFFIXES)})")
        if not path.is_file():
            raise ValueError(f"{text}: no such file")
        return path

    # -- the frames --------------------------------------------------------------------------

    def _submit(self, camera: Optional[Camera] = None, size=None, moving: bool = False) -> None:
        """Make the next ViewState from the current one and what changed, and hand it to the loop."""
        with self._lock:
            prev = self._state
            camera = camera or (prev.camera if prev is not None else self._pinned or self.scene.default_camera())
            w, h = size or self._size()
            key, env = self._environment
            state = ViewState(camera, w, h, self.config, self.time, key, env, moving)
            self._state = state
        self.loop.submit(state)

    def _render(self, state: ViewState, full: bool):
        scene = self.scene
        if self.animated and state.time != self._posed_time:
            scene.pose(state.time)
            self._posed_time = state.time
        scene.environment = state.environment
        w, h = (state.width, state.height) if full else preview_size(state.width, state.height, self.preview_scale)
        config = state.config if full else preview_config(state.config)
        renderer = self.renderers.get(w, h, config)
        frame = renderer.render(scene, state.camera, time=state.time)
        frame.image                                   # read now: the frame time includes it
        return frame

    def _publish(self, shown) -> None:
        frame = shown.frame
        image = frame.preview(self._aov)
        if self._highlight and self._picked is not None:
            image = highlight(image, frame.object_id == self._picked)
        self.server.scene.set_background_image(np.ascontiguousarray(image), format=self.transport,
                                               jpeg_quality=JPEG_QUALITY if self.transport == "jpeg" else None)
        self.panels.timing.content = self._timing_text(shown)

    @staticmethod
    def _timing_text(shown) -> str:
        from clrender.render.pipeline import pass_ms
        stats = shown.frame.stats
        kind = "full" if shown.full else "preview"
        passes = ", ".join(f"{k[:-3]} {v:.1f}" for k, v in pass_ms(stats).items())
        return (f"**{kind}** {shown.frame.width}×{shown.frame.height}: {shown.seconds * 1e3:.0f} ms "
                f"(render() {stats.get('wall_ms', 0.0):.0f} ms)  \npasses (ms): {passes}")

    def _on_error(self, exc: BaseException, state) -> None:
        message = f"{type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}"
        self.errors.append(message)
        self._notify("frame failed", message, error=True)

    def _clicked(self, event) -> None:
        shown = self.loop.last
        if shown is None:
            return
        frame = shown.frame
        u, v = event.screen_pos
        x = min(max(int(u * frame.width), 0), frame.width - 1)
        y = min(max(int(v * frame.height), 0), frame.height - 1)
        p = pick(frame, self.scene, x, y)
        self.last_pick = p
        self._picked = None if p is None else p.object_id
        self.panels.pick.content = pick_markdown(p)
        self.loop.republish()

    def _notify(self, title: str, body: str, error: bool = False) -> None:
        for client in self.server.get_clients().values():
            client.add_notification(title, body, auto_close_seconds=None if error else 4.0,
                                    color="red" if error else None)
        self.panels.message.content = f"**{title}:** {body}"

    def _tick(self) -> None:
        """The status line: building programs (the progress stage), rendering, ready."""
        from clrender import progress
        shown = None
        while not self._closed:
            time.sleep(0.25)
            if self._closed:
                return
            stage = progress.current()
            if stage is not None:
                text = f"{stage.what}: {stage.done}/{stage.total or '?'} ({stage.device})"
            else:
                text = "rendering…" if self.loop.busy else f"ready · {self.device.name}"
            if text != shown:
                self.panels.status.content = text
                shown = text

    # -- the handle --------------------------------------------------------------------------
    @property
    def url(self) -> str:
        host = f"[{self.host}]" if ":" in self.host else self.host
        # fixedDpr=1: viser otherwise lowers the canvas's pixel ratio after a run of slow frames
        # (software WebGL) and never raises it while idle: the full frame is then shown resampled
        return f"http://{host}:{self.port}/?fixedDpr=1"

    @property
    def camera(self) -> Optional[Camera]:
        state = self._state
        return None if state is None else state.camera

    @property
    def frame(self):
        """The last full-resolution Frame shown (None before the first)."""
        shown = self.loop.last_full
        return None if shown is None else shown.frame

    def wait_idle(self, timeout: float = 120.0) -> bool:
        return self.loop.wait_idle(timeout)

    def close(self, wait: bool = True) -> None:
        """Stop the render loop, release the renderers and stop the server. viser's stop waits
        about 6 s for its threads once a page has connected; `wait=False` leaves that to a daemon
        thread (a process about to exit: the CLI's Ctrl-C)."""
        if self._closed:
            return
        self._closed = True
        self._playing = False
        self.loop.close()
        self._ticker.join(2.0)
        self.renderers.clear()

        def stop():
            with contextlib.redirect_stdout(io.StringIO()):
                self.server.stop()
        if wait:
            stop()
        else:
            threading.Thread(target=stop, name="clrender-view-stop", daemon=True).start()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
