"""Frame ranges, output patterns and the manifest (clrender.batch.frames, clrender.batch.manifest): no device."""
from __future__ import annotations

import json
import os

import pytest

from clrender.batch import frames
from clrender.batch.manifest import Manifest, manifest_folder


@pytest.mark.parametrize("text, expected", [
    ("0:240", range(0, 240)), ("0:240:2", range(0, 240, 2)), ("7", range(7, 8)), ("3:4", range(3, 4)),
    (" 10:13 ", range(10, 13))])
def test_parse_frames(text, expected):
    assert frames.parse_frames(text) == expected


@pytest.mark.parametrize("text, message", [
    ("5:5", "empty range"), ("9:2", "reversed range"), ("0:10:0", "step must be >= 1"), ("-1", ">= 0"),
    ("a:b", "expected an integer"), ("1:2:3:4", "START:END"), ("-3:2", ">= 0")])
def test_parse_frames_errors(text, message):
    with pytest.raises(ValueError, match=message):
        frames.parse_frames(text)


def test_time_range_names_the_same_frames_as_frame_numbers():
    assert frames.parse_time_range("2:4", 24) == range(48, 96)
    assert frames.parse_time_range("0:1", 10) == range(0, 10)
    assert frames.parse_time_range("0.05:0.3", 10) == range(1, 3)      # t = 0.1, 0.2 lie in [0.05, 0.3)
    for text, message in (("2:2", "empty"), ("3:1", "reversed"), ("x", "START:END"), ("-1:2", ">= 0")):
        with pytest.raises(ValueError, match=message):
            frames.parse_time_range(text, 24)
    with pytest.raises(ValueError, match="no frame"):
        frames.parse_time_range("0.01:0.02", 24)


def test_animation_frames_cover_the_duration_inclusive():
    assert frames.animation_frames(2.0, 24) == range(0, 49)
    assert frames.animation_frames(None, 24) == range(0, 1)
    assert frames.animation_frames(0.0, 24) == range(0, 1)
    assert [ft.time for ft in frames.frame_times(range(0, 3), 4)] == [0.0, 0.25, 0.5]


@pytest.mark.parametrize("pattern", ["out/{name}_{frame:04d}.png", "{time:.3f}.png", "o/{name}/{frame}.jpg"])
def test_good_patterns(pattern):
    frames.check_pattern(pattern)


@pytest.mark.parametrize("pattern, message", [
    ("out/{frame_number}.png", "unknown field {frame_number}"), ("out/{}.png", "unknown field {}"),
    ("out/{0}.png", "unknown field {0}"), ("out/{frame:q}.png", "bad output pattern"),
    ("out/{frame.png", "bad output pattern"), ("out/{index}.png", "use {name}, {frame}, {time}")])
def test_bad_patterns(pattern, message):
    with pytest.raises(ValueError, match=message.replace("{", r"\{").replace("}", r"\}")):
        frames.check_pattern(pattern)


def test_plan_images_refuses_one_file_for_several_frames(tmp_path):
    times = frames.frame_times(range(3), 24)
    images = frames.plan_images(str(tmp_path / "f_{frame:03d}.png"), ["a/s.gltf"], times)
    assert [p.name for p in images.values()] == ["f_000.png", "f_001.png", "f_002.png"]
    with pytest.raises(ValueError, match=r"put \{frame\} in it"):
        frames.plan_images(str(tmp_path / "f.png"), ["s.gltf"], times)
    with pytest.raises(ValueError, match=r"put \{name\} in it"):
        frames.plan_images(str(tmp_path / "f_{frame}.png"), ["a/s.gltf", "b/t.gltf"], times[:1])
    with pytest.raises(ValueError, match="unsupported image type"):
        frames.plan_images(str(tmp_path / "f.tif"), ["s.gltf"], times[:1])
    # a folder gets <name>_<frame:04d>.png
    pattern = frames.output_pattern(str(tmp_path) + "/", False)
    assert os.path.basename(pattern) == frames.DEFAULT_FRAME_NAME


def test_manifest_folder():
    assert str(manifest_folder("out/frame_{frame:04d}.png")) == "out"
    assert str(manifest_folder("out/{name}/f_{frame}.png")) == "out"
    assert str(manifest_folder("{name}_{frame}.png")) == "."
    assert str(manifest_folder("out/still.png")) == "out"


def test_manifest_resume_trusts_only_complete_frames_of_the_same_job(tmp_path):
    job = {"scenes": {"s.gltf": {"bytes": 1}}, "fps": 24.0}
    images = [tmp_path / f"f{i}.png" for i in range(3)]
    for p in images:
        p.write_bytes(b"x" * 10)
    m = Manifest.open(tmp_path / "manifest.json", job, "0.1.0", resume=False)
    for i in range(3):
        m.record("s.gltf", i, {"status": "ok", "outputs": [images[i]], "stats": {"a": 1.5}})
    m.record("s.gltf", 3, {"status": "failed", "error": "boom"})
    m.save()
    data = json.loads((tmp_path / "manifest.json").read_text())
    assert [r["frame"] for r in data["frames"]] == [0, 1, 2, 3]
    assert data["frames"][0]["outputs"] == [{"path": "f0.png", "bytes": 10}]

    r = Manifest.open(tmp_path / "manifest.json", job, "0.1.0", resume=True)
    assert r.is_done("s.gltf", 0, [images[0]])
    images[1].write_bytes(b"x" * 4)                       # changed since: not trusted
    assert not r.is_done("s.gltf", 1, [images[1]])
    images[2].unlink()                                    # gone: not trusted
    assert not r.is_done("s.gltf", 2, [images[2]])
    assert not r.is_done("s.gltf", 3, [])                 # failed before
    assert not r.is_done("s.gltf", 0, [images[0], tmp_path / "f0.depth.npy"])   # other outputs asked now
    assert [f["frame"] for f in r.failed()] == [3]

    with pytest.raises(ValueError, match=r"different job \(fps differ\)"):
        Manifest.open(tmp_path / "manifest.json", {**job, "fps": 30.0}, "0.1.0", resume=True)
    fresh = Manifest.open(tmp_path / "manifest.json", {**job, "fps": 30.0}, "0.1.0", resume=False)
    assert fresh.records == {}                            # another job without --resume: a new manifest
    kept = Manifest.open(tmp_path / "manifest.json", job, "0.1.0", resume=False)
    assert set(kept.records) == {("s.gltf", i) for i in range(4)}   # the same job: earlier frames stay listed
    (tmp_path / "manifest.json").write_text("{not json")
    with pytest.raises(ValueError, match="cannot read"):
        Manifest.open(tmp_path / "manifest.json", job, "0.1.0", resume=True)
