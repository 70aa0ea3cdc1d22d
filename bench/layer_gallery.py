"""The glTF surface extensions' parameter sweeps on spheres, next to the plain base layer: the
pictures of docs/shading.md (issue 37, item 7).

    python -m bench.layer_gallery [--width 640] [--layers clearcoat sheen ...] [--hdri courtyard.exr]
                                  [--device NAME]

One picture per layer (tests/layered_cases.py's SWEEPS: specular/IOR, clearcoat, sheen, iridescence,
anisotropy), docs/images/layers-<layer>.png: the left sphere is the base material alone
(tests/layered_cases.py's BASE, no extension), the 2 x 4 others sweep the layer's parameters (each
labelled). Two bands: the built-in studio environment plus a sun, and one CC0 HDRI of
../shared/environments (never copied into the repository; the band is left out, with a message,
when the file is absent) plus the same sun. Prints each render()'s wall time.
"""
from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

from bench.common import REPO

sys.path.insert(0, str(REPO / "tests"))         # the sweep table and sphere helpers the tests use
from layered_cases import BASE, SUN_DIRECTION, SWEEPS, sphere_tangents  # noqa: E402
from reference.geometry import uv_sphere  # noqa: E402

ENVIRONMENTS = REPO.parent / "shared" / "environments"
SUN_COLOR = (3.0, 3.0, 3.0)
EXTENSION = {"specular": "KHR_materials_ior + KHR_materials_specular", "clearcoat": "KHR_materials_clearcoat",
             "sheen": "KHR_materials_sheen", "iridescence": "KHR_materials_iridescence",
             "anisotropy": "KHR_materials_anisotropy"}
# The base each picture's sweep is drawn over (tests/layered_cases.py's BASE, changed where that
# orange rough plastic hides the layer: a rough base under a glossy coat, dark velvet for sheen, a
# dark glossy film for iridescence, brushed metal for anisotropy). The base-layer sphere uses it too.
PICTURE_BASE = {"specular": dict(roughness=0.3), "clearcoat": dict(roughness=0.8),
                "sheen": dict(base_color=(0.08, 0.08, 0.1, 1.0), roughness=0.8),
                "iridescence": dict(base_color=(0.05, 0.05, 0.05, 1.0), roughness=0.2),
                "anisotropy": dict(base_color=(0.95, 0.95, 0.95, 1.0), metallic=1.0)}
# Layout (world units, spheres of radius 1 in the z = 0 plane): the base sphere left, centred
# between the sweep's two rows; room under each sphere for its label.
DX, DY, GAP = 2.45, 3.3, 0.5
FOV_Y = 20.0
# Label names (the picture's title names the extension).
SHORT = {"ior": "ior", "specular_factor": "specular", "specular_color": "spec. colour", "metallic": "metallic",
         "clearcoat": "clearcoat", "clearcoat_roughness": "roughness", "sheen_color": "colour",
         "sheen_roughness": "roughness", "iridescence": "factor", "iridescence_thickness_max": "thickness max",
         "anisotropy_strength": "strength", "anisotropy_rotation": "rotation (rad)", "roughness": "base roughness"}


def fmt(v) -> str:
    if isinstance(v, tuple):
        return "(" + ",".join(f"{x:g}" for x in v) + ")"
    return f"{v:g}"


def caption(kw: dict) -> str:
    """One line per parameter of a sweep entry."""
    lines = []
    for k, v in kw.items():
        if k == "iridescence_thickness_max":         # the sweep keeps the spec's default minimum
            lines.append(f"100-{v:g} nm")
        else:
            lines.append(f"{SHORT.get(k, k)} {fmt(v)}")
    return "\n".join(lines)


