"""Sizes read from files are checked against the memory budget before anything is allocated
(clrender.loaders.budget), images decode once per load under a total budget, and frame ranges are
planned lazily (issue 34, item 2).

Hostile loads run in a child process whose address space is capped (RLIMIT_AS): a regression is a
MemoryError in the child and a failed test, never a machine pushed into swap or the OOM killer.
"""
from __future__ import annotations

import json
import os
import struct
import subprocess
import sys
import textwrap
import time
import zlib
from pathlib import Path

import numpy as np
import pytest

from clrender import SceneError
from clrender.loaders import load_scene
from clrender.loaders import budget as budget_mod

ROOT = Path(__file__).resolve().parents[1]
AS_LIMIT = 3 << 30            # the child's address space: imports fit, a hostile array does not
GROWTH_LIMIT_MB = 400         # peak RSS growth a refused load may cost


def run_capped(code: str, env: dict | None = None, timeout: float = 60.0) -> dict:
    """Run `code` in a child with RLIMIT_AS; it must print one JSON line {...} last. Adds the child's
    peak RSS growth over its imports (MB) as "growth_mb" and the wall time as "wall_s"."""
    prelude = textwrap.dedent(f"""
        import json, resource, sys
        resource.setrlimit(resource.RLIMIT_AS, ({AS_LIMIT}, {AS_LIMIT}))
        import numpy, clrender, clrender.loaders, clrender.loaders.gltf, clrender.loaders.toml_scene
        import PIL.Image, PIL.PngImagePlugin
        base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
        def peak_mb():
            return (resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - base) / 1024.0
    """)
    full_env = {**os.environ, "PYTHONPATH": str(ROOT), "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1",
                **(env or {})}
    start = time.perf_counter()
    proc = subprocess.run([sys.executable, "-c", prelude + textwrap.dedent(code)], capture_output=True, text=True,
                          env=full_env, timeout=timeout, cwd=str(ROOT))
    wall = time.perf_counter() - start
    lines = [line for line in proc.stdout.splitlines() if line.startswith("{")]
    assert proc.returncode == 0 and lines, f"child failed (rc {proc.returncode}):\n{proc.stdout}\n{proc.stderr[-3000:]}"
    return {**json.loads(lines[-1]), "wall_s": wall}


LOAD_AND_REPORT = """
    from clrender.loaders import load_scene
    try:
        load_scene(sys.argv[1] if len(sys.argv) > 1 else PATH)
        out = {"ok": True}
    except BaseException as exc:
        out = {"ok": False, "type": type(exc).__name__, "error": str(exc)}
    out["growth_mb"] = peak_mb()
    print(json.dumps(out))
"""


def load_capped(path: Path, env: dict | None = None) -> dict:
    return run_capped(f"PATH = {str(path)!r}\n" + textwrap.dedent(LOAD_AND_REPORT), env)


def assert_refused(result: dict, path: Path, field: str, growth_mb: float = GROWTH_LIMIT_MB) -> None:
    assert not result["ok"], result
    assert result["type"] in ("BudgetError", "SceneError"), result
    message = result["error"]
    assert "\n" not in message and message.startswith(str(path)), message
    assert field in message and "bytes" in message and "budget" in message, message
    assert result["growth_mb"] < growth_mb, result
    assert result["wall_s"] < 30, result


def write_gltf(folder: Path, doc: dict, name: str = "hostile.gltf") -> Path:
    path = folder / name
    path.write_text(json.dumps({"asset": {"version": "2.0"}, **doc}))
    return path


def zeros_accessor_gltf(folder: Path, count: int) -> Path:
    """The 1 KB file of the issue: a POSITION accessor without a bufferView (zeros, as the spec allows)."""
    return write_gltf(folder, {
        "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
        "accessors": [{"componentType": 5126, "type": "VEC3", "count": count}]})


