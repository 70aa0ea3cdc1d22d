"""Confinement (issue 34, item 1): a scene file reads only files in its own folder.

Every reference a scene file makes (glTF buffer/image URIs, OBJ mtllib, MTL map_Kd, PLY TextureFile,
TOML mesh paths and environment sources) must resolve, after `..`, percent-encoding and symlinks,
inside the scene's folder, unless the user allows another folder (`load_scene(..., allow=[...])`,
`--allow-outside PATH`). A refusal is one SceneError line naming the file that made the reference and
the reference as written; the outside file is never opened, so nothing of it reaches a message.
"""
from __future__ import annotations

import base64
import json
import os
import sys
from pathlib import Path

import numpy as np
import pytest

from clrender import SceneError, load_scene

SECRET = "TOPSECRET-4f1c9e"
PASSWD = f"root:x:0:0:{SECRET}:/root:/bin/bash\ndaemon:x:1:1:daemon:/usr/sbin:/usr/sbin/nologin\n"

# -- every file opened while a test runs (an audit hook: cannot be removed, so it checks a flag) --
_OPENED: list = []
_WATCH: list = []


def _audit(event, args):
    if event == "open" and _WATCH and args and isinstance(args[0], (str, bytes, os.PathLike)):
        _OPENED.append(os.fsdecode(args[0]))


sys.addaudithook(_audit)


@pytest.fixture
def opened():
    """The paths opened (by anything: clrender, trimesh, PIL) while the test runs."""
    _OPENED.clear()
    _WATCH.append(True)
    yield _OPENED
    _WATCH.clear()


@pytest.fixture
def dirs(tmp_path):
    """scene/ (where scene files live) and outside/ (a sibling folder with a secret and valid assets)."""
    scene, outside = tmp_path / "scene", tmp_path / "outside"
    scene.mkdir()
    outside.mkdir()
    (outside / "passwd").write_text(PASSWD)
    (outside / "secret.bin").write_bytes(PASSWD.encode()[:36])        # 36 bytes: 3 VEC3 floats of a buffer
    _png(outside / "tex.png")
    (outside / "good.mtl").write_text("newmtl red\nKd 1 0 0\nmap_Kd tex.png\n")
    (outside / "tri.bin").write_bytes(TRI.tobytes())
    (outside / "tri.obj").write_text(TRI_OBJ)
    return scene, outside


TRI = np.array([[-1, -1, -3], [1, -1, -3], [0, 1, -3]], np.float32)
TRI_OBJ = "v -1 -1 -3\nv 1 -1 -3\nv 0 1 -3\nvt 0 0\nvt 1 0\nvt 0.5 1\nf 1/1 2/2 3/3\n"


def _png(path: Path) -> Path:
    from PIL import Image
    Image.fromarray(np.full((4, 4, 3), 200, np.uint8)).save(path)
    return path


def _gltf(path: Path, buffer_uri: str = None, image_uri: str = None) -> Path:
    """A one-triangle glTF whose positions come from `buffer_uri` (default: a data URI) and whose
    material, with `image_uri`, has a base colour texture."""
    if buffer_uri is None:
        buffer_uri = "data:application/octet-stream;base64," + base64.b64encode(TRI.tobytes()).decode()
    uv = np.array([[0, 0], [1, 0], [0.5, 1]], np.float32).tobytes()
    doc = {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
           "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "TEXCOORD_0": 1}}]}],
           "buffers": [{"byteLength": 36, "uri": buffer_uri},
                       {"byteLength": 24, "uri": "data:application/octet-stream;base64," + base64.b64encode(uv).decode()}],
           "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 36},
                           {"buffer": 1, "byteOffset": 0, "byteLength": 24}],
           "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
                          "min": [-1, -1, -3], "max": [1, 1, -3]},
                         {"bufferView": 1, "componentType": 5126, "count": 3, "type": "VEC2"}]}
    if image_uri is not None:
        doc.update(images=[{"uri": image_uri}], textures=[{"source": 0}],
                   materials=[{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}])
        doc["meshes"][0]["primitives"][0]["material"] = 0
    path.write_text(json.dumps(doc))
    return path


def _refused(path, reference: str, referrer: str, opened, outside: Path, allow=None) -> str:
    """Loading `path` is one SceneError line naming `referrer` and `reference`, with none of the
    secret, and no file under `outside` was opened while loading."""
    opened.clear()
    with pytest.raises(SceneError) as info:
        load_scene(path, allow=allow)
    msg = str(info.value)
    assert "\n" not in msg, msg
    assert referrer in msg and repr(reference) in msg, msg
    assert "outside the scene's folder" in msg and "--allow-outside" in msg, msg
    assert SECRET not in msg and "root:x" not in msg, msg
    touched = [p for p in opened if Path(p).resolve().is_relative_to(outside.resolve())]
    assert not touched, f"opened outside files: {touched}"
    return msg


