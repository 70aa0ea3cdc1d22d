"""Helpers shared by the scene loaders: world-space flattening, images, errors.

Every loader turns its file into a list of `Piece`s (one per mesh instance, already in
world space, in load order) plus materials and textures; `assemble` concatenates them
into one `Scene` without reordering or dropping anything.
"""
from __future__ import annotations

import contextvars
import hashlib
import io
import os
import threading
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Callable, Optional, Sequence

import numpy as np

from clrender.scene.camera import Camera
from clrender.scene.geometry import vertex_normals
from clrender.scene.material import EXT_TEXTURE_SLOTS, TX_TEXTURE_SLOTS
from clrender.scene.model import TEXTURE_SLOTS, Material, Scene, SceneError, Texture
from clrender.scene.tangents import NO_TANGENT, generate_tangents

__all__ = ["SceneError", "Piece", "fail", "transform_points", "transform_normals", "transform_tangents",
           "world_piece", "assemble", "image_to_rgba", "decode_image", "load_images", "start_images", "check_faces",
           "trimesh_load", "flip_v", "shift_textures", "concat_vertex_attributes", "NO_TANGENT"]


def fail(path, message: str) -> SceneError:
    """A SceneError whose message starts with the file name."""
    return SceneError(f"{path}: {message}")


# Scene files (glTF JSON, TOML) nested deeper than this are refused when parsed: whatever walks the
# values later (dataclasses.asdict, json.dumps(indent=...), pickle, deepcopy) recurses per level, so a
# bound here keeps every later consumer far from Python's recursion limit (issue 34). Real files
# nest about 10 levels; `extras` are free-form but 100 levels leaves them plenty.
MAX_NESTING = 100
NESTING_ERROR = f"nested too deeply (more than {MAX_NESTING} levels of arrays / objects)"


def check_nesting(path, value, what: str) -> None:
    """SceneError naming `path` when the parsed `value` nests more than MAX_NESTING levels; iterative."""
    stack = [(value, 1)]
    while stack:
        item, depth = stack.pop()
        children = item.values() if isinstance(item, dict) else item if isinstance(item, list) else ()
        for child in children:
            if isinstance(child, (dict, list)):
                if depth >= MAX_NESTING:
                    raise fail(path, f"{what} is {NESTING_ERROR}")
                stack.append((child, depth + 1))


def parse_nested(path, parse: Callable, text, what: str):
    """parse(text) (json.loads, tomllib.loads) then check_nesting; the parser's own RecursionError on
    deeper input is the same one-line SceneError."""
    try:
        value = parse(text)
    except RecursionError:
        raise fail(path, f"{what} is {NESTING_ERROR}") from None
    check_nesting(path, value, what)
    return value


@dataclass
class Piece:
    """One mesh instance in world space, ready to be concatenated."""
    name: str
    positions: np.ndarray                 # (V, 3) float64, world space
    faces: np.ndarray                     # (T, 3) int64, local vertex indices, load order
    material: int                         # index into the loader's material list
    normals: Optional[np.ndarray] = None  # (V, 3) world space unit normals; None = compute
    uvs: Optional[np.ndarray] = None      # (V, 2) glTF convention; None = zeros
    colors: Optional[np.ndarray] = None   # (V, 4) linear RGBA; None = white (ones)
    tangents: Optional[np.ndarray] = None  # (V, 4) world space unit xyz + w = ±1; None = see below
    extra_uvs: Optional[list] = None      # [(V, 2) or None] = TEXCOORD_1, TEXCOORD_2, ...; None = zeros
    tangent_uv: Optional[int] = None      # tangents None: generate them from this uv set (0 = uvs,
                                          # k = extra_uvs[k - 1]); None: NO_TANGENT (no normal map)


