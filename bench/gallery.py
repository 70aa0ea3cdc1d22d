"""The Khronos sample models of docs/materials.md rendered by clrender: the picture in docs/materials.md.

    python -m bench.gallery [--size 384] [--device NAME]

DamagedHelmet (metallic-roughness, normal, occlusion and emissive textures), NormalTangentTest
(normal maps against geometry), MetalRoughSpheresNoTextures (the metallic × roughness grid) and
VertexColorTest (COLOR_0), each lit by a sun and two point lights placed from its bounds,
with bloom so the emission glows. Writes docs/images/khronos-materials.png and prints each
render()'s wall time.
"""
from __future__ import annotations

import argparse
import sys
import time

import numpy as np

from bench.common import HELMET_CAMERA, REPO, SHARED_SCENES, require_scene

MODELS = ("khronos-DamagedHelmet/DamagedHelmet.gltf", "khronos-NormalTangentTest/NormalTangentTest.gltf",
          "khronos-MetalRoughSpheresNoTextures/MetalRoughSpheresNoTextures.gltf",
          "khronos-VertexColorTest/VertexColorTest.gltf")


def light_rig(scene, camera) -> None:
    """A sun over the viewer's left shoulder and two point lights (warm key, cool fill) sized to the model."""
    lo, hi = scene.bounds().astype(np.float64)
    center, radius = (lo + hi) / 2, float(np.linalg.norm(hi - lo)) / 2
    eye = np.asarray(camera.eye, np.float64)
    forward = (center - eye) / np.linalg.norm(center - eye)
    right = np.cross(forward, camera.up)
    right /= np.linalg.norm(right)
    up = np.cross(right, forward)
    scene.set_sun(forward - 0.6 * up + 0.5 * right, (1.6, 1.55, 1.5), shadow=False)
    scene.add_point_light(center - forward * radius * 1.2 - right * radius + up * radius, (2.0, 1.7, 1.3),
                          radius * 4)
    scene.add_point_light(center - forward * radius * 1.2 + right * radius * 1.5, (0.5, 0.7, 1.0), radius * 4)
    scene.ambient = 0.15


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--size", type=int, default=384)
    ap.add_argument("--device", default=None)
    args = ap.parse_args(argv)
    import imageio.v3 as iio

    import clrender
    renderer = clrender.Renderer(args.size, args.size, device=args.device, bloom=True, bloom_threshold=1.0,
                                 edge_aa=True)
    tiles = []
    for rel in MODELS:
        scene = clrender.load_scene(require_scene(SHARED_SCENES / rel))
        camera = (clrender.Camera.look_at(**HELMET_CAMERA) if "Helmet" in rel else scene.default_camera())
        light_rig(scene, camera)
        renderer.render(scene, camera)                       # warm-up: programs, upload
        t0 = time.perf_counter()
        frame = renderer.render(scene, camera)
        print(f"{rel.split('/')[-1]:<36} {scene.triangle_count:>7,} triangles  render() {1e3 * (time.perf_counter() - t0):7.1f} ms")
        tiles.append(frame.image)
    out = REPO / "docs" / "images" / "khronos-materials.png"
    iio.imwrite(out, np.concatenate(tiles, 1))
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
