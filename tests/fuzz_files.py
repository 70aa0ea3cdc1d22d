"""One subject (the fuzzing tier's seed files and the mutations applied to them) in one file: 631 lines.

The fuzzing tier's inputs (tests/test_fuzz.py): small valid seed files and the mutations applied
to them. Pure Python and NumPy: no OpenCL, no clrender import.

A *case* is a folder holding one format's seed files (`write_seed`), changed by a list of
mutation ops (`apply`). Ops are plain tuples of JSON-able values so a failing case can be printed
and replayed (`python3 tests/fuzz_worker.py --replay OPS.json`):

    ("truncate", file, frac)                 keep the first int(len * frac) bytes
    ("flip", file, [[frac, bit], ...])       flip single bits
    ("overwrite", file, frac, hex)           overwrite bytes at a position
    ("insert", file, frac, hex)              insert bytes at a position
    ("at", file, [key, ...], value)          set the node at an explicit path ("__delete__": remove it)
    ("set", file, k, value)                  set the k-th node (mod count) of the parsed document
                                             (glTF/GLB JSON, TOML) to `value` (see HOSTILE)
    ("delete", file, k)                      delete the k-th node of the parsed document
    ("line", file, k, how, value)            OBJ/MTL text: line k (mod count): "drop", "dup", or
                                             "token" (replace its token `value[0]` by `value[1]`)
    ("ref", file, k, kind)                   the k-th file reference (glTF buffer/image uri, OBJ
                                             mtllib / map_Kd, TOML mesh path / environment source)
                                             becomes a hostile path of `kind` (REF_KINDS)
    ("png_size", file, w, h)                 a PNG's IHDR size (CRC fixed, data unchanged)
    ("exr_window", file, [x0, y0, x1, y1])   an OpenEXR header's dataWindow
    ("hdr_size", file, text)                 a Radiance file's resolution line
    ("glb_length", file, field, value)       a GLB header / chunk length field ("total", "json", "bin")

`OUTSIDE` is the name of a folder beside the case folder holding copies of the seed's referenced
files: a scene may never read it (issue 34, item 1); the worker watches it.
"""
from __future__ import annotations

import base64
import json
import math
import os
import re
import shutil
import struct
import sys
import zlib
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from gltf_files import primitive, write_gltf  # noqa: E402

FORMATS = ("gltf", "glb", "obj", "toml", "exr", "hdr")
# the file each format's case loads, and the files a mutation may change
SCENE = {"gltf": "model.gltf", "glb": "model.glb", "obj": "crate.obj", "toml": "scene.toml",
         "exr": "env_scene.toml", "hdr": "env_scene.toml"}
TARGETS = {"gltf": ("model.gltf", "model.bin", "tex.png"), "glb": ("model.glb", "tex.png"),
           "obj": ("crate.obj", "crate.mtl", "crate.png"), "toml": ("scene.toml",),
           "exr": ("env.exr",), "hdr": ("env.hdr",)}
OUTSIDE = "outside"
SECRET = b"CLRENDER-FUZZ-SECRET-6b1f0c"     # in every outside file: must never be printed
LONG = "A" * 300                             # a long string value (a long *path* is REF_KINDS' "long")

# Values `set` writes into a parsed document: counts that would allocate far too much, numbers
# that are not numbers, type confusion, deep nesting (a recursion bomb for a recursive walker).
HOSTILE = [0, -1, 1, 3, 65535, 2 ** 31 - 1, 2 ** 31, 2 ** 32, 2 ** 53, 2 ** 63, 2 ** 64, 402653184,
           300_000_000, 10 ** 9, -2 ** 31, 1.5, -0.0, 1e-45, 3e38, 1e39, 1e308, math.nan, math.inf, -math.inf,
           "", "x", "0", "VEC3", "SCALAR", "MAT4", "BLEND", "data:", "data:application/octet-stream;base64,!!",
           LONG, "\u0000", None, True, False, [], [0], [1, 2, 3], [[0, 1], [2]], [None], {}, {"x": 1},
           {"count": 402653184}, "DEEP"]
DEEP_LEVELS = 20000

REF_KINDS = ("parent", "secret", "absolute", "percent", "dotdot_inside", "symlink", "symlink_dir", "long", "nul",
             "missing", "empty", "dir", "fifo", "dev_zero", "backslash", "url", "file_url")


# -- seeds --------------------------------------------------------------------------------------------------
def _png(rgba: np.ndarray) -> bytes:
    import io
    from PIL import Image
    out = io.BytesIO()
    Image.fromarray(rgba).save(out, format="PNG")
    return out.getvalue()


