"""Reading a glTF document's animations into the host model (clrender.scene.animation).

`from_document` turns the document's animation channels and samplers into an `Animation` (None for
a static file), `rig` gives the rest transforms of every node (for skins without animations) and
`bind` records which scene meshes, camera and KHR_lights_punctual lights hang from which node.
Sampling and posing are the model's (clrender.scene.animation); this module only reads and checks.
"""
from __future__ import annotations

from typing import Optional

import numpy as np

from clrender.scene.animation import INTERPOLATIONS, PATHS, Animation, Channel, Sampler, normalized_quaternions
from clrender.loaders.gltf.validate import node_light, punctual_lights


def _sampler(doc, a: int, s: int, sampler: dict, path: str, targets: int = 0) -> Sampler:
    what = f"animation {a} sampler {s}"
    interpolation = sampler.get("interpolation", "LINEAR")
    if interpolation not in INTERPOLATIONS:
        raise doc.err(f"{what}: unknown interpolation {interpolation!r} (expected one of {INTERPOLATIONS})")
    for key in ("input", "output"):
        doc.get("accessors", sampler.get(key), f"{what} {key}")
    times = doc.accessor(sampler["input"]).astype(np.float64).reshape(-1)
    values = doc.accessor(sampler["output"]).astype(np.float64)
    n = len(times)
    if n == 0:
        raise doc.err(f"{what}: no keyframes")
    if not np.isfinite(times).all() or (np.diff(times) <= 0).any():
        raise doc.err(f"{what}: input times must be finite and strictly increasing")
    if path == "weights":         # scalars, `targets` per key (per element of a CUBICSPLINE triplet)
        if values.ndim != 2 or values.shape[1] != 1 or targets < 1 or values.shape[0] % targets:
            raise doc.err(f"{what}: weights output must be scalars, a multiple of the {targets} morph targets, "
                          f"got shape {values.shape}")
        values = values.reshape(-1, targets)
    elif values.ndim != 2 or values.shape[1] != PATHS[path]:
        raise doc.err(f"{what}: {path} output must have {PATHS[path]} components, got shape {values.shape}")
    expected = 3 * n if interpolation == "CUBICSPLINE" else n
    if len(values) != expected or not np.isfinite(values).all():
        raise doc.err(f"{what}: output needs {expected} finite values for {n} {interpolation} keys, "
                      f"got {len(values)}")
    if path == "rotation" and interpolation != "CUBICSPLINE":
        values = normalized_quaternions(values)
    return Sampler(times, values, interpolation)


def from_document(doc, order: list, features: dict) -> Optional[Animation]:
    """The document's animation, or None when it has no usable channel. Ignored channels add an
    entry to `features` (warned once per file by the loader)."""
    animations = doc.list("animations")
    if not animations:
        return None
    nodes = doc.list("nodes")
    channels = []
    for a, anim in enumerate(animations):
        if not isinstance(anim, dict):
            raise doc.err(f"animations[{a}] must be an object")
        samplers = anim.get("samplers", [])
        for key in ("samplers", "channels"):
            if not isinstance(anim.get(key, []), list):
                raise doc.err(f"animations[{a}].{key} must be an array, got {type(anim[key]).__name__}")
        cache: dict = {}
        for c, ch in enumerate(anim.get("channels", [])):
            target = ch.get("target", {}) if isinstance(ch, dict) else {}
            if not isinstance(target, dict):
                raise doc.err(f"animation {a} channel {c}: target must be an object, got {type(target).__name__}")
            path, node = target.get("path"), target.get("node")
            if node is None:     # KHR_animation_pointer: already warned as an unsupported extension
                if not any("KHR_animation_pointer" in f for f in features):
                    features.setdefault(f"animation channels without a target node (path {path!r})", "ignored")
                continue
            if not isinstance(path, str) or (path not in PATHS and path != "weights"):
                raise doc.err(f"animation {a} channel {c}: unknown target path {path!r}")
            doc.get("nodes", node, f"animation {a} channel {c}")
            targets = 0
            if path == "weights":
                targets = morph_target_count(doc, nodes[node].get("mesh"))
                if not targets:
                    raise doc.err(f"animation {a} channel {c} animates the weights of node {node}, whose mesh "
                                  f"has no morph targets")
            elif "matrix" in nodes[node]:
                features.setdefault("animations of nodes given by a matrix", "ignored (the spec forbids them)")
                continue
            s = ch.get("sampler")
            if not isinstance(s, int) or isinstance(s, bool) or not 0 <= s < len(samplers):
                raise doc.err(f"animation {a} channel {c} references sampler {s!r}, which does not exist "
                              f"(there are {len(samplers)})")
            if (s, path) not in cache:
                cache[(s, path)] = _sampler(doc, a, s, samplers[s], path, targets)
            channels.append(Channel(int(node), path, cache[(s, path)]))
    return rig(doc, order, channels) if channels else None


