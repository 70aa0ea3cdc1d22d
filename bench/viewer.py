"""`clrender view` in a browser (issue 39): preview rate, camera-to-pixels latency, and the wait
for the full frame once the camera stops.

    python -m bench.viewer [--scene PATH] [--device NAME] [--width 1280] [--height 720]
                           [--preview-scale 0.375] [--seconds 5] [--rounds 3] [--rate 30]
                           [--transport jpeg|png] [--screenshots DIR]

Crytek Sponza (bench.common.SPONZA; scenes/demo.toml, with a note in the record, when the shared
scenes are absent) in `clrender.view` at --width x --height, previews at --preview-scale of that
(0.375: 480x270 for 1280x720), JPEG frames as users get them, in headless Chromium (selenium,
/usr/bin/chromium + chromedriver) whose page is exactly --width x --height CSS pixels at device
scale 1. The camera is driven from Python as a user's drag drives it: the page's camera is set
(viser's `client.camera.position/look_at`, sent to the browser) --rate times a second along an
orbit through the atrium; the browser moves its camera and sends it back over the websocket, as
it does for the mouse, and the viewer renders what comes back. So every latency below includes
the browser's round trip.

One warm-up orbit (programs, renderers of both sizes, the page), then --rounds orbits of
--seconds each, each followed by a stop (the camera left still until the full frame is shown).
Per round, from the viewer's frame log (RenderLoop.history: Shown with state.submitted, started,
published):

* preview frames per second while moving (previews published in the orbit's window / its length);
* camera-to-pixels latency per preview: the camera's arrival from the page (state.submitted) to
  its frame handed to the page (published), and from Python setting the page's camera to that
  publish (matched by the camera's eye: the round trip through the browser included);
* stop -> full frame: from the last camera move's arrival (and from the last set) to the full
  frame's render start and to its publish (the settle time, SETTLE_S, is part of it);
* render time of preview and full frames (Shown.seconds: render() and reading the image).

Medians (and p90 of the latencies) over the rounds' frames; printed, and written to
bench/results/viewer-*.json with the device, the machine (cores, load average) and the browser.
Targets (issue 39): >= 8 preview frames/s and <= 250 ms from the last camera move to the full
1280x720 frame's start on a 2-core machine.

--screenshots DIR: after the measurement, page screenshots (--width x --height) of the first frame
with the panel, a view after an orbit, the object_id AOV, a pick shown, and the saved-view
notice, as DIR/viewer-{first,orbit,object-id,pick,saved}.png, quantized to a palette so each
stays small (the README's pictures: --screenshots docs/images).
"""
from __future__ import annotations

import argparse
import io
import math
import os
import shutil
import socket
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from bench.common import REPO, SPONZA, write_record
from clrender.dataset.views import quaternion_from_rotation

DEMO = REPO / "scenes" / "demo.toml"
# An orbit inside Sponza's atrium (world units): the eye swings on an ellipse round the atrium's
# centre (semi-axes along x and z: it stays between the colonnades) looking at the centre;
# ORBIT_PERIOD_S per full swing, ORBIT_SWING_DEG to either side.
ATRIUM_CENTRE = np.array([0.0, 5.5, -0.5])
ATRIUM_AXES = (9.0, 2.6)
ORBIT_SWING_DEG, ORBIT_PERIOD_S = 70.0, 5.0
SCREENSHOT_COLOURS = (192, 128, 96, 64)   # palette sizes tried, largest first, for a screenshot PNG ...
SCREENSHOT_MAX_BYTES = 400_000            # ... under this size (the README's pictures)


def free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def percentile(values, q: float) -> float:
    return float(np.percentile(np.asarray(values, np.float64), q)) if values else float("nan")


def median(values) -> float:
    return float(statistics.median(values)) if values else float("nan")


