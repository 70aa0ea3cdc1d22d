"""Compressed and quantized glTF (clrender.loaders.gltf.compression, docs/compression.md).

Round trips of `compressed_files.sheet()` (integral positions in grid units, so exact encoders give
back the very same floats): files written here with DracoPy, the meshoptimizer binding and int16
KHR_mesh_quantization load to the original's arrays and render the same depth and triangle ids
bit for bit. The gltf-transform fixtures (tests/data/compressed/, an independent writer; lossy
14-bit quantization, and Draco's edgebreaker and meshopt's reordering change the vertex and
triangle order) are compared as sets of triangles rounded back to the grid, and rendered with
their triangle ids mapped to the original's. Missing packages (imports made to fail), undecodable
data and unavailable image extensions are one-line SceneErrors.
"""
from __future__ import annotations

import base64
import io
import json
import os
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

from compressed_files import CAMERA, FIXTURES, GRID_SCALE, NODE, sheet, texture, write_sheet
from gltf_files import primitive, write_gltf

import clrender
from clrender import Camera, SceneError
from clrender.loaders.gltf import compression as gltf_compression

# The `test` extra installs the encoders; CI (CI=true) fails rather than skips without them.
if os.environ.get("CI", "").lower() in ("1", "true"):
    import DracoPy
    import meshoptimizer
else:
    DracoPy = pytest.importorskip("DracoPy", reason='pip install "clrender[compression]"')
    meshoptimizer = pytest.importorskip("meshoptimizer", reason='pip install "clrender[compression]"')

W, H = 64, 48
INSTALL = 'pip install "clrender[compression]"'
COLORS = np.random.default_rng(7).integers(0, 256, (192, 4), dtype=np.uint8)