# -- the size strings --------------------------------------------------------------------------------
def test_parse_size():
    assert budget_mod.parse_size("123") == 123
    assert budget_mod.parse_size("8G") == 8 << 30
    assert budget_mod.parse_size("512m") == 512 << 20
    assert budget_mod.parse_size("1.5K") == 1536
    assert budget_mod.parse_size("2GiB") == 2 << 30
    assert budget_mod.parse_size(" 3 TB ") == 3 << 40
    assert budget_mod.parse_size("50%") == budget_mod.physical_memory() // 2
    for bad in ("", "lots", "-1G", "0", "1Q", "1e9", "nan"):
        with pytest.raises(ValueError, match="CLRENDER_MAX_MEMORY") as info:
            budget_mod.parse_size(bad)
        assert "\n" not in str(info.value)


def test_default_limit_is_half_the_memory(monkeypatch):
    monkeypatch.delenv(budget_mod.ENV, raising=False)
    assert budget_mod.memory_limit() == budget_mod.physical_memory() // 2
    monkeypatch.setenv(budget_mod.ENV, "64M")
    assert budget_mod.memory_limit() == 64 << 20


def test_bad_env_value_is_one_line_naming_the_variable(tmp_path, monkeypatch):
    path = zeros_accessor_gltf(tmp_path, 3)
    monkeypatch.setenv(budget_mod.ENV, "twelve")
    with pytest.raises(ValueError, match=r"CLRENDER_MAX_MEMORY='twelve': not a size") as info:
        load_scene(path)
    assert "\n" not in str(info.value)


def test_budget_total_and_single():
    b = budget_mod.Budget(1000)
    b.charge(600, "f.gltf", "a")
    with pytest.raises(budget_mod.BudgetError, match=r"^f.gltf: b would take 500 bytes.*already holds"):
        b.charge(500, "f.gltf", "b")
    with pytest.raises(budget_mod.BudgetError, match=r"over the memory budget of 1000 bytes"):
        b.check(1001, "f.gltf", "c")
    b.charge(400, "f.gltf", "d")
    assert b.used == 1000


# -- glTF counts --------------------------------------------------------------------------------------
@pytest.mark.parametrize("count", [402_653_184, 2 ** 31, 2 ** 62])
def test_gltf_huge_accessor_without_buffer_view(tmp_path, count):
    path = zeros_accessor_gltf(tmp_path, count)
    assert path.stat().st_size < 1024
    assert_refused(load_capped(path), path, "accessors[0].count")


def test_gltf_accessor_count_over_a_small_budget(tmp_path, monkeypatch):
    """CLRENDER_MAX_MEMORY takes effect: 30,000 zero vertices load by default, not under 100K."""
    path = zeros_accessor_gltf(tmp_path, 30_000)
    monkeypatch.delenv(budget_mod.ENV, raising=False)
    assert load_scene(path).positions.shape == (30_000, 3)
    monkeypatch.setenv(budget_mod.ENV, "100K")
    with pytest.raises(budget_mod.BudgetError, match=r"accessors\[0\]\.count .* over the memory budget of 100 KiB"):
        load_scene(path)


def test_gltf_huge_sparse_count(tmp_path):
    """A sparse accessor's count is at most its accessor's; its index and value views are real bytes."""
    blob = struct.pack("<I", 0) + struct.pack("<3f", 1, 2, 3)
    (tmp_path / "s.bin").write_bytes(blob)
    path = write_gltf(tmp_path, {
        "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
        "buffers": [{"uri": "s.bin", "byteLength": len(blob)}],
        "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 4},
                        {"buffer": 0, "byteOffset": 4, "byteLength": 12}],
        "accessors": [{"componentType": 5126, "type": "VEC3", "count": 3,
                       "sparse": {"count": 2 ** 40, "indices": {"bufferView": 0, "componentType": 5125},
                                  "values": {"bufferView": 1}}}]})
    with pytest.raises(SceneError, match=r"accessors\[0\]\.sparse\.count") as info:
        load_scene(path)
    assert "\n" not in str(info.value) and str(info.value).startswith(str(path))


def test_gltf_instanced_mesh_counts_every_instance(tmp_path, monkeypatch):
    """A mesh drawn by many nodes costs its vertices once per node: 2,000 nodes x 3,000 vertices."""
    n = 2000
    path = write_gltf(tmp_path, {
        "scenes": [{"nodes": list(range(n))}], "nodes": [{"mesh": 0} for _ in range(n)],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
        "accessors": [{"componentType": 5126, "type": "VEC3", "count": 3000}]})
    monkeypatch.setenv(budget_mod.ENV, "64M")
    with pytest.raises(budget_mod.BudgetError, match=r"mesh 0 .*primitive 0 .*node \d+.*already holds"):
        load_scene(path)