# -- transforms ---------------------------------------------------------------------------------
def transform_points(matrix: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Apply a 4x4 affine matrix to (N, 3) points (float64)."""
    m = np.asarray(matrix, np.float64)
    p = np.asarray(points, np.float64).reshape(-1, 3)
    return p @ m[:3, :3].T + m[:3, 3]


def normal_matrix(matrix: np.ndarray) -> np.ndarray:
    """Inverse transpose of the upper 3x3 (pseudo-inverse when singular)."""
    a = np.asarray(matrix, np.float64)[:3, :3]
    try:
        inv = np.linalg.inv(a)
    except np.linalg.LinAlgError:
        inv = np.linalg.pinv(a)
    if not np.isfinite(inv).all():
        inv = np.linalg.pinv(a)
    return inv.T


def transform_normals(matrix: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """Normals through the inverse-transpose, renormalized (zero-length normals stay zero)."""
    n = np.asarray(normals, np.float64).reshape(-1, 3) @ normal_matrix(matrix).T
    length = np.linalg.norm(n, axis=1, keepdims=True)
    ok = length[:, 0] > 0
    n[ok] /= length[ok]
    return n


def transform_tangents(matrix: np.ndarray, tangents: Optional[np.ndarray]) -> Optional[np.ndarray]:
    """(V, 4) tangents through a 4x4 affine matrix: xyz by its linear 3x3 part (tangents are surface
    directions), renormalized (zero ones stay zero); w times the sign of its determinant (a mirror
    flips the handedness). None stays None."""
    if tangents is None:
        return None
    t = np.asarray(tangents, np.float64).reshape(-1, 4)
    a = np.asarray(matrix, np.float64)[:3, :3]
    xyz = t[:, :3] @ a.T
    length = np.linalg.norm(xyz, axis=1, keepdims=True)
    ok = np.isfinite(length[:, 0]) & (length[:, 0] > 0)
    xyz[ok] /= length[ok]
    xyz[~ok] = 0.0
    w = t[:, 3] * (-1.0 if np.linalg.det(a) < 0 else 1.0)
    return np.concatenate([xyz, w[:, None]], 1)


def world_piece(name: str, matrix, positions, faces, material: int, normals=None, uvs=None,
                colors=None, tangents=None, extra_uvs=None, tangent_uv=None) -> Piece:
    """Build a Piece from local-space arrays and a local->world matrix.

    A mirroring transform (negative determinant) reverses the triangle winding so that the
    front face stays the front face (glTF 2.0 spec, "Transformations"); the face order is kept.
    Tangents follow `transform_tangents`; colors and uvs are not transformed.
    """
    matrix = np.asarray(matrix, np.float64)
    faces = np.asarray(faces, np.int64).reshape(-1, 3)
    if np.linalg.det(matrix[:3, :3]) < 0:
        faces = faces[:, [0, 2, 1]]
    world = transform_points(matrix, positions)
    wn = None if normals is None else transform_normals(matrix, normals)
    return Piece(name, world, faces, int(material), wn, uvs, colors, transform_tangents(matrix, tangents),
                 extra_uvs, tangent_uv)


# -- assembling ----------------------------------------------------------------------------------
def assemble(pieces: Sequence[Piece], materials: list[Material],
             textures: "list[Texture] | Callable[[], list[Texture]]", source: str,
             camera: Optional[Camera] = None, settings: Optional[dict] = None, objects: Optional[list] = None,
             piece_object: Optional[Sequence[int]] = None) -> Scene:
    """Concatenate pieces (in order) into one Scene; normals are computed where a piece has none.
    `objects` (SceneObject) and `piece_object` (each piece's index into them): the drawn instances
    (Scene.objects); None: one object per piece.
    `textures`: a list, or a callable returning it, called last (images decoding in the background
    while the pieces are put together: load_materials in gltf_materials.py).

    Per-vertex extras (docs/materials.md): `Scene.colors` is None when no piece has colours, else
    pieces without get white (1, 1, 1, 1). `Scene.extra_uvs` has K sets, K = the most any piece
    has; a set a piece lacks is zeros. `Scene.tangents` is None when no piece has tangents or asks
    for generated ones (`tangent_uv`); else a piece's own, or `generate_tangents` from its
    world-space positions, normals and uv set `tangent_uv`, or NO_TANGENT (0, 0, 0, 1)."""
    if not materials:
        materials = [Material()]
    positions, normals, uvs, triangles, tri_mat, tri_mesh, tri_face = [], [], [], [], [], [], []
    colors, tangents, extras = [], [], []
    want_colors = any(p.colors is not None for p in pieces)
    want_tangents = any(p.tangents is not None or p.tangent_uv is not None for p in pieces)
    k_sets = max((len(p.extra_uvs) for p in pieces if p.extra_uvs), default=0)
    vertex_bytes = 32 + 16 * want_colors + 16 * want_tangents + 8 * k_sets     # float32 per vertex
    charge_scene_arrays(sum(np.size(p.positions) // 3 for p in pieces), sum(np.size(p.faces) // 3 for p in pieces),
                        vertex_bytes, source)
    names = []
    offset = 0
    for k, piece in enumerate(pieces):
        pos = np.asarray(piece.positions, np.float64).reshape(-1, 3)
        faces = np.asarray(piece.faces, np.int64).reshape(-1, 3)
        nv, nt = len(pos), len(faces)
        if nt and (faces.min() < 0 or faces.max() >= nv):
            raise fail(source, f"mesh {piece.name!r}: a vertex index is out of range ({nv} vertices)")
        if piece.normals is None:
            nrm = vertex_normals(pos, faces)
        else:
            nrm = np.asarray(piece.normals).reshape(-1, 3)
        uv = np.zeros((nv, 2), np.float32) if piece.uvs is None else np.asarray(piece.uvs).reshape(-1, 2)
        if len(nrm) != nv or len(uv) != nv:
            raise fail(source, f"mesh {piece.name!r}: normals/uvs do not have one entry per vertex ({nv})")
        sets = [None if piece.extra_uvs is None or j >= len(piece.extra_uvs) else piece.extra_uvs[j]
                for j in range(k_sets)]
        sets = [np.zeros((nv, 2), np.float32) if a is None else np.asarray(a, np.float32).reshape(-1, 2)
                for a in sets]
        if want_colors:
            col = np.ones((nv, 4), np.float32) if piece.colors is None else \
                np.asarray(piece.colors, np.float32).reshape(-1, 4)
            colors.append(col)
        if want_tangents:
            if piece.tangents is not None:
                tan = np.asarray(piece.tangents, np.float32).reshape(-1, 4)
            elif piece.tangent_uv is not None:
                s = piece.tangent_uv
                if not 0 <= s <= len(sets):
                    raise fail(source, f"mesh {piece.name!r}: no uv set {s} to generate tangents from")
                tan = generate_tangents(pos, nrm, uv if s == 0 else sets[s - 1], faces)
            else:
                tan = np.tile(np.float32(NO_TANGENT), (nv, 1))
            tangents.append(tan)
        if any(len(a) != nv for a in sets + colors[-1:] + tangents[-1:]):
            raise fail(source, f"mesh {piece.name!r}: colors/tangents/uv sets do not have one entry per "
                               f"vertex ({nv})")
        extras.append(sets)
        positions.append(pos.astype(np.float32))
        normals.append(nrm.astype(np.float32))
        uvs.append(uv.astype(np.float32))
        triangles.append(faces + offset)
        tri_mat.append(np.full(nt, piece.material, np.int32))
        tri_mesh.append(np.full(nt, k, np.int32))
        tri_face.append(np.arange(nt, dtype=np.int32))
        names.append(piece.name)
        offset += nv
    if offset > np.iinfo(np.int32).max:
        raise fail(source, f"too many vertices ({offset}) for 32-bit indices")

    def cat(parts, shape, dtype):
        return np.concatenate(parts).astype(dtype) if parts else np.zeros(shape, dtype)

    extra_uvs = np.stack([cat([e[k] for e in extras], (0, 2), np.float32) for k in range(k_sets)]) \
        if k_sets else None
    return Scene(
        positions=cat(positions, (0, 3), np.float32),
        normals=cat(normals, (0, 3), np.float32),
        uvs=cat(uvs, (0, 2), np.float32),
        triangles=cat(triangles, (0, 3), np.int32),
        triangle_material=cat(tri_mat, (0,), np.int32),
        materials=list(materials),
        textures=list(textures() if callable(textures) else textures),
        mesh_names=names,
        triangle_mesh=cat(tri_mesh, (0,), np.int32),
        triangle_face=cat(tri_face, (0,), np.int32),
        camera=camera,
        source=str(source),
        settings=dict(settings or {}),
        colors=cat(colors, (0, 4), np.float32) if want_colors else None,
        tangents=cat(tangents, (0, 4), np.float32) if want_tangents else None,
        extra_uvs=extra_uvs,
        objects=list(objects or []),
        mesh_object=None if piece_object is None else np.asarray(piece_object, np.int32).reshape(-1),
    )


def charge_scene_arrays(vertices: int, triangles: int, vertex_bytes: int, source) -> None:
    """Charge the memory budget for a Scene's arrays before they are concatenated: each per-vertex
    and per-triangle array twice (the per-piece converted parts, then the whole)."""
    from clrender.loaders import budget
    # triangles: int64 parts and int32 indices, material, mesh and face ids
    nbytes = 2 * vertices * vertex_bytes + triangles * (24 + 2 * 24)
    budget.current().charge(nbytes, source, f"the scene's arrays ({vertices} vertices, {triangles} triangles)")


# -- combining scenes (TOML) -------------------------------------------------------------------------
def shift_textures(material: Material, offset: int) -> Material:
    """`material` with every texture slot's index moved by `offset` (-1, no texture, stays -1)."""
    kw = {f"{s}_texture": getattr(material, f"{s}_texture") + offset
          for s in TEXTURE_SLOTS + EXT_TEXTURE_SLOTS + TX_TEXTURE_SLOTS if getattr(material, f"{s}_texture") >= 0}
    return replace(material, **kw) if kw and offset else material


def concat_vertex_attributes(scenes: Sequence[Scene]) -> dict:
    """{colors, tangents, extra_uvs} of the scenes' vertices concatenated in order, with the
    defaults of `assemble` where a scene has none (white, NO_TANGENT, zero uv sets); each None
    when no scene has it. Keyword arguments for `Scene(...)`."""
    sizes = [len(s.positions) for s in scenes]

    def per_vertex(name, fill):
        if all(getattr(s, name) is None for s in scenes):
            return None
        parts = [np.tile(np.float32(fill), (n, 1)) if getattr(s, name) is None else getattr(s, name)
                 for s, n in zip(scenes, sizes)]
        return np.concatenate(parts).astype(np.float32) if parts else None

    k_sets = max((len(s.extra_uvs) for s in scenes if s.extra_uvs is not None), default=0)
    extra = None
    if k_sets:
        extra = np.stack([np.concatenate([
            s.extra_uvs[k] if s.extra_uvs is not None and k < len(s.extra_uvs) else np.zeros((n, 2), np.float32)
            for s, n in zip(scenes, sizes)]).astype(np.float32) for k in range(k_sets)])
    return {"colors": per_vertex("colors", (1.0, 1.0, 1.0, 1.0)),
            "tangents": per_vertex("tangents", NO_TANGENT), "extra_uvs": extra}


def check_faces(faces: np.ndarray, vertex_count: int, where, what: str) -> None:
    """SceneError when a face references a vertex that does not exist."""
    faces = np.asarray(faces)
    if faces.size == 0:
        return
    bad = (faces < 0) | (faces >= vertex_count)
    if bad.any():
        row = int(np.argmax(bad.any(axis=1)))
        raise fail(where, f"{what}: face {row} has a vertex index out of range "
                          f"{faces[row].tolist()} (there are {vertex_count} vertices)")


def flip_v(uv: np.ndarray) -> np.ndarray:
    """OpenGL-style uv (v up, origin bottom-left) -> glTF convention (v down, origin top-left)."""
    out = np.array(uv, np.float64).reshape(-1, 2)
    out[:, 1] = 1.0 - out[:, 1]
    return out


# -- images ----------------------------------------------------------------------------------------
def image_to_rgba(img) -> np.ndarray:
    """A PIL image -> (H, W, 4) uint8, row 0 at the top. 16-bit and float modes are scaled down."""
    from PIL import Image

    mode = img.mode
    if mode in ("I;16", "I;16B", "I;16L", "I;16N"):
        a = (np.asarray(img, dtype=np.uint16) >> 8).astype(np.uint8)
        img = Image.fromarray(a, "L")
    elif mode == "I":
        a = np.asarray(img, dtype=np.int64)
        scale = 257.0 if a.max(initial=0) > 255 else 1.0
        img = Image.fromarray(np.clip(a / scale, 0, 255).astype(np.uint8), "L")
    elif mode == "F":
        a = np.asarray(img, dtype=np.float64)
        img = Image.fromarray(np.clip(a * 255.0 + 0.5, 0, 255).astype(np.uint8), "L")
    if img.mode != "RGBA":
        img = img.convert("RGBA")
    return np.array(img, dtype=np.uint8)


def decode_image(data, where: str) -> np.ndarray:
    """Decode image bytes or a file path to RGBA8; SceneError naming `where` on failure.

    A file is decoded once per load (`LoadContext.images`, keyed by its resolved path; embedded
    bytes by their hash): entries that name it again share the array. The size in the image's header is charged to the load's memory
    budget before any pixel is decoded (`_decode`)."""
    if isinstance(data, (str, os.PathLike)):
        if not Path(data).is_file():
            raise SceneError(f"{where}: texture file not found: {data}")
        return _decoded_once(str(Path(data).resolve()), lambda: _decode(data, where, Path(data).name))
    data = bytes(data)      # embedded (bufferView, data URI): the same bytes named twice decode once too
    return _decoded_once(f"sha256:{hashlib.sha256(data).hexdigest()}",
                         lambda: _decode(io.BytesIO(data), where, "the embedded image"))


class _ImageEntry:
    """One file's decoding in a load: the first caller decodes, the others wait for its result."""
    def __init__(self):
        self.lock = threading.Lock()
        self.result = None              # the RGBA array, or the SceneError decoding raised


_IMAGES_LOCK = threading.Lock()


def _decoded_once(key: str, decode: Callable[[], np.ndarray]) -> np.ndarray:
    from clrender.loaders.context import current
    images = current().images
    with _IMAGES_LOCK:
        entry = images.get(key)
        if entry is None:
            entry = images[key] = _ImageEntry()
    with entry.lock:
        if entry.result is None:
            try:
                entry.result = decode()
            except SceneError as exc:
                entry.result = exc
    if isinstance(entry.result, SceneError):
        raise type(entry.result)(str(entry.result))
    return entry.result


_PIL_LIMIT_LOCK = threading.Lock()


def _open_image(source):
    """Image.open without Pillow's decompression-bomb guard (a warning past 89 M pixels, an error
    past 179 M): the load's memory budget is the gate, checked on the header's size before any
    pixel is decoded, so a large texture that fits is decoded silently and one that does not is the
    budget's one-line error. Pillow checks only in `open`; the global is restored at once."""
    from PIL import Image
    with _PIL_LIMIT_LOCK:
        limit, Image.MAX_IMAGE_PIXELS = Image.MAX_IMAGE_PIXELS, None
        try:
            return Image.open(source)
        finally:
            Image.MAX_IMAGE_PIXELS = limit


def _decode(source, where: str, name: str) -> np.ndarray:
    """Decode one image: its header's size is checked against the memory budget first, charging
    the RGBA array kept and checking the decoding's peak beside what the load holds."""
    from PIL import UnidentifiedImageError

    from clrender.loaders import ktx2
    from clrender.loaders.budget import current
    if ktx2.is_ktx2(source):                    # KHR_texture_basisu: Pillow does not read KTX2
        return ktx2.decode(source, where, name)
    try:
        with _open_image(source) as img:
            w, h = img.size
            band_bytes = 4 if img.mode in ("I", "F") else 2 if img.mode.startswith("I;16") else 1
            # peak (measured): Pillow's decoded image, its RGBA conversion, the bytes numpy copies from
            kept = current().charge(w * h * 4, where, f"{name} ({w}x{h} pixels, decoded)",
                                    peak=w * h * (12 + len(img.getbands()) * band_bytes))
            try:
                img.load()
                return image_to_rgba(img)
            except BaseException:
                current().release(kept)         # nothing is kept of an image that failed to decode
                raise
    except SceneError:
        raise
    except (UnidentifiedImageError, OSError, ValueError, SyntaxError) as exc:
        raise SceneError(f"{where}: cannot decode image ({type(exc).__name__}: {exc})") from None


def load_images(jobs: Sequence[Callable[[], np.ndarray]]) -> list[np.ndarray]:
    """Run image-decoding jobs in a thread pool (PIL releases the GIL while decoding)."""
    return start_images(jobs)()


def start_images(jobs: Sequence[Callable[[], np.ndarray]]) -> Callable[[], list[np.ndarray]]:
    """Start the jobs in a thread pool and return `wait() -> images` (a job's error is raised
    there; `wait.cancel()` drops the jobs not started): the caller works on (the glTF loader reads
    geometry) while the images decode."""
    if len(jobs) <= 1:
        def run() -> list[np.ndarray]:
            return [job() for job in jobs]
        run.cancel = lambda: None
        return run
    workers = min(len(jobs), max(1, (os.cpu_count() or 2)), 16)
    pool = ThreadPoolExecutor(max_workers=workers)
    # each job in a copy of this thread's context: the load's budget and image cache (loaders.context)
    futures = [pool.submit(contextvars.copy_context().run, job) for job in jobs]
    pool.shutdown(wait=False)               # the workers exit when the jobs are done

    def wait() -> list[np.ndarray]:
        try:
            return [f.result() for f in futures]
        finally:
            for f in futures:
                f.cancel()                  # after an error: the jobs not started yet are dropped
    wait.cancel = lambda: [f.cancel() for f in futures]
    return wait


# -- trimesh -----------------------------------------------------------------------------------------
def trimesh_load(path, **kwargs):
    """`trimesh.load(..., force='scene')` with every failure turned into a SceneError naming `path`."""
    import logging

    import trimesh

    # trimesh logs warnings (with tracebacks, and text of the file) that Python's last-resort handler
    # would print on stderr; clrender reports problems itself. An application's own logging config
    # (a handler on the root logger) still receives them.
    log = logging.getLogger("trimesh")
    if not any(isinstance(h, logging.NullHandler) for h in log.handlers):
        log.addHandler(logging.NullHandler())
    where = kwargs.pop("where", path)
    try:
        return trimesh.load(path, force="scene", **kwargs)
    except SceneError:
        raise
    except IndexError as exc:  # trimesh indexes vertex arrays with the file's face indices
        raise fail(where, f"a face vertex index is out of range ({exc})") from None
    except Exception as exc:  # trimesh raises anything from KeyError to AssertionError
        raise fail(where, f"cannot parse file ({type(exc).__name__}: {exc})") from None


def trimesh_vertex_normals(geom) -> Optional[np.ndarray]:
    """The vertex normals stored in the file, or None when trimesh would have to compute them.

    trimesh keeps normals read from a file in its cache; reading `geom.vertex_normals` when they
    are absent would silently compute (angle-weighted) ones, which we do not want.
    """
    cache = getattr(geom, "_cache", None)
    if cache is not None and "vertex_normals" in cache:
        n = np.asarray(cache["vertex_normals"], np.float64)
        if n.shape == np.shape(geom.vertices):
            return n
    return None
