"""Assertions shared by several test modules."""
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
