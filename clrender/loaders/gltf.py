"""glTF 2.0 (.gltf / .glb) -> Scene.

Geometry and the node hierarchy go through trimesh (`trimesh.load(..., force='scene')`); the
scene graph is flattened to world space by walking `scene.graph.nodes_geometry` and applying each
node's world matrix `scene.graph[node]` to positions and (inverse-transpose, renormalized) normals.
Everything trimesh gets wrong or loses is read from the glTF JSON and buffers directly:

* the file is read and validated first by `gltf_document` (JSON, GLB chunks, buffers, buffer
  views, accessor ranges, indices into every array), so bad input is a `SceneError` naming the
  file, never a trimesh traceback;
* trimesh is handed a copy of the JSON whose nodes are named ``n<node>`` and meshes ``m<mesh>``
  (so every trimesh geometry maps back to its glTF node / mesh / primitive), with camera
  references removed (trimesh 5.2 drops a camera node from its graph, mesh and children included)
  and with materials skipped (we read them from the JSON);
* triangle order is the glTF node traversal order (scene roots in order, depth-first, children in
  order; trimesh's own `nodes_geometry` order is reversed), then primitives in order, then faces in
  file order;
* TEXCOORD_0 is read from its accessor (trimesh flips v in float32, which is not invertible
  exactly, and drops uvs of primitives without a material), so `Scene.uvs` equals the file data;
* NORMAL comes from trimesh's cache of the file normals (process=False: no merging, no
  recomputation); primitives without NORMAL get area-weighted normals in world space;
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
  normalTexture and no TANGENT gets `clrender.tangents.generate_tangents` of its world-space
  positions and normals and of the uv set the normal map reads; other primitives (0, 0, 0, 1)
  ("no tangent"); None when no primitive has or needs tangents;
* animations (translation / rotation / scale channels) -> `Scene.animation`, a
  `clrender.animation.Animation` (None for static files) that `Scene.pose(t)` applies; the scene
  loads at the nodes' static transforms;
* what is not rendered -- skins, morph targets, animated morph weights, point/line/fan primitives,
  COLOR_n for n >= 1, non-default scenes, nearest magnification, any extension outside
  `gltf_document.SUPPORTED_EXTENSIONS` (in extensionsUsed or on any object) -- is collected while
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
  point and spot lights, lux for directional ones); they are NOT rescaled: a 10 cd light gets
  color 10, whatever units the renderer's falloff then assumes. `range` -> radius; without a range (infinite) the radius is
  sqrt(256 * max(color * intensity)) clamped to [1e-3, 4 x scene diagonal] (see
  `clrender.loaders.lights`). Node scale does not change a light's range or cone (spec).
  the first `directional` light becomes the sun (`Scene.sun`, shadowed); all are kept in
  `Scene.settings["directional_lights"]` (direction, color x intensity); the others warn.
"""
from __future__ import annotations

import io
import json
import re
import warnings
from pathlib import Path
from typing import Optional

import numpy as np

from .. import animation as gltf_animation
from ..camera import Camera
from ..scene import Material, Scene, SceneError
from .common import Piece, assemble, check_faces, trimesh_load, trimesh_vertex_normals, world_piece
from .gltf_document import (MODE_FAN, MODE_STRIP, MODE_TRIANGLES, SUPPORTED_EXTENSIONS, Document, attribute_sets,
                            extensions_in_use, load_document, node_light, punctual_lights)
from .gltf_materials import load_materials
from .lights import (AUTO_RADIUS_KEY, DIRECTIONAL_KEY, auto_radius, scene_diagonal, sun_from_directional,
                     warn_directional)

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


def _triangle_primitives(mesh: dict) -> list[tuple[int, dict]]:
    """(index, primitive) of the primitives that are rendered: TRIANGLES and TRIANGLE_STRIP."""
    return [(p, prim) for p, prim in enumerate(mesh["primitives"])
            if prim.get("mode", MODE_TRIANGLES) in (MODE_TRIANGLES, MODE_STRIP)]