def test_gltf_morph_targets_times_vertices(tmp_path, monkeypatch):
    """10,000 morph targets naming one 10,000-vertex accessor: 1.2 GB of deltas from a 150 KB file."""
    t, v = 10_000, 9_999
    path = write_gltf(tmp_path, {
        "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "targets": [{"POSITION": 0}] * t}],
                    "weights": [0.0] * t}],
        "accessors": [{"componentType": 5126, "type": "VEC3", "count": v}]})
    monkeypatch.setenv(budget_mod.ENV, "256M")
    with pytest.raises(budget_mod.BudgetError, match=r"morph targets \(10000 targets x 9999 vertices\)"):
        load_scene(path)


# -- TOML counts --------------------------------------------------------------------------------------
def write_obj(folder: Path) -> Path:
    obj = folder / "tri.obj"
    obj.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    return obj


def test_toml_random_light_count(tmp_path):
    write_obj(tmp_path)
    path = tmp_path / "lights.toml"
    path.write_text('[[mesh]]\npath = "tri.obj"\n\n[lights]\nrandom = { count = 300000000, seed = 1 }\n')
    assert_refused(load_capped(path), path, "lights.random.count")


def test_toml_mesh_entries_share_one_budget(tmp_path, monkeypatch):
    """Ten [[mesh]] entries loading one 30,000-vertex glTF: each fits, together they do not."""
    zeros_accessor_gltf(tmp_path, 30_000, )
    path = tmp_path / "many.toml"
    path.write_text("".join('[[mesh]]\npath = "hostile.gltf"\n' for _ in range(10)))
    monkeypatch.setenv(budget_mod.ENV, "12M")
    with pytest.raises(SceneError, match=r"already holds"):
        load_scene(path)


# -- images -------------------------------------------------------------------------------------------
def png_bytes(width: int, height: int, idat: bytes = b"") -> bytes:
    """A PNG (8-bit RGB) whose header says width x height; the pixel data `idat` may be truncated."""
    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))
    ihdr = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", idat or zlib.compress(b"\0")) + \
        chunk(b"IEND", b"")


def textured_gltf(folder: Path, images: list[str]) -> Path:
    """A triangle whose material uses each image (one texture, one material slot per image)."""
    blob = struct.pack("<9f", 0, 0, 0, 1, 0, 0, 0, 1, 0) + struct.pack("<6f", 0, 0, 1, 0, 0, 1)
    (folder / "tri.bin").write_bytes(blob)
    slots = ["baseColorTexture", "metallicRoughnessTexture"]
    materials = []
    for k in range(len(images)):
        pbr = {slots[k % 2]: {"index": k}}
        materials.append({"pbrMetallicRoughness": pbr})
    return write_gltf(folder, {
        "scenes": [{"nodes": list(range(len(images)))}],
        "nodes": [{"mesh": k} for k in range(len(images))],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0, "TEXCOORD_0": 1}, "material": k}]}
                   for k in range(len(images))],
        "materials": materials,
        "textures": [{"source": k} for k in range(len(images))],
        "images": [{"uri": uri} for uri in images],
        "buffers": [{"uri": "tri.bin", "byteLength": len(blob)}],
        "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 36},
                        {"buffer": 0, "byteOffset": 36, "byteLength": 24}],
        "accessors": [{"componentType": 5126, "type": "VEC3", "count": 3, "bufferView": 0,
                       "min": [0, 0, 0], "max": [1, 1, 0]},
                      {"componentType": 5126, "type": "VEC2", "count": 3, "bufferView": 1}]}, "textured.gltf")