def _texture(seed=0, size=8) -> np.ndarray:
    return np.random.default_rng(seed).integers(0, 256, (size, size, 4), dtype=np.uint8)


def _gltf_doc(folder: Path) -> tuple[dict, bytes]:
    """The glTF seed: textured quad on a child node (TRS), a camera, a point light, an animation
    and a morph target whose accessor is sparse without a bufferView; (JSON doc, binary buffer)."""
    tex = _texture(1)
    tex[..., 3] = 255
    target = np.zeros((4, 3), np.float32)

    def edit(doc):
        blob = bytearray(base64.b64decode(doc["buffers"][0]["uri"].partition(",")[2]))
        blob.extend(b"\0" * (-len(blob) % 4))
        views = doc["bufferViews"]
        for data in (np.array([2], np.uint32).tobytes(), np.array([0, 0, 0.25], np.float32).tobytes()):
            views.append({"buffer": 0, "byteOffset": len(blob), "byteLength": len(data)})
            blob.extend(data)
        morph = doc["meshes"][0]["primitives"][0]["targets"][0]["POSITION"]
        acc = doc["accessors"][morph]
        acc.pop("bufferView")
        acc["sparse"] = {"count": 1, "indices": {"bufferView": len(views) - 2, "componentType": 5125},
                         "values": {"bufferView": len(views) - 1}}
        acc["min"], acc["max"] = [0, 0, 0], [0, 0, 0.25]
        doc["meshes"][0]["weights"] = [0.5]
        doc["buffers"][0] = {"byteLength": len(blob), "uri": "data:application/octet-stream;base64,"
                             + base64.b64encode(bytes(blob)).decode()}

    path = write_gltf(
        folder / "model.gltf",
        primitives=[primitive(material=0, targets=[{"POSITION": target}])],
        materials=[{"name": "mat_gltf", "pbrMetallicRoughness": {"baseColorTexture": {"index": 0},
                                                                 "metallicFactor": 0.0, "roughnessFactor": 0.6}}],
        images=[tex], samplers=[{"magFilter": 9729, "minFilter": 9987, "wrapS": 10497, "wrapT": 33648}],
        textures=[{"source": 0, "sampler": 0}],
        nodes=[{"name": "root", "children": [1], "translation": [-0.5, -0.5, 0.0]},
               {"name": "quad", "mesh": 0, "rotation": [0, 0, 0, 1], "scale": [1, 1, 1]},
               {"name": "cam", "camera": 0, "translation": [0, 0, 2.5]},
               {"name": "lamp", "translation": [0, 0.5, 1.5], "extensions": {"KHR_lights_punctual": {"light": 0}}}],
        cameras=[{"type": "perspective", "perspective": {"yfov": 0.9, "znear": 0.1, "zfar": 50.0}}],
        extensionsUsed=["KHR_lights_punctual"],
        extensions={"KHR_lights_punctual": {"lights": [{"type": "point", "color": [1, 0.9, 0.8], "intensity": 4.0}]}},
        animations=[{"channels": [{"sampler": 0, "target": {"node": 1, "path": "translation"}}],
                     "samplers": [{"input": np.array([0.0, 1.0], np.float32),
                                   "output": np.array([[0, 0, 0], [0, 0.1, 0]], np.float32)}]}],
        edit=edit)
    doc = json.loads(path.read_text())
    blob = base64.b64decode(doc["buffers"][0]["uri"].partition(",")[2])
    (folder / "model_image0.png").rename(folder / "tex.png")
    doc["images"][0]["uri"] = "tex.png"
    path.unlink()
    return doc, blob


def glb_bytes(doc: dict, blob: bytes) -> bytes:
    text = _json_dump(doc).encode("utf-8", "surrogatepass")
    text += b" " * (-len(text) % 4)
    blob = bytes(blob) + b"\0" * (-len(blob) % 4)
    total = 12 + 8 + len(text) + 8 + len(blob)
    return (struct.pack("<4sII", b"glTF", 2, total) + struct.pack("<I4s", len(text), b"JSON") + text
            + struct.pack("<I4s", len(blob), b"BIN\0") + blob)


