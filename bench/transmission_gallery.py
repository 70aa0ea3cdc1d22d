"""The see-through extensions next to the same scene without them: the pictures of docs/transmission.md
(issue 38, item 7).

    python -m bench.transmission_gallery [--width 320] [--height 240] [--subjects sphere slab prism leaf]
                                         [--transparency abuffer] [--device NAME]

One picture per subject, docs/images/transmission-<subject>.png: left the material with its extensions,
right the same material without them (the extension fields at their defaults: what clrender drew
before issue 38). Every subject stands on a checkerboard floor before a checkerboard wall (vertex
colours), under the studio HDRI of ../shared/environments (studio.exr; the built-in studio environment
when the file is absent, with a message) and a sun from behind the subject (no shadow maps: see
docs/transmission.md on shadows):

* sphere: a glass sphere (KHR_materials_transmission 1, _volume thickness = its diameter, IOR 1.5);
* slab: a thick green slab turned 30° (thickness = its real thickness, attenuation colour and distance);
* prism: a triangular prism with KHR_materials_dispersion 5 (exaggerated: real glass is 0.3–0.7);
* leaf: a thin leaf lit from behind (KHR_materials_diffuse_transmission 1, a yellow-green colour).

Prints each render()'s wall time.
"""
from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

from bench.common import REPO
from bench.transmission import uv_sphere

ENVIRONMENTS = REPO.parent / "shared" / "environments"
SUN_DIRECTION = (0.25, -0.55, 0.8)          # travelling towards the camera: the subjects are back-lit
SUN_COLOR = (3.0, 3.0, 3.0)
CAMERA = dict(eye=(0.0, 2.0, 5.0), target=(0.0, 0.95, 0.0), fov_y_deg=32.0, near=0.1, far=50.0)
CHECK = 0.5                                  # checker square (world units)
GLASS = dict(base_color=(1.0, 1.0, 1.0, 1.0), metallic=0.0, roughness=0.0, ior=1.5)
SUBJECTS = {
    "sphere": ("glass sphere\ntransmission 1, IOR 1.5\nvolume thickness 2 (diameter)",
               dict(GLASS, transmission=1.0, thickness=2.0)),
    "slab": ("thick slab, turned 30°\ntransmission 1, thickness 0.5\nattenuation (0.3, 0.85, 0.45), 0.25",
             dict(GLASS, transmission=1.0, thickness=0.5, attenuation_color=(0.3, 0.85, 0.45),
                  attenuation_distance=0.25)),
    "prism": ("prism\ntransmission 1, thickness 0.8\ndispersion 5 (exaggerated)",
              dict(GLASS, transmission=1.0, thickness=0.8, dispersion=5.0)),
    "leaf": ("back-lit leaf\ndiffuse transmission 1\ncolour (0.75, 0.9, 0.2)",
             dict(base_color=(0.2, 0.45, 0.08, 1.0), metallic=0.0, roughness=0.6, diffuse_transmission=1.0,
                  diffuse_transmission_color=(0.75, 0.9, 0.2))),
}
# the extension fields at their defaults: "without the extensions"
PLAIN = dict(transmission=0.0, thickness=0.0, attenuation_color=(1.0, 1.0, 1.0), attenuation_distance=math.inf,
             dispersion=0.0, diffuse_transmission=0.0, diffuse_transmission_color=(1.0, 1.0, 1.0))


def flat(vertices, faces):
    """(positions, normals, faces) with every triangle's own vertices and its face normal."""
    v = np.asarray(vertices, np.float64)[np.asarray(faces)].reshape(-1, 3)
    t = v.reshape(-1, 3, 3)
    n = np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    return v, np.repeat(n, 3, axis=0), np.arange(len(v)).reshape(-1, 3)


def turned(p, n, deg: float, about, axis: int = 1):
    """Positions and normals turned by deg about the axis through `about`."""
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    i, j = [a for a in range(3) if a != axis]
    rot = np.eye(3)
    rot[i, i], rot[i, j], rot[j, i], rot[j, j] = c, -s, s, c
    return (p - about) @ rot.T + about, n @ rot.T


def box(lo, hi):
    lo, hi = np.asarray(lo, np.float64), np.asarray(hi, np.float64)
    v = np.array([[(lo, hi)[(k >> a) & 1][a] for a in range(3)] for k in range(8)])
    faces = [(0, 2, 3), (0, 3, 1), (4, 5, 7), (4, 7, 6), (0, 1, 5), (0, 5, 4), (2, 6, 7), (2, 7, 3),
             (0, 4, 6), (0, 6, 2), (1, 3, 7), (1, 7, 5)]                        # outward, CCW from outside
    return flat(v, faces)