def test_image_named_four_times_decodes_once(tmp_path, monkeypatch):
    from PIL import Image
    Image.new("RGB", (64, 32), (200, 10, 10)).save(tmp_path / "one.png")
    path = textured_gltf(tmp_path, ["one.png", "./one.png", "one.png", "%6Fne.png"])
    opened = []
    real_open = Image.open
    monkeypatch.setattr(Image, "open", lambda fp, *a, **k: (opened.append(fp), real_open(fp, *a, **k))[1])
    scene = load_scene(path)
    assert len(scene.textures) == 4
    assert len({id(t.rgba) for t in scene.textures}) == 1       # one decoded array, shared
    assert len(opened) == 1


def test_image_header_over_the_budget_is_refused_before_decoding(tmp_path):
    """12000 x 12000 in a 100-byte file: refused from its header under a 512 MB budget (its RGBA is 549 MB)."""
    (tmp_path / "big.png").write_bytes(png_bytes(12000, 12000))
    path = textured_gltf(tmp_path, ["big.png"] * 4)
    result = load_capped(path, {budget_mod.ENV: "512M"})
    assert_refused(result, path, "big.png")
    assert "12000x12000" in result["error"]


def test_images_share_a_total_budget(tmp_path):
    """Four 5000 x 5000 files (one colour, 76 KB each): each fits 512 MB, together they do not."""
    from PIL import Image
    Image.new("RGB", (5000, 5000), (10, 200, 30)).save(tmp_path / "i0.png", compress_level=1)
    for k in range(1, 4):
        (tmp_path / f"i{k}.png").write_bytes((tmp_path / "i0.png").read_bytes())
    path = textured_gltf(tmp_path, [f"i{k}.png" for k in range(4)])
    result = load_capped(path, {budget_mod.ENV: "512M"})
    assert_refused(result, path, "already holds", growth_mb=1024)     # two decoded (and freed) before


def test_decompression_bomb_is_a_budget_error(tmp_path, monkeypatch):
    """An image past Pillow's decompression-bomb limit (2 x MAX_IMAGE_PIXELS) is judged by the budget
    alone: over it, the one-line budget error naming the file and its size."""
    (tmp_path / "bomb.png").write_bytes(png_bytes(20000, 20000))
    path = textured_gltf(tmp_path, ["bomb.png"])
    monkeypatch.setenv(budget_mod.ENV, "1G")
    with pytest.raises(budget_mod.BudgetError, match=r"bomb\.png \(20000x20000 pixels, decoded\).*budget") as info:
        load_scene(path)
    assert "\n" not in str(info.value) and str(info.value).startswith(str(path))


def test_large_texture_within_the_budget_decodes_without_pillow_warning(tmp_path):
    """9500 x 9500 is past Pillow's DecompressionBombWarning (89 M pixels) but within the budget:
    decoded, with no warning (the budget is the gate, not Pillow's heuristic)."""
    import warnings

    from PIL import Image
    Image.new("L", (9500, 9500), 90).save(tmp_path / "big.png", compress_level=1)
    path = textured_gltf(tmp_path, ["big.png"])
    with warnings.catch_warnings():
        warnings.simplefilter("error", Image.DecompressionBombWarning)
        scene = load_scene(path)
    assert [t.rgba.shape for t in scene.textures] == [(9500, 9500, 4)]


