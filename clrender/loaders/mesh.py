"""OBJ (+MTL), PLY and STL -> Scene, through trimesh.

trimesh is called with `process=False` (no vertex merging, no reordering, no NaN removal) and the
default `maintain_order=False`: in trimesh 5.2, `maintain_order=True` makes the OBJ loader drop
uvs and normals. With `group_material=True` (the default) an OBJ becomes one geometry per
`usemtl` material with its faces in file order; geometries are ordered by the first appearance of
their material in the file. trimesh stores OBJ/PLY uvs as written (v up, OpenGL style); they are
converted to the glTF convention (v' = 1 - v). Materials are read from the MTL file here (trimesh
rounds Kd to 8 bits and ignores missing texture files). OBJ/PLY/STL materials are double-sided.

Relative (negative) OBJ indices are resolved by trimesh against the end of the whole vertex list,
which is only right when every vertex precedes the faces that use it.
"""
from __future__ import annotations

import re
import warnings
from pathlib import Path
from typing import Optional

import numpy as np

from clrender.scene.geometry import BAD_COORDINATES, bad_vertex, coordinates_text
from clrender.scene.model import Material, Scene, SceneError, SceneObject, Texture
from clrender.loaders import confine
from clrender.loaders.common import (
    Piece, assemble, check_faces, decode_image, fail, flip_v, load_images, trimesh_load, trimesh_vertex_normals,
    world_piece)

# map_Kd options and how many arguments each takes (-o/-s/-t take 1 to 3 numbers)
_MAP_OPTIONS = {"-blendu": 1, "-blendv": 1, "-bm": 1, "-boost": 1, "-cc": 1, "-clamp": 1, "-imfchan": 1,
                "-mm": 2, "-texres": 1, "-type": 1, "-o": 3, "-s": 3, "-t": 3}


def _finite(text: str) -> float:
    """An MTL number; nan and inf are not numbers a material can hold (ValueError, as for garbage)."""
    value = float(text)
    if not np.isfinite(value):
        raise ValueError(text)
    return value


def _read_text(path: Path) -> str:
    try:
        return path.read_bytes().decode("utf-8", errors="replace")
    except OSError as exc:
        raise fail(path, f"cannot read file ({exc.strerror or exc})") from None


def _vetted_resolver(path: Path, served: dict):
    """A trimesh resolver for `path` that hands out only the files clrender has already checked
    (`served`: the name as written in the file -> its path): trimesh finds `mtllib` anywhere in the
    text (a comment too) and reads map_Kd/TextureFile images itself; clrender reads the materials and
    textures on its own, so trimesh needs nothing else and must not open anything else."""
    from trimesh.resolvers import FilePathResolver

    class Vetted(FilePathResolver):
        def get(self, name):
            file = served.get(str(name).strip())
            if file is None:
                raise FileNotFoundError(name)       # trimesh catches it and goes on without that asset
            return file.read_bytes()

    return Vetted(str(path))


def _trimesh_geometries(tm_scene):
    """(graph node, matrix, geometry name, geometry) for every triangle mesh, in trimesh's order."""
    import trimesh

    out = []
    for gnode in tm_scene.graph.nodes_geometry:
        matrix, gname = tm_scene.graph[gnode]
        geom = tm_scene.geometry[gname]
        if isinstance(geom, trimesh.Trimesh):
            out.append((gnode, np.asarray(matrix, np.float64), gname, geom))
    return out


def _uv(geom) -> Optional[np.ndarray]:
    uv = getattr(geom.visual, "uv", None)
    if uv is None or len(uv) != len(geom.vertices):
        return None
    return flip_v(uv)


# -- OBJ -----------------------------------------------------------------------------------------------
_NUM = r"[-+]?(?:(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?|nan|inf(?:inity)?)"
# a `v` line that is not 3 to 7 numbers (x y z [w] or x y z r g b [a]), optionally commented
_BAD_VERTEX = re.compile(rf"^v[ \t](?![ \t]*{_NUM}(?:[ \t]+{_NUM}){{2,6}}[ \t]*(?:#.*)?\r?$).*$", re.M | re.I)


