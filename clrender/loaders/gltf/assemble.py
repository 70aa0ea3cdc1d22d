"""glTF 2.0 (.gltf / .glb) -> Scene.

Geometry and the node hierarchy are read from the accessors and the node JSON
(`gltf_geometry.NumpyGeometry`, which repeats trimesh 5.2's glTF loader and scene graph bit for
bit: CLRENDER_GLTF_TRIMESH=1 still loads through trimesh, the reference the tests compare with);
each mesh node's world matrix is applied to positions and (inverse-transpose, renormalized) normals.
Also:

* the file is read and validated first by `document` and `validate` (JSON, GLB chunks, buffers, buffer
  views, accessor ranges, indices into every array), so bad input is a `SceneError` naming the
  file, never a traceback;
* triangle order is the glTF node traversal order (scene roots in order, depth-first, children in
  order), then primitives in order, then faces in file order;
* TEXCOORD_0 is read from its accessor, so `Scene.uvs` equals the file data;
* NORMAL is the file's (no merging, no recomputation); primitives without NORMAL get
  area-weighted normals in world space;
* materials (docs/materials.md): every glTF 2.0 property, KHR_materials_emissive_strength and
  KHR_materials_unlit into `Material`; every textureInfo's texCoord and KHR_texture_transform
  (whose texCoord overrides) into `<slot>_uv`. One `Texture` per (image, wrapS, wrapT, sRGB): base
  colour and emissive images are sRGB, metallic-roughness, normal and occlusion ones linear, so an
  image used both ways is two textures. A texture must read a TEXCOORD set its primitive has
  (SceneError naming the primitive, material, slot and set, as the glTF validator's error);
* COLOR_0 (VEC3 gets alpha 1; normalized integers in [0, 1]) -> `Scene.colors`, white for
  primitives without it, None when no primitive has it. TEXCOORD_n, n >= 1 -> `Scene.extra_uvs`
  (K = the highest set any primitive has; a set a primitive lacks is zeros);
* TANGENT -> `Scene.tangents` in world space (xyz by the node's 3x3, renormalized; w times the
  sign of its determinant); ignored without NORMAL (spec). A primitive whose material has a
  normalTexture and no TANGENT gets `clrender.scene.tangents.generate_tangents` of its world-space
  positions and normals and of the uv set the normal map reads; other primitives (0, 0, 0, 1)
  ("no tangent"); None when no primitive has or needs tangents;
* animations (translation / rotation / scale / morph `weights` channels) -> `Scene.animation`, a
  `clrender.scene.animation.Animation` (None for static files) that `Scene.pose(t)` applies; the scene
  loads at the nodes' static transforms;
* skins and morph targets (clrender/loaders/gltf/skin.py) -> `Scene.deformation`
  (clrender.scene.deform): each node x primitive with a skin or targets keeps its bind attributes; the
  Scene's arrays hold the pose at load (rest transforms, default weights) and the device poses it
  per frame (kernels/pose.cl). A skinned mesh ignores its node's transform and keeps its winding;
* what is not rendered -- point/line/fan primitives,
  COLOR_n for n >= 1, non-default scenes, nearest magnification, any extension outside
  `spec.SUPPORTED_EXTENSIONS` (in extensionsUsed or on any object) -- is collected while
  loading and warned ONCE per file and feature at the end; the rest loads. An extension outside
  that set in extensionsRequired is a SceneError naming it;
* the camera is the first camera in traversal order, perspective (`yfov`, `znear`, `zfar`) or
  orthographic (`xmag`, `ymag`, `znear`, `zfar` -> `Camera.orthographic`: like glTF viewers, the
  image's aspect decides the horizontal extent, ymag·width/height; xmag is kept);
* `KHR_lights_punctual`: every node of the default scene that references a light adds one light,
  in traversal order, placed by the node's world matrix (computed here from the JSON
  matrix / TRS): position = the transformed origin, direction = the transformed local -Z,
  normalized. `point` -> `Scene.add_point_light`, `spot` -> `Scene.add_spot_light` with
  innerConeAngle (default 0) and outerConeAngle (default pi/4) in degrees. Color = `color`
  (default [1, 1, 1]) x `intensity` (default 1). glTF intensities are photometric (candela for
  point and spot lights, lux for directional ones) and keep the extension's meaning: a 10 cd light
  gets color 10 and `Light.falloff` inverse square (irradiance I/d², with the extension's range
  window clamp(1 − (d/range)⁴, 0, 1)² when `range` is given; docs/shading.md). `range` -> radius;
  without a range (infinite) the radius is sqrt(256 * max(color * intensity)) (where I/d² has
  fallen to 1/256) clamped to [1e-3, 4 x scene diagonal] (see `clrender.scene.lights`), and no
  window. Node scale does not change a light's range or cone (spec).
  the first `directional` light becomes the sun (`Scene.sun`, shadowed); all are kept in
  `Scene.settings["directional_lights"]` (direction, color x intensity); the others warn.
"""
from __future__ import annotations

