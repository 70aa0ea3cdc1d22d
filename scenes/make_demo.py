#!/usr/bin/env python3
"""Generate clrender's own small demo scene (everything here is procedural, no third-party data).

Writes, next to this script:
  demo.gltf + demo.bin        glTF 2.0: textured checker floor, three boxes under a parent node
                              (one non-uniformly scaled), a sphere, a single-sided torus, an
                              alpha-MASK leaf card without normals (second primitive: its post),
                              and a perspective camera
  checker.png, leaf_mask.png  the procedural textures the glTF references
  crate.obj + crate.mtl       a textured crate (quads, v/vt/vn, two materials)
  crate.png
  demo.toml                   places both, sets a camera, render size, ambient, three point lights,
                              one spot light and 64 random small colored point lights

Run:  python scenes/make_demo.py   (deterministic; the files are small, < 100 KB in all)
The functions here are also used by tests/test_loaders.py to know what the files must contain.
"""
from __future__ import annotations

import json
import math
import struct
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent


# -- procedural textures (sRGB-encoded RGBA8, row 0 at the top) -----------------------------------
def checker_texture(size: int = 64, cells: int = 8) -> np.ndarray:
    y, x = np.mgrid[0:size, 0:size]
    cell = size // cells
    odd = ((x // cell) + (y // cell)) % 2 == 1
    img = np.empty((size, size, 4), np.uint8)
    img[...] = (200, 200, 196, 255)
    img[odd] = (70, 72, 80, 255)
    # a red marker in the top-left cell and a green one in the top-right cell: shows orientation
    img[:cell, :cell] = (220, 40, 30, 255)
    img[:cell, -cell:] = (40, 180, 60, 255)
    return img


def leaf_texture(size: int = 64) -> np.ndarray:
    """A leaf-shaped cut-out: alpha 255 inside the leaf, 0 outside (for alphaMode MASK)."""
    v, u = (np.mgrid[0:size, 0:size] + 0.5) / size          # v down, u right, both in (0, 1)
    # leaf outline: |u - 0.5| < half-width(v), pointed at both ends, stem at the bottom
    half = 0.42 * np.sin(np.pi * np.clip((v - 0.04) / 0.82, 0, 1)) ** 0.8
    inside = np.abs(u - 0.5) < half
    stem = (np.abs(u - 0.5) < 0.03) & (v > 0.8)
    vein = (np.abs(u - 0.5) < 0.012) | (np.abs(np.abs(u - 0.5) - 0.6 * (0.86 - v) % 0.16) < 0.01)
    img = np.zeros((size, size, 4), np.uint8)
    img[..., 0] = 40 + (70 * v).astype(np.uint8)
    img[..., 1] = 120 + (90 * (1 - v)).astype(np.uint8)
    img[..., 2] = 30
    img[vein & inside] = (170, 210, 90, 0)
    img[stem] = (90, 70, 30, 0)
    img[..., 3] = np.where(inside | stem, 255, 0)
    return img


def crate_texture(size: int = 32) -> np.ndarray:
    y, x = np.mgrid[0:size, 0:size]
    img = np.empty((size, size, 4), np.uint8)
    plank = (y // 8) % 2
    img[...] = (150, 105, 55, 255)
    img[plank == 1] = (125, 85, 45, 255)
    border = (x < 3) | (x >= size - 3) | (y < 3) | (y >= size - 3)
    img[border] = (90, 60, 30, 255)
    diagonal = np.abs(x - y) < 2
    img[diagonal & ~border] = (105, 70, 35, 255)
    return img


# -- geometry (positions, normals, uvs in the glTF convention, uint16 triangle indices) ------------
def floor_mesh(half: float = 10.0, repeats: float = 10.0):
    p = np.array([[-half, 0, -half], [-half, 0, half], [half, 0, half], [half, 0, -half]], np.float32)
    n = np.tile(np.array([0, 1, 0], np.float32), (4, 1))
    uv = np.array([[0, 0], [0, repeats], [repeats, repeats], [repeats, 0]], np.float32)
    idx = np.array([0, 1, 2, 0, 2, 3], np.uint16)
    return p, n, uv, idx


def box_mesh(size=(1.0, 1.0, 1.0)):
    sx, sy, sz = (s / 2 for s in size)
    faces = [  # normal, u axis, v axis (v axis points down the image)
        ((1, 0, 0), (0, 0, -1), (0, -1, 0)), ((-1, 0, 0), (0, 0, 1), (0, -1, 0)),
        ((0, 1, 0), (1, 0, 0), (0, 0, 1)), ((0, -1, 0), (1, 0, 0), (0, 0, -1)),
        ((0, 0, 1), (1, 0, 0), (0, -1, 0)), ((0, 0, -1), (-1, 0, 0), (0, -1, 0)),
    ]
    p, n, uv, idx = [], [], [], []
    for k, (normal, ua, va) in enumerate(faces):
        normal, ua, va = (np.array(a, np.float64) for a in (normal, ua, va))
        for du, dv in ((-1, -1), (-1, 1), (1, 1), (1, -1)):
            q = normal + du * ua + dv * va
            p.append(q * (sx, sy, sz))
            n.append(normal)
            uv.append(((du + 1) / 2, (dv + 1) / 2))
        b = 4 * k
        idx += [b, b + 1, b + 2, b, b + 2, b + 3]
    return (np.array(p, np.float32), np.array(n, np.float32), np.array(uv, np.float32),
            np.array(idx, np.uint16))


def sphere_mesh(radius: float = 1.0, nu: int = 32, nv: int = 16):
    v, u = np.mgrid[0:nv + 1, 0:nu + 1]
    theta, phi = np.pi * v / nv, 2 * np.pi * u / nu
    n = np.stack([np.sin(theta) * np.cos(phi), np.cos(theta), -np.sin(theta) * np.sin(phi)], -1).reshape(-1, 3)
    uv = np.stack([u / nu, v / nv], -1).reshape(-1, 2)
    idx = []
    for i in range(nv):
        for j in range(nu):
            a, b = i * (nu + 1) + j, (i + 1) * (nu + 1) + j
            if i > 0:
                idx += [a, b, a + 1]
            if i < nv - 1:
                idx += [a + 1, b, b + 1]
    return (radius * n).astype(np.float32), n.astype(np.float32), uv.astype(np.float32), np.array(idx, np.uint16)


def torus_mesh(major: float = 0.8, minor: float = 0.3, nu: int = 40, nv: int = 16):
    v, u = np.mgrid[0:nv + 1, 0:nu + 1]
    a, b = 2 * np.pi * u / nu, 2 * np.pi * v / nv
    center = np.stack([np.cos(a), np.zeros_like(a), -np.sin(a)], -1)
    n = np.stack([np.cos(b) * np.cos(a), np.sin(b), -np.cos(b) * np.sin(a)], -1)
    p = major * center + minor * n
    uv = np.stack([u / nu, v / nv], -1)
    idx = []
    for i in range(nv):
        for j in range(nu):
            k0, k1 = i * (nu + 1) + j, (i + 1) * (nu + 1) + j
            idx += [k0, k0 + 1, k1, k1, k0 + 1, k1 + 1]
    return (p.reshape(-1, 3).astype(np.float32), n.reshape(-1, 3).astype(np.float32),
            uv.reshape(-1, 2).astype(np.float32), np.array(idx, np.uint16))


def card_mesh(width: float = 1.6, height: float = 1.6):
    """A vertical quad facing +Z, bottom edge at y = 0 (no normals: the loader computes them)."""
    w = width / 2
    p = np.array([[-w, height, 0], [-w, 0, 0], [w, 0, 0], [w, height, 0]], np.float32)
    uv = np.array([[0, 0], [0, 1], [1, 1], [1, 0]], np.float32)
    return p, None, uv, np.array([0, 1, 2, 0, 2, 3], np.uint16)


# -- glTF writing ---------------------------------------------------------------------------------------
def quat_axis_angle(axis, degrees) -> list[float]:
    axis = np.asarray(axis, np.float64) / np.linalg.norm(axis)
    h = math.radians(degrees) / 2
    return [*(axis * math.sin(h)).tolist(), math.cos(h)]


def quat_look_at(eye, target, up=(0, 1, 0)) -> list[float]:
    """Rotation of a glTF camera node (camera looks down its local -Z) at `eye` looking at `target`."""
    back = np.subtract(eye, target).astype(np.float64)
    back /= np.linalg.norm(back)
    right = np.cross(up, back)
    right /= np.linalg.norm(right)
    true_up = np.cross(back, right)
    m = np.stack([right, true_up, back], 1)
    w = math.sqrt(max(0.0, 1 + m[0, 0] + m[1, 1] + m[2, 2])) / 2
    x = math.copysign(math.sqrt(max(0.0, 1 + m[0, 0] - m[1, 1] - m[2, 2])) / 2, m[2, 1] - m[1, 2])
    y = math.copysign(math.sqrt(max(0.0, 1 - m[0, 0] + m[1, 1] - m[2, 2])) / 2, m[0, 2] - m[2, 0])
    z = math.copysign(math.sqrt(max(0.0, 1 - m[0, 0] - m[1, 1] + m[2, 2])) / 2, m[1, 0] - m[0, 1])
    return [x, y, z, w]


class GltfBuilder:
    def __init__(self):
        self.bin = bytearray()
        self.doc = {"asset": {"version": "2.0", "generator": "clrender scenes/make_demo.py"},
                    "buffers": [], "bufferViews": [], "accessors": [], "meshes": [], "nodes": [],
                    "materials": [], "textures": [], "images": [], "samplers": [], "cameras": [],
                    "scenes": [{"name": "demo", "nodes": []}], "scene": 0}

    def _view(self, data: bytes, target=None) -> int:
        self.bin += b"\0" * (-len(self.bin) % 4)
        view = {"buffer": 0, "byteOffset": len(self.bin), "byteLength": len(data)}
        if target:
            view["target"] = target
        self.bin += data
        self.doc["bufferViews"].append(view)
        return len(self.doc["bufferViews"]) - 1

    def accessor(self, array: np.ndarray, kind: str, bounds=False) -> int:
        array = np.ascontiguousarray(array)
        ctype = {np.dtype(np.float32): 5126, np.dtype(np.uint16): 5123, np.dtype(np.uint32): 5125}[array.dtype]
        target = 34963 if kind == "SCALAR" else 34962
        acc = {"bufferView": self._view(array.astype(array.dtype.newbyteorder("<")).tobytes(), target),
               "componentType": ctype, "count": int(len(array)), "type": kind}
        if bounds:
            acc["min"] = array.min(0).tolist()
            acc["max"] = array.max(0).tolist()
        self.doc["accessors"].append(acc)
        return len(self.doc["accessors"]) - 1

    def mesh(self, name: str, primitives) -> int:
        prims = []
        for (p, n, uv, idx), material in primitives:
            attrs = {"POSITION": self.accessor(p, "VEC3", bounds=True)}
            if n is not None:
                attrs["NORMAL"] = self.accessor(n, "VEC3")
            if uv is not None:
                attrs["TEXCOORD_0"] = self.accessor(uv, "VEC2")
            prims.append({"attributes": attrs, "indices": self.accessor(idx, "SCALAR"), "material": material})
        self.doc["meshes"].append({"name": name, "primitives": prims})
        return len(self.doc["meshes"]) - 1

    def texture(self, uri: str, wrap=10497) -> int:
        self.doc["images"].append({"uri": uri})
        self.doc["samplers"].append({"magFilter": 9729, "minFilter": 9987, "wrapS": wrap, "wrapT": wrap})
        self.doc["textures"].append({"source": len(self.doc["images"]) - 1,
                                     "sampler": len(self.doc["samplers"]) - 1})
        return len(self.doc["textures"]) - 1

    def material(self, **kw) -> int:
        self.doc["materials"].append(kw)
        return len(self.doc["materials"]) - 1

    def node(self, parent=None, **kw) -> int:
        self.doc["nodes"].append(kw)
        index = len(self.doc["nodes"]) - 1
        if parent is None:
            self.doc["scenes"][0]["nodes"].append(index)
        else:
            self.doc["nodes"][parent].setdefault("children", []).append(index)
        return index

    def finish(self, bin_uri: str) -> tuple[dict, bytes]:
        self.bin += b"\0" * (-len(self.bin) % 4)
        self.doc["buffers"] = [{"uri": bin_uri, "byteLength": len(self.bin)}]
        return self.doc, bytes(self.bin)


CAMERA_EYE, CAMERA_TARGET = (0.0, 4.0, 10.0), (0.0, 1.0, 0.0)


def build_demo() -> tuple[dict, bytes]:
    """The demo glTF document and its binary buffer (buffer uri 'demo.bin')."""
    g = GltfBuilder()
    checker = g.texture("checker.png", wrap=10497)
    leaf = g.texture("leaf_mask.png", wrap=33071)
    m_floor = g.material(name="FloorChecker", doubleSided=True, pbrMetallicRoughness={
        "baseColorTexture": {"index": checker}, "metallicFactor": 0.0, "roughnessFactor": 0.9})
    m_red = g.material(name="RedPlastic", doubleSided=True, pbrMetallicRoughness={
        "baseColorFactor": [0.8, 0.1, 0.08, 1.0], "metallicFactor": 0.0, "roughnessFactor": 0.4})
    m_blue = g.material(name="BlueMetal", doubleSided=True, pbrMetallicRoughness={
        "baseColorFactor": [0.2, 0.3, 0.9, 1.0], "metallicFactor": 1.0, "roughnessFactor": 0.3})
    # doubleSided omitted on purpose: the glTF default (false) makes the torus single-sided
    m_gold = g.material(name="GoldSingleSided", pbrMetallicRoughness={
        "baseColorFactor": [1.0, 0.766, 0.336, 1.0], "metallicFactor": 1.0, "roughnessFactor": 0.25})
    m_white = g.material(name="WhiteGloss", doubleSided=True, pbrMetallicRoughness={
        "baseColorFactor": [0.9, 0.9, 0.9, 1.0], "metallicFactor": 0.0, "roughnessFactor": 0.2})
    m_leaf = g.material(name="LeafMask", doubleSided=True, alphaMode="MASK", alphaCutoff=0.5,
                        pbrMetallicRoughness={"baseColorTexture": {"index": leaf},
                                              "metallicFactor": 0.0, "roughnessFactor": 0.7})

    floor = g.mesh("Floor", [(floor_mesh(), m_floor)])
    box = g.mesh("Box", [(box_mesh(), m_red)])
    box_blue = g.mesh("BlueBox", [(box_mesh(), m_blue)])
    sphere = g.mesh("Sphere", [(sphere_mesh(0.8), m_white)])
    torus = g.mesh("Torus", [(torus_mesh(), m_gold)])
    card = g.mesh("LeafCard", [(card_mesh(), m_leaf), (box_mesh((0.08, 0.5, 0.08)), m_red)])

    g.node(name="Floor", mesh=floor)
    boxes = g.node(name="Boxes", translation=[-3.0, 0.0, 0.0])
    g.node(boxes, name="BoxA", mesh=box, translation=[0.0, 0.5, 0.0])
    g.node(boxes, name="BoxTall", mesh=box, translation=[1.4, 0.75, 0.9], scale=[0.8, 1.5, 0.8],
           rotation=quat_axis_angle([0, 1, 0], 20))
    g.node(boxes, name="BoxBlue", mesh=box_blue, translation=[-0.4, 0.35, 2.0], scale=[0.7, 0.7, 0.7],
           rotation=quat_axis_angle([0, 1, 0], 45))
    g.node(name="Sphere", mesh=sphere, translation=[0.0, 0.8, 0.0])
    g.node(name="Torus", mesh=torus, translation=[3.0, 1.0, -0.5], rotation=quat_axis_angle([1, 0, 0], 60))
    leaf_node = g.node(name="Leaf", translation=[1.3, 0.0, -2.2])
    g.node(leaf_node, name="LeafCard", mesh=card, translation=[0.0, 0.25, 0.0])
    g.doc["cameras"].append({"name": "DemoCamera", "type": "perspective", "perspective": {
        "yfov": math.radians(50.0), "znear": 0.1, "zfar": 100.0, "aspectRatio": 16 / 9}})
    g.node(name="Camera", camera=0, translation=list(CAMERA_EYE),
           rotation=quat_look_at(CAMERA_EYE, CAMERA_TARGET))
    return g.finish("demo.bin")


def to_glb(doc: dict, bin_data: bytes, base: Path) -> bytes:
    """Pack a .gltf document into one GLB, embedding its external images as buffer views."""
    doc = json.loads(json.dumps(doc))
    data = bytearray(bin_data)
    for image in doc.get("images", []):
        if "uri" in image and not image["uri"].startswith("data:"):
            blob = (base / image.pop("uri")).read_bytes()
            data += b"\0" * (-len(data) % 4)
            doc["bufferViews"].append({"buffer": 0, "byteOffset": len(data), "byteLength": len(blob)})
            data += blob
            image["bufferView"] = len(doc["bufferViews"]) - 1
            image["mimeType"] = "image/png"
    data += b"\0" * (-len(data) % 4)
    doc["buffers"] = [{"byteLength": len(data)}]
    text = json.dumps(doc, separators=(",", ":")).encode()
    text += b" " * (-len(text) % 4)
    total = 12 + 8 + len(text) + 8 + len(data)
    return (struct.pack("<3I", 0x46546C67, 2, total) + struct.pack("<2I", len(text), 0x4E4F534A) + text
            + struct.pack("<2I", len(data), 0x004E4942) + bytes(data))


# -- OBJ --------------------------------------------------------------------------------------------------
CRATE_MTL = """\
# clrender demo crate (procedural)
newmtl crate
Kd 1.0 1.0 1.0
Ks 0.2 0.2 0.2
Ns 40
map_Kd crate.png

newmtl crate_top
Kd 0.55 0.38 0.2
Ks 0.05 0.05 0.05
Ns 8
"""


def crate_obj() -> str:
    """A 1 x 1 x 1 crate standing on y = 0: five textured sides (quads), then the untextured top."""
    lines = ["# clrender demo crate (procedural): OBJ uv convention, v up", "mtllib crate.mtl", "o crate"]
    corners = [(x, y, z) for x in (-0.5, 0.5) for y in (0.0, 1.0) for z in (-0.5, 0.5)]
    lines += [f"v {x:g} {y:g} {z:g}" for x, y, z in corners]
    lines += ["vt 0 0", "vt 1 0", "vt 1 1", "vt 0 1"]
    normals = [(1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1), (0, 0, -1)]
    lines += [f"vn {x} {y} {z}" for x, y, z in normals]

    def vid(x, y, z):
        return corners.index((x, y, z)) + 1

    sides = {  # counter-clockwise seen from outside, starting bottom-left of the face
        1: [(0.5, 0, 0.5), (0.5, 0, -0.5), (0.5, 1, -0.5), (0.5, 1, 0.5)],
        2: [(-0.5, 0, -0.5), (-0.5, 0, 0.5), (-0.5, 1, 0.5), (-0.5, 1, -0.5)],
        3: [(-0.5, 1, 0.5), (0.5, 1, 0.5), (0.5, 1, -0.5), (-0.5, 1, -0.5)],
        4: [(-0.5, 0, -0.5), (0.5, 0, -0.5), (0.5, 0, 0.5), (-0.5, 0, 0.5)],
        5: [(-0.5, 0, 0.5), (0.5, 0, 0.5), (0.5, 1, 0.5), (-0.5, 1, 0.5)],
        6: [(0.5, 0, -0.5), (-0.5, 0, -0.5), (-0.5, 1, -0.5), (0.5, 1, -0.5)],
    }
    lines.append("usemtl crate")
    for n in (5, 1, 6, 2, 4):
        lines.append("f " + " ".join(f"{vid(*c)}/{t + 1}/{n}" for t, c in enumerate(sides[n])))
    lines.append("usemtl crate_top")
    lines.append("f " + " ".join(f"{vid(*c)}/{t + 1}/3" for t, c in enumerate(sides[3])))
    return "\n".join(lines) + "\n"


DEMO_TOML = """\
# clrender demo scene: generated by scenes/make_demo.py (procedural content only)
ambient = 0.04

[[mesh]]
path = "demo.gltf"

[[mesh]]
path = "crate.obj"
transform = { translate = [2.6, 0.0, 2.4], rotate_deg = [0, 30, 0], scale = 0.8 }

[camera]
eye = [0.0, 4.0, 10.0]
target = [0.0, 1.0, 0.0]
up = [0.0, 1.0, 0.0]
fov_y_deg = 50
near = 0.1
far = 100

[render]
width = 960
height = 540

# warm light over the boxes
[[light]]
type = "point"
position = [-3.0, 2.2, 1.2]
color = [1.0, 0.72, 0.45]
intensity = 3.0
radius = 4.5

# cool light over the torus and the crate (`range` is a synonym of `radius`)
[[light]]
type = "point"
position = [3.0, 2.2, 1.0]
color = [0.45, 0.65, 1.0]
intensity = 3.0
range = 4.5

# magenta rim light behind the leaf
[[light]]
type = "point"
position = [0.5, 2.0, -3.5]
color = [1.0, 0.35, 0.8]
intensity = 2.5
radius = 4.0

# spot from above the camera onto the sphere
[[light]]
type = "spot"
position = [0.0, 6.0, 3.0]
direction = [0.0, -5.2, -3.0]
color = [1.0, 0.95, 0.85]
intensity = 6.0
radius = 10.0
inner_cone_deg = 10
outer_cone_deg = 18

[lights]
random = { count = 64, seed = 7, radius = [1.0, 2.0], intensity = 0.8 }
"""


def save_png(path: Path, rgba: np.ndarray) -> None:
    from PIL import Image

    Image.fromarray(rgba, "RGBA").save(path, optimize=True)


def main(out: Path = HERE) -> list[Path]:
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    save_png(out / "checker.png", checker_texture())
    save_png(out / "leaf_mask.png", leaf_texture())
    save_png(out / "crate.png", crate_texture())
    doc, data = build_demo()
    (out / "demo.gltf").write_text(json.dumps(doc, indent=1) + "\n")
    (out / "demo.bin").write_bytes(data)
    (out / "crate.obj").write_text(crate_obj())
    (out / "crate.mtl").write_text(CRATE_MTL)
    (out / "demo.toml").write_text(DEMO_TOML)
    return [out / n for n in ("demo.gltf", "demo.bin", "checker.png", "leaf_mask.png",
                              "crate.obj", "crate.mtl", "crate.png", "demo.toml")]


if __name__ == "__main__":
    for f in main():
        print(f"{f.relative_to(HERE.parent) if f.is_relative_to(HERE.parent) else f}: {f.stat().st_size} bytes")
