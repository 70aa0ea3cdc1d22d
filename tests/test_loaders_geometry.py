"""glTF geometry without trimesh (clrender/loaders/gltf/geometry.py): the numpy path loads every
shared glTF scene, and files with every node-transform and primitive form, into exactly the arrays
the trimesh path (CLRENDER_GLTF_TRIMESH=1, the loader before) does."""
from __future__ import annotations

import math
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

from gltf_files import QUAD_INDICES, QUAD_POSITIONS, primitive, write_gltf

from clrender.loaders import load_scene
from clrender.loaders.gltf import geometry as gg

SHARED = Path(__file__).resolve().parents[2] / "shared" / "scenes"
SHARED_GLTF = sorted(p for p in SHARED.glob("*/*.gl*") if p.suffix in (".gltf", ".glb")) if SHARED.is_dir() else []
ARRAYS = ("positions", "normals", "uvs", "triangles", "triangle_material", "tangents", "colors", "extra_uvs")


def _load(path, monkeypatch, trimesh: bool):
    monkeypatch.setenv(gg.ENV_TRIMESH, "1" if trimesh else "0")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return load_scene(path)


def assert_same_scene(a, b, where):
    for name in ARRAYS:
        x, y = getattr(a, name), getattr(b, name)
        assert (x is None) == (y is None), (where, name)
        if x is not None:
            assert x.dtype == y.dtype and np.array_equal(x, y), (where, name)
    assert [repr(m) for m in a.materials] == [repr(m) for m in b.materials], where
    assert [(t.name, t.srgb, t.wrap_s, t.wrap_t) for t in a.textures] == \
        [(t.name, t.srgb, t.wrap_s, t.wrap_t) for t in b.textures], where
    assert all(np.array_equal(s.rgba, t.rgba) for s, t in zip(a.textures, b.textures)), where
    assert repr(a.camera) == repr(b.camera), where
    assert np.array_equal(np.asarray(a.lights), np.asarray(b.lights)), where


@pytest.mark.skipif(not SHARED_GLTF, reason=f"no shared glTF scenes under {SHARED}")
@pytest.mark.parametrize("path", SHARED_GLTF, ids=[p.parent.name for p in SHARED_GLTF])
def test_shared_scenes_load_as_through_trimesh(path, monkeypatch):
    assert_same_scene(_load(path, monkeypatch, False), _load(path, monkeypatch, True), path)


def _quat(axis, degrees):
    axis = np.asarray(axis, np.float64) / np.linalg.norm(axis)
    s = math.sin(math.radians(degrees) / 2)
    return [*(axis * s).tolist(), math.cos(math.radians(degrees) / 2)]


def _nodes():
    """Roots and chains with matrix, TRS, partial TRS, non-unit quaternions, near-identity and
    almost-rigid (fix_rigid's SVD) matrices, a camera; meshes of one and of two primitives."""
    almost = np.eye(4)
    almost[:3, :3] += 1e-7 * np.arange(9).reshape(3, 3)         # off by 1e-13..1e-5: repaired
    near_eye = np.eye(4)
    near_eye[0, 3] = 1e-9                                         # within 1e-8: dropped in chains
    return [
        {"mesh": 0, "translation": [1, 2, 3], "rotation": _quat([1, 2, 3], 37), "scale": [2, 2, 2],
         "children": [1, 2]},
        {"mesh": 1, "matrix": np.eye(4).T.reshape(-1).tolist(), "children": [3]},
        {"mesh": 0, "rotation": [0.1, 0.2, 0.3, 0.9], "children": [4]},                 # not unit
        {"mesh": 1, "matrix": almost.T.reshape(-1).tolist(), "camera": 0},
        {"mesh": 0, "matrix": near_eye.T.reshape(-1).tolist()},
        {"mesh": 1, "rotation": _quat([0, 1, 0], 90)},                                  # a root
        {"mesh": 0, "matrix": almost.T.reshape(-1).tolist()},                           # root, almost rigid
        {"mesh": 1, "translation": [0.5, 0, 0], "scale": [1, -1, 1], "children": [8]},        # mirrored
        {"mesh": 1, "scale": [3, 1, 0.5], "rotation": [0, 0, 0, 0]},                    # zero quaternion
    ]