def _check_obj_vertices(path: Path, text: str, geoms) -> None:
    """A NaN, infinite or absurd (beyond ±1e30) vertex that a face uses: one line naming the file
    line and the OBJ vertex number (the triangle would otherwise vanish from the render silently).
    The loaded arrays are checked first (fast); only then is the text searched for the line."""
    if all(bad_vertex(geom.vertices) < 0 for _, _, _, geom in geoms):
        return
    number = 0
    for lineno, line in enumerate(text.splitlines(), 1):
        if not re.match(r"v[ \t]", line):
            continue
        number += 1
        try:
            xyz = np.array([float(v) for v in line.split("#", 1)[0].split()[1:4]])
        except ValueError:
            continue                    # _check_obj_indices refused such lines already
        if bad_vertex(xyz) == 0:
            raise fail(path, f"line {lineno}: vertex {number} is {coordinates_text(xyz)}: {BAD_COORDINATES}")
    for _, _, gname, geom in geoms:     # not found in the text: name the geometry and its vertex
        i = bad_vertex(geom.vertices)
        if i >= 0:
            raise fail(path, f"geometry {gname!r}: vertex {i} is {coordinates_text(geom.vertices[i])}: "
                             f"{BAD_COORDINATES}")


def _snippet(text: str, limit: int = 40) -> str:
    """A short quote of the offending statement (never a whole line of an arbitrary file)."""
    text = text.strip()
    return repr(text) if len(text) <= limit else repr(text[:limit]) + f" ... ({len(text)} characters)"


def _check_obj_indices(path: Path, text: str) -> None:
    bad_vertex = _BAD_VERTEX.search(text)
    if bad_vertex:
        line = text.count("\n", 0, bad_vertex.start()) + 1
        raise fail(path, f"line {line}: cannot parse vertex {_snippet(bad_vertex.group(0))} (needs 3 numbers)")
    counts = {key: len(re.findall(rf"^{key}[ \t]", text, re.M)) for key in ("v", "vt", "vn")}
    tokens = " ".join(re.findall(r"^f[ \t]+([^\n]*)", text, re.M)).split()
    if not tokens:
        return
    if not any("/" in t for t in tokens):
        columns = {"v": tokens}
    else:
        split = [t.split("/") for t in tokens]
        columns = {"v": [s[0] for s in split],
                   "vt": [s[1] for s in split if len(s) > 1 and s[1]],
                   "vn": [s[2] for s in split if len(s) > 2 and s[2]]}
    for key, found in columns.items():
        if not found:
            continue
        try:
            idx = np.array(found, dtype=np.int64)
        except ValueError:
            bad = next(t for t in found if not re.fullmatch(r"[-+]?\d+", t))
            raise fail(path, f"face {key} index {_snippet(bad)} is not an integer") from None
        except OverflowError:             # integers beyond int64: out of range whatever the file holds
            big = max(found, key=lambda t: len(t.lstrip("+-0")))
            raise fail(path, f"face {key} index {_snippet(big)} is out of range (there are {counts[key]} "
                             f"{key} entries)") from None
        n = counts[key]
        bad = (idx == 0) | (idx > n) | (idx < -n)
        if bad.any():
            value = int(idx[np.argmax(bad)])
            raise fail(path, f"face {key} index {value} out of range (the file has {n} '{key}' lines; "
                             f"OBJ indices start at 1)")


def _parse_map(args: list[str]) -> tuple[Optional[str], bool]:
    """map_Kd arguments -> (file name, clamp)."""
    clamp = False
    i = 0
    while i < len(args) and args[i].startswith("-") and args[i].lower() in _MAP_OPTIONS:
        opt = args[i].lower()
        n = _MAP_OPTIONS[opt]
        if opt == "-clamp" and i + 1 < len(args):
            clamp = args[i + 1].lower() == "on"
        if opt in ("-o", "-s", "-t"):  # 1 to 3 numbers
            j = i + 1
            while j < len(args) and j <= i + 3 and re.fullmatch(r"[-+]?[\d.eE+-]+", args[j]):
                j += 1
            i = j
        else:
            i += 1 + n
    name = " ".join(args[i:]).strip()
    return (name or None), clamp