def load(path):
    """load_scene, its warnings (e.g. an ignored KHR_texture_basisu) silenced."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return clrender.load_scene(path)


def render(make_renderer, scene):
    frame = make_renderer(W, H).render(scene, Camera.look_at(**CAMERA))
    return frame.depth, frame.triangle_id


def original(tmp_path, **attributes) -> Path:
    """The uncompressed sheet without material (COLOR_0 = COLORS unless given)."""
    p, n, uv, idx = sheet()
    attributes.setdefault("COLOR_0", COLORS)
    return write_gltf(tmp_path / "original.gltf", primitives=[primitive(p, idx, normals=n, uvs=uv, **attributes)],
                      nodes=[dict(NODE)])


def write_doc(path: Path, doc: dict, blob: bytes, extra_buffers=()) -> Path:
    """`doc` with buffer 0 = `blob` (data URI), then `extra_buffers` (JSON) as buffers 1, ..."""
    doc = {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [dict(NODE)], **doc}
    doc["buffers"] = [{"byteLength": len(blob),
                       "uri": "data:application/octet-stream;base64," + base64.b64encode(blob).decode()},
                      *extra_buffers]
    path.write_text(json.dumps(doc))
    return path


def rotated(triangles) -> np.ndarray:
    """Each triangle rotated to start at its smallest vertex index (winding kept)."""
    start = np.argmin(triangles, axis=1)[:, None]
    return triangles[np.arange(len(triangles))[:, None], (start + np.arange(3)) % 3]


def assert_same_scene(a, b, normals_atol=0.0, rotations=False):
    """Same arrays; `rotations`: a triangle may start at another corner (meshopt's TRIANGLES codec
    rotates them for compression, keeping their order and winding)."""
    np.testing.assert_array_equal(a.positions, b.positions)
    if rotations:
        np.testing.assert_array_equal(rotated(a.triangles), rotated(b.triangles))
    else:
        np.testing.assert_array_equal(a.triangles, b.triangles)
    np.testing.assert_allclose(a.normals, b.normals, atol=normals_atol, rtol=0)
    np.testing.assert_array_equal(a.uvs, b.uvs)


def assert_same_render(make_renderer, a, b, depth_rtol=0.0):
    """Same triangle ids and depth (bit for bit unless `depth_rtol`: rotated triangles interpolate
    depth from another corner, a float rounding apart)."""
    depth_a, ids_a = render(make_renderer, a)
    depth_b, ids_b = render(make_renderer, b)
    assert (ids_a >= 0).mean() > 0.5            # the sheet fills most of the frame
    np.testing.assert_array_equal(ids_a, ids_b)
    if depth_rtol:
        np.testing.assert_allclose(depth_a, depth_b, rtol=depth_rtol, atol=0)
    else:
        np.testing.assert_array_equal(depth_a, depth_b)


# -- mapped comparison (reordered vertices and triangles) ------------------------------------------------
def grid_triangles(scene) -> np.ndarray:
    """(T, 9) int64: each triangle's corners in grid units (world positions undone by NODE and
    rounded), rotated to start at its smallest corner (winding kept)."""
    g = np.round((scene.positions.astype(np.float64) - NODE["translation"]) / GRID_SCALE).astype(np.int64)
    tri = g[scene.triangles]                                    # (T, 3, 3)
    key = (tri[..., 0] << 40) + (tri[..., 1] << 20) + tri[..., 2]
    start = np.argmin(key, axis=1)
    rows = np.arange(len(tri))[:, None]
    return tri[rows, (start[:, None] + np.arange(3)) % 3].reshape(-1, 9)


def triangle_map(scene, reference) -> np.ndarray:
    """scene triangle -> the reference triangle with the same grid corners (a permutation, asserted)."""
    a, r = grid_triangles(scene), grid_triangles(reference)
    index = {tuple(row): k for k, row in enumerate(r)}
    mapped = np.array([index.get(tuple(row), -1) for row in a])
    assert len(index) == len(r) and (mapped >= 0).all(), "a triangle is not the original's"
    assert len(set(mapped.tolist())) == len(r) == len(a)
    return mapped


def assert_mapped_render(make_renderer, scene, reference, depth_atol):
    mapped = triangle_map(scene, reference)
    depth_s, ids_s = render(make_renderer, scene)
    depth_r, ids_r = render(make_renderer, reference)
    covered = (ids_s >= 0) & (ids_r >= 0)
    assert covered.mean() > 0.5
    assert ((ids_s >= 0) != (ids_r >= 0)).mean() <= 0.02          # only edge pixels may differ
    same = mapped[ids_s[covered]] == ids_r[covered]
    assert same.mean() >= 0.97, f"{same.mean():.3f} of the pixels see the same triangle"
    both = covered.copy()
    both[covered] = same
    np.testing.assert_allclose(depth_s[both], depth_r[both], atol=depth_atol, rtol=0)


# -- KHR_mesh_quantization ------------------------------------------------------------------------------------
def quantized(tmp_path, used=True) -> Path:
    p, n, uv, idx = sheet()
    path = write_gltf(tmp_path / "q.gltf",
                      primitives=[primitive(p.astype(np.int16), idx, normals=np.round(n * 127).astype(np.int8),
                                            uvs=np.round(uv * 65535).astype(np.uint16), COLOR_0=COLORS,
                                            TEXCOORD_1=p[:, :2].astype(np.int16))],
                      nodes=[dict(NODE)], edit=lambda d: [d["accessors"][a].pop("normalized")
                                                          for a in (d["meshes"][0]["primitives"][0]["attributes"][k]
                                                                    for k in ("POSITION", "TEXCOORD_1"))])
    if used:
        doc = json.loads(path.read_text())
        doc["extensionsUsed"] = doc["extensionsRequired"] = ["KHR_mesh_quantization"]
        path.write_text(json.dumps(doc))
    return path


def test_mesh_quantization_round_trip(tmp_path, make_renderer):
    reference = load(original(tmp_path, TEXCOORD_1=sheet()[0][:, :2]))
    scene = load(quantized(tmp_path))
    assert scene.positions.dtype == reference.positions.dtype
    np.testing.assert_array_equal(scene.positions, reference.positions)      # int16 grid units: exact
    np.testing.assert_array_equal(scene.triangles, reference.triangles)
    np.testing.assert_allclose(scene.normals, reference.normals, atol=1.5 / 127, rtol=0)   # one int8 step
    np.testing.assert_allclose(scene.uvs, reference.uvs, atol=0.5 / 65535 + 1e-7, rtol=0)
    np.testing.assert_array_equal(scene.extra_uvs[0], reference.extra_uvs[0])  # non-normalized: the values
    np.testing.assert_array_equal(scene.colors, reference.colors)
    assert_same_render(make_renderer, scene, reference)


def test_integer_texcoords_need_the_quantization_extension(tmp_path):
    with pytest.raises(SceneError, match=r"q\.gltf: .*TEXCOORD_1.*KHR_mesh_quantization"):
        load(quantized(tmp_path, used=False))


# -- KHR_draco_mesh_compression (DracoPy) ---------------------------------------------------------------------
DRACO_TYPES = {"POSITION": 0, "NORMAL": 1, "COLOR_0": 2, "TEXCOORD_0": 3}    # draco::GeometryAttribute::Type


def draco(tmp_path, preserve_order=True, fallback=False, required=True, data=None, edit=None) -> Path:
    """The sheet as a Draco primitive (11-bit positions over 2047 grid units: exact; normals, uvs
    and colours lossless); `fallback`: uncompressed copies of the accessors too."""
    p, n, uv, idx = sheet()
    buf = DracoPy.encode(p.astype(np.float64), idx.reshape(-1, 3).astype(np.uint32), quantization_bits=11,
                         quantization_range=2047, quantization_origin=[0, 0, 0], preserve_order=preserve_order,
                         normals=n.astype(np.float64), tex_coord=uv.astype(np.float64), colors=COLORS)
    mesh = DracoPy.decode(buf)
    uid = {a["attribute_type"]: a["unique_id"] for a in mesh.attributes}
    nv, nf = len(mesh.points), len(mesh.faces)
    blob = bytearray(buf if data is None else data)
    views = [{"buffer": 0, "byteOffset": 0, "byteLength": len(blob)}]
    accessors = [{"componentType": 5126, "type": "VEC3", "count": nv,
                  "min": p.min(0).tolist(), "max": p.max(0).tolist()},
                 {"componentType": 5126, "type": "VEC3", "count": nv},
                 {"componentType": 5121, "normalized": True, "type": "VEC4", "count": nv},
                 {"componentType": 5126, "type": "VEC2", "count": nv},
                 {"componentType": 5123, "type": "SCALAR", "count": nf * 3}]
    if fallback:
        for acc, array in zip(accessors, (p, n, COLORS, uv, idx)):
            blob += b"\0" * (-len(blob) % 4)
            views.append({"buffer": 0, "byteOffset": len(blob), "byteLength": array.nbytes})
            acc["bufferView"] = len(views) - 1
            blob += np.ascontiguousarray(array).tobytes()
    names = ("POSITION", "NORMAL", "COLOR_0", "TEXCOORD_0")
    prim = {"attributes": {k: i for i, k in enumerate(names)}, "indices": 4, "extensions": {
        "KHR_draco_mesh_compression": {"bufferView": 0, "attributes": {k: uid[DRACO_TYPES[k]] for k in names}}}}
    ext = ["KHR_draco_mesh_compression"]
    doc = {"meshes": [{"name": "sheet", "primitives": [prim]}], "accessors": accessors, "bufferViews": views,
           "extensionsUsed": ext, **({"extensionsRequired": ext} if required else {})}
    if edit is not None:
        edit(doc)
    return write_doc(tmp_path / "draco.gltf", doc, bytes(blob))


def test_draco_round_trip(tmp_path, make_renderer):
    reference = load(original(tmp_path))
    scene = load(draco(tmp_path))
    assert_same_scene(scene, reference)
    np.testing.assert_array_equal(scene.colors, reference.colors)     # uint8 normalized through Draco
    assert_same_render(make_renderer, scene, reference)


def test_draco_edgebreaker_reorders_faces(tmp_path, make_renderer):
    """Draco's default (edgebreaker) encoding reorders vertices and faces: same triangles, other ids."""
    reference = load(original(tmp_path))
    scene = load(draco(tmp_path, preserve_order=False))
    assert not np.array_equal(scene.positions, reference.positions)
    np.testing.assert_array_equal(np.unique(scene.positions, axis=0), np.unique(reference.positions, axis=0))
    assert_mapped_render(make_renderer, scene, reference, depth_atol=1e-5)