def orbit_pose(t: float, centre: np.ndarray, radius) -> tuple[np.ndarray, np.ndarray]:
    """(eye, target) at time t of the scripted orbit round `centre`: the eye on a horizontal
    ellipse of semi-axes `radius` (x, z), swinging ORBIT_SWING_DEG either side, bobbing a little,
    looking at the centre."""
    rx, rz = radius
    a = math.radians(ORBIT_SWING_DEG) * math.sin(2 * math.pi * t / ORBIT_PERIOD_S)
    eye = centre + np.array([-rx * math.cos(a), 0.08 * rx * math.sin(2 * a), rz * math.sin(a)])
    return eye, centre.copy()


def start_browser(width: int, height: int):
    from selenium import webdriver
    from selenium.webdriver.chrome.options import Options
    from selenium.webdriver.chrome.service import Service
    chromium = shutil.which("chromium") or "/usr/bin/chromium"
    driver = shutil.which("chromedriver") or "/usr/bin/chromedriver"
    options = Options()
    for arg in ("--headless=new", "--no-sandbox", "--disable-dev-shm-usage", f"--window-size={width},{height + 150}"):
        options.add_argument(arg)
    options.binary_location = chromium
    d = webdriver.Chrome(options=options, service=Service(driver))      # no selenium-manager lookup
    d.execute_cdp_cmd("Emulation.setDeviceMetricsOverride",
                      {"width": width, "height": height, "deviceScaleFactor": 1, "mobile": False})
    return d


def page_url(viewer) -> str:
    """The viewer's URL with the page's resolution fixed: viser otherwise lowers the canvas's
    pixel ratio after a run of slow (software WebGL) frames, and the picture is resampled."""
    url = viewer.url
    return url if "fixedDpr" in url else url.rstrip("/") + "/?fixedDpr=1"


def connect(d, viewer, timeout: float = 60.0):
    from selenium.webdriver.common.by import By
    d.get(page_url(viewer))
    deadline = time.monotonic() + timeout
    while not viewer.server.get_clients():
        if time.monotonic() > deadline:
            raise SystemExit(f"the page at {viewer.url} did not connect in {timeout:.0f} s")
        time.sleep(0.05)
    for button in d.find_elements(By.CSS_SELECTOR, "button.mantine-Notification-closeButton"):
        if button.is_displayed():            # "Software WebGL rendering detected"
            button.click()
    return next(iter(viewer.server.get_clients().values()))


def set_camera(client, eye, target, up=(0.0, 1.0, 0.0)) -> None:
    with client.atomic():
        client.camera.position = tuple(float(v) for v in eye)
        client.camera.look_at = tuple(float(v) for v in target)
        client.camera.up_direction = up


def wait_full(viewer, after: float, timeout: float = 60.0):
    """The first full frame published after monotonic time `after`, once the viewer is idle."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        viewer.wait_idle(timeout)
        time.sleep(0.3)                      # a last camera echo from the page may still arrive
        if viewer.wait_idle(0.01):
            fulls = [s for s in viewer.loop.history if s.full and s.started >= after]
            if fulls:
                return fulls[-1]
    raise SystemExit(f"no full frame within {timeout:.0f} s of the stop")


def look_at_wxyz(eye, target, up=(0.0, 1.0, 0.0)) -> tuple:
    """viser's camera orientation (OpenCV axes: x right, y down, z forward) as a quaternion wxyz."""
    z = np.asarray(target, np.float64) - eye
    z /= np.linalg.norm(z)
    x = np.cross(z, np.asarray(up, np.float64))          # right
    x /= np.linalg.norm(x)
    return tuple(quaternion_from_rotation(np.stack([x, np.cross(z, x), z], 1)))     # y = z × x: down


class DirectDrive:
    """The camera handed to the viewer as the page's camera message would hand it, without the
    browser's round trip (what a page with a GPU sends: viser throttles to 50 Hz); the page still
    receives and shows every frame."""

    def __init__(self, viewer, client, arrivals: list):
        self.viewer, self.client, self.arrivals = viewer, client, arrivals

    def __call__(self, eye, target) -> None:
        from types import SimpleNamespace
        cam = self.client.camera
        handle = SimpleNamespace(position=eye, look_at=target, wxyz=look_at_wxyz(eye, target), fov=cam.fov,
                                 image_width=cam.image_width, image_height=cam.image_height)
        self.arrivals.append(time.monotonic())
        self.viewer._camera_moved(handle)          # what viser's camera callback calls


