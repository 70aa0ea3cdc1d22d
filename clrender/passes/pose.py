"""Pose pass (kernels/pose.cl): skinned and morphing vertices posed on the device, before setup.

The bind attributes, influences and morph deltas of `Scene.deformation` (clrender/scene/deform.py) are
uploaded once per deformation and device; a frame uploads only the joint palette and the morph
weights (12 floats per joint matrix, one per target, twice when the pose has a previous state)
and writes the posed positions, normals and tangents into the scene upload's buffers, plus the
previous positions (velocity AOV) into the upload's `prev_positions` when it has one, else into a
buffer of this pass (a copy of the positions with the deformed vertices at t - dt).

A sequence of frames (t, then t + dt with the previous pose at t) keeps the previous positions: the
skinning kernel also writes the posed positions compactly (`last_pose`); when the next frame's
previous pose is that pose (the float32 palette and weights the kernels read), they are copied on
the device instead of posed again (the kernels run with PREVIOUS=0), bit-identical either way.

The kernels run only when the pose changed (Deformation.version) or the scene upload rewrote the
positions (an animation frame's set_transform); its outputs get new Array objects, so caches keyed
by buffer identity (chunk boxes, kept shadow maps) see the change. `scene_bounds` becomes the
union of the upload's bounds and the deformation's conservative bounds (the sun's shadow fit).
"""
from __future__ import annotations

import weakref

import numpy as np
import pyopencl as cl
import pyopencl.array as cla

from clrender.scene.tangents import NO_TANGENT
from clrender.passes.base import RenderPass, launch_1d

POSE_WG = 64
DEF_INTS = 8            # pose.cl's deformer record
DEF_MORPH_POSITION, DEF_MORPH_NORMAL, DEF_MORPH_TANGENT, DEF_RIGID = 1, 2, 4, 16


def device_layout(deformation) -> dict:
    """The host arrays pose.cl reads (module doc of kernels/pose.cl), in one dict."""
    ds = deformation.deformers
    k = deformation.influences
    n = deformation.vertex_count
    bind_pos, bind_nrm = np.empty((n, 3), np.float32), np.empty((n, 3), np.float32)
    bind_tan = np.tile(np.float32(NO_TANGENT), (n, 1))
    joints, weights = np.zeros((n, k), np.int32), np.zeros((n, k), np.float32)
    vertex_deformer = np.empty(n, np.int32)
    table = np.zeros((max(len(ds), 1), DEF_INTS), np.int32)
    deltas = {name: [] for name in ("positions", "normals", "tangents")}
    local = delta = 0
    for i, d in enumerate(ds):
        s = slice(local, local + d.count)
        bind_pos[s], bind_nrm[s] = d.positions, d.normals
        if d.tangents is not None:
            bind_tan[s] = d.tangents
        kd = d.joints.shape[1]
        joints[s, :kd], weights[s, :kd] = deformation.palette_index(i), d.weights
        vertex_deformer[s] = i
        flags = DEF_RIGID if d.skin < 0 else 0
        for bit, name, arr in ((DEF_MORPH_POSITION, "positions", d.target_positions),
                               (DEF_MORPH_NORMAL, "normals", d.target_normals),
                               (DEF_MORPH_TANGENT, "tangents", d.target_tangents)):
            if arr is not None:
                flags |= bit
            zeros = np.zeros((d.targets * d.count, 3), np.float32)
            deltas[name].append(zeros if arr is None else np.asarray(arr, np.float32).reshape(-1, 3))
        table[i] = (d.first, local, d.count, d.targets, deformation.weight_offsets[i], delta, flags, 0)
        local += d.count
        delta += d.targets * d.count
    if delta >= 2**31 // 3 or n * k >= 2**31:
        from clrender.errors import SceneError
        raise SceneError(f"{deformation.source}: too many deformed vertices or morph deltas for 32-bit offsets")
    morph_vertex = np.concatenate([np.arange(int(t[1]), int(t[1] + t[2]), dtype=np.int32)
                                   for t in table[: len(ds)] if t[3] > 0] or [np.zeros(0, np.int32)])
    out = {"bind_pos": bind_pos, "bind_nrm": bind_nrm, "bind_tan": bind_tan, "vertex_deformer": vertex_deformer,
           "deformers": table, "joints": joints, "weights": weights, "morph_vertex": morph_vertex}
    for name, parts in deltas.items():
        out[f"delta_{name}"] = np.concatenate(parts) if parts else np.zeros((0, 3), np.float32)
    return out