def test_draco_count_mismatch_names_the_accessor(tmp_path):
    def edit(doc):
        doc["accessors"][3]["count"] -= 1
        doc["accessors"][0]["count"] -= 1
        doc["accessors"][1]["count"] -= 1
        doc["accessors"][2]["count"] -= 1
    with pytest.raises(SceneError, match=r"draco\.gltf: mesh 0 \('sheet'\) primitive 0: .*bufferView 0.*"
                                         r"POSITION \(accessor 0\).*191") as info:
        load(draco(tmp_path, edit=edit))
    assert "\n" not in str(info.value)


@pytest.mark.parametrize("data", [b"\x00garbage" * 30, b"DRACO" + bytes(range(256)) * 2])
def test_undecodable_draco_data(tmp_path, data):
    with pytest.raises(SceneError, match=r"draco\.gltf: mesh 0 \('sheet'\) primitive 0: the "
                                         r"KHR_draco_mesh_compression data \(bufferView 0\)") as info:
        load(draco(tmp_path, data=data))
    assert "\n" not in str(info.value)


def test_truncated_and_corrupted_draco_data_never_crash(tmp_path):
    """Damaged real Draco streams (fixed seed): a SceneError or a load, never a crash."""
    p, _, _, idx = sheet()
    good = DracoPy.encode(p.astype(np.float64), idx.reshape(-1, 3).astype(np.uint32))
    rng = np.random.default_rng(3)
    for k in range(40):
        bad = bytearray(good[:rng.integers(6, len(good))] if k % 2 else good)
        for pos in rng.integers(5, len(bad), 4):
            bad[pos] = rng.integers(0, 256)
        try:
            load(draco(tmp_path, data=bytes(bad)))
        except SceneError as exc:
            assert "\n" not in str(exc)


