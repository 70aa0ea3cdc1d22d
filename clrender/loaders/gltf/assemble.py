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
  normalTexture (else a clearcoat normal texture, else anisotropy: `_tangent_set`) and no TANGENT
  gets `clrender.scene.tangents.generate_tangents` of its world-space positions and normals and of
  the uv set that map reads; other primitives (0, 0, 0, 1)
  ("no tangent"); None when no primitive has or needs tangents;
* KHR_materials_variants (clrender/loaders/gltf/variants.py) -> `Scene.material_variants`: the variant
  names and, per Scene mesh, the material each variant gives it (`Scene.set_variant`); every material
  loads, so one only a variant uses is there. Tangents are generated when the primitive's material
  or any of its variants' needs them (a normal map, a clearcoat normal map, anisotropy);
* EXT_mesh_gpu_instancing (clrender/loaders/gltf/instancing.py): a mesh node with instances is
  expanded, instance-major, each instance node-world · T·R·S, its own object "<node>#<i>" (pieces
  "<node>#<i>/<mesh>[/<p>]"); instancing on a skinned or morphing node is warned and drawn once;
* each object's `volume_scale` is |det|^(1/3) of its world matrix's 3x3 (× the instance's), at the load
  pose (KHR_materials_volume's thickness is in mesh units; `instancing.volume_scales`); 1 when skinned;
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
* cameras: `Scene.cameras` holds every camera node in traversal order (name: the node's, else the
  camera's, else "camera <index>"), perspective (`yfov`, `znear`, `zfar`) or orthographic (`xmag`,
  `ymag`, `znear`, `zfar` -> `Camera.orthographic`: like glTF viewers, the image's aspect decides the
  horizontal extent, ymag·width/height; xmag is kept); the camera is the first of them;
* `KHR_lights_punctual` (clrender/loaders/gltf/punctual.py): every node of the default scene that
  references a light adds one light, in traversal order, placed by the node's world matrix (from the JSON
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
from clrender.scene.camera import Camera
from clrender.scene.model import Material, Scene, SceneObject
from clrender.scene.deform import Deformation
from clrender.scene.geometry import BAD_COORDINATES, bad_vertex, coordinates_text, vertex_normals
from clrender.scene.tangents import generate_tangents
from clrender.loaders import budget
from clrender.loaders.common import Piece, assemble, check_faces, world_piece
from clrender.loaders.gltf.document import Document, extensions_in_use, load_document
from clrender.loaders.gltf.spec import MODE_FAN, MODE_STRIP, MODE_TRIANGLES, SUPPORTED_EXTENSIONS, attribute_sets
from clrender.loaders.gltf.geometry import geometry_for
from clrender.loaders.gltf.skin import deformer, read_skins
from clrender.loaders.gltf.materials import load_materials
from clrender.loaders.gltf import instancing, variants as gltf_variants
from clrender.scene.variants import MaterialVariants
from clrender.loaders.gltf.punctual import add_lights

# zfar absent (infinite projection): far = max(FAR_FROM_NEAR * znear, 2 * farthest scene corner)
FAR_FROM_NEAR = 1000.0


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


# -- cameras -----------------------------------------------------------------------------------------------
def _cameras(doc: Document, order: list[int], geometry, scene: Scene, notes: dict) -> list:
    """Every usable camera node of the default scene in traversal order, as (name, Camera): name =
    the node's, else the camera's, else "camera <index>". The first is `scene.camera`, and an unusable
    first camera is a SceneError as it always was; a later unusable one (which loads never read
    before) is left out with a warning, so that a file that loaded still loads."""
    nodes = doc.list("nodes")
    out: list = []
    for n in order:
        if "camera" not in nodes[n]:
            continue
        index = nodes[n]["camera"]
        cam = doc.json["cameras"][index]
        kind = cam.get("type")
        if kind not in ("perspective", "orthographic") or kind not in cam:
            continue  # not a camera this loader knows
        try:
            camera = _node_camera(n, kind, cam[kind], geometry, scene)
        except (KeyError, TypeError, ValueError, ZeroDivisionError, FloatingPointError) as exc:
            message = f"camera {index} (node {n}) is not usable: {exc}"
            if not out:
                raise doc.err(message) from None
            notes[message] = "left out of the scene's cameras"
            continue
        name = nodes[n].get("name") or cam.get("name") or f"camera {index}"
        out.append((str(name), camera))
    return out


def _node_camera(n: int, kind: str, persp: dict, geometry, scene: Scene) -> Camera:
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
    add_lights(doc, order, scene)
    _warn_features(doc, features, notes)
    return scene


def _tangent_set(candidates: list, attrs: dict) -> Optional[int]:
    """The TEXCOORD set to generate tangents from for a primitive without TANGENT that may show any
    of `candidates` (its material, then its variants' materials): the first normal map's set, else
    the first clearcoat normal map's, else, for anisotropy, its texture's set (TEXCOORD_0 without
    one; spec: the direction is in the tangent frame of the UVs). None: no material needs tangents
    (or anisotropy has no TEXCOORD to build them from)."""
    for m in candidates:
        if m.normal_texture >= 0:
            return m.normal_uv.texcoord
    for m in candidates:
        if getattr(m, "clearcoat_normal_texture", -1) >= 0:
            return m.clearcoat_normal_uv.texcoord
    for m in candidates:
        if getattr(m, "anisotropy_strength", 0.0) > 0:
            k = m.anisotropy_uv.texcoord if getattr(m, "anisotropy_texture", -1) >= 0 else 0
            if f"TEXCOORD_{k}" in attrs:
                return k
    return None


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
    names = gltf_variants.variant_names(doc)    # KHR_materials_variants
    doc_materials = list(materials)             # a mapping names one of these (not the default added below)
    mesh_maps: dict = {}                        # Scene mesh (piece) -> {variant: material}
    mesh_defaults: dict = {}                    # Scene mesh -> its own material
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
        instances = instancing.node_instances(doc, n, node, prims, features)     # None: drawn once
        templates: list = []        # instanced: each primitive's world_piece arguments, drawn per instance
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
            mapping = gltf_variants.primitive_mapping(doc, what, prim, len(names), doc_materials, attrs)
            # a normal map (the base's or the clearcoat's) or anisotropy without TANGENT: generated
            # (clrender.scene.tangents) from the set the map reads, for the material and its variants'
            shown = [materials[mat], *(materials[m] for m in mapping.values())]
            tangent_uv = _tangent_set(shown, attrs) if tangents is None else None
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
                gltf_variants.record(mesh_maps, mesh_defaults, len(pieces), mapping, mat)
                pieces.append(Piece(name, positions, faces, mat, normals, uvs, colors, tangents, extra_uvs))
                continue
            if instances is not None:
                templates.append((p, prim, what, name, matrix, positions, faces, mat, normals, uvs, colors, tangents,
                                  extra_uvs, tangent_uv, position_ref, mapping))
                continue
            if animation is not None:   # remember the mesh's node; a singular rest matrix builds it unposed
                matrix = animation.add_mesh(len(pieces), n, matrix)
            gltf_variants.record(mesh_maps, mesh_defaults, len(pieces), mapping, mat)
            pieces.append(world_piece(name, matrix, positions, faces, mat, normals, uvs, colors, tangents,
                                      extra_uvs, tangent_uv))
            _check_positions(doc, pieces[-1].positions, f"{position_ref} placed by node {n}'s world transform")
        if instances is not None:   # instance-major: each instance's triangles together, one object each
            scales = instancing.volume_scales(geometry.node_matrix(n), instances)
            for k, inst in enumerate(instances):
                if not templates:
                    break
                for (p, prim, what, name, matrix, positions, faces, mat, normals, uvs, colors, tangents, extra_uvs,
                     tangent_uv, position_ref, mapping) in templates:
                    if k:           # the primitive's first instance was charged above
                        _charge_piece(doc, n, mi, p, prim, f"{what} instance {k}")
                    if animation is not None:
                        matrix = animation.add_mesh(len(pieces), n, matrix)
                    gltf_variants.record(mesh_maps, mesh_defaults, len(pieces), mapping, mat)
                    piece_name = f"{node_name}#{k}{name[len(node_name):]}"
                    pieces.append(world_piece(piece_name, matrix @ inst, positions, faces, mat, normals, uvs, colors,
                                              tangents, extra_uvs, tangent_uv))
                    _check_positions(doc, pieces[-1].positions, f"{position_ref} placed by node {n}'s world "
                                                               f"transform and {instancing.NAME} instance {k}")
                piece_object.extend([len(objects)] * len(templates))
                objects.append(SceneObject(f"{node_name}#{k}", mesh_name, f"{path_of(n)}#{k}", node.get("extras"), n,
                                           scales[k]))
            continue
        if len(pieces) > first_piece:
            piece_object.extend([len(objects)] * (len(pieces) - first_piece))
            # a skinned mesh ignores its node's transform (spec): its volume keeps the mesh's units
            scale = 1.0 if "skin" in node else instancing.volume_scales(geometry.node_matrix(n))[0]
            objects.append(SceneObject(node_name, mesh_name, path_of(n), node.get("extras"), n, scale))

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
    if names:       # Scene meshes are the pieces, in order
        scene.material_variants = MaterialVariants.from_meshes(names, mesh_maps, mesh_defaults)
    if deformation is not None:
        firsts = np.cumsum([0] + [len(p.positions) for p in pieces])
        deformation.attach({d.mesh: firsts[d.mesh] for d in deformers})
        scene.deformation = deformation
    scene.cameras = _cameras(doc, order, geometry, scene, notes)
    scene.camera = scene.cameras[0][1] if scene.cameras else None
    if animation is not None:
        gltf_animation.bind(animation, doc, order, scene)
        scene.animation = animation
    return scene
