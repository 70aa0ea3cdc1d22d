"""Picking: what a rendered Frame shows at one pixel, read from its id buffers (NumPy only).

    p = pick(frame, scene, x, y)       # a Pick, or None on background
    text = pick_markdown(p)            # the viewer's panel text
    shown = highlight(frame.image, frame.object_id == p.object_id)

The surface at a pixel is the nearest one, `Frame.surface_triangle`: the nearest transparent
(BLEND or transmissive) fragment where one lies in front of the opaque surface (then `transparent`
is True), else the opaque surface (`Frame.triangle_id`). Object and material are that triangle's
(`Frame.object_id`, `Frame.material_id`); position and depth are `Frame.position` and `Frame.depth`
(z-depth along the optical axis), which for a BLEND fragment are the opaque surface's behind it
(the G-buffer keeps only the opaque surface; a transmissive surface has its own depth): NaN and
+inf where only the background lies behind it.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Optional

import numpy as np

if TYPE_CHECKING:
    from clrender.render.frame import Frame
    from clrender.scene.model import Scene

# highlight(): inside the mask each channel becomes (image + TINT) // 2; the pixels outside the
# mask that touch it (8-neighbourhood) become OUTLINE
TINT = (255, 170, 0)
OUTLINE = (255, 255, 0)


@dataclass(frozen=True)
class Pick:
    """What pixel (x, y) of a frame shows (module doc)."""
    x: int
    y: int
    object_id: int                  # index into scene.objects
    object_name: str
    object_path: str
    material_id: int                # index into scene.materials
    material_name: str
    mesh: str                       # scene.mesh_names entry of the triangle
    triangle: int                   # index into scene.triangles (Frame.surface_triangle)
    face: int                       # the face's index inside `mesh`
    position: tuple[float, float, float]   # world space
    depth: float                    # z-depth along the camera's optical axis
    transparent: bool               # the nearest surface is a transparent fragment


def _index(value, name: str) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise ValueError(f"pick: {name} must be an integer pixel index, got {value!r}")
    return int(value)


def pick(frame: "Frame", scene: "Scene", x: int, y: int) -> Optional[Pick]:
    """The surface at pixel (x, y) (column, row from the top-left) of `frame`, rendered from `scene`;
    None on background. A pixel outside the frame, or ids the scene does not have (a frame of
    another scene), is a ValueError."""
    x, y = _index(x, "x"), _index(y, "y")
    if not (0 <= x < frame.width and 0 <= y < frame.height):
        raise ValueError(f"pick: pixel ({x}, {y}) is outside the {frame.width}x{frame.height} frame")
    triangle = int(frame.surface_triangle[y, x])
    if triangle < 0:
        return None
    object_id, material_id = int(frame.object_id[y, x]), int(frame.material_id[y, x])
    if not (triangle < scene.triangle_count and 0 <= object_id < len(scene.objects)
            and 0 <= material_id < len(scene.materials)):
        raise ValueError(f"pick: pixel ({x}, {y}) shows triangle {triangle}, object {object_id}, material "
                         f"{material_id}, which {scene.source} does not have (a frame of another scene?)")
    obj = scene.objects[object_id]
    mesh, face = scene.triangle_source(triangle)
    return Pick(x, y, object_id, obj.name, obj.path, material_id, scene.materials[material_id].name, mesh,
                triangle, face, tuple(float(v) for v in frame.position[y, x]), float(frame.depth[y, x]),
                triangle != int(frame.triangle_id[y, x]))


_MARKDOWN_SPECIAL = set("\\`*_[]<>|~")     # what changes text inside a line (each field has a prefix)


def _text(s: str) -> str:
    """`s` with Markdown's special characters escaped, so a name shows as written."""
    return "".join("\\" + c if c in _MARKDOWN_SPECIAL else c for c in str(s))


def pick_markdown(p: Optional[Pick]) -> str:
    """The viewer's panel text for a pick: a Markdown list; "background" for None."""
    if p is None:
        return "background"
    xyz = ", ".join(f"{v:.6g}" for v in p.position)
    lines = [f"**{_text(p.object_name)}** (object {p.object_id}) at pixel ({p.x}, {p.y})", "",
             f"- path: {_text(p.object_path)}",
             f"- material: {_text(p.material_name)} (material {p.material_id})",
             f"- mesh: {_text(p.mesh)}, face {p.face} (triangle {p.triangle})"]
    if np.isfinite(p.depth):
        lines += [f"- position: ({xyz})", f"- depth: {p.depth:.6g}"]
    else:           # a BLEND surface over the background: no depth in the G-buffer
        lines.append("- position, depth: none (background behind the transparent surface)")
    if p.transparent:
        lines.append("- transparent: the nearest surface is a transparent fragment (a BLEND one's position and "
                     "depth are the opaque surface's behind it)")
    return "\n".join(lines)


def highlight(image: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """A new (H, W, 3) uint8 image: `image` with the pixels of `mask` ((H, W) bool) tinted, each
    channel (image + TINT) // 2, and a 1-pixel outline of OUTLINE on the pixels outside the mask
    that touch it (8-neighbourhood; none beyond the image's border)."""
    image, mask = np.asarray(image), np.asarray(mask)
    if image.dtype != np.uint8 or image.ndim != 3 or image.shape[2] != 3:
        raise ValueError(f"highlight: image must be (H, W, 3) uint8, got {image.shape} {image.dtype}")
    if mask.dtype != bool or mask.shape != image.shape[:2]:
        raise ValueError(f"highlight: mask must be (H, W) bool of the image's size {image.shape[:2]}, "
                         f"got {mask.shape} {mask.dtype}")
    out = image.copy()
    out[mask] = ((image[mask].astype(np.uint16) + np.array(TINT, np.uint16)) // 2).astype(np.uint8)
    h, w = mask.shape
    grown = np.zeros((h + 2, w + 2), bool)      # the mask dilated by one pixel (3x3), padded by one
    for dy in range(3):
        for dx in range(3):
            grown[dy:dy + h, dx:dx + w] |= mask
    out[grown[1:-1, 1:-1] & ~mask] = OUTLINE
    return out