def page_drive(client):
    return lambda eye, target: set_camera(client, eye, target)


def orbit(viewer, drive, seconds: float, rate: float, centre, radius, t0: float = 0.0) -> list:
    """Move the camera `rate` times a second for `seconds` (drive(eye, target)); [(time, eye)]."""
    sets, period = [], 1.0 / rate
    start = time.monotonic()
    k = 0
    while True:
        due = start + k * period
        now = time.monotonic()
        if due - start > seconds:
            break
        if due > now:
            time.sleep(due - now)
        eye, target = orbit_pose(t0 + k * period, centre, radius)
        sets.append((time.monotonic(), eye))
        drive(eye, target)
        k += 1
    return sets


def measure_round(viewer, drive, seconds: float, rate: float, centre, radius, t0: float, arrivals: list) -> dict:
    begin = time.monotonic()
    arrivals.clear()
    sets = orbit(viewer, drive, seconds, rate, centre, radius, t0)
    gaps = np.diff([t for t in arrivals if t <= sets[-1][0] + 0.5]) * 1e3
    stop = sets[-1][0]
    full = wait_full(viewer, stop)
    shown = [s for s in viewer.loop.history if s.started >= begin]
    previews = [s for s in shown if not s.full]
    moving = [s for s in previews if s.published <= stop + 0.5]
    window = max(stop - begin, 1e-6)
    eyes = np.array([e for _, e in sets])
    set_times = np.array([t for t, _ in sets])
    scale = float(np.linalg.norm(eyes[0] - centre)) or 1.0
    from_set = []
    for s in previews:                       # the latest set before it whose eye this preview shows
        dist = np.linalg.norm(eyes - np.asarray(s.state.camera.eye), axis=1)
        hits = np.nonzero((dist <= 1e-5 * scale) & (set_times <= s.state.submitted))[0]
        if len(hits):
            from_set.append((s.published - set_times[hits[-1]]) * 1e3)
    moves = [s.state.submitted for s in shown if s.state.moving]
    last_move = max(moves) if moves else stop
    return {
        "seconds": window, "camera_sets": len(sets), "camera_messages": int(len(gaps) + 1),
        "camera_message_interval_ms_median": median(list(gaps)),
        "full_frames_while_moving": sum(1 for s in shown if s.full and s.started <= stop),
        "previews": len(previews), "full_frames": sum(1 for s in shown if s.full),
        "preview_fps": len(moving) / window,
        "preview_latency_ms": [(s.published - s.state.submitted) * 1e3 for s in previews],
        "preview_latency_from_set_ms": from_set,
        "preview_render_ms": [s.seconds * 1e3 for s in previews],
        "preview_pass_ms": pass_medians(previews), "full_pass_ms": pass_medians([full]),
        "stop_to_full_start_ms": (full.started - last_move) * 1e3,
        "stop_to_full_published_ms": (full.published - last_move) * 1e3,
        "set_stop_to_full_start_ms": (full.started - stop) * 1e3,
        "set_stop_to_full_published_ms": (full.published - stop) * 1e3,
        "full_render_ms": full.seconds * 1e3,
        "full_size": [full.frame.width, full.frame.height],
        "preview_size": [previews[0].frame.width, previews[0].frame.height] if previews else None,
    }


def pass_medians(shown: list) -> dict:
    """Median device ms of each pass over the frames (Frame.stats' *_ms)."""
    from clrender.render.stats import pass_ms
    per = [pass_ms(s.frame.stats) for s in shown]
    return {k: median([p[k] for p in per if k in p]) for k in (per[0] if per else {})}