# MTL statements clrender reads or knowingly ignores; any other (a typo such as `Kdd`) is warned about.
_MTL_KEYS = {"newmtl", "ka", "kd", "ks", "ke", "ns", "ni", "d", "tr", "tf", "illum", "sharpness", "bump", "disp",
             "decal", "refl", "norm", "pr", "pm", "ps", "pc", "pcr", "aniso", "anisor"}


_KEYWORD = re.compile(r"[A-Za-z_][A-Za-z0-9_]{0,23}")


def _parse_mtl(file: Path, where: Path) -> dict[str, dict]:
    """The materials of an MTL file. Messages name line numbers and statement keywords, never the
    file's text: `mtllib` may name any file, and its lines are not ours to print."""
    materials: dict[str, dict] = {}
    current = None
    unknown = []
    garbled = 0                     # lines that do not start with a keyword at all
    for lineno, raw in enumerate(_read_text(file).splitlines(), 1):
        line = raw.split("#", 1)[0].strip()
        if not line:
            continue
        parts = line.split()
        key, args = parts[0].lower(), parts[1:]
        if not _KEYWORD.fullmatch(parts[0]):
            garbled += 1
            continue
        if key not in _MTL_KEYS and not key.startswith("map_"):
            unknown.append(f"line {lineno}: {parts[0]!r}")
        if key == "newmtl":
            current = materials.setdefault(" ".join(args), {})
            continue
        if current is None:
            continue
        try:
            if key in ("kd", "ks") and args and args[0].lower() not in ("spectral", "xyz"):
                values = [_finite(a) for a in args[:3]]
                if len(values) == 2:      # the MTL form is "r" (grey) or "r g b"
                    raise ValueError
                current[key] = tuple(values * 3)[:3] if len(values) == 1 else tuple(values)
            elif key == "ns" and args:
                current["ns"] = _finite(args[0])
            elif key == "d" and args:
                current["d"] = _finite(args[-1])
            elif key == "tr" and args:
                current["d"] = 1.0 - _finite(args[0])
            elif key == "map_kd":
                name, clamp = _parse_map(args)
                if name:
                    current["map_kd"] = (name.replace("\\", "/"), clamp)
        except ValueError:
            raise fail(file, f"line {lineno}: cannot parse the numbers of {parts[0]!r}") from None
    if (garbled or unknown) and not materials:      # not a material library: say so, show none of it
        bad = garbled + len(unknown)
        raise fail(where, f"material library {file} is not an MTL file (no newmtl statement, {bad} "
                          f"line{'s' if bad > 1 else ''} that are not MTL statements)")
    if garbled:
        unknown.append(f"{garbled} line{'s' if garbled > 1 else ''} not starting with a statement keyword")
    if unknown:
        warnings.warn(f"{file}: unknown MTL statements ignored: {'; '.join(unknown[:5])}"
                      f"{' ...' if len(unknown) > 5 else ''}", stacklevel=4)
    return materials


