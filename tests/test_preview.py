"""Looking at frames: Frame.preview (the CLI's AOV pictures), Frame._repr_png_ (Jupyter), the
labelled contact sheet (Frame.contact_sheet, `clrender render --aov-sheet`)."""
from __future__ import annotations

import io
from pathlib import Path

import imageio.v3 as iio
import numpy as np
import pytest

from clrender import Renderer, load_scene
from clrender.outputs.aov_io import LABEL_HEIGHT, contact_sheet, preview
from clrender.cli.app import main

WORM = Path(__file__).resolve().parents[1] / "scenes" / "worm.gltf"
W, H = 80, 45
NAMES = ["image", "depth", "normal", "triangle_id", "velocity", "albedo", "light_count"]


@pytest.fixture(scope="module")
def frame(device):
    scene = load_scene(WORM)
    previous = scene.pose(0.4, 1 / 24)
    return Renderer(W, H, device=device).render(scene, previous_camera=previous)


def test_preview_is_the_cli_picture_of_each_aov(frame):
    background = frame.triangle_id < 0
    assert background.any() and (~background).any()
    for name in NAMES[1:]:
        got = frame.preview(name)
        assert got.shape == (H, W, 3) and got.dtype == np.uint8
        expect = preview(name, np.asarray(frame.aov(name)), background)
        np.testing.assert_array_equal(got, expect if expect.ndim == 3 else np.repeat(expect[..., None], 3, -1))
    depth = frame.preview("depth")
    assert depth[~background].min() > 30        # something drawn: a black frame fails
    np.testing.assert_array_equal(frame.preview("image"), frame.image)
    with pytest.raises(ValueError, match="unknown AOV"):
        frame.preview("nope")


def test_repr_png_is_the_display_image(frame):
    png = frame._repr_png_()
    assert png[:8] == b"\x89PNG\r\n\x1a\n"
    np.testing.assert_array_equal(iio.imread(io.BytesIO(png))[..., :3], frame.image)


def test_contact_sheet_places_each_preview_under_its_label(frame):
    sheet = frame.contact_sheet(NAMES, columns=3)
    rows = -(-len(NAMES) // 3)
    assert sheet.shape == (rows * (H + LABEL_HEIGHT), 3 * W, 3)
    for k, name in enumerate(NAMES):
        x, y = (k % 3) * W, (k // 3) * (H + LABEL_HEIGHT)
        np.testing.assert_array_equal(sheet[y + LABEL_HEIGHT:y + LABEL_HEIGHT + H, x:x + W], frame.preview(name))
        label = sheet[y:y + LABEL_HEIGHT, x:x + W]
        assert (label.max(-1) > 128).sum() > 5, name               # the name is written
    with pytest.raises(ValueError, match="at least one"):
        contact_sheet([])
    with pytest.raises(ValueError, match="same size"):
        contact_sheet([("a", np.zeros((4, 4, 3), np.uint8)), ("b", np.zeros((5, 4, 3), np.uint8))])


def test_cli_aov_sheet_writes_the_image_and_the_aov_previews(tmp_path):
    out = tmp_path / "w.png"
    assert main(["render", str(WORM), "-o", str(out), "--width", str(W), "--height", str(H),
                 "--aov", "depth,normal", "--aov-sheet", "-q"]) == 0
    sheet = iio.imread(tmp_path / "w.sheet.png")
    image = iio.imread(out)[..., :3]
    assert sheet.shape == (H + LABEL_HEIGHT, 3 * W, 3)
    np.testing.assert_array_equal(sheet[LABEL_HEIGHT:, :W], image)
    for k, name in enumerate(("depth", "normal"), 1):
        tile = sheet[LABEL_HEIGHT:, k * W:(k + 1) * W]
        written = iio.imread(tmp_path / f"w.{name}.png")
        np.testing.assert_array_equal(tile, written if written.ndim == 3 else np.repeat(written[..., None], 3, -1))
