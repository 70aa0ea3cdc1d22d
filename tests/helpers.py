"""Assertions and files shared by several test modules."""
from pathlib import Path

import pytest

from clrender import load_scene
from clrender.scene import SceneError


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
    """Replace clrender.renderer.Renderer by a subclass that appends each new renderer's
    RenderConfig to the returned list (what the CLI turned its flags and [render] table into)."""
    from clrender import renderer as renderer_module

    seen = []

    class Recording(renderer_module.Renderer):
        def __init__(self, *args, **kwargs):
            super().__init__(*args, **kwargs)
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