# -- EXT_meshopt_compression (meshoptimizer) ------------------------------------------------------------------
def meshopt(tmp_path, index_mode="TRIANGLES", fallback_data=False, required=True, garbage=False) -> Path:
    """The sheet's buffer views compressed with the binding (lossless: float32 attributes, uint16
    indices); buffer 1 is the fallback: a placeholder without data, or (`fallback_data`) the data."""
    p, n, uv, idx = sheet()
    meshoptimizer.encode_vertex_version(0)          # EXT_meshopt_compression's attribute bitstream
    compressed, fallback, views = bytearray(), bytearray(), []
    for array, mode in ((p, "ATTRIBUTES"), (n, "ATTRIBUTES"), (uv, "ATTRIBUTES"), (COLORS, "ATTRIBUTES"),
                        (idx, index_mode)):
        if mode == "ATTRIBUTES":
            data = meshoptimizer.encode_vertex_buffer(np.ascontiguousarray(array), len(array), array[0].nbytes)
            stride, count = array[0].nbytes, len(array)
        else:
            encode = meshoptimizer.encode_index_buffer if mode == "TRIANGLES" else meshoptimizer.encode_index_sequence
            data = encode(idx.astype(np.uint32), len(idx), len(p))
            stride, count = 2, len(idx)
        if garbage:
            data = bytes(np.random.default_rng(len(views)).integers(0, 256, len(data), dtype=np.uint8))
        compressed += b"\0" * (-len(compressed) % 4)
        fallback += b"\0" * (-len(fallback) % 4)
        view = {"buffer": 1, "byteOffset": len(fallback), "byteLength": stride * count, "extensions": {
            "EXT_meshopt_compression": {"buffer": 0, "byteOffset": len(compressed), "byteLength": len(data),
                                        "byteStride": stride, "count": count, "mode": mode}}}
        if mode == "ATTRIBUTES":
            view["byteStride"] = stride
        views.append(view)
        compressed += data
        fallback += np.ascontiguousarray(array).tobytes()
    accessors = [{"bufferView": 0, "componentType": 5126, "type": "VEC3", "count": len(p),
                  "min": p.min(0).tolist(), "max": p.max(0).tolist()},
                 {"bufferView": 1, "componentType": 5126, "type": "VEC3", "count": len(p)},
                 {"bufferView": 2, "componentType": 5126, "type": "VEC2", "count": len(p)},
                 {"bufferView": 3, "componentType": 5121, "normalized": True, "type": "VEC4", "count": len(p)},
                 {"bufferView": 4, "componentType": 5123, "type": "SCALAR", "count": len(idx)}]
    prim = {"attributes": {"POSITION": 0, "NORMAL": 1, "TEXCOORD_0": 2, "COLOR_0": 3}, "indices": 4}
    ext = ["EXT_meshopt_compression"]
    doc = {"meshes": [{"name": "sheet", "primitives": [prim]}], "accessors": accessors, "bufferViews": views,
           "extensionsUsed": ext, **({"extensionsRequired": ext} if required else {})}
    blob = bytes(compressed)
    if fallback_data:
        extra = {"byteLength": len(fallback),
                 "uri": "data:application/octet-stream;base64," + base64.b64encode(bytes(fallback)).decode()}
    else:
        extra = {"byteLength": len(fallback), "extensions": {"EXT_meshopt_compression": {"fallback": True}}}
    return write_doc(tmp_path / "meshopt.gltf", doc, blob, [extra])


