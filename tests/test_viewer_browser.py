"""`clrender view` in a real browser (issue 39): headless Chromium (selenium + Debian's chromium
and chromium-driver) loads the viewer's page and the test reads the page back as the user sees it
(a screenshot, less the control panel, the axes gizmo and notifications), so that what the page
shows is compared pixel for pixel with an independent `Renderer.render` of a freshly loaded scene:

* the first full frame, and the page's camera is the scene file's camera;
* a mouse drag on the canvas moves the camera: previews, then the full frame of the new camera;
* choosing the `object_id` AOV in the page's "show" dropdown shows the id colours;
* a click on the canvas picks the object under it, and the page names it;
* "save view" appends the camera to the camera file; `clrender render --camera FILE` renders
  from it the image the page showed, bit for bit;
* a missing or out-of-folder environment path typed in the page: an error in the page, the
  file is never opened, and the viewer keeps rendering.

The viewer runs with transport="png" (JPEG would make the comparison approximate). The page is
W x H CSS pixels at device scale 1 (CDP's device-metrics override), and the viewer renders at a
fixed W x H, so the canvas pixel (x, y) is the frame's pixel (x, y). The browser decodes each new
background asynchronously: the page is polled until it matches (up to CANVAS_WAIT_S), then the
last read is asserted. Frame rates and latencies are printed (`-s`), not asserted (bench/viewer.py
measures them). CLRENDER_SCREENSHOTS=DIR saves a page screenshot of each step as
DIR/viewer-{first,drag,object-id,pick,saved,environment-error}.png.

Needs the `view` and `test` extras (viser, selenium) and chromium + chromedriver on the PATH
(apt: chromium chromium-driver): skipped when absent, a failure in CI (tests/helpers.skip_or_fail).
"""
from __future__ import annotations

import importlib.util
import json
import io
import os
import shutil
import socket
import statistics
import threading
import time
from pathlib import Path

import numpy as np
import pytest

import clrender
from helpers import skip_or_fail

REPO = Path(__file__).resolve().parents[1]
DEMO = REPO / "scenes" / "demo.toml"
W, H = 800, 450
PANEL_W = 350                # viser's control panel covers the right of the page (drag/click left of it)
GIZMO = 72                   # viser's axes gizmo in the bottom-left corner
CANVAS_WAIT_S = 20.0         # the page decodes a new background asynchronously: poll this long
CONNECT_WAIT_S = 30.0
CLOSE_WAIT_S = 30.0
CLOSING: list = []           # viewers closing in the background (viser's stop() waits ~6 s once a page connected)


def free_port() -> int:
    """A TCP port nobody listens on now (the OS's choice of an ephemeral one)."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _executable(*names) -> str | None:
    for name in names:
        path = shutil.which(name) or (f"/usr/bin/{name}" if os.access(f"/usr/bin/{name}", os.X_OK) else None)
        if path:
            return path
    return None


@pytest.fixture(scope="module")
def browser():
    """One headless Chromium for the module (it takes seconds to start); each test loads its own
    viewer's page in it."""
    if importlib.util.find_spec("viser") is None:
        skip_or_fail("the browser tests need viser (pip install -e '.[view]')")
    try:
        from selenium import webdriver
        from selenium.common.exceptions import WebDriverException
        from selenium.webdriver.chrome.options import Options
        from selenium.webdriver.chrome.service import Service
    except ImportError as exc:
        skip_or_fail(f"the browser tests need selenium (pip install -e '.[test]'): {exc}")
    chromium = _executable("chromium", "chromium-browser", "google-chrome")
    driver = _executable("chromedriver")
    if chromium is None or driver is None:
        skip_or_fail("the browser tests need chromium and chromedriver (apt install chromium chromium-driver)")
    options = Options()
    for arg in ("--headless=new", "--no-sandbox", "--disable-dev-shm-usage", f"--window-size={W},{H + 150}"):
        options.add_argument(arg)
    options.binary_location = chromium
    try:            # an explicit Service: otherwise selenium-manager looks for a driver on the network
        d = webdriver.Chrome(options=options, service=Service(driver))
    except WebDriverException as exc:
        skip_or_fail(f"chromium did not start under selenium: {str(exc).splitlines()[0]}")
    d.execute_cdp_cmd("Emulation.setDeviceMetricsOverride",
                      {"width": W, "height": H, "deviceScaleFactor": 1, "mobile": False})
    yield d
    d.quit()
    for thread in CLOSING:
        thread.join(CLOSE_WAIT_S)
    stuck = [t.name for t in CLOSING if t.is_alive()]
    CLOSING.clear()
    assert not stuck, f"viewers did not close in {CLOSE_WAIT_S} s: {stuck}"


