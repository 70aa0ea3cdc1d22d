"""Writes scenes/worm.gltf: a small skinned and morphing creature of our own making (CC0), the bundled
test and demo asset for skins, morph targets and animated weights.

A tube along +X (24 rings x 16 sides) skinned to a chain of 4 joints (two influences per vertex,
linear falloff between neighbouring joints), one morph target that swells the body ("breath"),
vertex colour stripes, an animation that wiggles the joints sideways (LINEAR rotations about +Y), slides the root (STEP would jump: LINEAR
translation) and breathes (CUBICSPLINE weights) over 2 s, a ground plane, a camera and a shadowing sun (KHR_lights_punctual).

    python scenes/make_worm.py          # rewrites scenes/worm.gltf (deterministic)
"""
from __future__ import annotations

import base64
import json
from pathlib import Path

import numpy as np

RINGS, SIDES, LENGTH, RADIUS, JOINTS = 24, 16, 4.0, 0.35, 4
DURATION, KEYS = 2.0, 9


def quat_y(angle: float) -> list:
    return [0.0, float(np.sin(angle / 2)), 0.0, float(np.cos(angle / 2))]


def tube():
    xs = np.linspace(0, LENGTH, RINGS)
    radius = RADIUS * np.maximum(np.sin(np.pi * xs / LENGTH) ** 0.4, 0.02)       # closed (nearly) at both ends
    a = np.linspace(0, 2 * np.pi, SIDES, endpoint=False)
    ring = np.stack([np.zeros_like(a), np.cos(a), np.sin(a)], 1)
    pos = np.concatenate([[x, 0, 0] + r * ring for x, r in zip(xs, radius)]).astype(np.float32)
    nrm = np.tile(ring, (RINGS, 1)).astype(np.float32)
    tris = []
    for i in range(RINGS - 1):
        for j in range(SIDES):
            a0, a1 = i * SIDES + j, i * SIDES + (j + 1) % SIDES
            b0, b1 = a0 + SIDES, a1 + SIDES
            tris += [(a0, b1, b0), (a0, a1, b1)]         # outward, counter-clockwise
    # influences: the two joints around x, linear falloff
    seg = LENGTH / (JOINTS - 1)
    f = np.clip(pos[:, 0] / seg, 0, JOINTS - 1 - 1e-6)
    j0 = np.floor(f).astype(np.uint8)
    t = (f - j0).astype(np.float32)
    joints = np.stack([j0, j0 + 1, np.zeros_like(j0), np.zeros_like(j0)], 1).astype(np.uint8)
    weights = np.stack([1 - t, t, np.zeros_like(t), np.zeros_like(t)], 1).astype(np.float32)
    swell = (0.25 * nrm * np.sin(np.pi * pos[:, :1] / LENGTH)).astype(np.float32)
    band = (np.arange(RINGS * SIDES) // SIDES) % 4 < 2                     # stripes: the wiggle shows
    colors = np.where(band[:, None], [1.0, 1.0, 1.0, 1.0], [0.55, 0.6, 0.35, 1.0]).astype(np.float32)
    return pos, nrm, np.array(tris, np.uint16), joints, weights, swell, colors


def write(path: Path) -> Path:
    pos, nrm, tris, joints, weights, swell, colors = tube()
    blob, views, accessors = bytearray(), [], []

    def add(a, kind, target=None, minmax=False):
        a = np.ascontiguousarray(a)
        blob.extend(b"\0" * (-len(blob) % 4))
        views.append({"buffer": 0, "byteOffset": len(blob), "byteLength": a.nbytes, **({"target": target} if target else {})})
        blob.extend(a.tobytes())
        comp = {np.dtype(np.float32): 5126, np.dtype(np.uint16): 5123, np.dtype(np.uint8): 5121}[a.dtype]
        acc = {"bufferView": len(views) - 1, "componentType": comp, "count": len(a), "type": kind}
        if minmax:
            acc["min"], acc["max"] = a.min(0).tolist(), a.max(0).tolist()
        accessors.append(acc)
        return len(accessors) - 1

    seg = LENGTH / (JOINTS - 1)
    ibm = np.stack([np.linalg.inv(np.array([[1, 0, 0, j * seg], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]))
                    for j in range(JOINTS)]).transpose(0, 2, 1).reshape(-1, 16).astype(np.float32)
    body = {"attributes": {"POSITION": add(pos, "VEC3", 34962, True), "NORMAL": add(nrm, "VEC3", 34962),
                           "JOINTS_0": add(joints, "VEC4", 34962), "WEIGHTS_0": add(weights, "VEC4", 34962),
                           "COLOR_0": add(colors, "VEC4", 34962)},
            "indices": add(tris.reshape(-1), "SCALAR", 34963), "material": 0,
            "targets": [{"POSITION": add(swell, "VEC3", 34962, True)}]}
    ground_pos = np.array([[-3, -0.36, -3], [7, -0.36, -3], [7, -0.36, 3], [-3, -0.36, 3]], np.float32)
    ground = {"attributes": {"POSITION": add(ground_pos, "VEC3", 34962, True),
                             "NORMAL": add(np.tile(np.float32([0, 1, 0]), (4, 1)), "VEC3", 34962)},
              "indices": add(np.array([0, 2, 1, 0, 3, 2], np.uint16), "SCALAR", 34963), "material": 1}
    times = np.linspace(0, DURATION, KEYS).astype(np.float32)
    phase = 2 * np.pi * times / DURATION
    samplers, channels = [], []

    def animate(node, path, values, interpolation="LINEAR"):
        samplers.append({"input": add(times, "SCALAR"), "output": add(np.asarray(values, np.float32),
                         "SCALAR" if path == "weights" else ("VEC4" if path == "rotation" else "VEC3")),
                         "interpolation": interpolation})
        channels.append({"sampler": len(samplers) - 1, "target": {"node": node, "path": path}})

    for j in range(1, JOINTS):
        animate(2 + j, "rotation", [quat_y(0.6 * np.sin(p - 1.1 * j)) for p in phase])
    animate(2, "translation", [[0.25 * np.sin(p), 0, 0] for p in phase])
    # CUBICSPLINE weights: (in-tangent, value, out-tangent) per key, one target
    breath = np.stack([np.zeros(KEYS), 0.5 + 0.5 * np.sin(2 * phase), np.zeros(KEYS)], 1).reshape(-1)
    animate(1, "weights", breath.reshape(-1, 1), "CUBICSPLINE")
    nodes = [{"name": "camera", "camera": 0, "translation": [2.0, 2.4, 4.4],
              "rotation": [-0.2588, 0.0, 0.0, 0.9659]},
             {"name": "worm", "mesh": 0, "skin": 0},
             {"name": "root", "translation": [0.0, 0.0, 0.0], "children": [3]}]
    for j in range(1, JOINTS):       # joint j (node 2 + j) sits seg further along x than its parent
        nodes.append({"name": f"joint{j}", "translation": [seg, 0, 0],
                      **({"children": [3 + j]} if j < JOINTS - 1 else {})})
    nodes.append({"name": "ground", "mesh": 1})
    nodes.append({"name": "sun", "rotation": [-0.3535, 0.3535, 0.1464, 0.8536],
                  "extensions": {"KHR_lights_punctual": {"light": 0}}})
    doc = {"asset": {"version": "2.0", "generator": "clrender scenes/make_worm.py", "copyright": "CC0"},
           "scene": 0, "scenes": [{"nodes": [0, 1, 2, len(nodes) - 2, len(nodes) - 1]}], "nodes": nodes,
           "cameras": [{"type": "perspective", "perspective": {"yfov": 0.75, "znear": 0.1, "zfar": 50.0}}],
           "meshes": [{"name": "worm", "primitives": [body], "weights": [0.0]},
                      {"name": "ground", "primitives": [ground]}],
           "materials": [{"name": "skin", "pbrMetallicRoughness": {"baseColorFactor": [0.45, 0.75, 0.3, 1.0],
                                                                   "metallicFactor": 0.0, "roughnessFactor": 0.45}},
                         {"name": "ground", "pbrMetallicRoughness": {"baseColorFactor": [0.8, 0.78, 0.74, 1.0],
                                                                     "metallicFactor": 0.0, "roughnessFactor": 0.9}}],
           "skins": [{"name": "spine", "joints": [2] + [2 + j for j in range(1, JOINTS)],
                      "inverseBindMatrices": add(ibm, "MAT4")}],
           "animations": [{"name": "wiggle", "samplers": samplers, "channels": channels}],
           "extensionsUsed": ["KHR_lights_punctual"],
           "extensions": {"KHR_lights_punctual": {"lights": [{"type": "directional", "intensity": 2.5,
                                                              "color": [1.0, 0.95, 0.85]}]}}}
    doc["accessors"], doc["bufferViews"] = accessors, views
    doc["buffers"] = [{"byteLength": len(blob),
                       "uri": "data:application/octet-stream;base64," + base64.b64encode(bytes(blob)).decode()}]
    path.write_text(json.dumps(doc, separators=(",", ":")))
    return path


if __name__ == "__main__":
    print(write(Path(__file__).resolve().parent / "worm.gltf"))