def _trimesh_scene(doc: Document):
    """trimesh's Scene for a renamed, triangles-only, material-less, camera-less copy of the document."""
    j = doc.json
    meshes = doc.list("meshes")
    header = {k: j[k] for k in ("asset", "scene", "scenes", "accessors", "bufferViews") if k in j}
    header["nodes"] = []
    for i, node in enumerate(doc.list("nodes")):
        keep = {k: v for k, v in node.items() if k in ("children", "matrix", "translation", "rotation", "scale")}
        # a node whose mesh has no triangle primitive would be left out of trimesh's graph,
        # children included: give it no mesh instead
        if "mesh" in node and _triangle_primitives(meshes[node["mesh"]]):
            keep["mesh"] = node["mesh"]
        header["nodes"].append(dict(keep, name=f"n{i}"))
    header["meshes"] = [{"name": f"m{i}", "primitives": [
        {"attributes": {a: prim["attributes"][a] for a in ("POSITION", "NORMAL") if a in prim["attributes"]},
         **{k: prim[k] for k in ("indices", "mode") if k in prim}}
        for _, prim in _triangle_primitives(mesh)]} for i, mesh in enumerate(meshes)]
    header["buffers"] = [{"uri": f"buffer{k}.bin", "byteLength": len(b)} for k, b in enumerate(doc.buffers)]
    resolver = {f"buffer{k}.bin": b for k, b in enumerate(doc.buffers)}
    stream = io.BytesIO(json.dumps(header).encode("utf-8"))
    return trimesh_load(stream, file_type="gltf", resolver=resolver, skip_materials=True,
                        process=False, where=doc.path)


def _primitive_names(doc: Document) -> dict[tuple[int, int], str]:
    """(mesh, primitive) -> trimesh geometry name, computed exactly as trimesh names them."""
    from trimesh.util import unique_name

    names: dict[str, None] = {}
    counts: dict = {}
    out = {}
    for i, mesh in enumerate(doc.list("meshes")):
        for p, _ in _triangle_primitives(mesh):
            name = unique_name(f"m{i}", names, counts=counts)
            names[name] = None
            out[(i, p)] = name
    return out


# -- camera ------------------------------------------------------------------------------------------------
def _camera(doc: Document, order: list[int], tm_scene, scene: Scene) -> Optional[Camera]:
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
            matrix = np.asarray(tm_scene.graph[f"n{n}"][0], np.float64)
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
    if doc.list("skins") or any("skin" in node for node in doc.list("nodes")) or \
            any(a.startswith(("JOINTS_", "WEIGHTS_")) for a in attrs):
        features["skins (skinned meshes)"] = "drawn unskinned, with their nodes' transforms"
    if any("targets" in prim for prim in prims) or any("weights" in mesh for mesh in doc.list("meshes")):
        features["morph targets"] = "drawn with their base geometry"
    extra_colors = sorted(a for a in attrs if a.startswith("COLOR_") and a != "COLOR_0")
    if extra_colors:
        features[f"vertex colour sets beyond COLOR_0 ({', '.join(extra_colors)})"] = "ignored"
    if len(doc.list("scenes")) > 1:
        features["scenes other than the default one"] = f"not loaded (scene {j.get('scene', 0)} is)"
    for name, where in extensions_in_use(doc).items():
        if name not in SUPPORTED_EXTENSIONS:
            features[f"extension {name}"] = f"ignored (first used in {where})"
    return features


def _warn_features(doc: Document, features: dict[str, str]) -> None:
    """One UserWarning per unsupported feature, naming the file and the feature."""
    for feature, instead in features.items():
        warnings.warn(f"{doc.path}: glTF {feature} not supported: {instead}", stacklevel=4)


def _needs_own_reader(accessor: dict) -> bool:
    """trimesh ignores sparse data and the `normalized` flag: read those accessors ourselves."""
    return "sparse" in accessor or accessor.get("componentType") != 5126