def _obj_materials(path: Path, text: str):
    """MTL materials as clrender Materials: (name -> index, materials, textures)."""
    libs = re.findall(r"^mtllib[ \t]+([^\n]+?)[ \t]*$", text, re.M)
    parsed: dict[str, dict] = {}
    mtl_files: dict[str, Path] = {}
    served: dict[str, Path] = {}         # the libraries trimesh may read too (_vetted_resolver)
    for lib in libs:
        file = confine.reference(path, lib.strip().replace("\\", "/"), "mtllib")
        if not file.is_file():
            raise fail(path, f"material library not found: {file}")
        served[lib.strip()] = file
        for name, props in _parse_mtl(file, path).items():
            parsed.setdefault(name, props)
            mtl_files.setdefault(name, file)
    index: dict[str, int] = {}
    materials: list[Material] = []
    slots: dict[tuple, int] = {}
    jobs, tex_names, wraps = [], [], []
    for name, props in parsed.items():
        tex = -1
        if "map_kd" in props:
            rel, clamp = props["map_kd"]
            file = confine.reference(mtl_files[name], rel, f"map_Kd of material {name!r}")
            if not file.is_file():
                raise fail(path, f"texture file not found: {file} (map_Kd of material {name!r})")
            key = (str(file.resolve()), clamp)
            if key not in slots:
                slots[key] = len(jobs)
                jobs.append(lambda file=file: decode_image(file, str(path)))
                tex_names.append(file.name)
                wraps.append("clamp" if clamp else "repeat")
            tex = slots[key]
        kd = props.get("kd", (1.0, 1.0, 1.0))
        kw = {}
        if "ks" in props:
            kw["specular_intensity"] = float(np.mean(props["ks"]))
        if "ns" in props:
            kw["specular_power"] = float(np.clip(props["ns"], 1.0, 2048.0))
        index[name] = len(materials)
        try:
            materials.append(Material(name=name, base_color=(*kd, props.get("d", 1.0)), base_color_texture=tex,
                                      double_sided=True, **kw))
        except SceneError as exc:         # the Material's own check names no file: the MTL that made it
            raise fail(mtl_files[name], str(exc)) from None
    pixels = load_images(jobs)
    textures = [Texture(n, rgba, w, w, srgb=True) for n, rgba, w in zip(tex_names, pixels, wraps)]
    return index, materials, textures, served


def load_obj(path) -> Scene:
    path = Path(path)
    text = _read_text(path)
    _check_obj_indices(path, text)
    index, materials, textures, served = _obj_materials(path, text)
    first_use = {}
    for name in re.findall(r"^usemtl[ \t]+([^\n]*?)[ \t]*$", text, re.M):
        first_use.setdefault(name, len(first_use))
    unknown = sorted(set(first_use) - set(index))
    if unknown:
        warnings.warn(f"{path}: usemtl names not defined in any material library: {unknown}", stacklevel=2)

    # o/g groups are the file's objects (Scene.objects): trimesh then splits per (group, material)
    grouped = re.search(r"^[og][ \t]+\S", text, re.M) is not None
    tm_scene = trimesh_load(str(path), process=False, file_type="obj", split_objects=grouped, split_groups=grouped,
                            resolver=_vetted_resolver(path, served))
    geoms = _trimesh_geometries(tm_scene)
    _check_obj_vertices(path, text, geoms)
    default = None
    keyed = []
    for rank, (gnode, matrix, gname, geom) in enumerate(reversed(geoms)):
        mat_name = getattr(getattr(geom.visual, "material", None), "name", None)
        if mat_name not in index and gname in first_use:
            mat_name = gname
        if mat_name in index:
            mat = index[mat_name]
        else:
            if default is None:
                default = len(materials)
                materials.append(Material(name="default", double_sided=True))
            mat = default
        order = first_use.get(mat_name, -1)
        keyed.append(((order, rank), (gnode, matrix, gname, geom, mat)))
    keyed.sort(key=lambda item: item[0])

    pieces, objects, piece_object, object_index = [], [], [], {}
    for _, (gnode, matrix, gname, geom, mat) in keyed:
        faces = np.asarray(geom.faces, np.int64)
        check_faces(faces, len(geom.vertices), path, f"geometry {gname!r}")
        group, material = _obj_group(gname, geom) if grouped else (path.stem, None)
        name = f"{group}/{material}" if material else f"{gnode}/{gname}"      # group/material, as loaded
        pieces.append(world_piece(name, matrix, geom.vertices, faces, mat, trimesh_vertex_normals(geom), _uv(geom)))
        if group not in object_index:
            object_index[group] = len(objects)
            objects.append(SceneObject(group, group, group))
        piece_object.append(object_index[group])
    return assemble(pieces, materials, textures, str(path), objects=objects, piece_object=piece_object)