import warnings
from pathlib import Path
from typing import Optional

import numpy as np

from clrender.loaders.gltf import animation as gltf_animation
from clrender.abi import structs
from clrender.scene.camera import Camera
from clrender.scene.model import Material, Scene, SceneError, SceneObject
from clrender.scene.deform import Deformation
from clrender.scene.geometry import BAD_COORDINATES, bad_vertex, coordinates_text, vertex_normals
from clrender.scene.tangents import generate_tangents
from clrender.loaders import budget
from clrender.loaders.common import Piece, assemble, check_faces, world_piece
from clrender.loaders.gltf.document import Document, extensions_in_use, load_document
from clrender.loaders.gltf.spec import MODE_FAN, MODE_STRIP, MODE_TRIANGLES, SUPPORTED_EXTENSIONS, attribute_sets
from clrender.loaders.gltf.validate import node_light, punctual_lights
from clrender.loaders.gltf.geometry import geometry_for
from clrender.loaders.gltf.skin import deformer, read_skins
from clrender.loaders.gltf.materials import load_materials
from clrender.scene.lights import (
    AUTO_RADIUS_KEY, DIRECTIONAL_KEY, auto_radius, scene_diagonal, sun_from_directional, warn_directional)

# zfar absent (infinite projection): far = max(FAR_FROM_NEAR * znear, 2 * farthest scene corner)
FAR_FROM_NEAR = 1000.0
# KHR_lights_punctual allows outerConeAngle = pi/2; Scene.add_spot_light needs < 90 degrees
MAX_SPOT_OUTER_DEG = 89.9


# -- traversal --------------------------------------------------------------------------------------
def _traversal(doc: Document) -> list[int]:
    """Node indices of the default scene, depth-first pre-order, roots and children in file order."""
    scenes = doc.list("scenes")
    if not scenes:
        return []
    roots = scenes[doc.json.get("scene", 0)].get("nodes", [])
    nodes = doc.list("nodes")
    order, seen = [], set()
    stack = list(reversed(roots))
    while stack:
        n = stack.pop()
        if n in seen:
            raise doc.err(f"node {n} is reached twice: the glTF node hierarchy must be a tree")
        seen.add(n)
        order.append(n)
        stack.extend(reversed(nodes[n].get("children", [])))
    return order


# -- camera ------------------------------------------------------------------------------------------------
def _camera(doc: Document, order: list[int], geometry, scene: Scene) -> Optional[Camera]:
    nodes = doc.list("nodes")
    for n in order:
        if "camera" not in nodes[n]:
            continue
        cam = doc.json["cameras"][nodes[n]["camera"]]
        kind = cam.get("type")
        if kind not in ("perspective", "orthographic") or kind not in cam:
            continue  # not a camera this loader knows
        persp = cam[kind]
        try:
            matrix = geometry.node_matrix(n)
            eye = matrix[:3, 3]
            forward = -matrix[:3, 2]
            up = matrix[:3, 1]
            norm = np.linalg.norm(forward)
            if kind == "orthographic":
                return Camera.orthographic(eye, eye + forward / norm, up, xmag=float(persp["xmag"]),
                                           ymag=float(persp["ymag"]), near=float(persp["znear"]),
                                           far=float(persp["zfar"]))
            znear = float(persp["znear"])
            zfar = persp.get("zfar")
            if zfar is None:
                lo, hi = scene.bounds().astype(np.float64)
                corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1])
                                    for z in (lo[2], hi[2])])
                reach = float(np.linalg.norm(corners - eye, axis=1).max()) if scene.triangle_count else 0.0
                zfar = max(FAR_FROM_NEAR * znear, 2.0 * reach)
            return Camera.look_at(eye, eye + forward / norm, up, np.degrees(float(persp["yfov"])),
                                  near=znear, far=float(zfar))
        except (KeyError, TypeError, ValueError, ZeroDivisionError, FloatingPointError) as exc:
            raise doc.err(f"camera {nodes[n]['camera']} (node {n}) is not usable: {exc}") from None
    return None