# -- entry point -------------------------------------------------------------------------------------------
def load_gltf(path) -> Scene:
    path = Path(path)
    doc = load_document(path)
    order = _traversal(doc)
    features = _unsupported_features(doc)      # {feature: what happens instead}, warned once each at the end
    materials, textures = load_materials(doc, features)
    animation = gltf_animation.from_document(doc, order, features)   # None: static

    tm_scene = _trimesh_scene(doc)
    prim_names = _primitive_names(doc)
    parents = tm_scene.graph.transforms.parents
    node_re = re.compile(r"n(\d+)$")
    instances: dict[tuple[int, str], str] = {}
    for gnode in tm_scene.graph.nodes_geometry:
        match = node_re.match(gnode) or node_re.match(str(parents.get(gnode, "")))
        if match is None:
            raise doc.err(f"internal: cannot map trimesh node {gnode!r} back to a glTF node")
        _, gname = tm_scene.graph[gnode]
        instances[(int(match.group(1)), gname)] = gnode

    nodes_json, meshes_json = doc.list("nodes"), doc.list("meshes")
    accessors = doc.list("accessors")
    default_material = None
    pieces: list[Piece] = []
    for n in order:
        node = nodes_json[n]
        if "mesh" not in node:
            continue
        mi = node["mesh"]
        mesh = meshes_json[mi]
        prims = mesh["primitives"]
        node_name = node.get("name") or f"node{n}"
        mesh_name = mesh.get("name") or f"mesh{mi}"
        for p, prim in enumerate(prims):
            mode = prim.get("mode", MODE_TRIANGLES)
            what = f"mesh {mi} ({mesh_name!r}) primitive {p}"
            if mode not in (MODE_TRIANGLES, MODE_STRIP):
                if mode == MODE_FAN:  # trimesh does not read fans
                    features.setdefault("TRIANGLE_FAN primitives", f"not loaded (first: {what})")
                else:
                    features.setdefault("point and line primitives", f"not drawn (first: {what})")
                continue
            gnode = instances.get((n, prim_names[(mi, p)]))
            if gnode is None:
                raise doc.err(f"internal: trimesh lost node {n} {what}")
            matrix, gname = tm_scene.graph[gnode]
            geom = tm_scene.geometry[gname]
            attrs = prim["attributes"]
            positions = np.asarray(geom.vertices, np.float64)
            faces = np.asarray(geom.faces, np.int64).reshape(-1, 3)
            nv = accessors[attrs["POSITION"]]["count"]
            if len(positions) != nv:
                raise doc.err(f"internal: trimesh returned {len(positions)} vertices for {what}, "
                              f"the POSITION accessor has {nv}")
            if _needs_own_reader(accessors[attrs["POSITION"]]):
                positions = doc.accessor(attrs["POSITION"]).astype(np.float64)
            check_faces(faces, nv, path, what)
            normals = None
            if "NORMAL" in attrs:
                normals = trimesh_vertex_normals(geom)
                if normals is None or _needs_own_reader(accessors[attrs["NORMAL"]]):
                    normals = doc.accessor(attrs["NORMAL"]).astype(np.float64)
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
            # a normal map without TANGENT: generated (clrender.tangents) from the set the map reads
            material = materials[mat]
            tangent_uv = material.normal_uv.texcoord if material.normal_texture >= 0 and tangents is None else None
            if animation is not None:   # remember the mesh's node; a singular rest matrix builds it unposed
                matrix = animation.add_mesh(len(pieces), n, matrix)
            pieces.append(world_piece(name, matrix, positions, faces, mat, normals, uvs, colors, tangents,
                                      extra_uvs, tangent_uv))

    scene = assemble(pieces, materials, textures, str(path))
    scene.camera = _camera(doc, order, tm_scene, scene)
    if animation is not None:
        gltf_animation.bind(animation, doc, order, scene)
        scene.animation = animation
    _lights(doc, order, scene)
    _warn_features(doc, features)
    return scene