@pytest.mark.parametrize("index_mode", ["TRIANGLES", "INDICES"])
def test_meshopt_round_trip(tmp_path, make_renderer, index_mode):
    reference = load(original(tmp_path))
    scene = load(meshopt(tmp_path, index_mode))
    assert_same_scene(scene, reference, rotations=index_mode == "TRIANGLES")
    if index_mode == "INDICES":
        np.testing.assert_array_equal(scene.triangles, reference.triangles)
    np.testing.assert_array_equal(scene.colors, reference.colors)
    assert_same_render(make_renderer, scene, reference, depth_rtol=1e-6 if index_mode == "TRIANGLES" else 0.0)


def test_undecodable_meshopt_data(tmp_path):
    with pytest.raises(SceneError, match=r"meshopt\.gltf: bufferView 0: the EXT_meshopt_compression data "
                                         r"\(ATTRIBUTES, buffer 0\) cannot be decoded") as info:
        load(meshopt(tmp_path, garbage=True))
    assert "\n" not in str(info.value)


def test_meshopt_rules_are_checked_before_decoding(tmp_path):
    """A TRIANGLES count not divisible by 3 would trip an assert in meshoptimizer's C code."""
    path = meshopt(tmp_path)
    doc = json.loads(path.read_text())
    ext = doc["bufferViews"][4]["extensions"]["EXT_meshopt_compression"]
    ext["count"] -= 1
    doc["bufferViews"][4]["byteLength"] -= 2
    doc["accessors"][4]["count"] -= 1
    path.write_text(json.dumps(doc))
    with pytest.raises(SceneError, match=r"bufferView 4 EXT_meshopt_compression: TRIANGLES needs a count divisible"):
        load(path)


def test_a_fallback_buffer_is_only_for_meshopt_views(tmp_path):
    path = meshopt(tmp_path)
    doc = json.loads(path.read_text())
    del doc["bufferViews"][2]["extensions"]
    path.write_text(json.dumps(doc))
    with pytest.raises(SceneError, match=r"bufferView 2 reads buffer 1, which has no data"):
        load(path)


# -- missing packages -----------------------------------------------------------------------------------------
@pytest.mark.parametrize("make, package, ext", [(draco, "DracoPy", "KHR_draco_mesh_compression"),
                                                (meshopt, "meshoptimizer", "EXT_meshopt_compression")])
def test_missing_package_is_a_one_line_error(tmp_path, monkeypatch, make, package, ext):
    path = make(tmp_path)
    monkeypatch.setitem(sys.modules, package, None)           # `import package` now raises ImportError
    with pytest.raises(SceneError) as info:
        load(path)
    message = str(info.value)
    assert message.startswith(str(path)) and ext in message and package in message and INSTALL in message
    assert "extensionsRequired" in message and "\n" not in message
    # only used, no uncompressed fallback: the error comes when the data is read
    path = make(tmp_path, required=False)
    with pytest.raises(SceneError) as info:
        load(path)
    message = str(info.value)
    assert message.startswith(str(path)) and ext in message and package in message and INSTALL in message


@pytest.mark.parametrize("make, package, kw", [(draco, "DracoPy", {"fallback": True}),
                                               (meshopt, "meshoptimizer", {"fallback_data": True})])
def test_missing_package_with_fallback_loads_the_fallback(tmp_path, monkeypatch, make, package, kw):
    reference = load(original(tmp_path))
    path = make(tmp_path, required=False, **kw)
    assert_same_scene(load(path), reference, rotations=True)  # decoded
    monkeypatch.setitem(sys.modules, package, None)
    assert_same_scene(load(path), reference)                  # from the uncompressed fallback


# -- gltf-transform fixtures (an independent writer) ----------------------------------------------------------
def test_fixture_original_is_in_sync(tmp_path):
    a, b = load(FIXTURES / "original.gltf"), load(write_sheet(tmp_path / "original.gltf"))
    assert_same_scene(a, b)


@pytest.mark.parametrize("name, normals_atol", [("quantized.glb", 2e-3), ("draco.glb", 4e-3),
                                                ("meshopt.glb", 2e-2), ("webp.glb", 0.0)])