def _merged_ranges(table: np.ndarray) -> list:
    """(first scene vertex, first bind vertex, count) of the deformers' vertex ranges, adjacent ones
    (in both) merged."""
    out: list = []
    for first, local, count in sorted((int(t[0]), int(t[1]), int(t[2])) for t in table):
        if out and out[-1][0] + out[-1][2] == first and out[-1][1] + out[-1][2] == local:
            out[-1] = (out[-1][0], out[-1][1], out[-1][2] + count)
        else:
            out.append((first, local, count))
    return out


def _put(queue, a) -> cla.Array:
    a = np.ascontiguousarray(a).reshape(-1)
    return cla.to_device(queue, a if a.size else np.zeros(1, a.dtype))


class PosePass(RenderPass):
    name = "pose"
    inputs = ("deformation", "positions", "normals", "tangents", "n_vertices", "scene_bounds")
    outputs = ("positions", "normals", "tangents", "prev_positions", "scene_bounds")

    def __init__(self, device, config):
        super().__init__(device, config)
        self._kernels: dict = {}     # (kernel, influences, tangents, previous) -> kernel: build options
        self._static: "weakref.WeakKeyDictionary" = weakref.WeakKeyDictionary()   # deformation -> buffers
        self._done = None           # (deformation ref, version, positions Array written)
        self._prev = None           # this pass's previous positions (no upload prev_positions)
        self._prev_of = None        # the positions Array whose other vertices _prev holds
        self._state = None          # palette / weights device arrays
        self._last = None           # (deformation, palette, weights) the last run posed
        self.kept_previous = False  # whether the last run copied the previous positions instead of posing them
        self.bytes_per_frame = 0    # uploaded by the last run (palette + weights)
        self.ran = False            # whether the last run enqueued the kernel

    def prepare_scene(self, res) -> None:
        d = res["deformation"]
        if d not in self._static:
            self._static.clear()            # one deformation at a time per pipeline
            layout = device_layout(d)
            static = {name: _put(self.queue, a) for name, a in layout.items()}
            static["n_morph"] = len(layout["morph_vertex"])
            static["end"] = max((x.first + x.count for x in d.deformers), default=0)   # last scene vertex + 1
            static["ranges"] = _merged_ranges(layout["deformers"][: len(d.deformers)])
            static["last_pose"] = cla.empty(self.queue, max(3 * d.vertex_count, 1), np.float32)   # _kept
            # the skinning kernel's inputs: the bind attributes, morphed in place each frame where a mesh
            # has targets (morph_targets), copied once here
            for morphed, bind in (("morphed_pos", "bind_pos"), ("morphed_prev_pos", "bind_pos"),
                                  ("morphed_nrm", "bind_nrm"), ("morphed_tan", "bind_tan")):
                static[morphed] = static[bind].copy(queue=self.queue)
            self._static[d] = static

    def _kernel(self, name: str, influences: int, tangents: bool, previous: bool):
        key = (name, influences, tangents, previous)
        if key not in self._kernels:
            self._kernels[key] = self.device.kernel("pose.cl", name, {
                "POSE_WG": POSE_WG, "INFLUENCES": influences, "TANGENTS": int(tangents), "PREVIOUS": int(previous)})
        return self._kernels[key]

    def _upload_state(self, d, previous: bool) -> dict:
        """The palette and weights on the device (and the previous ones when `previous`: posed here)."""
        prev_palette = d.palette if d.previous_palette is None else d.previous_palette
        prev_weights = d.morph_weights if d.previous_morph_weights is None else d.previous_morph_weights
        host = {"palette": d.palette, "morph_weights": d.morph_weights, "prev_palette": prev_palette,
                "prev_morph_weights": prev_weights}
        if self._state is None or self._state["palette"].size != d.palette.size \
                or self._state["morph_weights"].size != d.morph_weights.size:
            self._state = {name: cla.empty(self.queue, np.asarray(a).size, np.float32) for name, a in host.items()}
        self.bytes_per_frame = 0
        for name, a in host.items():
            if name.startswith("prev") and not previous:
                continue
            data = np.ascontiguousarray(a, np.float32).reshape(-1)
            cl.enqueue_copy(self.queue, self._state[name].data, data, is_blocking=False)
            self.bytes_per_frame += data.nbytes
        return self._state

    def _kept(self, d, res) -> bool:
        """Whether the previous pose is the pose of the last run, whose positions `last_pose` keeps (a
        sequence of frames at t, t + dt, ...): the previous positions are then copied, not posed.
        Compared as the float32 values the kernels read, so the copy is bit-identical to posing."""
        last = self._last
        return (d.previous_palette is not None and last is not None and last[0] is d
                and np.array_equal(last[1], d.previous_palette.astype(np.float32))
                and np.array_equal(last[2], d.previous_morph_weights.astype(np.float32)))

    def _copy_ranges(self, static, src, dst) -> None:
        """The compact `last_pose` (skin_vertices writes it) into the scene's previous positions."""
        for first, local, count in static["ranges"]:
            cl.enqueue_copy(self.queue, dst.data, src.data, byte_count=12 * count, src_offset=12 * local,
                            dst_offset=12 * first)

    def run(self, res) -> None:
        """Pose into res's buffers (new views) when needed; always publish the previous positions
        and bounds of the current pose."""
        d = res["deformation"]
        n_vertices = int(res["n_vertices"])
        end = self._static[d]["end"]
        if end > n_vertices:       # arrays replaced by hand: the kernel would write past the buffers
            from clrender.errors import SceneError
            raise SceneError(f"{d.source}: the deformed meshes use vertices up to {end}, the scene has {n_vertices}")
        upload_prev = res.buffers.get("prev_positions")
        wants_prev = d.previous_palette is not None or upload_prev is not None
        done = self._done
        self.ran = (done is None or done[0] is not d or done[1] != d.version or done[2] is not res.buffers["positions"]
                    or done[3] is not upload_prev)
        if self.ran:
            kept = self._kept(d, res)
            static = self._static[d]
            prev = upload_prev
            if prev is None and wants_prev:      # the other vertices do not move: their current positions
                if self._prev is None or self._prev.size != 3 * n_vertices:
                    self._prev = cla.empty(self.queue, 3 * n_vertices, np.float32)
                    self._prev_of = None
                if self._prev_of is not res.buffers["positions"]:    # (re)written by the upload since
                    cl.enqueue_copy(self.queue, self._prev.data, res.buffers["positions"].data)
                prev = self._prev
            if kept:                             # the deformed vertices' last pose
                self._copy_ranges(static, static["last_pose"], prev)
            tangents = res.buffers["tangents"]
            write_tangents = tangents.size == 4 * n_vertices
            write_prev = prev is not None and not kept
            state = self._upload_state(d, write_prev)
            k = self._kernel("morph_targets", d.influences, write_tangents, write_prev)
            n = static["n_morph"]
            if n:
                k(self.queue, *launch_1d(n, POSE_WG), np.int32(n), static["morph_vertex"].data,
                  static["vertex_deformer"].data, static["deformers"].data, static["bind_pos"].data,
                  static["bind_nrm"].data, static["bind_tan"].data, static["delta_positions"].data,
                  static["delta_normals"].data, static["delta_tangents"].data, state["morph_weights"].data,
                  state["prev_morph_weights"].data, static["morphed_pos"].data, static["morphed_nrm"].data,
                  static["morphed_tan"].data, static["morphed_prev_pos"].data)
            n = d.vertex_count
            k = self._kernel("skin_vertices", d.influences, write_tangents, write_prev)
            k(self.queue, *launch_1d(n, POSE_WG), np.int32(n), static["vertex_deformer"].data,
              static["deformers"].data, static["morphed_pos"].data, static["morphed_nrm"].data,
              static["morphed_tan"].data, static["morphed_prev_pos"].data, static["joints"].data,
              static["weights"].data, state["palette"].data, state["prev_palette"].data,
              res.buffers["positions"].data, res.buffers["normals"].data, tangents.data,
              (prev if write_prev else res.buffers["positions"]).data, static["last_pose"].data)
            for name in ("positions", "normals") + (("tangents",) if write_tangents else ()):
                res.buffers[name] = res.buffers[name].view()
            if upload_prev is not None:
                res.buffers["prev_positions"] = upload_prev.view()
            self._done = (d, d.version, res.buffers["positions"], res.buffers.get("prev_positions") if upload_prev
                          is not None else None)
            self._last = (d, d.palette.astype(np.float32), d.morph_weights.astype(np.float32))
            # the positions whose undeformed vertices _prev holds (a later run skips copying them)
            self._prev_of = res.buffers["positions"] if prev is not None and prev is self._prev else None
            self.kept_previous = kept
        if upload_prev is None:
            if d.previous_palette is not None:
                res.buffers["prev_positions"] = self._prev
            else:
                res.buffers.pop("prev_positions", None)
        lo, hi = np.asarray(res["scene_bounds"], np.float64)
        dlo, dhi = d.bounds()
        res.values["scene_bounds"] = np.stack([np.minimum(lo, dlo), np.maximum(hi, dhi)]).astype(np.float32)