def split_glb(data: bytes):
    """(doc, blob) of a well-formed GLB, else None."""
    try:
        magic, _, _ = struct.unpack_from("<4sII", data, 0)
        jlen, jtype = struct.unpack_from("<I4s", data, 12)
        if magic != b"glTF" or jtype != b"JSON":
            return None
        doc = json.loads(data[20:20 + jlen])
        rest = data[20 + jlen:]
        blob = b""
        if len(rest) >= 8:
            blen, _ = struct.unpack_from("<I4s", rest, 0)
            blob = rest[8:8 + blen]
        return doc, blob
    except (struct.error, ValueError, RecursionError):
        return None


OBJ_TEXT = """# fuzz seed
mtllib crate.mtl
o crate
v -0.5 -0.5 0
v 0.5 -0.5 0
v 0.5 0.5 0
v -0.5 0.5 0
vt 0 0
vt 1 0
vt 1 1
vt 0 1
vn 0 0 1
usemtl mat_obj
f 1/1/1 2/2/1 3/3/1
f 1/1/1 3/3/1 4/4/1
"""
MTL_TEXT = """newmtl mat_obj
Ka 0.1 0.1 0.1
Kd 0.8 0.7 0.6
Ks 0.2 0.2 0.2
Ns 32
d 1.0
map_Kd crate.png
"""
TOML_TEXT = """ambient = 0.05

[[mesh]]
path = "model.gltf"
name = "model"
transform = { translate = [0.0, 0.0, -0.5], rotate_deg = [0.0, 20.0, 0.0], scale = 1.0 }
extras = { class = "quad" }

[[mesh]]
path = "crate.obj"
opacity = 1.0

[[material]]
name = "mat_*"
alpha_cutoff = 0.5

[camera]
eye = [0.0, 0.3, 3.0]
target = [0.0, 0.0, 0.0]
fov_y_deg = 50.0

[render]
width = 16
height = 12

[[light]]
type = "point"
position = [0.0, 1.0, 1.5]
color = [1.0, 0.8, 0.6]
intensity = 3.0
radius = 6.0

[[light]]
type = "spot"
position = [0.0, 2.0, 2.0]
direction = [0.0, -1.0, -1.0]
inner_cone_deg = 10.0
outer_cone_deg = 30.0

[lights]
random = { count = 4, seed = 3, radius = [0.5, 1.0], intensity = 0.5 }

[sun]
direction = [-0.4, -1.0, -0.3]
intensity = 0.5
shadow = false

[environment]
source = "env.hdr"
intensity = 0.5
"""
ENV_TOML = """[[mesh]]
path = "crate.obj"

[environment]
source = "{env}"
"""


def env_pixels() -> np.ndarray:
    rng = np.random.default_rng(5)
    return (rng.random((8, 16, 3)) * 4.0).astype(np.float32)


def write_exr(path: Path, img: np.ndarray) -> None:
    import OpenEXR
    channels = {c: np.ascontiguousarray(img[..., k], np.float32) for k, c in enumerate("RGB")}
    OpenEXR.File({"compression": OpenEXR.NO_COMPRESSION, "type": OpenEXR.scanlineimage}, channels).write(str(path))