# -- KHR_lights_punctual -------------------------------------------------------------------------------------
def _local_matrix(node: dict) -> np.ndarray:
    """A node's local matrix: `matrix` (column-major) or T . R . S."""
    if "matrix" in node:
        return np.asarray(node["matrix"], np.float64).reshape(4, 4).T
    x, y, z, w = np.asarray(node.get("rotation", [0.0, 0.0, 0.0, 1.0]), np.float64)
    norm = np.sqrt(x * x + y * y + z * z + w * w)
    if norm > 0:
        x, y, z, w = x / norm, y / norm, z / norm, w / norm
    r = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                  [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                  [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
    m = np.eye(4)
    m[:3, :3] = r * np.asarray(node.get("scale", [1.0, 1.0, 1.0]), np.float64)
    m[:3, 3] = node.get("translation", [0.0, 0.0, 0.0])
    return m


def _world_matrices(doc: Document, order: list[int]) -> dict[int, np.ndarray]:
    """World matrix of every node in `order` (a pre-order traversal: parents come first)."""
    nodes = doc.list("nodes")
    parent = {c: n for n in order for c in nodes[n].get("children", [])}
    world: dict[int, np.ndarray] = {}
    for n in order:
        local = _local_matrix(nodes[n])
        world[n] = world[parent[n]] @ local if n in parent else local
    return world


def _lights(doc: Document, order: list[int], scene: Scene) -> None:
    """Add the KHR_lights_punctual lights of the default scene's nodes to `scene` (see module doc)."""
    lights = punctual_lights(doc)
    nodes = doc.list("nodes")
    refs = [(n, node_light(doc, n, nodes[n])) for n in order]
    refs = [(n, k) for n, k in refs if k is not None]
    if not refs:
        return
    world = _world_matrices(doc, order)
    diagonal = scene_diagonal(scene)
    directional, auto = [], []
    for n, k in refs:
        light = lights[k]
        what = f"KHR_lights_punctual light {k}" + (f" ({light['name']!r})" if light.get("name") else "") + \
            f" on node {n}"
        m = world[n]
        position = m[:3, 3]
        direction = m[:3, :3] @ np.array([0.0, 0.0, -1.0])
        norm = float(np.linalg.norm(direction))
        color = np.asarray(light.get("color", [1.0, 1.0, 1.0]), np.float64) * float(light.get("intensity", 1.0))
        kind = light["type"]
        if kind != "point" and not (np.isfinite(norm) and norm > 0):
            raise doc.err(f"{what}: the node's world transform has no -Z direction (zero scale?)")
        if kind == "directional":
            directional.append({"direction": (direction / norm).tolist(), "color": color.tolist()})
            continue
        if "range" in light:
            radius = float(light["range"])
        else:
            radius = auto_radius(color, diagonal)
            auto.append(len(scene.lights))
        try:
            if kind == "point":
                scene.add_point_light(position, color, radius)
            else:
                spot = light.get("spot", {})
                inner = np.degrees(float(spot.get("innerConeAngle", 0.0)))
                outer = np.degrees(float(spot.get("outerConeAngle", np.pi / 4)))
                if outer >= MAX_SPOT_OUTER_DEG:  # the spec allows pi/2; the renderer needs < 90 degrees
                    warnings.warn(f"{doc.path}: {what}: outerConeAngle {outer:g} deg clamped to "
                                  f"{MAX_SPOT_OUTER_DEG} deg", stacklevel=4)
                    outer = MAX_SPOT_OUTER_DEG
                    inner = min(inner, outer)
                scene.add_spot_light(position, direction / norm, color, radius, inner, outer)
            # KHR_lights_punctual units: candela, inverse-square falloff (the range window when given)
            scene.lights["falloff"][-1] = (structs.FALLOFF_INVERSE_SQUARE if "range" in light
                                           else structs.FALLOFF_INVERSE_SQUARE_UNBOUNDED)
        except SceneError as exc:
            raise doc.err(f"{what}: {exc}") from None
    if auto:
        scene.settings[AUTO_RADIUS_KEY] = auto
    if directional:
        scene.settings[DIRECTIONAL_KEY] = directional
        sun_from_directional(scene)
        warn_directional(doc.path, len(directional), stacklevel=5)


# -- vertex attributes and unsupported features ------------------------------------------------------------
def _colors(doc: Document, what: str, attrs: dict) -> Optional[np.ndarray]:
    """COLOR_0 as (V, 4) float32 linear RGBA (normalized integers are in [0, 1]; VEC3 gets alpha 1)."""
    if "COLOR_0" not in attrs:
        return None
    c = doc.accessor(attrs["COLOR_0"]).astype(np.float32)
    if not np.isfinite(c).all():
        raise doc.err(f"{what}: attribute COLOR_0 (accessor {attrs['COLOR_0']}) has non-finite values")
    if c.shape[1] == 3:
        c = np.concatenate([c, np.ones((len(c), 1), np.float32)], 1)
    return c


def _tangents(doc: Document, what: str, attrs: dict) -> Optional[np.ndarray]:
    """TANGENT as (V, 4) float64 in the mesh's local space, w snapped to ±1 (0 counts as +1)."""
    if "TANGENT" not in attrs:
        return None
    t = doc.accessor(attrs["TANGENT"]).astype(np.float64)
    if not np.isfinite(t).all():
        raise doc.err(f"{what}: attribute TANGENT (accessor {attrs['TANGENT']}) has non-finite values")
    t[:, 3] = np.where(t[:, 3] < 0, -1.0, 1.0)
    return t


def _unsupported_features(doc: Document) -> dict[str, str]:
    """{feature: what clrender does instead} for what the document uses and clrender does not render.
    Other entries are added while loading; `_warn_features` reports each once."""
    j = doc.json
    features: dict[str, str] = {}
    prims = [prim for mesh in doc.list("meshes") for prim in mesh.get("primitives", [])]
    attrs = {a for prim in prims for a in prim.get("attributes", {})}
    extra_colors = sorted(a for a in attrs if a.startswith("COLOR_") and a != "COLOR_0")
    if extra_colors:
        features[f"vertex colour sets beyond COLOR_0 ({', '.join(extra_colors)})"] = "ignored"
    if len(doc.list("scenes")) > 1:
        features["scenes other than the default one"] = f"not loaded (scene {j.get('scene', 0)} is)"
    for name, where in extensions_in_use(doc).items():
        if name not in SUPPORTED_EXTENSIONS:
            features[f"extension {name}"] = f"ignored (first used in {where})"
    return features


def _warn_features(doc: Document, features: dict[str, str], notes: dict[str, str]) -> None:
    """One UserWarning per unsupported feature (and per note on what was repaired), naming the file."""
    for feature, instead in features.items():
        warnings.warn(f"{doc.path}: glTF {feature} not supported: {instead}", stacklevel=4)
    for note, done in notes.items():
        warnings.warn(f"{doc.path}: glTF {note}: {done}", stacklevel=4)


# -- entry point -------------------------------------------------------------------------------------------
def load_gltf(path) -> Scene:
    path = Path(path)
    doc = load_document(path)
    order = _traversal(doc)
    features = _unsupported_features(doc)      # {feature: what happens instead}, warned once each at the end
    notes: dict[str, str] = {}                 # {what was repaired: how}, warned once each at the end
    materials, textures = load_materials(doc, features)     # the images decode from here on
    try:
        scene = _geometry(doc, path, order, features, notes, materials, textures)
    except BaseException:
        textures.cancel()
        raise
    _lights(doc, order, scene)
    _warn_features(doc, features, notes)
    return scene


# What one drawn primitive costs while the scene is put together (common.Piece): float64 positions
# and normals, and their world-space copies, per vertex; int64 faces and a flipped copy per triangle
PIECE_VERTEX_BYTES, PIECE_TRIANGLE_BYTES, PIECE_BYTES = 96, 48, 2048


def _charge_piece(doc: Document, n: int, mi: int, p: int, prim: dict, what: str) -> None:
    """Charge the memory budget for primitive `p` of mesh `mi` drawn by node `n`, before its arrays
    are made: a mesh drawn by many nodes costs its vertices once per node."""
    accessors = doc.list("accessors")
    nv = accessors[prim["attributes"]["POSITION"]]["count"]
    ni = accessors[prim["indices"]]["count"] if "indices" in prim else nv
    nt = max(ni - 2, 0) if prim.get("mode", MODE_TRIANGLES) == MODE_STRIP else ni // 3
    budget.current().charge(nv * PIECE_VERTEX_BYTES + nt * PIECE_TRIANGLE_BYTES + PIECE_BYTES, doc.path,
                            f"{what} on node {n} ({nv} vertices, {nt} triangles)")


# Object paths name at most PATH_HEAD + PATH_TAIL nodes and PATH_NAME characters of each: a deeper
# path keeps the first PATH_HEAD and the last PATH_TAIL names around a "...<k nodes>..." part, so that a
# chain of n drawing nodes costs O(n) characters, not O(n * depth) (issue 34)
PATH_HEAD, PATH_TAIL, PATH_NAME = 16, 47, 256


def _node_paths(nodes_json: list, order: list[int]):
    """path(n) -> "root/…/node" of node names (unnamed: node<i>) for the nodes of `order` (a pre-order
    traversal: parents first), shortened as PATH_HEAD / PATH_TAIL / PATH_NAME say. O(PATH_TAIL) per
    node, no walk up the hierarchy."""
    def name(n: int) -> str:
        s = nodes_json[n].get("name") or f"node{n}"
        return s if len(s) <= PATH_NAME else s[:PATH_NAME - 3] + "..."

    parent = {c: n for n in order for c in nodes_json[n].get("children", [])}
    chain: dict = {}        # node -> (depth, first names, last names)
    for n in order:
        p = parent.get(n)
        if p is None:
            chain[n] = (1, (name(n),), (name(n),))
        else:
            depth, head, tail = chain[p]
            head = head if len(head) == PATH_HEAD else head + (name(n),)
            chain[n] = (depth + 1, head, (tail + (name(n),))[-PATH_TAIL:])

    def path(n: int) -> str:
        depth, head, tail = chain[n]
        if depth <= PATH_HEAD + PATH_TAIL:
            return "/".join((head + tail[len(head) - depth:]) if depth > len(head) else head)
        return "/".join(head + (f"...<{depth - PATH_HEAD - PATH_TAIL} nodes>...",) + tail)

    return path


def _check_positions(doc: Document, positions, what: str) -> None:
    """One line naming the accessor (and the transform that carried it there) when a vertex is NaN,
    infinite or beyond ±1e30: such a triangle would vanish from the render without a word."""
    i = bad_vertex(positions)
    if i >= 0:
        row = np.asarray(positions).reshape(-1, 3)[i]
        raise doc.err(f"{what}: vertex {i} is {coordinates_text(row)}: {BAD_COORDINATES}")


def _geometry(doc: Document, path: Path, order: list[int], features: dict, notes: dict, materials: list,
              textures) -> Scene:
    """The Scene: mesh nodes' primitives, camera, animation and deformation (textures() waited for last)."""
    animation = gltf_animation.from_document(doc, order, features)   # None: static
    skins = read_skins(doc)
    deformers: list = []        # skinned / morphed pieces: posed below, then on the device per frame

    geometry = geometry_for(doc, order)
    nodes_json, meshes_json = doc.list("nodes"), doc.list("meshes")
    default_material = None
    pieces: list[Piece] = []
    objects: list[SceneObject] = []     # one per node that draws a primitive
    piece_object: list[int] = []
    path_of = _node_paths(nodes_json, order)
    for n in order:
        node = nodes_json[n]
        if "mesh" not in node:
            continue
        mi = node["mesh"]
        mesh = meshes_json[mi]
        prims = mesh["primitives"]
        node_name = node.get("name") or f"node{n}"
        mesh_name = mesh.get("name") or f"mesh{mi}"
        first_piece = len(pieces)
        for p, prim in enumerate(prims):
            mode = prim.get("mode", MODE_TRIANGLES)
            what = f"mesh {mi} ({mesh_name!r}) primitive {p}"
            if mode not in (MODE_TRIANGLES, MODE_STRIP):
                if mode == MODE_FAN:
                    features.setdefault("TRIANGLE_FAN primitives", f"not loaded (first: {what})")
                else:
                    features.setdefault("point and line primitives", f"not drawn (first: {what})")
                continue
            attrs = prim["attributes"]
            _charge_piece(doc, n, mi, p, prim, what)
            matrix, positions, faces, normals = geometry.primitive(n, mi, p, prim)
            position_ref = f"{what} POSITION (accessors[{attrs['POSITION']}])"
            _check_positions(doc, positions, position_ref)
            check_faces(faces, len(positions), path, what)
            uvs = doc.accessor(attrs["TEXCOORD_0"]) if "TEXCOORD_0" in attrs else None
            sets = [k for k in attribute_sets(attrs, "TEXCOORD") if k > 0]
            extra_uvs = [doc.accessor(attrs[f"TEXCOORD_{k}"]) if f"TEXCOORD_{k}" in attrs else None
                         for k in range(1, max(sets) + 1)] if sets else None
            colors = _colors(doc, what, attrs)
            # spec: without NORMAL the TANGENT attribute MUST be ignored
            tangents = _tangents(doc, what, attrs) if "NORMAL" in attrs else None
            if "material" in prim:
                mat = prim["material"]
            else:
                if default_material is None:
                    default_material = len(materials)
                    materials.append(Material.from_metallic_roughness(
                        "default", (1.0, 1.0, 1.0, 1.0), 1.0, 1.0, double_sided=False))
                mat = default_material
            name = f"{node_name}/{mesh_name}" + (f"/{p}" if len(prims) > 1 else "")
            # a normal map without TANGENT: generated (clrender.scene.tangents) from the set the map reads
            material = materials[mat]
            tangent_uv = material.normal_uv.texcoord if material.normal_texture >= 0 and tangents is None else None
            skinned = "skin" in node
            if not skinned and any(a.startswith(("JOINTS_", "WEIGHTS_")) for a in attrs):
                features.setdefault("JOINTS/WEIGHTS on a node without a skin", f"drawn unskinned (first: {what})")
            if skinned or prim.get("targets"):
                if normals is None:         # bind-space area-weighted normals, then posed like the file's
                    normals = vertex_normals(positions, faces)
                if skinned:
                    doc.get("skins", node["skin"], f"node {n} skin")
                elif np.linalg.det(matrix[:3, :3]) < 0:     # a mirroring node transform: the winding flips
                    faces = faces[:, [0, 2, 1]]
                if tangent_uv is not None:  # bind-space tangents, then posed
                    uv_set = uvs if tangent_uv == 0 else (extra_uvs[tangent_uv - 1] if extra_uvs and tangent_uv
                                                          <= len(extra_uvs) else None)
                    if uv_set is None:
                        raise doc.err(f"{what}: no TEXCOORD_{tangent_uv} to generate tangents from")
                    tangents, tangent_uv = generate_tangents(positions, normals, uv_set, faces), None
                deformers.append(deformer(doc, what, name, len(pieces), n, node, mesh, prim, positions, normals,
                                          tangents, skins, notes))
                pieces.append(Piece(name, positions, faces, mat, normals, uvs, colors, tangents, extra_uvs))
                continue
            if animation is not None:   # remember the mesh's node; a singular rest matrix builds it unposed
                matrix = animation.add_mesh(len(pieces), n, matrix)
            pieces.append(world_piece(name, matrix, positions, faces, mat, normals, uvs, colors, tangents,
                                      extra_uvs, tangent_uv))
            _check_positions(doc, pieces[-1].positions, f"{position_ref} placed by node {n}'s world transform")
        if len(pieces) > first_piece:
            piece_object.extend([len(objects)] * (len(pieces) - first_piece))
            objects.append(SceneObject(node_name, mesh_name, path_of(n), node.get("extras"), n))

    deformation = None
    if deformers:               # the load pose (rest transforms, default weights) into the pieces
        deformation = Deformation(deformers, skins, animation or gltf_animation.rig(doc, order), str(path))
        deformation.rest()
        for i, d in enumerate(deformers):
            p, nrm, tan = deformation.posed(i)
            old = pieces[d.mesh]
            pieces[d.mesh] = Piece(old.name, p, old.faces, old.material, nrm, old.uvs, old.colors, tan,
                                   old.extra_uvs)
            _check_positions(doc, p, f"mesh {old.name!r} posed by its skin or morph targets at load")
    scene = assemble(pieces, materials, textures, str(path), objects=objects, piece_object=piece_object)
    if deformation is not None:
        firsts = np.cumsum([0] + [len(p.positions) for p in pieces])
        deformation.attach({d.mesh: firsts[d.mesh] for d in deformers})
        scene.deformation = deformation
    scene.camera = _camera(doc, order, geometry, scene)
    if animation is not None:
        gltf_animation.bind(animation, doc, order, scene)
        scene.animation = animation
    return scene