def summarize(rounds: list) -> dict:
    def pooled(key):
        return [v for r in rounds for v in r[key]]
    lat, lat_set = pooled("preview_latency_ms"), pooled("preview_latency_from_set_ms")
    return {
        "preview_fps_median": median([r["preview_fps"] for r in rounds]),
        "preview_latency_ms_median": median(lat), "preview_latency_ms_p90": percentile(lat, 90),
        "preview_latency_from_set_ms_median": median(lat_set),
        "preview_latency_from_set_ms_p90": percentile(lat_set, 90),
        "preview_render_ms_median": median(pooled("preview_render_ms")),
        "stop_to_full_start_ms_median": median([r["stop_to_full_start_ms"] for r in rounds]),
        "stop_to_full_published_ms_median": median([r["stop_to_full_published_ms"] for r in rounds]),
        "set_stop_to_full_start_ms_median": median([r["set_stop_to_full_start_ms"] for r in rounds]),
        "set_stop_to_full_published_ms_median": median([r["set_stop_to_full_published_ms"] for r in rounds]),
        "full_render_ms_median": median([r["full_render_ms"] for r in rounds]),
    }


# -- screenshots --------------------------------------------------------------------------------
def save_screenshot(d, folder: Path, step: str) -> Path:
    """The page as a palette PNG, the most colours of SCREENSHOT_COLOURS that keep it under
    SCREENSHOT_MAX_BYTES: the README's pictures stay small. The mouse is parked first (a hovered
    control shows its hint)."""
    from PIL import Image
    from selenium.webdriver.common.action_chains import ActionChains
    from selenium.webdriver.common.by import By
    canvas = d.find_element(By.TAG_NAME, "canvas")
    size = canvas.size
    ActionChains(d).move_to_element_with_offset(canvas, -size["width"] // 2 + 8, size["height"] // 2 - 8).perform()
    time.sleep(0.5)
    image = Image.open(io.BytesIO(d.get_screenshot_as_png())).convert("RGB")
    path = folder / f"viewer-{step}.png"
    for colours in SCREENSHOT_COLOURS:
        small = image.quantize(colours, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE)
        small.save(path, optimize=True)
        if path.stat().st_size <= SCREENSHOT_MAX_BYTES:
            break
    print(f"  {path} ({path.stat().st_size // 1024} KB)")
    return path


def choose(d, label: str, option: str) -> None:
    """Pick `option` in the panel's select labelled `label`, as a user does."""
    from selenium.webdriver.common.by import By
    for element in d.find_elements(By.TAG_NAME, "label"):
        if element.text.strip() == label:
            field = d.find_element(By.ID, element.get_attribute("for"))
            field.click()
            deadline = time.monotonic() + 5
            while time.monotonic() < deadline:
                for opt in d.find_elements(By.CSS_SELECTOR, "[role=option]"):
                    if opt.is_displayed() and opt.text.strip() == option:
                        opt.click()
                        return
                time.sleep(0.1)
    raise SystemExit(f"the page has no select {label!r} with the option {option!r}")


def pick_pixel(frame, panel_w: int = 360) -> tuple[int, int]:
    """A pixel well inside the largest object seen left of the panel (Sponza: not the floor's edge)."""
    oid = frame.object_id
    h, w = oid.shape
    free = np.zeros(oid.shape, bool)
    free[h // 5:h - h // 5, w // 8:w - panel_w]= True
    ids, counts = np.unique(oid[free & (oid >= 0)], return_counts=True)
    target = int(ids[np.argmax(counts)])
    inside = free & (oid == target)
    for axis in (0, 1):
        for shift in (1, 2, 3, 4):
            inside &= np.roll(oid == target, shift, axis) & np.roll(oid == target, -shift, axis)
    ys, xs = np.nonzero(inside)
    k = int(np.argmin((xs - xs.mean()) ** 2 + (ys - ys.mean()) ** 2))
    return int(xs[k]), int(ys[k])


def screenshots(d, viewer, client, folder: Path, centre, radius, width: int, height: int) -> list:
    from selenium.webdriver.common.action_chains import ActionChains
    from selenium.webdriver.common.by import By
    folder.mkdir(parents=True, exist_ok=True)
    out = []
    pose = orbit_pose(0.0, centre, radius)                                # the first view, the panel open
    set_camera(client, *pose)
    wait_full(viewer, time.monotonic())
    time.sleep(1.0)
    out.append(save_screenshot(d, folder, "first"))
    orbit(viewer, page_drive(client), 0.5, 30.0, centre, radius, t0=0.0)           # swung ~40 degrees
    wait_full(viewer, time.monotonic() - 0.5)
    time.sleep(1.0)
    out.append(save_screenshot(d, folder, "orbit"))
    choose(d, "show", "object_id")
    time.sleep(1.5)
    out.append(save_screenshot(d, folder, "object-id"))
    choose(d, "show", "image")
    x, y = pick_pixel(viewer.frame)
    canvas = d.find_element(By.TAG_NAME, "canvas")
    ActionChains(d).move_to_element_with_offset(canvas, x - width // 2, y - height // 2).click().perform()
    deadline = time.monotonic() + 10
    while viewer.last_pick is None and time.monotonic() < deadline:
        time.sleep(0.05)
    time.sleep(1.5)
    out.append(save_screenshot(d, folder, "pick"))
    for button in d.find_elements(By.TAG_NAME, "button"):
        if button.text.strip() == "save view":
            button.click()
            break
    time.sleep(1.0)
    out.append(save_screenshot(d, folder, "saved"))
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scene", default=None, help="scene to view (default: Sponza, else scenes/demo.toml)")
    ap.add_argument("--device", default=None)
    ap.add_argument("--width", type=int, default=1280)
    ap.add_argument("--height", type=int, default=720)
    ap.add_argument("--preview-scale", type=float, default=0.375)
    ap.add_argument("--seconds", type=float, default=5.0, help="length of each measured orbit")
    ap.add_argument("--rounds", type=int, default=3, help="measured orbits (each followed by a stop)")
    ap.add_argument("--warmup", type=float, default=2.0, help="seconds of the warm-up orbit")
    ap.add_argument("--rate", type=float, default=30.0, help="camera updates per second")
    ap.add_argument("--transport", choices=("jpeg", "png"), default="jpeg")
    ap.add_argument("--modes", nargs="+", choices=("page", "direct", "no-page"), default=["page", "direct", "no-page"],
                    help="page: the camera set in the browser, which sends it back (its round trip timed); "
                         "direct: handed to the viewer as the page's message would be; no-page: as direct with "
                         "the browser closed (the render machine's share alone: a page on another machine)")
    ap.add_argument("--screenshots", type=Path, default=None, metavar="DIR")
    args = ap.parse_args(argv)

    try:
        import selenium
        import viser
    except ImportError as exc:
        raise SystemExit(f"bench.viewer needs viser and selenium (pip install -e '.[view,test]'): {exc}")
    import clrender

    note = None
    if args.scene is not None:
        scene_path = Path(args.scene)
    elif SPONZA.is_file():
        scene_path = SPONZA
    else:
        scene_path = DEMO
        note = f"{SPONZA} not found: measured on {DEMO.name} instead"
        print(f"note: {note}")
    scene = clrender.load_scene(scene_path)
    lo, hi = (np.asarray(b, np.float64) for b in scene.bounds())
    if scene_path == SPONZA:
        centre, radius = ATRIUM_CENTRE, ATRIUM_AXES
    else:
        centre = (lo + hi) / 2
        radius = (0.9 * float(np.linalg.norm(hi - lo)),) * 2

    camera_dir = Path(tempfile.mkdtemp(prefix="clrender-bench-viewer-"))
    viewer = clrender.view(scene, width=args.width, height=args.height, device=args.device, port=free_port(),
                           transport=args.transport, preview_scale=args.preview_scale, show=False,
                           cameras=str(camera_dir / "views.json"))
    d = None
    try:
        d = start_browser(args.width, args.height)
        client = connect(d, viewer)
        wait_full(viewer, 0.0)
        device = viewer.device.name
        arrivals: list = []
        client.camera.on_update(lambda _handle: arrivals.append(time.monotonic()))
        drives = {"page": page_drive(client), "direct": DirectDrive(viewer, client, arrivals)}
        print(f"{scene_path.name} on {device}: {args.width}x{args.height}, previews x{args.preview_scale} "
              f"({args.transport}), camera moved at {args.rate:g} Hz; warm-up {args.warmup:g} s")
        modes = {}

        def measure(mode, drive):
            if args.warmup > 0:
                orbit(viewer, drive, args.warmup, args.rate, centre, radius)
                wait_full(viewer, time.monotonic() - 0.5)
            rounds = []
            for r in range(args.rounds):
                res = measure_round(viewer, drive, args.seconds, args.rate, centre, radius, r * 1.3, arrivals)
                rounds.append(res)
                print(f"  {mode} round {r}: {res['camera_messages']} camera messages (every "
                      f"{res['camera_message_interval_ms_median']:.0f} ms), {res['previews']} previews "
                      f"{res['preview_size']} at {res['preview_fps']:.1f}/s, {res['full_frames_while_moving']} full "
                      f"frames while moving; latency median {median(res['preview_latency_ms']):.0f} ms (from set "
                      f"{median(res['preview_latency_from_set_ms']):.0f} ms); stop -> full start "
                      f"{res['stop_to_full_start_ms']:.0f} ms, published {res['stop_to_full_published_ms']:.0f} ms; "
                      f"full render {res['full_render_ms']:.0f} ms")
            passes = {k: median([r["preview_pass_ms"][k] for r in rounds if k in r["preview_pass_ms"]])
                      for k in rounds[0]["preview_pass_ms"]}
            modes[mode] = {"summary": summarize(rounds), "preview_pass_ms": passes, "rounds": rounds}
            print(f"{mode} medians: " + ", ".join(f"{k} {v:.1f}" for k, v in modes[mode]["summary"].items()))

        for mode in args.modes:
            if mode in drives:
                measure(mode, drives[mode])
        shots = []
        if args.screenshots is not None:
            shots = [str(p) for p in screenshots(d, viewer, client, args.screenshots, centre, radius,
                                                 args.width, args.height)]
        browser = f"chromium {d.capabilities.get('browserVersion', '?')} headless, software WebGL"
        if "no-page" in args.modes:             # the page closed: only the viewer's own work on this machine
            from types import SimpleNamespace
            page = SimpleNamespace(camera=SimpleNamespace(fov=client.camera.fov, image_width=args.width,
                                                          image_height=args.height))
            d.quit()
            d = None
            deadline = time.monotonic() + 30
            while viewer.server.get_clients() and time.monotonic() < deadline:
                time.sleep(0.1)
            measure("no-page", DirectDrive(viewer, page, arrivals))
        record = {
            "scene": scene_path.name, "note": note, "triangles": int(scene.triangle_count),
            "width": args.width, "height": args.height, "preview_scale": args.preview_scale,
            "transport": args.transport, "rate_hz": args.rate, "seconds": args.seconds, "rounds_n": args.rounds,
            "warmup_s": args.warmup, "device": device, "config": {k: getattr(viewer.config, k) for k in vars(viewer.config)},
            "settle_s": viewer.loop.settle_s, "counts": dict(viewer.loop.counts),
            "cores": os.cpu_count(), "load_average": list(os.getloadavg()),
            "browser": browser,
            "viser": viser.__version__, "selenium": selenium.__version__, "python": sys.version.split()[0],
            "modes": modes, "screenshots": shots,
            "targets": {"preview_fps_min": 8, "stop_to_full_start_ms_max": 250},
        }
        path = write_record("viewer", record)
        print(f"record: {path}")
    finally:
        if d is not None:
            d.quit()
        viewer.close()
        shutil.rmtree(camera_dir, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
