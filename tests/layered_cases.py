"""Scenes for the surface-layer tests (tests/test_surface_layers.py, bench/materials.py): a grid of
spheres, one material each, sweeping one extension's parameter, with analytic tangents (the
anisotropy direction's frame) and what the NumPy reference needs per pixel from a Frame."""
from __future__ import annotations

import numpy as np

from clrender.scene.camera import Camera
from clrender.scene.material import Material
from clrender.scene.model import Scene
from reference.geometry import uv_sphere

COLS, ROWS = 4, 2
SPACING = 2.3
CAMERA = Camera.look_at((0.0, 0.0, 8.6), (0.0, 0.0, 0.0), fov_y_deg=30.0, near=1.0, far=30.0)
SUN_DIRECTION = (-0.4, -0.6, -0.69)        # the direction the light travels
BASE = dict(base_color=(0.8, 0.35, 0.2, 1.0), metallic=0.0, roughness=0.5)

# One sweep per layer: (name, list of Material keyword sets over BASE), at most COLS x ROWS.
SWEEPS = {
    "specular": [dict(ior=i) for i in (1.0, 1.33, 1.5, 2.4)] + [
        dict(specular_factor=0.3), dict(specular_color=(2.0, 0.5, 1.0)), dict(ior=0.0, specular_color=(0.9, 0.6, 0.2)),
        dict(metallic=1.0, ior=2.0, specular_factor=0.5)],
    "clearcoat": [dict(clearcoat=c, clearcoat_roughness=r) for c in (0.25, 1.0) for r in (0.0, 0.2, 0.5, 1.0)],
    "sheen": [dict(sheen_color=c, sheen_roughness=r) for c in ((1.0, 1.0, 1.0), (0.2, 0.6, 1.0))
              for r in (0.1, 0.3, 0.6, 1.0)],
    "iridescence": [dict(iridescence=f, iridescence_thickness_max=t) for f in (0.5, 1.0) for t in (150.0, 300.0, 450.0, 700.0)],
    "anisotropy": [dict(anisotropy_strength=s, anisotropy_rotation=a, roughness=0.6) for a in (0.0, 1.1)
                   for s in (0.2, 0.5, 0.8, 1.0)],
    "diffuse_transmission": [dict(diffuse_transmission=t) for t in (0.25, 0.5, 0.75, 1.0)] + [
        dict(diffuse_transmission=t, diffuse_transmission_color=(1.0, 0.2, 0.1)) for t in (0.5, 1.0)] + [
        dict(diffuse_transmission=0.6, metallic=0.5), dict(diffuse_transmission=0.8, roughness=0.2)],
}


def sphere_tangents(p: np.ndarray, center) -> np.ndarray:
    """(V, 4) unit tangents along increasing longitude of a uv_sphere about `center` (handedness +1);
    at the poles any horizontal direction."""
    d = np.asarray(p, np.float64) - np.asarray(center)
    t = np.stack([-d[:, 2], np.zeros(len(d)), d[:, 0]], 1)
    n = np.linalg.norm(t, axis=1, keepdims=True)
    t = np.where(n > 1e-6, t / np.maximum(n, 1e-12), [1.0, 0.0, 0.0])
    return np.concatenate([t, np.ones((len(d), 1))], 1).astype(np.float32)


def centers(count: int) -> list:
    out = []
    for k in range(count):
        col, row = k % COLS, k // COLS
        out.append(((col - (COLS - 1) / 2) * SPACING, ((ROWS - 1) / 2 - row) * SPACING, 0.0))
    return out


def sphere_grid(materials: list, lat: int = 32, lon: int = 64) -> Scene:
    """One sphere per material on a COLS x ROWS grid facing the camera."""
    parts, tangents = [], []
    for k, c in enumerate(centers(len(materials))):
        p, f, n = uv_sphere(lat, lon, radius=1.0, center=c)
        parts.append((p, f, n, k))
        tangents.append(sphere_tangents(p, c))
    offsets = np.cumsum([0] + [len(p) for p, *_ in parts])
    positions = np.concatenate([p for p, *_ in parts]).astype(np.float32)
    normals = np.concatenate([n for _, _, n, _ in parts]).astype(np.float32)
    faces = np.concatenate([f + o for (_, f, _, _), o in zip(parts, offsets)]).astype(np.int32)
    mats = np.concatenate([np.full(len(f), k) for _, f, _, k in parts]).astype(np.int32)
    scene = Scene(positions, normals, np.zeros((len(positions), 2), np.float32), faces, mats, list(materials))
    scene.tangents = np.concatenate(tangents)
    scene.ambient = 0.0
    return scene


def layer_materials(layer: str) -> list:
    out = []
    for k, kw in enumerate(SWEEPS[layer]):
        args = {**BASE, **kw}
        out.append(Material(f"{layer}{k}", **args))
    return out


def frame_inputs(frame) -> dict:
    """Per foreground pixel (flattened, mask order), what the reference needs from the frame:
    normal, position, view vector (unit, towards the eye), material index, base colour / metallic /
    roughness (the G-buffer's quantized values: the test's tolerance covers the difference)."""
    fg = frame.triangle_id >= 0
    eye = np.asarray(CAMERA.eye, np.float64)
    p = frame.position[fg].astype(np.float64)
    v = eye - p
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    n = frame.normal[fg].astype(np.float64)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    return {"mask": fg, "normal": n, "position": p, "view": v, "material": frame.material_id[fg].astype(np.int64)}


def psnr(got: np.ndarray, ref: np.ndarray) -> float:
    """PSNR in dB of linear colours against the reference's peak (max over the compared pixels)."""
    mse = float(np.mean((np.asarray(got, np.float64) - ref) ** 2))
    peak = float(np.max(ref))
    return float("inf") if mse == 0 else 10.0 * np.log10(peak * peak / mse)
