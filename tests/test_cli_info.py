"""`clrender info` on glTF files: skins, morph targets, animations and extensions, read from the
glTF document. The Khronos samples (../shared/scenes) are checked against numbers computed here
from their JSON and binary buffers; a generated file covers two JOINTS / WEIGHTS sets."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from clrender.cli import app as cli
from gltf_files import primitive, write_gltf
from helpers import SHARED_SCENES, skip_or_fail

RIGGED = "khronos-RiggedSimple/RiggedSimple.gltf"
MORPH = "khronos-SimpleMorph/SimpleMorph.gltf"
DETAIL_KEYS = ("skins", "morph_targets", "animations", "extensions_used", "extensions_required")


@pytest.fixture(autouse=True)
def _no_debug(monkeypatch):
    monkeypatch.delenv(cli.ENV_DEBUG, raising=False)


def _shared(rel: str) -> Path:
    """A Khronos sample under ../shared/scenes: skipped when absent, a failure in CI."""
    path = SHARED_SCENES / rel
    if not path.is_file():
        skip_or_fail(f"shared test scene {path} is not available (needs ../shared/scenes next to the repo)")
    return path


def _info(path, capsys) -> dict:
    assert cli.main(["info", str(path), "--json"]) == 0
    return json.loads(capsys.readouterr().out)


def _text(path, capsys) -> str:
    assert cli.main(["info", str(path)]) == 0
    return capsys.readouterr().out


def _read_floats(gltf: Path, j: dict, index: int) -> np.ndarray:
    """A FLOAT accessor read straight from its .bin file (independent of clrender's decoder)."""
    acc = j["accessors"][index]
    assert acc["componentType"] == 5126 and "sparse" not in acc
    view = j["bufferViews"][acc["bufferView"]]
    data = (gltf.parent / j["buffers"][view["buffer"]]["uri"]).read_bytes()
    ncomp = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4}[acc["type"]]
    stride = view.get("byteStride") or 4 * ncomp
    start = view.get("byteOffset", 0) + acc.get("byteOffset", 0)
    return np.array([np.frombuffer(data, "<f4", ncomp, start + i * stride) for i in range(acc["count"])])


def _durations(j: dict) -> list[float]:
    return [max(j["accessors"][s["input"]]["max"][0] for s in a["samplers"]) for a in j["animations"]]


# -- the Khronos samples ------------------------------------------------------------------------------
def test_rigged_simple_skin(capsys):
    path = _shared(RIGGED)
    j = json.loads(path.read_text())
    info = _info(path, capsys)
    assert all(key in info for key in DETAIL_KEYS)

    assert len(info["skins"]) == len(j["skins"]) == 1
    skin, expected = info["skins"][0], j["skins"][0]
    assert skin["name"] == expected["name"] == "Armature"
    assert skin["joints"] == len(expected["joints"]) == 2
    assert skin["skeleton"] == expected["skeleton"]
    users = [n for n, node in enumerate(j["nodes"]) if node.get("skin") == 0]
    assert skin["nodes"] == users
    assert skin["meshes"] == sorted({j["nodes"][n]["mesh"] for n in users})
    prims = [p for m in skin["meshes"] for p in j["meshes"][m]["primitives"]]
    sets = max(sum(1 for a in p["attributes"] if a.startswith("JOINTS_")) for p in prims)
    assert skin["influences_per_vertex"] == 4 * sets == 4
    weights = np.concatenate([_read_floats(path, j, p["attributes"]["WEIGHTS_0"]) for p in prims])
    assert skin["max_nonzero_weights"] == int(np.count_nonzero(weights, axis=1).max()) == 2

    assert info["morph_targets"] == []
    assert len(info["animations"]) == len(j["animations"]) == 1
    anim, expected = info["animations"][0], j["animations"][0]
    assert anim["channels"] == len(expected["channels"]) == 6
    assert anim["paths"] == {"translation": 2, "rotation": 2, "scale": 2}
    assert anim["samplers"] == len(expected["samplers"])
    assert anim["interpolations"] == {"LINEAR": len(expected["samplers"])}
    assert anim["duration"] == pytest.approx(_durations(j)[0]) and anim["duration"] > 2.0
    assert info["extensions_used"] == j.get("extensionsUsed", []) == []
    assert info["extensions_required"] == []

    text = _text(path, capsys)
    assert text.startswith("source ") and "\ntriangles " in text      # the existing lines first
    assert "skin 0 'Armature': 2 joints, skeleton root node 2" in text
    assert "4 influences per vertex" in text and "at most 2 non-zero weights" in text
    assert "duration 2.08333 s" in text and "extensions used: none" in text


def test_simple_morph_targets_and_weights_animation(capsys):
    path = _shared(MORPH)
    j = json.loads(path.read_text())
    info = _info(path, capsys)

    assert info["skins"] == []
    meshes = [(m, mesh) for m, mesh in enumerate(j["meshes"])
              if any(p.get("targets") for p in mesh["primitives"])]
    assert [t["mesh"] for t in info["morph_targets"]] == [m for m, _ in meshes] == [0]
    morph, (_, mesh) = info["morph_targets"][0], meshes[0]
    assert morph["targets"] == len(mesh["primitives"][0]["targets"]) == 2
    assert morph["attributes"] == ["POSITION"]
    assert morph["weights"] == mesh["weights"] == [0.5, 0.5] and morph["weights_given"]

    anim = info["animations"][0]
    assert anim["channels"] == 1 and anim["paths"] == {"weights": 1}
    assert anim["interpolations"] == {"LINEAR": 1}
    assert anim["duration"] == pytest.approx(_durations(j)[0]) == 4.0

    text = _text(path, capsys)
    assert "mesh 0: 2 targets moving POSITION, default weights [0.5, 0.5]" in text
    assert "1 channels (weights)" in text and "duration 4 s" in text


