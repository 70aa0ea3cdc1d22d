"""Chunk cull pass (kernels/chunk_cull.cl): which chunks of CHUNK (128) consecutive triangles a view
can see, so that setup (kernels/setup.cl, CHUNK_CULL=1) reads and transforms only those.

Each chunk's world-space box is computed on the device once per scene geometry: boxes are kept
per device, keyed by the identity of the positions and triangles buffers (an animation frame
replaces them, see clrender/render/scene_upload.py), and shared by every view -- the camera's setup and
each shadow map's (clrender/passes/shadow.py). Per view one single-work-group kernel tests the
boxes against the planes setup.cl trivially rejects triangles on and lists the visible chunks
first (ascending) and the culled ones last; setup then launches over chunk slots and gives the
culled triangles no prim and the status it would have given them (Frame.stats keeps its
meaning; `chunks` / `culled_chunks` count the chunks of the camera's view).

RenderConfig.chunk_cull=False: setup runs over every triangle as before and no kernel of this
pass is built or launched. Prims, maps and images are bit-identical either way.
"""
from __future__ import annotations

import weakref

import numpy as np

from clrender.passes.base import RenderPass, empty, launch_1d

CHUNK = 128          # triangles per chunk (chunk_cull.cl and setup.cl CHUNK; Sponza shadow setup: 128 < 256 < 64)
CULL_WG = 64         # chunk_cull's single work-group

_BOUNDS: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()   # device -> (positions, triangles, n, bounds)


def chunk_defines(ortho: bool = False) -> dict:
    return {"CHUNK": CHUNK, "CULL_WG": CULL_WG, **({"ORTHO": 1} if ortho else {})}


def n_chunks(n_tris: int) -> int:
    return -(-int(n_tris) // CHUNK)


def chunk_bounds(device, positions, triangles, n_tris: int):
    """float[8·chunks] boxes of the scene's triangle chunks (chunk_cull.cl `chunk_bounds`),
    recomputed only when positions or triangles is another buffer than last time."""
    kept = _BOUNDS.get(device)
    if kept is not None and kept[0] is positions and kept[1] is triangles and kept[2] == n_tris:
        return kept[3]
    c = n_chunks(n_tris)
    bounds = empty(device.queue, 8 * c, np.float32)
    if c:
        kernel = device.kernel("chunk_cull.cl", "chunk_bounds", chunk_defines())
        kernel(device.queue, *launch_1d(c), positions.data, triangles.data, np.int32(n_tris), bounds.data)
    _BOUNDS[device] = (positions, triangles, n_tris, bounds)
    return bounds


class ChunkCullPass(RenderPass):
    name = "chunk_cull"
    inputs = ("positions", "triangles", "n_tris", "view_proj", "width", "height", "near")
    outputs = ("chunk_list", "chunk_count", "chunk_status")

    def __init__(self, device, config, ortho: bool = False):
        """ortho: the view is orthographic (chunk_cull.cl ORTHO, as setup.cl's)."""
        super().__init__(device, config)
        self.kernel = device.kernel("chunk_cull.cl", "chunk_cull", chunk_defines(ortho))
        self.n_chunks = -1
        self.bounds = None

    def prepare_scene(self, scene_res):
        n = scene_res["n_tris"]
        c = n_chunks(n)
        if c != self.n_chunks:
            self.n_chunks = c
            self.chunk_list = empty(self.queue, c, np.int32)
            self.chunk_status = empty(self.queue, c, np.uint8)
            self.chunk_count = empty(self.queue, 1, np.int32)
        self.bounds = chunk_bounds(self.device, scene_res["positions"], scene_res["triangles"], n)

    def publish(self, res):
        res.buffers.update(chunk_list=self.chunk_list, chunk_count=self.chunk_count, chunk_status=self.chunk_status)

    def run(self, res):
        self.kernel(self.queue, (CULL_WG,), (CULL_WG,), self.bounds.data, np.int32(self.n_chunks),
                    res["view_proj"].data, np.int32(res["width"]), np.int32(res["height"]),
                    np.float32(res["near"]), self.chunk_status.data, self.chunk_list.data, self.chunk_count.data)

    def visible_chunks(self) -> int:
        """Chunks the last run kept (reads back one int)."""
        return int(self.chunk_count.get(queue=self.queue)[0]) if self.n_chunks > 0 else 0
