"""Small procedural meshes shared by the tests."""
import numpy as np


def uv_sphere(n_lat=24, n_lon=48, radius=1.0, center=(0, 0, -4)):
    """(positions, faces, normals); counter-clockwise seen from outside, so normals point out."""
    lat = np.linspace(0, np.pi, n_lat + 1)
    lon = np.linspace(0, 2 * np.pi, n_lon + 1)
    la, lo = np.meshgrid(lat, lon, indexing="ij")
    normals = np.stack([np.sin(la) * np.cos(lo), np.cos(la), np.sin(la) * np.sin(lo)], -1).reshape(-1, 3)
    positions = normals * radius + np.asarray(center)
    idx = np.arange((n_lat + 1) * (n_lon + 1)).reshape(n_lat + 1, n_lon + 1)
    a, b, c, d = idx[:-1, :-1], idx[:-1, 1:], idx[1:, :-1], idx[1:, 1:]
    faces = np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3), np.stack([b, d, c], -1).reshape(-1, 3)])
    return positions.astype(np.float32), faces, normals.astype(np.float32)