def test_node_transforms_and_primitive_forms_load_as_through_trimesh(tmp_path, monkeypatch):
    def prim(positions, **kw):
        n = len(positions)
        normals = np.tile(np.float32([0, 0.6, 0.8]), (n, 1))
        return primitive(positions=np.float32(positions), normals=normals, uvs=np.zeros((n, 2), np.float32), **kw)

    strip = prim([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0], [0, 2, 0]], indices=np.uint16([0, 1, 2, 3, 4]), mode=5)
    no_indices = prim([[0, 0, 1], [1, 0, 1], [0, 1, 1], [1, 1, 1], [0, 2, 1], [1, 2, 1]], indices=None)
    strip_no_indices = primitive(positions=np.float32([[0, 0, 2], [1, 0, 2], [0, 1, 2], [1, 1, 2]]), indices=None,
                                 mode=5, normals=None, uvs=None)
    quad = primitive(QUAD_POSITIONS + np.float32([0, 0, -1]), QUAD_INDICES.astype(np.uint32))
    path = write_gltf(tmp_path / "t.gltf", meshes=[[quad], [strip, no_indices, strip_no_indices]], nodes=_nodes(),
                      scenes=[{"nodes": [0, 5, 6, 7]}], scene=0,
                      cameras=[{"type": "perspective", "perspective": {"yfov": 0.8, "znear": 0.1, "zfar": 50}}])
    a, b = _load(path, monkeypatch, False), _load(path, monkeypatch, True)
    assert a.triangle_count == b.triangle_count > 10 and a.camera is not None
    assert_same_scene(a, b, path)
    # the float64 world matrices themselves, of every node and primitive frame
    from clrender.loaders.gltf.assemble import _traversal
    from clrender.loaders.gltf.document import load_document
    doc = load_document(path)
    order = _traversal(doc)
    mine, ref = gg.NumpyGeometry(doc, order), gg.TrimeshGeometry(doc, order)
    nodes, meshes = doc.list("nodes"), doc.list("meshes")
    for n in order:
        assert np.array_equal(mine.node_matrix(n), ref.node_matrix(n)), n
        for p, prim in gg.triangle_primitives(meshes[nodes[n]["mesh"]]):
            for x, y in zip(mine.primitive(n, nodes[n]["mesh"], p, prim), ref.primitive(n, nodes[n]["mesh"], p, prim)):
                assert (x is None and y is None) or (x.dtype == y.dtype and np.array_equal(x, y)), (n, p)


def test_quaternion_and_rigid_repair_match_trimesh():
    from trimesh import transformations as tf
    rng = np.random.default_rng(0)
    for q in list(rng.normal(size=(200, 4))) + [np.zeros(4), np.array([1e-9, 0, 0, 0])]:
        assert np.array_equal(gg.quaternion_matrix(q), tf.quaternion_matrix(q))
    for _ in range(100):
        m = np.eye(4)
        m[:3, :3] = tf.random_rotation_matrix(rng.random(3))[:3, :3] + rng.normal(scale=1e-7, size=(3, 3))
        m[:3, 3] = rng.normal(size=3)
        assert np.array_equal(gg.fix_rigid(m), tf.fix_rigid(m, max_deviance=1e-5))


def test_strips_unroll_as_trimesh_does():
    from trimesh.util import triangle_strips_to_faces
    for n in (0, 1, 2, 3, 4, 7, 10):
        s = np.arange(n) * 3 % 11
        assert np.array_equal(gg.strip_faces(s), triangle_strips_to_faces([s]).reshape(-1, 3))


def test_a_gltf_load_does_not_import_trimesh():
    code = ("import sys, warnings; warnings.simplefilter('ignore'); from clrender.loaders import load_scene; "
            f"s = load_scene({str(SHARED_GLTF[0]) if SHARED_GLTF else ''!r}); print('trimesh' in sys.modules)")
    if not SHARED_GLTF:
        pytest.skip(f"no shared glTF scenes under {SHARED}")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    assert out.stdout.strip().splitlines()[-1] == "False"