# -- OBJ / MTL --------------------------------------------------------------------------------------
@pytest.mark.parametrize("ref", ["../outside/passwd", "../../scene/../outside/passwd", "ABSOLUTE", "sub/../../outside/passwd"])
def test_obj_mtllib_outside_is_refused(dirs, opened, ref):
    scene, outside = dirs
    ref = str(outside / "passwd") if ref == "ABSOLUTE" else ref
    (scene / "m.obj").write_text(f"mtllib {ref}\n" + TRI_OBJ)
    _refused(scene / "m.obj", ref, "m.obj", opened, outside)


def test_obj_mtllib_deep_climb(tmp_path, opened):
    """`../../../x` from a folder three deep, to a file at the top."""
    deep = tmp_path / "a" / "b" / "c"
    deep.mkdir(parents=True)
    (tmp_path / "x").write_text(PASSWD)
    (deep / "m.obj").write_text("mtllib ../../../x\n" + TRI_OBJ)
    _refused(deep / "m.obj", "../../../x", "m.obj", opened, tmp_path / "x")


def test_mtl_map_kd_outside_is_refused(dirs, opened):
    scene, outside = dirs
    (scene / "m.mtl").write_text("newmtl red\nKd 1 0 0\nmap_Kd ../outside/tex.png\n")
    (scene / "m.obj").write_text("mtllib m.mtl\nusemtl red\n" + TRI_OBJ)
    msg = _refused(scene / "m.obj", "../outside/tex.png", "m.mtl", opened, outside)
    assert "map_Kd" in msg and "'red'" in msg


def test_trimesh_does_not_read_outside_files_either(dirs, opened):
    """trimesh finds `mtllib` anywhere in an OBJ (a comment too) and opens map_Kd images itself:
    it may read only the material libraries clrender has checked."""
    scene, outside = dirs
    (scene / "m.obj").write_text(f"# exported: mtllib {outside / 'passwd'}\n" + TRI_OBJ)
    loaded = load_scene(scene / "m.obj")
    assert loaded.triangle_count == 1
    (scene / "n.obj").write_text(f"mtllib {outside / 'good.mtl'}\nusemtl red\n" + TRI_OBJ)
    opened.clear()
    with pytest.raises(SceneError):
        load_scene(scene / "n.obj")
    assert not [p for p in opened if Path(p).resolve().is_relative_to(outside.resolve())]


def test_symlink_out_of_the_folder_is_outside(dirs, opened):
    scene, outside = dirs
    (scene / "lib.mtl").symlink_to(outside / "passwd")
    (scene / "m.obj").write_text("mtllib lib.mtl\n" + TRI_OBJ)
    _refused(scene / "m.obj", "lib.mtl", "m.obj", opened, outside)
    (scene / "link").symlink_to(outside, target_is_directory=True)
    (scene / "n.obj").write_text("mtllib link/good.mtl\n" + TRI_OBJ)
    _refused(scene / "n.obj", "link/good.mtl", "n.obj", opened, outside)


def test_symlink_loop_is_one_line(dirs):
    scene, _ = dirs
    (scene / "loop.mtl").symlink_to(scene / "loop2.mtl")
    (scene / "loop2.mtl").symlink_to(scene / "loop.mtl")
    (scene / "m.obj").write_text("mtllib loop.mtl\n" + TRI_OBJ)
    with pytest.raises(SceneError) as info:
        load_scene(scene / "m.obj")
    msg = str(info.value)
    assert "\n" not in msg and "m.obj" in msg and "'loop.mtl'" in msg, msg