def write_hdr(path: Path, img: np.ndarray) -> None:
    """Radiance RGBE, RLE scanlines (the reader's main path), written by hand here so the seed does
    not depend on the code under test."""
    peak = img.max(-1)
    mant, expo = np.frexp(peak)
    scale = np.where(peak > 1e-32, mant * 256.0 / np.maximum(peak, 1e-32), 0)
    rgbe = np.zeros(img.shape[:2] + (4,), np.uint8)
    rgbe[..., :3] = np.clip(img * scale[..., None], 0, 255).astype(np.uint8)
    rgbe[..., 3] = np.where(peak > 1e-32, expo + 128, 0)
    h, w = img.shape[:2]
    out = bytearray(b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n" + f"-Y {h} +X {w}\n".encode())
    for row in rgbe:
        out += bytes((2, 2, w >> 8, w & 255))
        for c in range(4):
            values = row[:, c].tobytes()
            x = 0
            while x < w:                      # literal chunks and runs (the first 8 bytes as a run if equal)
                if x + 4 <= w and len(set(values[x:x + 4])) == 1:
                    n = 4
                    while x + n < w and n < 127 and values[x + n] == values[x]:
                        n += 1
                    out += bytes((128 + n, values[x]))
                else:
                    n = min(128, w - x)
                    out += bytes((n,)) + values[x:x + n]
                x += n
    path.write_bytes(bytes(out))


def write_seed(fmt: str, folder: Path) -> Path:
    """Write `fmt`'s valid seed files into `folder` (created); returns the file a case loads."""
    folder.mkdir(parents=True, exist_ok=True)
    if fmt in ("gltf", "glb", "toml"):
        doc, blob = _gltf_doc(folder)
        if fmt == "glb":
            doc["buffers"][0].pop("uri")
            (folder / "model.glb").write_bytes(glb_bytes(doc, blob))
        else:
            doc["buffers"][0]["uri"] = "model.bin"
            (folder / "model.bin").write_bytes(blob)
            (folder / "model.gltf").write_text(json.dumps(doc, indent=1))
    if fmt in ("obj", "toml", "exr", "hdr"):
        (folder / "crate.obj").write_text(OBJ_TEXT)
        (folder / "crate.mtl").write_text(MTL_TEXT)
        tex = _texture(2)
        tex[..., 3] = 255
        (folder / "crate.png").write_bytes(_png(tex))
    if fmt in ("toml", "hdr"):
        write_hdr(folder / "env.hdr", env_pixels())
    if fmt == "exr":
        write_exr(folder / "env.exr", env_pixels())
    if fmt == "toml":
        (folder / "scene.toml").write_text(TOML_TEXT)
    if fmt in ("exr", "hdr"):
        (folder / "env_scene.toml").write_text(ENV_TOML.format(env=f"env.{fmt}"))
    return folder / SCENE[fmt]


def write_outside(folder: Path) -> None:
    """The folder a scene must never read: copies of every seed's files with SECRET appended
    (still loadable: a reader that follows a reference there succeeds silently, so only the
    worker's watch on this folder can tell), and a plain secret file."""
    folder.mkdir(parents=True, exist_ok=True)
    for fmt in FORMATS:
        write_seed(fmt, folder)
    for f in list(folder.iterdir()):
        if f.is_file():
            f.write_bytes(f.read_bytes() + b"\n" + SECRET + b"\n")
    (folder / "secret.txt").write_bytes(SECRET + b" password line\n" + SECRET + b" key line\n")


# -- mutations ----------------------------------------------------------------------------------------------
def _deep():
    out: list = []
    for _ in range(DEEP_LEVELS):
        out = [out]
    return out


def _nodes(doc, path=()):
    """Every node of a parsed JSON/TOML document (its path), in a fixed order (not below depth 40:
    an earlier op may have nested it 20000 deep)."""
    out = [path] if path else []
    if len(path) > 40:
        return out
    if isinstance(doc, dict):
        for k in doc:
            out.extend(_nodes(doc[k], path + (k,)))
    elif isinstance(doc, list):
        for i, v in enumerate(doc):
            out.extend(_nodes(v, path + (i,)))
    return out


def _parent(doc, path):
    for key in path[:-1]:
        doc = doc[key]
    return doc


def mutate_tree(doc, op):
    """Apply a "set" / "delete" op to a parsed document (in place); True if it changed it."""
    nodes = _nodes(doc)
    if not nodes:
        return False
    path = nodes[op[2] % len(nodes)]
    parent = _parent(doc, path)
    if op[0] == "delete":
        del parent[path[-1]]
    else:
        parent[path[-1]] = _deep() if op[3] == "DEEP" else op[3]
    return True


def _set_at(doc, path, value) -> bool:
    try:
        parent = _parent(doc, path)
        if value == "__delete__":
            del parent[path[-1]]
        else:
            parent[path[-1]] = value
        return True
    except (KeyError, IndexError, TypeError):
        return False


def _ref_string(kind: str, case: Path, original: str, outside: Path) -> str:
    """A hostile reference replacing `original` (a name inside the case folder); may create the
    symlink, folder or FIFO it names."""
    name = Path(original).name or "x"
    target = outside / name if (outside / name).exists() else outside / "secret.txt"
    rel_up = os.path.relpath(target, case)
    if kind == "parent":
        return rel_up
    if kind == "secret":                    # a file that is not what the reference expects at all
        return os.path.relpath(outside / "secret.txt", case)
    if kind == "absolute":
        return str(target)
    if kind == "percent":
        return "".join(f"%{ord(c):02X}" if c in "./" else c for c in rel_up)
    if kind == "dotdot_inside":
        return f"sub/../{rel_up}"
    if kind == "symlink":
        link = case / f"link_{name}"
        if not link.exists():
            link.symlink_to(target)
        return link.name
    if kind == "symlink_dir":
        link = case / "linkdir"
        if not link.exists():
            link.symlink_to(outside, target_is_directory=True)
        return f"linkdir/{target.name}"
    if kind == "long":
        return "d/" * 2100 + name
    if kind == "nul":
        return name + "\u0000.txt"
    if kind == "missing":
        return "missing_" + name
    if kind == "empty":
        return ""
    if kind == "dir":
        (case / "adir").mkdir(exist_ok=True)
        return "adir"
    if kind == "fifo":
        fifo = case / ("fifo" + Path(name).suffix)
        if not fifo.exists():
            os.mkfifo(fifo)
        return fifo.name
    if kind == "dev_zero":
        return "/dev/zero"
    if kind == "backslash":
        return rel_up.replace("/", "\\")
    if kind == "url":
        return "http://127.0.0.1:9/" + name
    if kind == "file_url":
        return "file://" + str(target)
    raise ValueError(kind)


def _gltf_refs(doc):
    out = []
    for key in ("buffers", "images"):
        items = doc.get(key) if isinstance(doc, dict) else None
        for item in items if isinstance(items, list) else ():
            if isinstance(item, dict) and isinstance(item.get("uri"), str):
                out.append(item)
    return out


def _set_ref_json(doc, op, case, outside) -> bool:
    refs = _gltf_refs(doc)
    if not refs:
        return False
    item = refs[op[2] % len(refs)]
    item["uri"] = _ref_string(op[3], case, item["uri"], outside)
    return True


_OBJ_REF = re.compile(r"^(\s*(?:mtllib|map_\w+|bump|disp|norm)\s+(?:-\S+\s+[-\d.\s]*?)*)(\S.*?)\s*$")


def _toml_dump(doc: dict) -> str:
    """TOML for a parsed scene document (inline tables and arrays only; enough for tomllib)."""
    def value(v):
        if isinstance(v, bool):
            return "true" if v else "false"
        if isinstance(v, int):
            return str(v)
        if isinstance(v, float):
            return "nan" if math.isnan(v) else ("inf" if v > 0 else "-inf") if math.isinf(v) else repr(v)
        if isinstance(v, str):
            return json.dumps(v)
        if isinstance(v, list):
            if _max_depth(v) >= 500:
                return _flat_dump(v)
            return "[" + ", ".join(value(x) for x in v) + "]"
        if isinstance(v, dict):
            return "{" + ", ".join(f"{json.dumps(str(k))} = {value(x)}" for k, x in v.items()) + "}"
        return '"null"'                         # TOML has no null: a string in its place
    return "".join(f"{json.dumps(str(k))} = {value(v)}\n" for k, v in doc.items())


def apply(fmt: str, case: Path, ops: list, outside: Path) -> None:
    """Apply `ops` to the case folder's files in order; an op that cannot apply (a structured op
    on a file an earlier op made unparseable) does nothing."""
    for op in ops:
        file = case / op[1]
        if not file.is_file():
            continue
        data = file.read_bytes()
        kind = op[0]
        pos = lambda frac: min(int(len(data) * frac), len(data))      # noqa: E731
        if kind == "truncate":
            data = data[:pos(op[2])]
        elif kind == "flip":
            b = bytearray(data)
            for frac, bit in op[2]:
                if b:
                    b[min(pos(frac), len(b) - 1)] ^= 1 << (bit % 8)
            data = bytes(b)
        elif kind == "overwrite":
            p, new = pos(op[2]), bytes.fromhex(op[3])
            data = data[:p] + new + data[p + len(new):]
        elif kind == "insert":
            p = pos(op[2])
            data = data[:p] + bytes.fromhex(op[3]) + data[p:]
        elif kind in ("set", "delete", "ref", "at") and file.suffix in (".gltf", ".glb", ".toml"):
            glb = split_glb(data) if file.suffix == ".glb" else None
            try:
                if file.suffix == ".glb":
                    if glb is None:
                        continue
                    doc, blob = glb
                elif file.suffix == ".toml":
                    import tomllib
                    doc = tomllib.loads(data.decode("utf-8"))
                else:
                    doc = json.loads(data)
            except (ValueError, RecursionError):
                continue
            if kind == "at":
                changed = _set_at(doc, op[2], op[3])
            elif kind == "ref":
                changed = (_set_ref_toml(doc, op, case, outside) if file.suffix == ".toml"
                           else _set_ref_json(doc, op, case, outside))
            else:
                changed = mutate_tree(doc, op)
            if not changed:
                continue
            if file.suffix == ".glb":
                data = glb_bytes(doc, blob)
            elif file.suffix == ".toml":
                data = _toml_dump(doc).encode("utf-8", "surrogatepass")
            else:
                data = _json_dump(doc).encode("utf-8", "surrogatepass")
        elif kind in ("line", "ref") and file.suffix in (".obj", ".mtl"):
            lines = data.decode("utf-8", "replace").split("\n")
            if kind == "ref":
                hits = [i for i, line in enumerate(lines) if _OBJ_REF.match(line)]
                if not hits:
                    continue
                i = hits[op[2] % len(hits)]
                m = _OBJ_REF.match(lines[i])
                lines[i] = m.group(1) + _ref_string(op[3], case, m.group(2), outside)
            else:
                i = op[2] % len(lines)
                if op[3] == "drop":
                    del lines[i]
                elif op[3] == "dup":
                    lines.insert(i, lines[i])
                else:
                    words = lines[i].split()
                    if len(words) > 1:
                        words[1 + op[4][0] % (len(words) - 1)] = op[4][1]
                        lines[i] = " ".join(words)
            data = "\n".join(lines).encode("utf-8", "surrogatepass")
        elif kind == "png_size" and data[:8] == b"\x89PNG\r\n\x1a\n" and data[12:16] == b"IHDR":
            ihdr = struct.pack(">II", op[2], op[3]) + data[24:29]
            data = data[:16] + ihdr + struct.pack(">I", zlib.crc32(b"IHDR" + ihdr)) + data[33:]
        elif kind == "exr_window":
            at = data.find(b"dataWindow\0box2i\0")
            if at < 0:
                continue
            at += len(b"dataWindow\0box2i\0") + 4
            data = data[:at] + struct.pack("<4i", *op[2]) + data[at + 16:]
        elif kind == "hdr_size":
            m = re.search(rb"\n\n(-Y [^\n]*)\n", data)
            if not m:
                continue
            data = data[:m.start(1)] + op[2].encode("latin-1") + data[m.end(1):]
        elif kind == "glb_length" and data[:4] == b"glTF" and len(data) >= 20:
            at = {"total": 8, "json": 12, "bin": None}[op[2]]
            if at is None:
                jlen = struct.unpack_from("<I", data, 12)[0]
                at = 20 + jlen
                if at + 4 > len(data):
                    continue
            data = data[:at] + struct.pack("<I", op[3] % 2 ** 32) + data[at + 4:]
        else:
            continue
        file.write_bytes(data)


def _json_dump(doc) -> str:
    # the deep nesting value: json.dumps recurses, so write it by hand
    text = json.dumps(doc, default=str, check_circular=False) if _max_depth(doc) < 500 else _flat_dump(doc)
    return text


def _max_depth(v, d=0):
    while isinstance(v, list) and len(v) == 1 and isinstance(v[0], list):
        v, d = v[0], d + 1
    if isinstance(v, dict):
        return max((_max_depth(x, d + 1) for x in v.values()), default=d)
    if isinstance(v, list):
        return max((_max_depth(x, d + 1) for x in v), default=d)
    return d


def _flat_dump(v) -> str:
    """json.dumps without recursion limits for the one-element nested lists _deep() makes."""
    if isinstance(v, list) and len(v) == 1 and isinstance(v[0], list):
        n = 0
        while isinstance(v, list) and len(v) == 1 and isinstance(v[0], list):
            v, n = v[0], n + 1
        return "[" * n + _flat_dump(v) + "]" * n
    if isinstance(v, dict):
        return "{" + ", ".join(f"{json.dumps(str(k))}: {_flat_dump(x)}" for k, x in v.items()) + "}"
    if isinstance(v, list):
        return "[" + ", ".join(_flat_dump(x) for x in v) + "]"
    return json.dumps(v)


def _set_ref_toml(doc, op, case, outside) -> bool:
    refs = []
    for entry in doc.get("mesh", []) if isinstance(doc.get("mesh"), list) else ():
        if isinstance(entry, dict) and isinstance(entry.get("path"), str):
            refs.append(entry)
    env = doc.get("environment")
    if isinstance(env, dict) and isinstance(env.get("source"), str):
        refs.append(env)
    if not refs:
        return False
    item = refs[op[2] % len(refs)]
    key = "path" if "path" in item else "source"
    item[key] = _ref_string(op[3], case, item[key], outside)
    return True


def fresh_case(fmt: str, seeds: Path, case: Path) -> Path:
    """Copy `fmt`'s seed folder to `case` (emptied first); returns the file to load."""
    if case.exists() or case.is_symlink():
        shutil.rmtree(case)
    shutil.copytree(seeds / fmt, case, symlinks=True)
    return case / SCENE[fmt]