@pytest.fixture(scope="module")
def scene():
    """The reference scene: loaded apart from the viewer's (which the viewer poses and lights)."""
    return clrender.load_scene(DEMO)


class Page:
    """A viewer and its page in the browser: the canvas read back, the DOM driven like a user."""

    def __init__(self, d, viewer):
        from selenium.webdriver.common.by import By
        self.d, self.viewer, self.By = d, viewer, By
        d.get(viewer.url)
        deadline = time.monotonic() + CONNECT_WAIT_S
        while not viewer.server.get_clients():
            assert time.monotonic() < deadline, f"the page at {viewer.url} did not connect"
            time.sleep(0.05)
        self.client = next(iter(viewer.server.get_clients().values()))
        self.canvas_element = d.find_element(By.TAG_NAME, "canvas")
        for button in d.find_elements(By.CSS_SELECTOR, "button.mantine-Notification-closeButton"):
            if button.is_displayed():        # "Software WebGL rendering detected" (no GPU here)
                button.click()
        self.settle()

    # -- reading ---------------------------------------------------------------------------------
    def canvas(self) -> tuple[np.ndarray, np.ndarray]:
        """(the page's pixels as the user sees them, the mask of those that show the picture): a
        screenshot of the page, less the control panel, the axes gizmo and any notification.
        (viser's own get_render draws the scene again with the camera the page last *reported*,
        while the picture is a plane locked to the live camera; after a drag the camera controls'
        damping can leave the two a hair apart, so a read-back through it is resampled.)"""
        from PIL import Image
        from selenium.webdriver.common.action_chains import ActionChains
        # the mouse parked on the gizmo's corner (masked): a control's hover hint would cover pixels
        ActionChains(self.d).move_to_element_with_offset(self.canvas_element, 8 - W // 2, H // 2 - 8).perform()
        shot = np.asarray(Image.open(io.BytesIO(self.d.get_screenshot_as_png())).convert("RGB"))
        mask = np.zeros(shot.shape[:2], bool)
        mask[:, : W - PANEL_W] = True
        mask[H - GIZMO:, :GIZMO] = False
        overlays = ".mantine-Notification-root, [role=tooltip], [role=listbox], .mantine-Popover-dropdown"
        for note in self.d.find_elements(self.By.CSS_SELECTOR, overlays):
            if note.is_displayed():
                r = note.rect
                x0, y0 = max(int(r["x"]) - 2, 0), max(int(r["y"]) - 2, 0)
                mask[y0: int(r["y"] + r["height"]) + 3, x0: int(r["x"] + r["width"]) + 3] = False
        assert mask.mean() > 0.3, "the panel and notifications cover the picture"
        return shot, mask

    def canvas_equal(self, expected, what: str) -> np.ndarray:
        """The page's picture once it equals `expected` where visible (an image, or a function of
        the viewer's current camera giving one: the page's camera controls may still send a last,
        tiny move after the drag), polled, as the newest background is decoded asynchronously; an
        assertion naming the difference if it never does. self.matched: the camera of the image
        matched. Returns the screenshot with the hidden pixels taken from `expected`."""
        deadline, camera, ref = time.monotonic() + CANVAS_WAIT_S, None, expected
        while True:
            if callable(expected) and self.viewer.camera != camera:
                camera = self.viewer.camera
                ref = expected(camera)
            got, mask = self.canvas()
            if got.shape == ref.shape and np.array_equal(got[mask], ref[mask]):
                self.matched = camera
                return np.where(mask[..., None], got, ref)
            if time.monotonic() > deadline:
                break
            time.sleep(0.2)
        assert got.shape == ref.shape, f"{what}: page {got.shape} vs {ref.shape}"
        diff = np.where(mask[..., None], np.abs(got.astype(int) - ref.astype(int)), 0)
        shown = self.viewer.frame
        also = ""
        if shown is not None and shown.image.shape == got.shape:     # which side is off: the page or the frame
            also = (f"; frame vs reference {np.abs(shown.image.astype(int) - ref).max()}; viewer camera is the "
                    f"reference's: {self.viewer.camera == camera}; page size {self.client.camera.image_width}x"
                    f"{self.client.camera.image_height}")
        raise AssertionError(f"{what}: the page differs from the reference: max |diff| {diff.max()}, "
                             f"{(diff.max(-1) > 0).sum()} of {mask.sum()} visible pixels{also}")

    def text(self) -> str:
        return self.d.find_element(self.By.TAG_NAME, "body").text

    def wait_text(self, words, timeout: float = 10.0) -> str:
        deadline = time.monotonic() + timeout
        while True:
            text = self.text()
            if all(w in text for w in words):
                return text
            assert time.monotonic() < deadline, f"the page never showed {words!r}; it shows:\n{text}"
            time.sleep(0.1)

    def settle(self, quiet_s: float = 0.4) -> None:
        """Wait until the viewer has rendered everything asked and no new camera came for quiet_s
        (the page's camera controls damp a drag for a moment after the button is released)."""
        loop = self.viewer.loop
        deadline = time.monotonic() + 120
        while True:
            assert self.viewer.wait_idle(60), "the viewer never went idle"
            before = (len(loop.history), dict(loop.counts))
            time.sleep(quiet_s)
            if (len(loop.history), loop.counts) == before and self.viewer.wait_idle(0.01):
                return
            assert time.monotonic() < deadline, "the viewer kept rendering"

    def screenshot(self, step: str) -> None:
        folder = os.environ.get("CLRENDER_SCREENSHOTS", "").strip()
        if folder:
            Path(folder).mkdir(parents=True, exist_ok=True)
            self.d.save_screenshot(str(Path(folder) / f"viewer-{step}.png"))

    # -- acting ----------------------------------------------------------------------------------
    def drag(self, x: int = 150, y: int = 300, steps=((25, 0), (25, 4), (25, 4), (25, 0))) -> None:
        """A left-button drag from canvas pixel (x, y) (orbits the camera)."""
        from selenium.webdriver.common.action_chains import ActionChains
        chain = ActionChains(self.d).move_to_element_with_offset(self.canvas_element, x - W // 2, y - H // 2)
        chain.click_and_hold()
        for dx, dy in steps:
            chain.move_by_offset(dx, dy)
        chain.release().perform()

    def click_pixel(self, x: int, y: int) -> None:
        from selenium.webdriver.common.action_chains import ActionChains
        ActionChains(self.d).move_to_element_with_offset(self.canvas_element, x - W // 2, y - H // 2).click().perform()

    def input_of(self, label: str):
        """The input a panel label names: its <label for=id>, else (viser's text field's label names
        no element) the first input in the label's row."""
        for element in self.d.find_elements(self.By.TAG_NAME, "label"):
            if element.text.strip() == label:
                found = self.d.execute_script(
                    "const label = arguments[0]; const byId = document.getElementById(label.htmlFor);"
                    "if (byId) return byId;"
                    "for (let e = label.parentElement; e; e = e.parentElement) {"
                    "  const i = e.querySelector('input:not([type=hidden]), textarea'); if (i) return i; }"
                    "return null;", element)
                if found is not None:
                    return found
        raise AssertionError(f"no control labelled {label!r} in the page")

    def choose(self, label: str, option: str) -> None:
        """Pick `option` in the Mantine select labelled `label` (click it, then the option)."""
        field = self.input_of(label)
        self.d.execute_script("arguments[0].scrollIntoView({block: 'center'})", field)
        field.click()
        deadline = time.monotonic() + 5
        while True:
            shown = [e for e in self.d.find_elements(self.By.CSS_SELECTOR, "[role=option]")
                     if e.is_displayed() and e.text.strip() == option]
            if shown:
                shown[0].click()
                return
            assert time.monotonic() < deadline, f"{label!r}: no option {option!r} appeared"
            time.sleep(0.1)

    def button(self, text: str):
        for element in self.d.find_elements(self.By.TAG_NAME, "button"):
            if element.text.strip() == text:
                return element
        raise AssertionError(f"no button {text!r} in the page")

    def open_folder(self, title: str) -> None:
        heads = [e for e in self.d.find_elements(self.By.XPATH, f"//*[normalize-space(text())='{title}']")
                 if e.is_displayed()]
        assert heads, f"no folder {title!r} in the page"
        self.d.execute_script("arguments[0].scrollIntoView({block: 'center'})", heads[0])
        heads[0].click()


@pytest.fixture
def page(browser, tmp_path):
    viewer = clrender.view(str(DEMO), width=W, height=H, port=free_port(), transport="png", show=False,
                           cameras=str(tmp_path / "cams.json"))
    try:
        yield Page(browser, viewer)
        assert viewer.errors == [], viewer.errors
    finally:
        browser.get("about:blank")
        viewer.loop.close()
        thread = threading.Thread(target=viewer.close, name=f"close {viewer.url}", daemon=True)
        thread.start()
        CLOSING.append(thread)


def reference(page, scene, camera):
    """The frame an independent Renderer (of the viewer's device and config) makes of the
    reference scene from `camera`."""
    v = page.viewer
    key = (v.device.info, v.config)
    if getattr(page, "_reference", (None,))[0] != key:
        page._reference = (key, clrender.Renderer(W, H, device=v.device.info, config=v.config))
    return page._reference[1].render(scene, camera)


def colour(page, scene):
    return lambda camera: reference(page, scene, camera).image


def test_first_full_frame_is_the_renderers_and_the_page_has_the_scenes_camera(page, scene):
    v = page.viewer
    camera = scene.cameras[0][1]
    assert v.camera == camera, (v.camera, camera)
    pc = page.client.camera
    np.testing.assert_allclose(pc.position, camera.eye, atol=1e-6)
    np.testing.assert_allclose(pc.look_at, camera.target, atol=1e-6)
    assert abs(np.degrees(pc.fov) - camera.fov_y_deg) < 1e-6
    assert (pc.image_width, pc.image_height) == (W, H)
    ref = reference(page, scene, camera).image
    assert v.frame is not None and v.loop.last.full
    assert np.array_equal(v.frame.image, ref)
    page.canvas_equal(ref, "first full frame")
    page.screenshot("first")


def test_a_drag_orbits_the_camera_with_previews_then_the_full_frame(page, scene):
    v = page.viewer
    before_cam, before_img = v.camera, page.canvas_equal(reference(page, scene, v.camera).image, "first frame")
    full0 = v.loop.counts["full"]
    page.drag()
    page.settle()
    got = page.canvas_equal(colour(page, scene), "the full frame after the drag")
    cam = page.matched
    assert not np.allclose(cam.eye, before_cam.eye), "the drag did not move the camera"
    np.testing.assert_allclose(np.asarray(page.client.camera.position), cam.eye, atol=1e-5)
    assert v.loop.counts["preview"] >= 1, v.loop.counts
    assert v.loop.counts["full"] > full0 and v.loop.last.full and v.loop.last.state.camera == cam
    assert not np.array_equal(got, before_img)
    page.screenshot("drag")
    previews = [s for s in v.loop.history if not s.full]
    lat = [(s.published - s.state.submitted) * 1e3 for s in previews]
    print(f"\n{len(previews)} previews {previews[0].frame.width}x{previews[0].frame.height}: camera->published "
          f"median {statistics.median(lat):.0f} ms; full frame {v.loop.last.seconds * 1e3:.0f} ms")


def test_the_object_id_aov_chosen_in_the_page_shows_the_id_colours(page, scene):
    v = page.viewer
    ref = reference(page, scene, v.camera)
    page.canvas_equal(ref.image, "first frame")
    page.choose("show", "object_id")
    ids = ref.preview("object_id")
    assert not np.array_equal(ids, ref.image)
    shown_ids = np.unique(ref.object_id)
    assert len(shown_ids) >= 3, f"the reference shows too few objects: {shown_ids}"
    assert len(np.unique(ids.reshape(-1, 3), axis=0)) == len(shown_ids), "one colour per id (and background)"
    page.canvas_equal(ids, "the object_id AOV")
    assert v.panels.aov.value == "object_id"
    assert np.array_equal(v.frame.preview("object_id"), ids)
    page.screenshot("object-id")


def _interior_pixel(object_id: np.ndarray, margin: int = 4) -> tuple[int, int]:
    """A pixel deep inside the largest object seen left of the panel (margin pixels of the same
    object all round), nearest that object's centre."""
    free = np.zeros(object_id.shape, bool)
    free[20:H - 20, 20:W - PANEL_W] = True
    ids, counts = np.unique(object_id[free & (object_id >= 0)], return_counts=True)
    assert len(ids), "no object in the free part of the page"
    oid = int(ids[np.argmax(counts)])
    inside = free & (object_id == oid)
    for axis in (0, 1):
        for shift in range(1, margin + 1):
            inside &= np.roll(object_id == oid, shift, axis) & np.roll(object_id == oid, -shift, axis)
    ys, xs = np.nonzero(inside)
    assert len(xs), f"object {oid} has no interior pixel"
    k = np.argmin((xs - xs.mean()) ** 2 + (ys - ys.mean()) ** 2)
    return int(xs[k]), int(ys[k])


def test_a_click_picks_the_object_under_it(page, scene):
    from clrender.viewer.pick import pick
    v = page.viewer
    frame = v.frame
    x, y = _interior_pixel(frame.object_id)
    expected = scene.objects[int(frame.object_id[y, x])].name
    assert v.last_pick is None
    page.click_pixel(x, y)
    deadline = time.monotonic() + 10
    while v.last_pick is None:
        assert time.monotonic() < deadline, "the click never reached the viewer"
        time.sleep(0.05)
    p = v.last_pick
    assert abs(p.x - x) <= 1 and abs(p.y - y) <= 1, ((p.x, p.y), (x, y))
    assert p.object_name == expected, (p, expected)
    assert p == pick(frame, v.scene, p.x, p.y)
    page.wait_text([expected, f"pixel ({p.x}, {p.y})", p.mesh, p.material_name])
    page.screenshot("pick")


def test_save_view_writes_the_camera_file_that_render_turns_into_the_same_image(page, scene, tmp_path):
    from clrender.cli import main
    from clrender.dataset.camera_file import entry_camera, read_camera_file
    from PIL import Image
    v = page.viewer
    cams = tmp_path / "cams.json"
    shown, cameras = [], []
    for n in (1, 2):
        if n == 2:                                        # the page's own camera, not the scene's
            page.drag(steps=((-30, 0), (-30, -6)))
            page.settle()
        shown.append(page.canvas_equal(colour(page, scene), f"view {n}"))
        cameras.append(page.matched)
        assert not cams.exists() if n == 1 else len(read_camera_file(cams).entries) == 1
        page.button("save view").click()
        deadline = time.monotonic() + 10
        while not cams.exists() or len(read_camera_file(cams).entries) < n:
            assert time.monotonic() < deadline, f"save view did not write camera {n} to {cams}"
            time.sleep(0.05)
        page.wait_text(["view saved"])
        if n == 1:
            page.screenshot("saved")
        page.settle()
    cf = read_camera_file(cams)
    assert len(cf.entries) == 2 and (cf.width, cf.height) == (W, H), json.loads(cams.read_text())
    assert not np.array_equal(shown[0], shown[1])
    for i, entry in enumerate(cf.entries):               # the file holds the cameras the page showed
        assert entry_camera(entry, v.scene.bounds(), W, H) == cameras[i], (i, entry, cameras[i])
    out = tmp_path / "shot{camera}.png"
    assert main(["render", str(DEMO), "--camera", str(cams), "-o", str(out), "--width", str(W),
                 "--height", str(H), "-q"]) == 0
    for i, canvas in enumerate(shown):
        png = np.asarray(Image.open(tmp_path / f"shot{i}.png").convert("RGB"))
        assert np.array_equal(png, canvas), f"render --camera's image {i} differs from the page's canvas"


def test_a_bad_environment_path_shows_an_error_and_the_viewer_keeps_rendering(page, scene, tmp_path, monkeypatch):
    import clrender.scene.environment as environment
    opened = []
    real = environment.load_environment

    def recording(source, *args, **kwargs):
        opened.append(str(source))
        return real(source, *args, **kwargs)

    monkeypatch.setattr(environment, "load_environment", recording)
    v = page.viewer
    outside = tmp_path / "outside.exr"                 # exists, but outside the scene's folder
    outside.write_bytes(b"not an image")
    page.open_folder("environment")
    page.choose("lighting", "file")
    field = page.input_of("file")
    for path, words in (("missing.exr", ["missing.exr: no such file"]),
                        (str(outside), ["outside the scene's folder"]),
                        ("../../x.exr", ["../../x.exr: outside the scene's folder"])):
        field.click()
        field.clear()
        field.send_keys(path)
        page.wait_text(["error:", *words])
        deadline = time.monotonic() + 5
        while page.viewer.panels.env_path.value != path:
            assert time.monotonic() < deadline, "the typed path never reached the viewer"
            time.sleep(0.05)
    page.screenshot("environment-error")
    assert opened == [], f"refused paths were opened: {opened}"
    assert v.errors == []
    page.settle()
    before = dict(v.loop.counts)
    page.drag(x=330)               # right of the error notifications the page stacks on the left
    page.settle()
    assert v.loop.counts["preview"] > before["preview"] and v.loop.counts["full"] > before["full"]
    page.canvas_equal(colour(page, scene), "after the refused environments")