def test_a_file_that_is_not_mtl_is_not_printed(dirs):
    """An mtllib naming a file in the folder that is no material library: one line, none of its text."""
    scene, _ = dirs
    (scene / "notes.txt").write_text(PASSWD + "Hello world\n")
    (scene / "m.obj").write_text("mtllib notes.txt\n" + TRI_OBJ)
    with pytest.raises(SceneError, match="not an MTL file") as info:
        load_scene(scene / "m.obj")
    msg = str(info.value)
    assert SECRET not in msg and "root:x" not in msg and "Hello" not in msg, msg
    # a material library with a garbled line: the warning counts it, never quotes it
    (scene / "m.mtl").write_text(f"newmtl red\nKd 1 0 0\n{PASSWD}")
    (scene / "n.obj").write_text("mtllib m.mtl\nusemtl red\n" + TRI_OBJ)
    with pytest.warns(UserWarning) as record:
        load_scene(scene / "n.obj")
    assert all(SECRET not in str(w.message) and "root:x" not in str(w.message) for w in record)
    (scene / "bad.mtl").write_text(f"newmtl red\nKd {SECRET} 0 0\n")
    (scene / "b.obj").write_text("mtllib bad.mtl\nusemtl red\n" + TRI_OBJ)
    with pytest.raises(SceneError, match="line 2") as info:
        load_scene(scene / "b.obj")
    assert SECRET not in str(info.value)


def test_ply_texture_file_outside_is_refused(dirs, opened):
    scene, outside = dirs
    (scene / "t.ply").write_text("ply\nformat ascii 1.0\ncomment TextureFile ../outside/tex.png\n"
                                 "element vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
                                 "element face 1\nproperty list uchar int vertex_indices\nend_header\n"
                                 "-1 -1 -3\n1 -1 -3\n0 1 -3\n3 0 1 2\n")
    _refused(scene / "t.ply", "../outside/tex.png", "t.ply", opened, outside)
    assert load_scene(scene / "t.ply", allow=[outside]).textures


def test_obj_allowed_folder_and_inside_references(dirs):
    scene, outside = dirs
    (scene / "m.obj").write_text(f"mtllib {outside / 'good.mtl'}\nusemtl red\n" + TRI_OBJ)
    loaded = load_scene(scene / "m.obj", allow=[outside])
    assert loaded.materials[0].base_color[:3] == pytest.approx((1, 0, 0)) and len(loaded.textures) == 1
    loaded = load_scene(scene / "m.obj", allow=str(outside))          # one folder, not its characters
    assert len(loaded.textures) == 1
    # inside: a subfolder, `./`, `sub/../`, and a symlink that stays inside
    sub = scene / "sub"
    sub.mkdir()
    _png(sub / "t.png")
    (sub / "m.mtl").write_text("newmtl red\nKd 1 0 0\nmap_Kd ./t.png\n")
    for ref in ("sub/m.mtl", "./sub/m.mtl", "sub/../sub/m.mtl", str(sub / "m.mtl")):
        (scene / "i.obj").write_text(f"mtllib {ref}\nusemtl red\n" + TRI_OBJ)
        assert len(load_scene(scene / "i.obj").textures) == 1, ref
    (sub / "plain.mtl").write_text("newmtl red\nKd 1 0 0\n")
    (scene / "alias.mtl").symlink_to(sub / "plain.mtl")                # a symlink that stays inside
    (scene / "i.obj").write_text("mtllib alias.mtl\nusemtl red\n" + TRI_OBJ)
    assert load_scene(scene / "i.obj").materials[0].name == "red"


# -- glTF -------------------------------------------------------------------------------------------
@pytest.mark.parametrize("kind", ["relative", "absolute", "percent", "percent-upper", "file-uri", "symlink"])
def test_gltf_buffer_outside_is_refused(dirs, opened, kind):
    scene, outside = dirs
    secret = outside / "secret.bin"
    uri = {"relative": "../outside/secret.bin", "absolute": str(secret),
           "percent": "%2e%2e/outside/secret.bin", "percent-upper": "%2E%2E%2Foutside%2Fsecret.bin",
           "file-uri": secret.as_uri(), "symlink": "data.bin"}[kind]
    if kind == "symlink":
        (scene / "data.bin").symlink_to(secret)
    path = _gltf(scene / "s.gltf", buffer_uri=uri)
    msg = _refused(path, uri, "s.gltf", opened, outside)
    assert "buffer 0" in msg


@pytest.mark.parametrize("kind", ["relative", "absolute", "percent", "file-uri"])
def test_gltf_image_outside_is_refused(dirs, opened, kind):
    scene, outside = dirs
    tex = outside / "tex.png"
    uri = {"relative": "../outside/tex.png", "absolute": str(tex), "percent": "..%2Foutside%2Ftex.png",
           "file-uri": tex.as_uri()}[kind]
    path = _gltf(scene / "s.gltf", image_uri=uri)
    msg = _refused(path, uri, "s.gltf", opened, outside)
    assert "image 0" in msg


