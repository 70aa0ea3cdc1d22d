"""KHR_lights_punctual: the lights of the default scene's nodes into a Scene (the rules are in
clrender/loaders/gltf/assemble.py's module doc, which calls `add_lights` after the geometry)."""
from __future__ import annotations

import warnings

import numpy as np

from clrender.abi import structs
from clrender.scene.model import Scene, SceneError
from clrender.loaders.gltf.document import Document
from clrender.loaders.gltf.validate import node_light, punctual_lights
from clrender.scene.lights import (
    AUTO_RADIUS_KEY, DIRECTIONAL_KEY, auto_radius, scene_diagonal, sun_from_directional, warn_directional)

# KHR_lights_punctual allows outerConeAngle = pi/2; Scene.add_spot_light needs < 90 degrees
MAX_SPOT_OUTER_DEG = 89.9


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


def add_lights(doc: Document, order: list[int], scene: Scene) -> None:
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
