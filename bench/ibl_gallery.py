"""glTF assets under HDR environments, next to the old look: the picture of the glTF BRDF
and of image-based lighting in docs/shading.md.

    python -m bench.ibl_gallery [--size 320] [--device NAME]

Rows: DamagedHelmet, MetalRoughSpheresNoTextures, Crytek Sponza, the bundled demo. Columns: the
old look (shading="blinn_phong", the constant ambient, the file's own lights), the default look
(`load_scene`: the built-in studio environment for files without lights), and two CC0 HDRIs of
../shared/environments (never copied into the repository). Writes docs/images/gltf-ibl.png and
prints each render()'s wall time.
"""
from __future__ import annotations

import argparse
import sys
import time

import numpy as np

from bench.common import HELMET_CAMERA, REPO, SHARED_SCENES, SPONZA, SPONZA_CAMERA, require_scene

ENVIRONMENTS = REPO.parent / "shared" / "environments"
ROWS = (("DamagedHelmet", SHARED_SCENES / "khronos-DamagedHelmet" / "DamagedHelmet.gltf", HELMET_CAMERA),
        ("MetalRoughSpheres", SHARED_SCENES / "khronos-MetalRoughSpheresNoTextures" /
         "MetalRoughSpheresNoTextures.gltf", None),
        ("Sponza", SPONZA, SPONZA_CAMERA),
        ("demo", REPO / "scenes" / "demo.gltf", None))
COLUMNS = ("before: Blinn-Phong, constant ambient", "default: glTF BRDF + studio", "courtyard.exr", "sunset.exr")


def label(image: np.ndarray, text: str) -> np.ndarray:
    try:
        from PIL import Image, ImageDraw
    except ImportError:
        return image
    im = Image.fromarray(image)
    draw = ImageDraw.Draw(im)
    draw.rectangle((0, 0, im.width, 14), fill=(0, 0, 0))
    draw.text((4, 1), text, fill=(255, 255, 255))
    return np.asarray(im)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--size", type=int, default=320, help="cell width (height = width · 9/16)")
    ap.add_argument("--device", default=None)
    ap.add_argument("--out", default=str(REPO / "docs" / "images" / "gltf-ibl.png"))
    args = ap.parse_args(argv)
    import imageio.v3 as iio

    import clrender
    from clrender.scene.environment import load_environment
    w, h = args.size, args.size * 9 // 16
    old = clrender.Renderer(w, h, device=args.device, shading="blinn_phong")
    new = clrender.Renderer(w, h, device=args.device)
    envs = [load_environment(require_scene(ENVIRONMENTS / n)) for n in ("courtyard.exr", "sunset.exr")]
    rows = []
    for name, path, cam in ROWS:
        scene = clrender.load_scene(require_scene(path))
        camera = clrender.Camera.look_at(**cam) if cam else scene.default_camera()
        default_env = scene.environment
        cells = []
        for col, title in enumerate(COLUMNS):
            if col == 0:
                scene.environment, renderer = None, old
            elif col == 1:
                scene.environment, renderer = default_env or load_environment("studio"), new
            else:
                scene.environment, renderer = envs[col - 2], new
            t0 = time.perf_counter()
            frame = renderer.render(scene, camera)
            image = frame.image
            print(f"{name:<18} {title:<40} {(time.perf_counter() - t0) * 1e3:8.0f} ms")
            cells.append(label(image, f"{name}: {title}" if col == 0 else title))
        rows.append(np.concatenate(cells, 1))
    sheet = np.concatenate(rows, 0)
    iio.imwrite(args.out, sheet)
    print(f"wrote {args.out} ({sheet.shape[1]}x{sheet.shape[0]})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
