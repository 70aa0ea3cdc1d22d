"""The camera's per-frame upload: its matrices into device buffers the passes read, and the scalar
camera values they take as arguments (Pipeline.render)."""
from __future__ import annotations

import numpy as np

from clrender.passes.base import zeros

MATRICES = ("view_proj", "prev_view_proj", "view_matrix", "camera_params")     # 16 floats each
VALUES = ("width", "height", "near", "far", "has_prev", "tan_x", "tan_y", "shift_x", "shift_y")


def camera_buffers(queue) -> dict:
    """The MATRICES' device buffers, allocated once per pipeline and rewritten every frame."""
    return {name: zeros(queue, 16, np.float32) for name in MATRICES}


def upload_camera(queue, matrices: dict, camera, width, height, prev_camera, ortho: bool) -> dict:
    """Upload the camera matrices; returns the scalar camera values (VALUES) passes read. tan_x,
    tan_y: the image's half-extents per unit depth (perspective) or in world units (orthographic:
    ymag·aspect, ymag), as the camera block's R·tan_x, U·tan_y; shift_x, shift_y: the principal
    point in NDC (Camera.principal_offset), also the camera block's eye.w and F.w."""
    if camera.is_orthographic != ortho:
        raise ValueError(f"this pipeline renders {'orthographic' if ortho else 'perspective'} cameras, "
                         f"got a {camera.projection} one (Renderer picks the pipeline)")
    vp = camera.raster_matrix(width, height)
    prev = prev_camera.view_projection(width, height) if prev_camera else camera.view_projection(width, height)
    tan_x, tan_y = (float(v) for v in camera.half_extents(width / height))
    shift_x, shift_y = camera.principal_offset()     # an off-centre principal point (Camera.from_opencv)
    right, up, back = camera.basis()
    params = np.zeros((4, 4))
    params[0, :3], params[1, :3], params[2, :3], params[3, :3] = camera.eye, -back, right * tan_x, up * tan_y
    params[0, 3], params[1, 3] = shift_x, shift_y
    for name, m in (("view_proj", vp), ("prev_view_proj", prev), ("view_matrix", camera.view_matrix()),
                    ("camera_params", params)):
        matrices[name].set(np.ascontiguousarray(m, np.float32).reshape(-1), queue=queue)
    return dict(width=width, height=height, near=camera.near, far=camera.far,
                has_prev=int(prev_camera is not None), tan_x=tan_x, tan_y=tan_y, shift_x=shift_x, shift_y=shift_y)