def prism(height: float, side: float, y0: float):
    """A vertical triangular prism, one edge towards the camera (+z)."""
    r = side / math.sqrt(3)
    tri = [(r * math.sin(a), r * math.cos(a)) for a in (0.0, 2 * math.pi / 3, 4 * math.pi / 3)]
    v = [(x, y0, z) for x, z in tri] + [(x, y0 + height, z) for x, z in tri]
    faces = [(0, 2, 1), (3, 4, 5)] + [f for k in range(3) for f in
                                      ((k, (k + 1) % 3, 3 + (k + 1) % 3), (k, 3 + (k + 1) % 3, 3 + k))]
    return flat(v, faces)


def leaf(length: float, width: float, center, rings: int = 12, segments: int = 32):
    """A thin curved leaf (a pointed ellipse bent backwards), facing +z, smooth normals."""
    cx, cy, cz = center
    pts, nrm = [], []
    for i in range(rings + 1):
        u = i / rings                                             # base (0) to tip (1)
        half = width / 2 * math.sin(math.pi * u) ** 0.8
        for j in range(segments + 1):
            w = (j / segments * 2 - 1) * half
            y = cy + (u - 0.5) * length
            z = cz - 0.35 * (w / (width / 2)) ** 2 - 0.15 * (u - 0.5) ** 2
            pts.append((cx + w, y, z))
    pts = np.array(pts)
    idx = np.arange(len(pts)).reshape(rings + 1, segments + 1)
    a, b, c, d = idx[:-1, :-1], idx[:-1, 1:], idx[1:, :-1], idx[1:, 1:]
    faces = np.concatenate([np.stack([a, b, d], -1).reshape(-1, 3), np.stack([a, d, c], -1).reshape(-1, 3)])
    tri = pts[faces]
    fn = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    nrm = np.zeros_like(pts)
    for k in range(3):
        np.add.at(nrm, faces[:, k], fn)
    ok = np.linalg.norm(nrm, axis=1) > 1e-12
    nrm[~ok] = (0.0, 0.0, 1.0)
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    return pts, nrm, faces


def checker_studio():
    """Floor (y = 0) and back wall (z = -3) of CHECK squares: (positions, normals, colours, faces)."""
    parts = []
    for kind, (nu, nv) in (("floor", (24, 18)), ("wall", (24, 14))):
        i, j = np.meshgrid(np.arange(nu), np.arange(nv), indexing="ij")
        i, j = i.ravel(), j.ravel()
        x0 = -nu / 2 * CHECK + i * CHECK
        if kind == "floor":       # x, z from the wall forwards; CCW from +y
            z0 = -3.0 + j * CHECK
            quad = [np.stack([x0 + dx, np.zeros_like(x0), z0 + dz], -1)
                    for dx, dz in ((0, 0), (0, CHECK), (CHECK, CHECK), (CHECK, 0))]
            n = (0.0, 1.0, 0.0)
        else:                     # x, y on z = -3; CCW from +z
            y0 = j * CHECK
            quad = [np.stack([x0 + dx, y0 + dy, np.full_like(x0, -3.0)], -1)
                    for dx, dy in ((0, 0), (CHECK, 0), (CHECK, CHECK), (0, CHECK))]
            n = (0.0, 0.0, 1.0)
        pos = np.stack(quad, 1).reshape(-1, 3)
        grey = np.where((i + j) % 2 == 0, 0.8, 0.12)
        col = np.repeat(np.stack([grey, grey, grey, np.ones_like(grey)], -1), 4, axis=0)
        base = 4 * np.arange(len(i))[:, None]
        parts.append((pos, np.tile(n, (len(pos), 1)), col, np.concatenate([base + (0, 1, 2), base + (0, 2, 3)],
                                                                          1).reshape(-1, 3)))
    return parts


def subject_mesh(name: str):
    if name == "sphere":
        return uv_sphere(48, 1.0, (0.0, 1.0, 0.0))
    if name == "slab":
        p, n, f = box((-1.1, 0.0, -0.25), (1.1, 1.9, 0.25))
        p, n = turned(p, n, 30.0, np.array([0.0, 0.0, 0.0]))
        return p, n, f
    if name == "prism":
        return prism(1.9, 1.6, 0.0)
    return leaf(2.0, 1.1, (0.0, 1.25, 0.0))