def centers(count: int) -> list:
    """Base sphere first (column 0, between the rows), then the sweep, 4 per row."""
    out = [(-2 * DX - GAP, 0.0, 0.0)]
    for k in range(count):
        out.append(((k % 4 - 1) * DX + GAP / 2, DY / 2 - (k // 4) * DY, 0.0))
    return out


def grid_scene(materials: list):
    """Spheres with analytic tangents (the anisotropy direction's frame), one material each."""
    from clrender.scene.model import Scene
    parts = [uv_sphere(32, 64, radius=1.0, center=c) for c in centers(len(materials) - 1)]
    offsets = np.cumsum([0] + [len(p) for p, _, _ in parts])
    scene = Scene(np.concatenate([p for p, _, _ in parts]).astype(np.float32),
                  np.concatenate([n for _, _, n in parts]).astype(np.float32),
                  np.zeros((int(offsets[-1]), 2), np.float32),
                  np.concatenate([f + o for (_, f, _), o in zip(parts, offsets)]).astype(np.int32),
                  np.concatenate([np.full(len(f), k) for k, (_, f, _) in enumerate(parts)]).astype(np.int32),
                  list(materials))
    scene.tangents = np.concatenate([sphere_tangents(p, c) for (p, _, _), c in zip(parts, centers(len(parts) - 1))])
    scene.ambient = 0.0
    scene.set_sun(SUN_DIRECTION, SUN_COLOR, shadow=False)
    return scene


def camera_for(width: int, height: int):
    """A camera on +z framing every sphere and its label, and the pinhole projection of a point."""
    from clrender.scene.camera import Camera
    cs = centers(8)
    half_w = (max(c[0] for c in cs) - min(c[0] for c in cs)) / 2 + 1.3
    below, above = 1.3, 0.4                     # room for the labels under the spheres, the title above
    cy = (above - below) / 2
    half_h = DY / 2 + 1.0 + (above + below) / 2
    t = math.tan(math.radians(FOV_Y) / 2)
    dist = max(half_h / t, half_w / (t * width / height))
    cx = (min(c[0] for c in cs) + max(c[0] for c in cs)) / 2
    cam = Camera.look_at((cx, cy, dist), (cx, cy, 0.0), fov_y_deg=FOV_Y, near=1.0, far=dist + 10)

    def project(p):
        z = dist - p[2]
        return (width / 2 + (p[0] - cx) / (z * t) * height / 2, height / 2 - (p[1] - cy) / (z * t) * height / 2)
    return cam, project


def draw_labels(image: np.ndarray, texts: list, project, title: str, subtitle: str) -> np.ndarray:
    try:
        from PIL import Image, ImageDraw, ImageFont
    except ImportError:                          # the labels are listed in docs/shading.md too
        return image
    im = Image.fromarray(image)
    d = ImageDraw.Draw(im)
    size = max(10, im.height // 24)
    try:
        font = ImageFont.load_default(size=size)
    except TypeError:                            # Pillow < 10.1: the fixed bitmap font
        font = ImageFont.load_default()
    for text, c in zip(texts, centers(len(texts) - 1)):
        x, y = project((c[0], c[1] - 1.08, 0.0))
        d.multiline_text((x, y), text, fill=(235, 235, 235), font=font, anchor="ma", align="center", spacing=1)
    d.text((6, 4), title, fill=(255, 255, 255), font=font)
    d.multiline_text((6, 8 + size), subtitle, fill=(190, 190, 190), font=font, spacing=1)
    return np.asarray(im)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--width", type=int, default=720, help="picture width (each band's height = width / 2)")
    ap.add_argument("--layers", nargs="+", choices=tuple(SWEEPS), default=list(SWEEPS))
    ap.add_argument("--hdri", default="courtyard.exr", help="file in ../shared/environments")
    ap.add_argument("--device", default=None)
    ap.add_argument("--out", default=str(REPO / "docs" / "images"))
    args = ap.parse_args(argv)
    import imageio.v3 as iio

    import clrender
    from clrender.scene.environment import load_environment
    from clrender.scene.material import Material
    w = args.width
    h = w // 4 * 2
    renderer = clrender.Renderer(w, h, device=args.device)
    camera, project = camera_for(w, h)
    bands = [("studio environment + sun", load_environment("studio", background=False))]
    hdri = ENVIRONMENTS / args.hdri
    if hdri.is_file():
        bands.append((f"{args.hdri} + sun", load_environment(hdri, background=False)))
    else:
        print(f"HDRI {hdri} not found (the CC0 environments live in ../shared/environments next to the "
              f"repository): its band is left out")
    for layer in args.layers:
        sweep = SWEEPS[layer]
        # parameters every entry of the sweep shares belong to its base (and the base-layer sphere)
        shared = {k: v for k, v in sweep[0].items() if all(kw.get(k, object()) == v for kw in sweep)}
        base = {**BASE, **PICTURE_BASE.get(layer, {}), **shared}
        materials = [Material("base", **base)] + [Material(f"{layer}{k}", **{**base, **kw})
                                                  for k, kw in enumerate(sweep)]
        texts = ["base layer"] + [caption({k: v for k, v in kw.items() if k not in shared}) for kw in sweep]
        about = "base:\n" + "\n".join(f"{k.replace('base_color', 'colour')} {fmt(v[:3] if k == 'base_color' else v)}"
                                        for k, v in base.items())
        scene = grid_scene(materials)
        images = []
        for name, env in bands:
            scene.environment = env
            t0 = time.perf_counter()
            frame = renderer.render(scene, camera)
            image = frame.image[..., :3]
            print(f"{layer:<12} {name:<32} render() {(time.perf_counter() - t0) * 1e3:7.0f} ms")
            images.append(draw_labels(np.ascontiguousarray(image), texts, project, f"{EXTENSION[layer]}: {name}",
                                      about))
        rule = np.full((2, w, 3), 90, np.uint8)           # a grey line between the bands
        sheet = np.concatenate([x for im in images for x in (rule, im)][1:], 0)
        path = f"{args.out}/layers-{layer}.png"
        iio.imwrite(path, sheet, optimize=True)
        size = Path(path).stat().st_size
        print(f"wrote {path} ({w}x{sheet.shape[0]}, {size / 1024:.0f} KB)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