def test_hdr_environment_header_is_checked(tmp_path, monkeypatch):
    """A 2048 x 1024 RLE header over 140 KB: its 32 MB of pixels are refused under a 16 MB budget."""
    from clrender.scene.environment import load_environment
    path = tmp_path / "huge.hdr"
    line = bytes([2, 2, 2048 >> 8, 2048 & 255]) + bytes([128 + 127, 0] * 17 * 4)
    path.write_bytes(b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 1024 +X 2048\n" + line * 1024)
    monkeypatch.setenv(budget_mod.ENV, "16M")
    with pytest.raises(budget_mod.BudgetError, match=r"huge\.hdr.*-Y 1024 \+X 2048.*budget") as info:
        load_environment(path)
    assert "\n" not in str(info.value)


def test_exr_environment_header_is_checked(tmp_path, monkeypatch):
    OpenEXR = pytest.importorskip("OpenEXR")
    from clrender.scene.environment import load_environment
    path = tmp_path / "env.exr"
    pixels = np.zeros((512, 1024, 3), np.float32)
    OpenEXR.File({"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage},
                 {"RGB": pixels}).write(str(path))
    assert load_environment(path).pixels.shape == (512, 1024, 3)
    monkeypatch.setenv(budget_mod.ENV, "4M")
    with pytest.raises(budget_mod.BudgetError, match=r"env\.exr: the OpenEXR data window \(1024x512 pixels\)"):
        load_environment(path)


# -- frames and views ---------------------------------------------------------------------------------
def test_hundred_million_frames_plan_lazily(tmp_path):
    """`--frames 0:100000000`: the plan exists at once, its first task is frame 0, memory stays flat."""
    scene = write_obj(tmp_path)
    result = run_capped(f"""
        import time
        from clrender.batch import plan_tasks, job_signature
        start = time.perf_counter()
        tasks, manifest = plan_tasks([{str(scene)!r}], range(0, 100_000_000), {str(tmp_path / 'out')!r}, 24.0)
        first = next(iter(tasks))
        sig = job_signature(tasks, 24.0)
        print(json.dumps({{"n": len(tasks), "frame": first.frame, "image": first.image, "last": tasks[-1].frame,
                          "s": time.perf_counter() - start, "growth_mb": peak_mb()}}))
    """)
    assert result["n"] == 100_000_000 and result["frame"] == 0 and result["last"] == 99_999_999
    assert result["image"].endswith("tri_0000.png")
    assert result["s"] < 1.0 and result["growth_mb"] < 50, result


def test_lazy_plan_still_refuses_shared_files(tmp_path):
    from clrender.batch.jobs import plan_tasks
    scene = write_obj(tmp_path)
    with pytest.raises(ValueError, match="gives one file"):
        plan_tasks([str(scene)], range(0, 10_000_000), str(tmp_path / "out_{time:.0f}.png"), 24.0)
    with pytest.raises(ValueError, match="gives one file"):
        plan_tasks([str(scene)], range(0, 3), str(tmp_path / "same.png"), 24.0)
    tasks, _ = plan_tasks([str(scene)], range(5, 10_000_000, 5), str(tmp_path / "f{frame:08d}.png"), 24.0)
    assert [t.frame for t in tasks[:3]] == [5, 10, 15] and tasks[2].image.endswith("f00000015.png")


def test_cli_hundred_million_frames_start_at_once(tmp_path):
    """`clrender render SCENE --frames 0:100000000`: every check passes and frame 0 is handed to the
    renderer within seconds, the memory flat (the child's render_task reports and exits)."""
    scene = write_obj(tmp_path)
    result = run_capped(f"""
        import os, time
        import clrender.batch, clrender.cli
        start = time.perf_counter()
        def first_frame(task):
            print(json.dumps({{"frame": task.frame, "image": task.image, "s": time.perf_counter() - start,
                              "growth_mb": peak_mb()}}), flush=True)
            os._exit(0)
        clrender.batch.jobs.render_task = first_frame
        clrender.cli.main(["render", {str(scene)!r}, "--frames", "0:100000000", "-o", {str(tmp_path / 'out')!r} + "/",
                           "--width", "8", "--height", "8", "-q"])
        print(json.dumps({{"frame": None}}))
    """)
    assert result["frame"] == 0 and result["image"].endswith("tri_0000.png"), result
    assert result["s"] < 5 and result["growth_mb"] < 100, result


def test_dataset_views_are_checked_before_planning(tmp_path, capsys):
    """`clrender dataset --views 100000000`: a dataset's camera files list every view before the first
    renders, so the count is checked against the budget first: one line, at once, nothing written."""
    from clrender.cli import app as cli
    scene = write_obj(tmp_path)
    out = tmp_path / "ds"
    start = time.perf_counter()
    rc = cli.main(["dataset", str(scene), "-o", str(out), "--views", "100000000", "--width", "8", "--height", "8"])
    err = [line for line in capsys.readouterr().err.splitlines() if line.strip()]
    assert rc != 0 and len(err) == 1, err
    assert err[0].startswith("clrender: error: --views: 100000000 views") and "budget" in err[0], err
    assert time.perf_counter() - start < 10 and not (out / "transforms.json").exists()