def build(name: str, with_extensions: bool, environment):
    from clrender.scene.material import Material
    from clrender.scene.model import Scene
    kw = SUBJECTS[name][1]
    if not with_extensions:
        kw = {**kw, **PLAIN}
    parts = [(p, n, c, f, 0) for p, n, c, f in checker_studio()]
    p, n, f = subject_mesh(name)
    parts.append((p, n, np.ones((len(p), 4)), f, 1))
    offs = np.cumsum([0] + [len(x[0]) for x in parts])
    scene = Scene(np.concatenate([x[0] for x in parts]).astype(np.float32),
                  np.concatenate([x[1] for x in parts]).astype(np.float32),
                  np.zeros((int(offs[-1]), 2), np.float32),
                  np.concatenate([x[3] + o for x, o in zip(parts, offs)]).astype(np.int32),
                  np.concatenate([np.full(len(x[3]), x[4]) for x in parts]).astype(np.int32),
                  [Material("checker", metallic=0.0, roughness=0.85), Material(name, double_sided=True, **kw)],
                  colors=np.concatenate([x[2] for x in parts]).astype(np.float32))
    scene.ambient = 0.0
    scene.environment = environment
    scene.set_sun(SUN_DIRECTION, SUN_COLOR, shadow=False)
    return scene


def caption(image: np.ndarray, text: str) -> np.ndarray:
    """Lines of text on a dark box at the top left (the panel stays unlabelled without Pillow)."""
    try:
        from PIL import Image, ImageDraw, ImageFont
    except ImportError:
        return image
    im = Image.fromarray(image)
    d = ImageDraw.Draw(im)
    try:
        font = ImageFont.load_default(size=max(10, im.height // 22))
    except TypeError:                            # Pillow < 10.1: the fixed bitmap font
        font = ImageFont.load_default()
    box = d.multiline_textbbox((6, 4), text, font=font, spacing=1)
    d.rectangle((2, 2, box[2] + 4, box[3] + 4), fill=(0, 0, 0))
    d.multiline_text((6, 4), text, fill=(255, 255, 255), font=font, spacing=1)
    return np.asarray(im)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--width", type=int, default=320, help="panel width")
    ap.add_argument("--height", type=int, default=240, help="panel height")
    ap.add_argument("--subjects", nargs="+", choices=tuple(SUBJECTS), default=list(SUBJECTS))
    ap.add_argument("--transparency", default="abuffer", choices=("abuffer", "depth_peeling", "screen_door"))
    ap.add_argument("--hdri", default="studio.exr", help="file in ../shared/environments")
    ap.add_argument("--device", default=None)
    ap.add_argument("--out", default=str(REPO / "docs" / "images"))
    args = ap.parse_args(argv)
    import imageio.v3 as iio

    import clrender
    from clrender.scene.environment import load_environment
    hdri = ENVIRONMENTS / args.hdri
    if hdri.is_file():
        env, env_name = load_environment(hdri), args.hdri
    else:
        print(f"HDRI {hdri} not found (the CC0 environments live in ../shared/environments next to the "
              f"repository): the built-in studio environment instead")
        env, env_name = load_environment("studio"), "built-in studio"
    renderer = clrender.Renderer(args.width, args.height, device=args.device, transparency=args.transparency)
    camera = clrender.Camera.look_at(**CAMERA)
    for name in args.subjects:
        panels = []
        for ext in (True, False):
            scene = build(name, ext, env)
            t0 = time.perf_counter()
            frame = renderer.render(scene, camera)
            print(f"{name:<8} {'with' if ext else 'without':<8} extensions: render() "
                  f"{(time.perf_counter() - t0) * 1e3:7.0f} ms")
            text = SUBJECTS[name][0] if ext else "the same material\nwithout the extensions"
            panels.append(caption(np.ascontiguousarray(frame.image[..., :3]), text))
        rule = np.full((args.height, 2, 3), 90, np.uint8)
        sheet = np.concatenate([panels[0], rule, panels[1]], 1)
        path = Path(args.out) / f"transmission-{name}.png"
        iio.imwrite(path, sheet, optimize=True)
        print(f"wrote {path} ({sheet.shape[1]}x{sheet.shape[0]}, {path.stat().st_size / 1024:.0f} KB; {env_name} + sun)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