def test_gltf_other_uri_schemes_and_types(dirs):
    scene, _ = dirs
    with pytest.raises(SceneError, match="scheme 'http'"):
        load_scene(_gltf(scene / "h.gltf", buffer_uri="http://example.com/x.bin"))
    doc = json.loads(_gltf(scene / "t.gltf").read_text())
    doc["buffers"][0]["uri"] = 12
    (scene / "t.gltf").write_text(json.dumps(doc))
    with pytest.raises(SceneError, match=r"t\.gltf: buffer 0 uri must be"):
        load_scene(scene / "t.gltf")


def test_gltf_allowed_and_inside(dirs):
    scene, outside = dirs
    for uri in ("../outside/tri.bin", (outside / "tri.bin").as_uri(), "%2e%2e/outside/tri.bin"):
        loaded = load_scene(_gltf(scene / "s.gltf", buffer_uri=uri, image_uri="../outside/tex.png"),
                            allow=[outside])
        assert loaded.positions[:3].tolist() == TRI.tolist() and len(loaded.textures) == 1
    (scene / "bin").mkdir()
    (scene / "bin" / "tri data.bin").write_bytes(TRI.tobytes())
    _png(scene / "t.png")
    for uri in ("bin/tri%20data.bin", "./bin/tri%20data.bin", (scene / "bin" / "tri data.bin").as_uri()):
        loaded = load_scene(_gltf(scene / "s.gltf", buffer_uri=uri, image_uri="./t.png"))
        assert loaded.positions[:3].tolist() == TRI.tolist() and len(loaded.textures) == 1


def test_glb_is_confined_too(dirs, opened):
    scene, outside = dirs
    doc = json.loads(_gltf(scene / "x.gltf", buffer_uri="../outside/secret.bin").read_text())
    chunk = json.dumps(doc).encode()
    chunk += b" " * (-len(chunk) % 4)
    blob = b"glTF" + (2).to_bytes(4, "little") + (12 + 8 + len(chunk)).to_bytes(4, "little") + \
        len(chunk).to_bytes(4, "little") + b"JSON" + chunk
    (scene / "s.glb").write_bytes(blob)
    _refused(scene / "s.glb", "../outside/secret.bin", "s.glb", opened, outside)


# -- TOML -------------------------------------------------------------------------------------------
def test_toml_mesh_and_environment_outside(dirs, opened):
    scene, outside = dirs
    (scene / "a.toml").write_text('[[mesh]]\npath = "../outside/tri.obj"\n')
    msg = _refused(scene / "a.toml", "../outside/tri.obj", "a.toml", opened, outside)
    assert "mesh[0].path" in msg
    (scene / "b.toml").write_text(f'[[mesh]]\npath = "{outside / "tri.obj"}"\n')
    _refused(scene / "b.toml", str(outside / "tri.obj"), "b.toml", opened, outside)
    from clrender.scene.environment_files import write_rgbe
    write_rgbe(outside / "env.hdr", np.ones((4, 8, 3), np.float32))
    (scene / "tri.obj").write_text(TRI_OBJ)
    (scene / "c.toml").write_text('[[mesh]]\npath = "tri.obj"\n[environment]\nsource = "../outside/env.hdr"\n')
    msg = _refused(scene / "c.toml", "../outside/env.hdr", "c.toml", opened, outside)
    assert "environment.source" in msg
    # a TOML include outside: refused as outside before anything else
    (outside / "inc.toml").write_text("")
    (scene / "d.toml").write_text('[[mesh]]\npath = "../outside/inc.toml"\n')
    _refused(scene / "d.toml", "../outside/inc.toml", "d.toml", opened, outside)
    # allowed
    loaded = load_scene(scene / "a.toml", allow=[outside])
    assert loaded.triangle_count == 1
    assert load_scene(scene / "c.toml", allow=[outside]).environment is not None


def test_toml_mesh_files_reach_the_toml_folder_only(dirs, opened):
    """A mesh file in a subfolder of a TOML scene may reference files beside the TOML file (the
    scene's folder), not beyond it; loaded on its own, it reads only its own folder."""
    scene, outside = dirs
    (scene / "models").mkdir()
    (scene / "tri.bin").write_bytes(TRI.tobytes())
    _gltf(scene / "models" / "m.gltf", buffer_uri="../tri.bin")
    (scene / "s.toml").write_text('[[mesh]]\npath = "models/m.gltf"\n')
    assert load_scene(scene / "s.toml").triangle_count == 1
    _refused(scene / "models" / "m.gltf", "../tri.bin", "m.gltf", opened, scene / "tri.bin")
    _gltf(scene / "models" / "n.gltf", buffer_uri="../../outside/secret.bin")
    (scene / "t.toml").write_text('[[mesh]]\npath = "models/n.gltf"\n')
    msg = _refused(scene / "t.toml", "../../outside/secret.bin", "n.gltf", opened, outside)
    assert msg.startswith(str(scene / "t.toml")) and str(scene) in msg


