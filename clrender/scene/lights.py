"""Light helpers shared by the glTF and TOML loaders.

Every punctual light the renderer draws has a finite radius of influence (`Scene.lights["radius"]`,
the attenuation reaches 0 there). A light that does not give one (glTF `range` absent, which the
KHR_lights_punctual spec calls infinite; TOML `[[light]]` without `radius`/`range`) gets

    radius = sqrt(256 * max(color * intensity))

i.e. the distance at which the inverse-square falloff `intensity / d^2` has dropped below 1/256 of
1 (one 8-bit step of a unit-exposure image), clamped to [1e-3, 4 x the scene's bounding-box
diagonal] (no upper clamp while the scene has no geometry). The rule is stated for an
inverse-square falloff whatever falloff the shading kernel applies inside the radius; it only
decides where a light with no range is cut off. Such lights are listed in
`Scene.settings["lights_auto_radius"]` (indices into `Scene.lights`) so that a loader combining
several files (TOML) can recompute the clamp against the final scene.

Directional lights (glTF `directional`, TOML `type = "directional"`) have no position and no radius:
they are not in `Scene.lights`; the loaders keep them all in `Scene.settings["directional_lights"]`
as ``{"direction": [x, y, z], "color": [r, g, b]}`` dicts, direction unit length in world space (the
way the light travels), color already multiplied by the intensity. The first one becomes the sun
(`Scene.sun`, shadowed, `sun_from_directional`) unless a TOML `[sun]` table gives one; the loaders
warn about the directional lights that are not rendered.
"""
from __future__ import annotations

import math
import warnings

import numpy as np

from clrender.abi import structs
from clrender.scene.model import Scene

AUTO_RADIUS_KEY = "lights_auto_radius"
DIRECTIONAL_KEY = "directional_lights"
AUTO_RADIUS_LEVELS = 256.0          # intensity / d^2 < 1 / 256 beyond the radius
MIN_RADIUS = 1e-3
MAX_RADIUS_DIAGONALS = 4.0

__all__ = ["AUTO_RADIUS_KEY", "DIRECTIONAL_KEY", "auto_radius", "scene_diagonal", "refresh_auto_radii",
           "transform_lights", "warn_directional", "sun_from_directional"]


def scene_diagonal(scene: Scene) -> float:
    """Length of the scene's bounding-box diagonal (0 without geometry)."""
    if scene.triangle_count == 0:
        return 0.0
    lo, hi = scene.bounds().astype(np.float64)
    return float(np.linalg.norm(hi - lo))


def auto_radius(color, diagonal: float) -> float:
    """Radius for a light of infinite range: sqrt(256 * max(color)), clamped (see the module doc).

    `color` is the light's color with the intensity already multiplied in.
    """
    peak = float(np.max(np.asarray(color, np.float64))) if np.size(color) else 0.0
    r = math.sqrt(max(peak, 0.0) * AUTO_RADIUS_LEVELS)
    upper = MAX_RADIUS_DIAGONALS * diagonal if diagonal > 0 else math.inf
    return float(min(max(r, MIN_RADIUS), max(upper, MIN_RADIUS)))


def refresh_auto_radii(scene: Scene) -> None:
    """Recompute the radius of every light listed in settings["lights_auto_radius"] for this scene."""
    indices = scene.settings.get(AUTO_RADIUS_KEY) or []
    if not indices:
        return
    diagonal = scene_diagonal(scene)
    for i in indices:
        scene.lights["radius"][i] = auto_radius(scene.lights["color"][i], diagonal)


def transform_lights(scene: Scene, matrix: np.ndarray) -> None:
    """Move the scene's lights (and its directional lights) by a 4x4 affine matrix, in place.

    Positions are transformed as points; spot and directional directions by the linear part and
    renormalized. Radii and cone angles are not scaled (KHR_lights_punctual: light properties
    are unaffected by node scale). A transform that collapses a direction raises ValueError.
    """
    m = np.asarray(matrix, np.float64)
    if len(scene.lights):
        lights = scene.lights.copy()
        pos = lights["position"].astype(np.float64)
        lights["position"] = pos @ m[:3, :3].T + m[:3, 3]
        spot = lights["type"] == structs.LIGHT_SPOT
        if spot.any():
            lights["direction"][spot] = _directions(m, lights["direction"][spot])
        scene.lights = lights
    directional = scene.settings.get(DIRECTIONAL_KEY)
    if directional:
        dirs = _directions(m, [d["direction"] for d in directional])
        scene.settings[DIRECTIONAL_KEY] = [dict(d, direction=v.tolist()) for d, v in zip(directional, dirs)]


def _directions(m: np.ndarray, directions) -> np.ndarray:
    d = np.asarray(directions, np.float64).reshape(-1, 3) @ m[:3, :3].T
    norm = np.linalg.norm(d, axis=1, keepdims=True)
    if not (np.isfinite(norm).all() and (norm > 0).all()):
        raise ValueError("the transform collapses a light direction to zero length")
    return d / norm


def sun_from_directional(scene: Scene) -> None:
    """The scene's first directional light (settings) becomes `Scene.sun`, shadowed."""
    from clrender.scene.model import Sun
    directional = scene.settings.get(DIRECTIONAL_KEY)
    if directional:
        scene.sun = Sun(directional[0]["direction"], directional[0]["color"])


def warn_directional(where, count: int, sun_given: bool = False, stacklevel: int = 3) -> None:
    """Warn about directional lights that are not rendered: all but the first (the sun), or
    all of them when the file gives the sun itself (a TOML [sun] table)."""
    unrendered = count if sun_given else count - 1
    if unrendered > 0:
        which = "the [sun] table is the sun" if sun_given else "the first is the sun (Scene.sun)"
        warnings.warn(f"{where}: {unrendered} of {count} directional light(s) not rendered ({which}); all are kept "
                      f"in Scene.settings[{DIRECTIONAL_KEY!r}]", stacklevel=stacklevel)
