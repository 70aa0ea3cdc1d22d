"""The test geometry of tests/test_gltf_compression.py and the fixtures in tests/data/compressed/.

`sheet()` is a wavy, textured 16 x 12 vertex grid whose positions are integers in [0, 2047] ("grid
units"; node 0 scales them by GRID_SCALE and moves the sheet in front of `CAMERA`): Draco with 11
quantization bits over the range 2047 (step exactly 1) and KHR_mesh_quantization's int16 store
them exactly, and positions decoded from a lossier encoder (gltf-transform's 14-bit quantization)
round back to the grid. No triangle is degenerate (Draco would drop it).

    python tests/compressed_files.py     # rewrite tests/data/compressed/ (needs node and npm)

writes original.gltf (+ .png) with `write_sheet` and runs gltf-transform (FIXTURE_COMMANDS) on it.
"""
from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from gltf_files import primitive, write_gltf  # noqa: E402

FIXTURES = HERE / "data" / "compressed"
GLTF_TRANSFORM = "@gltf-transform/cli@4.5.1"
# fixture -> gltf-transform arguments (input, output appended)
FIXTURE_COMMANDS = {
    "quantized.glb": ["quantize"],
    "draco.glb": ["draco"],                        # edgebreaker: reorders faces and vertices
    "meshopt.glb": ["meshopt"],                    # quantizes, reorders; OCTAHEDRAL filter on NORMAL
    "webp.glb": ["webp", "--lossless", "true"],    # EXT_texture_webp (required, no PNG left)
}
GRID_SCALE = 0.001
NODE = {"mesh": 0, "scale": [GRID_SCALE] * 3, "translation": [-1.0, -0.75, -4.0]}
CAMERA = dict(eye=(0.0, 0.0, -1.0), target=(0.0, 0.0, -4.0), fov_y_deg=40.0, near=0.5, far=10.0)
NX, NY = 16, 12


def sheet():
    """(positions float32 integral grid units, normals float32, uvs float32, indices uint16)."""
    x, y = np.meshgrid(np.linspace(0, 2000, NX), np.linspace(0, 1500, NY))
    z = 300 * np.sin(x / 400.0) * np.cos(y / 500.0) + 400
    positions = np.round(np.stack([x, y, z], -1).reshape(-1, 3)).astype(np.float32)
    # analytic normals of the (unrounded) surface, unit length
    dzdx = 300 / 400.0 * np.cos(x / 400.0) * np.cos(y / 500.0)
    dzdy = -300 / 500.0 * np.sin(x / 400.0) * np.sin(y / 500.0)
    normals = np.stack([-dzdx, -dzdy, np.ones_like(x)], -1).reshape(-1, 3)
    normals = (normals / np.linalg.norm(normals, axis=1, keepdims=True)).astype(np.float32)
    uvs = np.stack([x / 2000.0, 1.0 - y / 1500.0], -1).reshape(-1, 2).astype(np.float32)
    quads = []
    for j in range(NY - 1):
        for i in range(NX - 1):
            a, b, c, d = j * NX + i, j * NX + i + 1, (j + 1) * NX + i + 1, (j + 1) * NX + i
            quads += [a, b, c, a, c, d]
    return positions, normals, uvs, np.array(quads, np.uint16)


def texture(seed: int = 0) -> np.ndarray:
    """An 8 x 8 RGBA pattern (fixed seed)."""
    rgba = np.random.default_rng(seed).integers(0, 256, (8, 8, 4), dtype=np.uint8)
    rgba[..., 3] = 255
    return rgba


MATERIAL = {"name": "sheet", "pbrMetallicRoughness": {"baseColorTexture": {"index": 0}, "metallicFactor": 0.0}}


def write_sheet(path: Path) -> Path:
    """The uncompressed original: sheet() as float32 / uint16, its texture as a PNG beside it."""
    positions, normals, uvs, indices = sheet()
    return write_gltf(path, primitives=[primitive(positions, indices, material=0, normals=normals, uvs=uvs)],
                      materials=[MATERIAL], images=[texture()], nodes=[dict(NODE)])


def main() -> None:
    FIXTURES.mkdir(parents=True, exist_ok=True)
    original = write_sheet(FIXTURES / "original.gltf")
    npx = shutil.which("npx")
    if npx is None:
        sys.exit("npx (node) is needed to write the gltf-transform fixtures")
    for name, args in FIXTURE_COMMANDS.items():
        subprocess.run([npx, "--yes", GLTF_TRANSFORM, *args, str(original), str(FIXTURES / name)], check=True)


if __name__ == "__main__":
    main()