# -- a generated file ---------------------------------------------------------------------------------
def _two_joint_sets(tmp_path) -> Path:
    """A skinned quad with JOINTS_0/1 and WEIGHTS_0/1 (vertex 1 has 7 non-zero weights), a second
    mesh with POSITION + NORMAL morph targets and no `weights`, a STEP translation animation and a
    LINEAR weights animation whose inputs have no JSON `max`, and a used + required extension."""
    joints0 = np.array([[0, 1, 0, 0], [0, 1, 0, 1], [0, 0, 0, 0], [1, 0, 0, 0]], np.uint8)
    joints1 = np.array([[0, 0, 0, 0], [1, 0, 1, 0], [0, 0, 0, 0], [0, 0, 0, 0]], np.uint8)
    weights0 = np.array([[0.5, 0.5, 0, 0], [0.2, 0.2, 0.1, 0.1], [1, 0, 0, 0], [1, 0, 0, 0]], np.float32)
    weights1 = np.array([[0, 0, 0, 0], [0.2, 0.1, 0.1, 0], [0, 0, 0, 0], [0, 0, 0, 0]], np.float32)
    skinned = primitive(JOINTS_0=joints0, JOINTS_1=joints1, WEIGHTS_0=weights0, WEIGHTS_1=weights1)
    offset = np.full((4, 3), 0.1, np.float32)
    morphing = primitive(targets=[{"POSITION": offset, "NORMAL": offset}, {"POSITION": -offset}])
    nodes = [{"mesh": 0, "skin": 0}, {"name": "hips", "children": [2]}, {"name": "spine"},
             {"mesh": 1, "translation": [2, 0, 0]}]
    skins = [{"name": "rig", "joints": [1, 2], "skeleton": 1}]
    animations = [{"name": "walk",
                   "samplers": [{"input": np.array([0.0, 0.5, 1.75], np.float32), "interpolation": "STEP",
                                 "output": np.zeros((3, 3), np.float32)},
                                {"input": np.array([0.0, 2.5], np.float32),
                                 "output": np.array([0, 1, 1, 0], np.float32)}],
                   "channels": [{"sampler": 0, "target": {"node": 1, "path": "translation"}},
                                {"sampler": 1, "target": {"node": 3, "path": "weights"}}]}]
    return write_gltf(tmp_path / "rig.gltf", meshes=[[skinned], [morphing]], nodes=nodes, skins=skins,
                      animations=animations, extensionsUsed=["KHR_materials_unlit"],
                      extensionsRequired=["KHR_materials_unlit"])


def test_generated_two_joint_sets(tmp_path, capsys):
    path = _two_joint_sets(tmp_path)
    j = json.loads(path.read_text())
    assert all("max" not in j["accessors"][s["input"]] for s in j["animations"][0]["samplers"])
    info = _info(path, capsys)

    assert info["skins"] == [{"index": 0, "name": "rig", "joints": 2, "skeleton": 1, "skeleton_name": "hips",
                              "meshes": [0], "nodes": [0], "joint_sets": 2, "influences_per_vertex": 8,
                              "max_nonzero_weights": 7}]
    assert info["morph_targets"] == [{"mesh": 1, "name": "mesh1", "targets": 2, "attributes": ["POSITION", "NORMAL"],
                                      "weights": [0.0, 0.0], "weights_given": False, "target_names": None}]
    assert info["animations"] == [{"index": 0, "name": "walk", "channels": 2,
                                   "paths": {"translation": 1, "weights": 1}, "samplers": 2,
                                   "interpolations": {"LINEAR": 1, "STEP": 1}, "duration": 2.5}]
    assert info["extensions_used"] == ["KHR_materials_unlit"]
    assert info["extensions_required"] == ["KHR_materials_unlit"]

    text = _text(path, capsys)
    assert "skin 0 'rig': 2 joints, skeleton root node 1 'hips'" in text
    assert "8 influences per vertex (2 JOINTS set(s)), at most 7 non-zero weights" in text
    assert "default weights [0, 0] (not given)" in text
    assert "animation 0 'walk': 2 channels (translation, weights), 2 samplers (LINEAR, STEP), duration 2.5 s" in text
    assert "extensions required: KHR_materials_unlit" in text


def test_static_gltf_has_empty_sections(tmp_path, capsys):
    info = _info(write_gltf(tmp_path / "quad.gltf"), capsys)
    assert {key: info[key] for key in DETAIL_KEYS} == {key: [] for key in DETAIL_KEYS}
    text = _text(tmp_path / "quad.gltf", capsys)
    assert "skins: none" in text and "animations: none" in text


def test_other_formats_have_empty_lists(tmp_path, capsys):
    obj = tmp_path / "tri.obj"
    obj.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    info = _info(obj, capsys)
    assert {key: info[key] for key in DETAIL_KEYS} == {key: [] for key in DETAIL_KEYS}
    assert "skins" not in _text(obj, capsys)


def test_malformed_skin_is_one_error_line(tmp_path, capsys):
    path = write_gltf(tmp_path / "bad.gltf", nodes=[{"mesh": 0, "skin": 0}],
                      skins=[{"joints": [0], "skeleton": 7}])
    assert cli.main(["info", str(path), "--json"]) != 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) >= 1 and err[-1].startswith("clrender: error: ") and "skeleton" in err[-1], err
