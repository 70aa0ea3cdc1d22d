"""The viewer's render loop (clrender/viewer/session.py), without a browser: the newest state
wins (nothing queues), a moving camera gets previews and the full frame once still, a panel
change renders the full frame at once, and a failing frame leaves the loop running."""
from __future__ import annotations

import threading
import time

import pytest

from clrender.config import RenderConfig
from clrender.scene.camera import Camera
from clrender.viewer.session import (
    PREVIEW_OPTIONS, RenderLoop, ViewState, preview_config, preview_size)


def _state(i: float, moving: bool) -> ViewState:
    return ViewState(Camera.look_at((0.0, 0.0, 5.0 + i), (0.0, 0.0, 0.0)), 64, 48, RenderConfig(), moving=moving)


class Recorder:
    """A render that takes `seconds` and records (eye z, full); publish and errors recorded too."""

    def __init__(self, seconds: float = 0.05, fail_on=None):
        self.seconds, self.fail_on = seconds, fail_on
        self.rendered, self.published, self.errors = [], [], []
        self.gate = threading.Event()
        self.gate.set()

    def render(self, state, full):
        self.gate.wait(10)
        if self.fail_on is not None and state.camera.eye[2] == self.fail_on:
            raise ValueError("this frame fails")
        time.sleep(self.seconds)
        self.rendered.append((state.camera.eye[2], full))
        return ("frame", state.camera.eye[2], full)

    def loop(self, settle_s=0.05):
        return RenderLoop(self.render, self.published.append, lambda exc, st: self.errors.append(str(exc)),
                          settle_s=settle_s)


def test_a_still_state_renders_the_full_frame_once():
    rec = Recorder()
    loop = rec.loop()
    try:
        loop.submit(_state(0, moving=False))
        assert loop.wait_idle(10)
        assert rec.rendered == [(5.0, True)]
        assert [s.full for s in rec.published] == [True]
        assert loop.last_full.frame == ("frame", 5.0, True)
    finally:
        loop.close()


def test_moves_get_previews_then_one_full_frame_of_the_last_camera():
    rec = Recorder(seconds=0.02)
    loop = rec.loop(settle_s=0.1)
    try:
        for i in range(5):                      # faster than a frame: some are replaced, never queued
            loop.submit(_state(i, moving=True))
            time.sleep(0.005)
        assert loop.wait_idle(10)
        previews = [z for z, full in rec.rendered if not full]
        fulls = [z for z, full in rec.rendered if full]
        assert fulls == [9.0], rec.rendered     # the full frame is the newest camera's, once
        assert previews and previews[-1] == 9.0
        assert len(previews) < 5 and loop.counts["dropped"] >= 1, rec.rendered    # stale states were dropped
        assert rec.rendered[-1] == (9.0, True)
    finally:
        loop.close()


def test_the_newest_state_wins_while_a_frame_renders():
    rec = Recorder(seconds=0.0)
    rec.gate.clear()                            # the first frame blocks in render()
    loop = rec.loop()
    try:
        loop.submit(_state(0, moving=False))
        time.sleep(0.1)
        for i in (1, 2, 3):
            loop.submit(_state(i, moving=False))
        rec.gate.set()
        assert loop.wait_idle(10)
        assert rec.rendered == [(5.0, True), (8.0, True)]      # 6 and 7 never rendered
        assert loop.counts["dropped"] == 2
    finally:
        loop.close()


def test_a_failing_frame_is_reported_and_the_loop_goes_on():
    rec = Recorder(fail_on=6.0)
    loop = rec.loop()
    try:
        loop.submit(_state(1, moving=False))
        assert loop.wait_idle(10)
        loop.submit(_state(2, moving=False))
        assert loop.wait_idle(10)
        assert rec.errors == ["this frame fails"]
        assert rec.rendered == [(7.0, True)]
    finally:
        loop.close()


def test_preview_settings():
    config = RenderConfig(supersample=2, edge_aa=True, color_aa="fxaa", ssao=True)
    p = preview_config(config)
    assert {k: getattr(p, k) for k in PREVIEW_OPTIONS} == PREVIEW_OPTIONS
    assert p.ssao and p.tonemap == config.tonemap                # everything else as configured
    assert preview_size(1280, 720) == (640, 360) and preview_size(1, 1) == (1, 1)
    with pytest.raises(Exception):
        ViewState(None, 1, 1, config).__setattr__("width", 2)     # frozen
