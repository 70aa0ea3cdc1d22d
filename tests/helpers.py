"""Assertions and files shared by several test modules."""
import os
from pathlib import Path

import pytest

import numpy as np

from clrender import load_scene
from clrender.scene.model import SceneError


# Shaded colour against the float64 NumPy reference (tests/reference/shading.py), as a fraction
# of the frame's brightest reference value, about 3x what was measured (2026-11-23, PoCL 3.1):
# the fixed scenes (test_lighting, test_light_accumulation, test_orthographic, test_bad_input)
# at most 1.6e-6; hypothesis's random scenes and lights (test_properties) at most 6e-5.
SHADING_TOL = 5e-6
SHADING_TOL_RANDOM = 2e-4


def in_ci() -> bool:
    """Whether this run is CI (.ci/run exports CLRENDER_CI=1): there, what is missing fails."""
    return os.environ.get("CLRENDER_CI", "").strip() not in ("", "0")


def skip_or_fail(reason: str):
    """pytest.skip(reason) locally; in CI a test that cannot run is a failure, so that a missing
    device, peer or second implementation cannot pass as success."""
    if in_ci():
        pytest.fail(f"CI: {reason}")
    pytest.skip(reason)


def assert_scene_error(path, words) -> str:
    """Loading `path` raises SceneError whose message names the file and every word."""
    with pytest.raises(SceneError) as info:
        load_scene(path)
    msg = str(info.value)
    assert str(path) in msg, msg
    for w in words:
        assert w in msg, msg
    return msg


def record_render_configs(monkeypatch) -> list:
    """Replace clrender.render.renderer.Renderer by a subclass that appends each new renderer's
    RenderConfig to the returned list (what the CLI turned its flags and [render] table into). The
    CLI's background warm-up renderer (clrender.tools.warmup.prepare_in_background) is not counted."""
    import threading

    from clrender.render import renderer as renderer_module

    seen = []

    class Recording(renderer_module.Renderer):
        def __init__(self, *args, **kwargs):
            super().__init__(*args, **kwargs)
            if threading.current_thread().name != "clrender-prepare":
                seen.append(self.config)

    monkeypatch.setattr(renderer_module, "Renderer", Recording)
    return seen


SHARED_SCENES = Path(__file__).resolve().parents[2] / "shared" / "scenes"


def shared_file(rel: str) -> Path:
    """A file under ../shared/scenes, or skip the test with a clear message when it is absent."""
    path = SHARED_SCENES / rel
    if not path.is_file():
        pytest.skip(f"shared test scene {path} is not available (needs ../shared/scenes next to the repo)")
    return path


def pixel_far_points(camera, width: int, height: int) -> np.ndarray:
    """(H, W, 3) float64: each pixel centre's point on the far plane (its ray from the eye)."""
    inv = np.linalg.inv(camera.view_projection(width, height))
    ys, xs = np.mgrid[0:height, 0:width] + 0.5
    ndc = np.stack([xs / width * 2 - 1, 1 - ys / height * 2, np.ones_like(xs), np.ones_like(xs)], -1)
    far = ndc @ inv.T
    return far[..., :3] / far[..., 3:]


def reach_the_raster_guard(monkeypatch) -> None:
    """Let Scenes hold NaN, infinite or huge vertex positions for the rest of a test. Scenes refuse
    them (clrender.scene.model.check_positions: a SceneError naming the vertex), but the raster kernels
    still drop and count such triangles (docs/raster_contract.md: device-side posing by skins and
    morph targets can produce them), and the raster tests check that guard on purpose."""
    import clrender.scene.model as scene_module
    monkeypatch.setattr(scene_module, "check_positions", lambda *args, **kwargs: None)