def test_gltf_transform_fixtures(make_renderer, name, normals_atol):
    reference = load(FIXTURES / "original.gltf")
    scene = load(FIXTURES / name)
    mapped = triangle_map(scene, reference)                  # every triangle, exactly once
    # corners: world positions within half a grid unit; normals and uvs per vertex
    scene_tri = grid_triangles(scene).reshape(-1, 3, 3)
    ref_tri = grid_triangles(reference).reshape(-1, 3, 3)[mapped]
    assert np.array_equal(scene_tri, ref_tri)
    corner_s = _corner_order(scene)
    corner_r = _corner_order(reference)[mapped]
    vs = scene.triangles[np.arange(len(mapped))[:, None], corner_s]
    vr = reference.triangles[mapped[:, None], corner_r]
    np.testing.assert_allclose(scene.positions[vs], reference.positions[vr], atol=GRID_SCALE * 0.1, rtol=0)
    np.testing.assert_allclose(scene.normals[vs], reference.normals[vr], atol=normals_atol, rtol=0)
    np.testing.assert_allclose(scene.uvs[vs], reference.uvs[vr], atol=2e-4, rtol=0)
    np.testing.assert_array_equal(scene.textures[0].rgba, reference.textures[0].rgba)   # webp: lossless
    assert_mapped_render(make_renderer, scene, reference, depth_atol=2e-3)


def _corner_order(scene) -> np.ndarray:
    g = np.round((scene.positions.astype(np.float64) - NODE["translation"]) / GRID_SCALE).astype(np.int64)
    tri = g[scene.triangles]
    key = (tri[..., 0] << 40) + (tri[..., 1] << 20) + tri[..., 2]
    return (np.argmin(key, axis=1)[:, None] + np.arange(3)) % 3


# -- image extensions -----------------------------------------------------------------------------------------
def _image_doc(tmp_path, texture_json, extra_used=()):
    from PIL import Image

    webp, png = io.BytesIO(), io.BytesIO()
    Image.fromarray(texture(1)).save(webp, "WEBP", lossless=True)
    Image.fromarray(texture(2)).save(png, "PNG")
    images = [{"uri": "data:image/webp;base64," + base64.b64encode(webp.getvalue()).decode(), "mimeType": "image/webp"},
              {"uri": "data:image/png;base64," + base64.b64encode(png.getvalue()).decode(), "mimeType": "image/png"},
              {"uri": "missing.ktx2", "mimeType": "image/ktx2"}]

    def edit(doc):
        doc["images"], doc["textures"] = images, [texture_json]
        doc["extensionsUsed"] = ["EXT_texture_webp", *extra_used]
    p, n, uv, idx = sheet()
    return write_gltf(tmp_path / "tex.gltf", primitives=[primitive(p, idx, material=0, normals=n, uvs=uv)],
                      materials=[{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}], nodes=[dict(NODE)],
                      edit=edit)


def test_webp_is_preferred_and_source_is_the_fallback(tmp_path, monkeypatch):
    path = _image_doc(tmp_path, {"source": 1, "extensions": {"EXT_texture_webp": {"source": 0}}})
    np.testing.assert_array_equal(load(path).textures[0].rgba, texture(1))
    monkeypatch.setattr(gltf_compression, "webp_available", lambda: False)
    np.testing.assert_array_equal(load(path).textures[0].rgba, texture(2))


def test_basisu_falls_back_to_source_or_errors(tmp_path, monkeypatch):
    """Without its decoder (its import made to fail; decoding: tests/test_ktx2.py)."""
    monkeypatch.setitem(sys.modules, "opengl_basisu", None)
    path = _image_doc(tmp_path, {"source": 1, "extensions": {"KHR_texture_basisu": {"source": 2}}},
                      ["KHR_texture_basisu"])
    np.testing.assert_array_equal(load(path).textures[0].rgba, texture(2))
    path = _image_doc(tmp_path, {"extensions": {"KHR_texture_basisu": {"source": 2}}}, ["KHR_texture_basisu"])
    with pytest.raises(SceneError, match=r"tex\.gltf: texture 0 has only a KHR_texture_basisu image") as info:
        load(path)
    assert "\n" not in str(info.value)
    doc = json.loads(path.read_text())
    doc["extensionsRequired"] = ["KHR_texture_basisu"]
    path.write_text(json.dumps(doc))
    with pytest.raises(SceneError, match=r"requires glTF extension KHR_texture_basisu \(extensionsRequired\)"):
        load(path)


def test_required_unknown_extension_still_errors(tmp_path):
    path = draco(tmp_path, edit=lambda d: d.update(extensionsRequired=["KHR_draco_mesh_compression",
                                                                       "VENDOR_zstd_buffers"]))
    with pytest.raises(SceneError, match=r"requires unsupported glTF extension\(s\) VENDOR_zstd_buffers"):
        load(path)