# -- CLI --------------------------------------------------------------------------------------------
def _one_error_line(capsys) -> str:
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("clrender: error: ") and "Traceback" not in err, err
    return lines[0]


def test_cli_info_and_allow_outside(dirs, capsys, monkeypatch):
    from clrender.cli import app as cli
    monkeypatch.delenv("CLRENDER_LOG", raising=False)
    scene, outside = dirs
    path = _gltf(scene / "s.gltf", buffer_uri="../outside/secret.bin")
    assert cli.main(["info", str(path)]) != 0
    line = _one_error_line(capsys)
    assert "'../outside/secret.bin'" in line and "s.gltf" in line and SECRET not in line
    capsys.readouterr()
    good = _gltf(scene / "g.gltf", buffer_uri="../outside/tri.bin")
    assert cli.main(["info", str(good), "--json", "--allow-outside", str(outside)]) == 0
    assert json.loads(capsys.readouterr().out)["triangles"] == 1
    assert cli.main(["info", str(good), "--allow-outside", str(outside / "nope")]) != 0
    assert "--allow-outside" in _one_error_line(capsys)


def test_cli_render_and_batch_allow_outside(dirs, tmp_path, capsys, device, monkeypatch):
    """`render` (a still) and `render --frames` (the batch path: tasks carry the folders to workers)."""
    from clrender.cli import app as cli
    monkeypatch.delenv("CLRENDER_LOG", raising=False)
    scene, outside = dirs
    (scene / "m.obj").write_text(f"mtllib {outside / 'good.mtl'}\nusemtl red\n" + TRI_OBJ)
    common = ["--width", "16", "--height", "12", "--device", device.id, "-q"]
    assert cli.main(["render", str(scene / "m.obj"), "-o", str(tmp_path / "a.png"), *common]) != 0
    line = _one_error_line(capsys)
    assert "mtllib" in line and "good.mtl" in line and "--allow-outside" in line
    assert cli.main(["render", str(scene / "m.obj"), "-o", str(tmp_path / "a.png"), *common,
                     "--allow-outside", str(outside)]) == 0, capsys.readouterr().err
    assert (tmp_path / "a.png").is_file()
    out = tmp_path / "frames"
    assert cli.main(["render", str(scene / "m.obj"), "-o", str(out), "--frames", "0:1", *common]) != 0
    assert "good.mtl" in capsys.readouterr().err
    assert cli.main(["render", str(scene / "m.obj"), "-o", str(out), "--frames", "0:1", *common,
                     "--allow-outside", str(outside)]) == 0, capsys.readouterr().err
    assert len(list(out.glob("*.png"))) == 1


def test_render_frames_library_allow(dirs, tmp_path, device):
    from clrender.batch.jobs import render_frames
    scene, outside = dirs
    (scene / "m.obj").write_text(f"mtllib {outside / 'good.mtl'}\nusemtl red\n" + TRI_OBJ)
    result = render_frames(scene / "m.obj", [0], tmp_path / "o1", width=16, height=12, device=device.id)
    assert result.failed and "outside the scene's folder" in result.failed[0][2]
    result = render_frames(scene / "m.obj", [0], tmp_path / "o2", width=16, height=12, device=device.id,
                           allow=[outside])
    assert result.ok and len(result.images) == 1


def test_cli_dataset_allow_outside(dirs, tmp_path, capsys, device, monkeypatch):
    from clrender.cli import app as cli
    monkeypatch.delenv("CLRENDER_LOG", raising=False)
    scene, outside = dirs
    path = _gltf(scene / "s.gltf", buffer_uri="../outside/tri.bin")
    common = ["--views", "1", "--width", "16", "--height", "12", "--aov", "none", "--device", device.id, "-q"]
    assert cli.main(["dataset", str(path), "-o", str(tmp_path / "d1"), *common]) != 0
    line = _one_error_line(capsys)
    assert "'../outside/tri.bin'" in line and "s.gltf" in line
    assert cli.main(["dataset", str(path), "-o", str(tmp_path / "d2"), *common,
                     "--allow-outside", str(outside)]) == 0, capsys.readouterr().err
    assert len(list((tmp_path / "d2" / "images").glob("*.png"))) == 1