def _obj_group(gname: str, geom) -> tuple:
    """(o/g group, material name or None) of a geometry trimesh split out, named "<group>_<material>"."""
    material = getattr(getattr(geom.visual, "material", None), "name", None)
    if material and gname.endswith("_" + material) and len(gname) > len(material) + 1:
        return gname[: -len(material) - 1], material
    return gname, None


# -- PLY / STL ------------------------------------------------------------------------------------------
def _ply_texture(path: Path) -> Optional[Path]:
    with open(path, "rb") as fh:
        head = fh.read(65536)
    end = head.find(b"end_header")
    header = head[: end if end >= 0 else len(head)].decode("latin-1")
    match = re.search(r"^comment[ \t]+TextureFile[ \t]+([^\r\n]+?)[ \t]*\r?$", header, re.M | re.I)
    if not match:
        return None
    file = confine.reference(path, match.group(1).replace("\\", "/"), "comment TextureFile")
    if not file.is_file():
        raise fail(path, f"texture file not found: {file} (comment TextureFile)")
    return file


def _load_simple(path: Path, file_type: str, texture_file: Optional[Path] = None) -> Scene:
    # the PLY texture is decoded here (_ply_texture, confined): trimesh must not open it itself
    tm_scene = trimesh_load(str(path), process=False, file_type=file_type, resolver=_vetted_resolver(path, {}),
                            **({"skip_materials": True} if file_type == "ply" else {}))
    textures = []
    material = Material(name="default", double_sided=True)
    if texture_file is not None:
        textures.append(Texture(texture_file.name, decode_image(texture_file, str(path)), srgb=True))
        material = Material(name=texture_file.stem, base_color_texture=0, double_sided=True)
    pieces: list[Piece] = []
    for gnode, matrix, gname, geom in sorted(_trimesh_geometries(tm_scene), key=lambda g: str(g[0])):
        faces = np.asarray(geom.faces, np.int64)
        check_faces(faces, len(geom.vertices), path, f"geometry {gname!r}")
        i = bad_vertex(geom.vertices)   # process=False: the file's vertex order (STL: 3 per facet)
        if i >= 0:
            where = f"facet {i // 3} vertex {i % 3}" if file_type == "stl" else f"vertex {i}"
            raise fail(path, f"{where} is {coordinates_text(geom.vertices[i])}: {BAD_COORDINATES}")
        pieces.append(world_piece(f"{gnode}/{gname}", matrix, geom.vertices, faces, 0,
                                  trimesh_vertex_normals(geom), _uv(geom)))
    return assemble(pieces, [material], textures, str(path))


def load_ply(path) -> Scene:
    path = Path(path)
    return _load_simple(path, "ply", _ply_texture(path))


def load_stl(path) -> Scene:
    """STL stores no vertex normals: flat, area-weighted normals come from the (unmerged) vertices."""
    _check_stl(Path(path))
    return _load_simple(Path(path), "stl")


def _check_stl(path: Path) -> None:
    """A binary STL is 84 + 50·N bytes (N in its header); trimesh reads any other file as ASCII STL,
    so a truncated binary one loaded as no triangles (or failed on a text-encoding guess). Refuse
    a file that is neither a complete binary STL nor text starting with `solid`."""
    size = path.stat().st_size
    with open(path, "rb") as fh:
        head = fh.read(84)
    if len(head) == 84:
        count = int.from_bytes(head[80:84], "little")
        if size == 84 + 50 * count:
            return
    if head.lstrip()[:5].lower() == b"solid" and b"\0" not in head:
        return                                        # ASCII STL: trimesh parses it
    if len(head) < 84:
        raise fail(path, f"truncated or corrupt STL: {size} bytes, shorter than a binary STL's 84-byte header")
    raise fail(path, f"truncated or corrupt binary STL: its header says {count} triangles "
                     f"({84 + 50 * count} bytes) but the file has {size} bytes")