def morph_target_count(doc, mesh) -> int:
    """Morph targets of glTF mesh `mesh` (its primitives' most; 0 without a mesh)."""
    if mesh is None:
        return 0
    return max((len(p.get("targets", [])) for p in doc.get("meshes", mesh, "node mesh").get("primitives", [])),
               default=0)


def full_order(doc, order: list) -> list:
    """Every node of the file, parents before children: the default scene's `order`, then the
    trees of the other root nodes (joints may sit outside the default scene)."""
    nodes = doc.list("nodes")
    seen, out = set(order), list(order)
    children = {c for node in nodes for c in node.get("children", [])}
    for root in range(len(nodes)):
        if root in seen or root in children:
            continue
        stack = [root]
        while stack:
            n = stack.pop()
            if n in seen:
                continue
            seen.add(n)
            out.append(n)
            stack.extend(reversed(nodes[n].get("children", [])))
    return out


def rig(doc, order: list, channels: Optional[list] = None) -> Animation:
    """An Animation over every node of the file (full_order) with `channels` (none: a rig that
    only gives rest transforms, for skins of a file without animations)."""
    nodes = doc.list("nodes")
    everything = full_order(doc, order)
    rest = {}
    for n in everything:
        node = nodes[n]
        if "matrix" in node:
            rest[n] = {"matrix": np.asarray(node["matrix"], np.float64).reshape(4, 4).T}
        else:
            rest[n] = {k: np.asarray(node[k], np.float64) for k in PATHS if k in node}
    parent = {c: n for n in everything for c in nodes[n].get("children", [])}
    return Animation(rest, parent, everything, list(channels or []), str(doc.path))


def bind(animation: Animation, doc, order: list, scene) -> None:
    """Drop meshes without triangles (nothing to pose); record the camera node (the loader's: the
    first usable camera in traversal order) and the KHR_lights_punctual nodes: point and spot lights are added to `scene.lights` from index
    len(scene.lights) in traversal order, directional ones to settings["directional_lights"]."""
    first_light = len(scene.lights)
    animation.meshes = [(m, n, inv) for m, n, inv in animation.meshes if (scene.triangle_mesh == m).any()]

    nodes = doc.list("nodes")
    cameras = doc.list("cameras")
    for n in order:
        if "camera" in nodes[n]:
            cam = cameras[nodes[n]["camera"]] if 0 <= nodes[n]["camera"] < len(cameras) else {}
            kind = cam.get("type")
            if kind in ("perspective", "orthographic") and kind in cam:
                animation.camera_node = n
                break
    lights = punctual_lights(doc)
    i = j = 0
    for n in order:
        k = node_light(doc, n, nodes[n])
        if k is None:
            continue
        if lights[k]["type"] == "directional":
            animation.directional_nodes.append((j, n))
            j += 1
        else:
            animation.light_nodes.append((first_light + i, n))
            i += 1
