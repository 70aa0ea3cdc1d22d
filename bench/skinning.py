"""Skins and morph targets: what posing costs on the device, against NumPy, and a batch of frames.

    python -m bench.skinning [--vertices 1000000] [--instances 256] [--morph-vertices 50000]
                             [--targets 8] [--repeats 7] [--warmup 2] [--frames 48] [--device NAME]

A generated glTF (written to a temporary folder): a skinned creature (a tube of 6 joints, 4
influences per vertex, NORMAL and TANGENT) instanced as `--instances` nodes, each with its own skin
and animated joints, to about `--vertices` skinned vertices, plus one `--morph-vertices` grid with
`--targets` morph targets (POSITION and NORMAL deltas) and animated weights. Measured in one run:

* posing per frame: the pose pass's device ms (OpenCL profiling events around kernels/pose.cl and
  its copies: morph, skin, normals, tangents and the previous positions for the velocity AOV),
  median after warm-up, and per million deformed vertices, for frames in any order (the previous
  pose is posed too) and for a frame sequence t, t + dt, ... (the previous positions are kept); next to the same posing in NumPy (clrender.scene.deform.Deformation.
  posed, vectorized float64, every deformer) and the host's `scene.pose(t, dt)` (animation
  sampling and joint matrices);
* bytes uploaded per posed frame (joint palette and weights, both poses) against the bind data
  uploaded once;
* a 48-frame batch at 640x360 through clrender.batch.jobs.render_frames (wall seconds, frames per second).

Writes bench/results/skinning-*.json.
"""
from __future__ import annotations

import argparse
import json
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from .common import write_record

JOINTS = 6


def quat_y(a):
    return [0.0, float(np.sin(a / 2)), 0.0, float(np.cos(a / 2))]


def creature(rings: int, sides: int):
    """A tube along +X over JOINTS joints: positions, normals, tangents, 4 joints and weights per vertex."""
    length = float(JOINTS - 1)
    xs = np.linspace(0, length, rings)
    a = np.linspace(0, 2 * np.pi, sides, endpoint=False)
    ring = np.stack([np.zeros_like(a), np.cos(a), np.sin(a)], 1)
    tang = np.stack([np.zeros_like(a), -np.sin(a), np.cos(a)], 1)
    radius = 0.3 + 0.1 * np.sin(np.pi * xs / length)
    pos = np.concatenate([[x, 0, 0] + r * ring for x, r in zip(xs, radius)]).astype(np.float32)
    nrm = np.tile(ring, (rings, 1)).astype(np.float32)
    tan = np.concatenate([np.tile(tang, (rings, 1)), np.ones((rings * sides, 1))], 1).astype(np.float32)
    idx = []
    for i in range(rings - 1):
        for j in range(sides):
            a0, a1 = i * sides + j, i * sides + (j + 1) % sides
            idx += [a0, a1 + sides, a0 + sides, a0, a1, a1 + sides]
    d = np.abs(pos[:, :1] - np.arange(JOINTS)[None])                 # distance to each joint along x
    near = np.argsort(d, 1, kind="stable")[:, :4]
    w = np.exp(-np.take_along_axis(d, near, 1) ** 2 / 0.5)
    return pos, nrm, tan, np.array(idx, np.uint32), near.astype(np.uint8), (w / w.sum(1, keepdims=True)).astype(np.float32)


def write_scene(path: Path, vertices: int, instances: int, morph_vertices: int, targets: int, seed: int = 1) -> Path:
    rng = np.random.default_rng(seed)
    per = max(vertices // instances, 64)
    sides = 32
    rings = max(per // sides, 2)
    pos, nrm, tan, idx, joints, weights = creature(rings, sides)
    blob, views, accessors = bytearray(), [], []

    def add(a, kind):
        a = np.ascontiguousarray(a)
        blob.extend(b"\0" * (-len(blob) % 4))
        views.append({"buffer": 0, "byteOffset": len(blob), "byteLength": a.nbytes})
        blob.extend(a.tobytes())
        comp = {np.dtype(np.float32): 5126, np.dtype(np.uint32): 5125, np.dtype(np.uint8): 5121}[a.dtype]
        accessors.append({"bufferView": len(views) - 1, "componentType": comp, "count": len(a), "type": kind})
        if kind == "VEC3" and comp == 5126:
            accessors[-1].update(min=a.min(0).tolist(), max=a.max(0).tolist())
        return len(accessors) - 1

    body = {"attributes": {"POSITION": add(pos, "VEC3"), "NORMAL": add(nrm, "VEC3"), "TANGENT": add(tan, "VEC4"),
                           "JOINTS_0": add(joints, "VEC4"), "WEIGHTS_0": add(weights, "VEC4")},
            "indices": add(idx, "SCALAR"), "material": 0}
    g = int(np.sqrt(morph_vertices))
    gx, gy = np.meshgrid(np.linspace(-4, 4, g), np.linspace(-4, 4, g))
    grid = np.stack([gx.ravel(), np.zeros(g * g), gy.ravel()], 1).astype(np.float32)
    gidx = []
    for r in range(g - 1):
        for c in range(g - 1):
            a0 = r * g + c
            gidx += [a0, a0 + g, a0 + 1, a0 + 1, a0 + g, a0 + g + 1]
    sheet = {"attributes": {"POSITION": add(grid, "VEC3"),
                            "NORMAL": add(np.tile(np.float32([0, 1, 0]), (g * g, 1)), "VEC3")},
             "indices": add(np.array(gidx, np.uint32), "SCALAR"), "material": 1,
             "targets": [{"POSITION": add((np.sin(grid[:, :1] * (k + 1) * 0.7 + grid[:, 2:] * 0.3 * k)
                                           * [[0, 0.3, 0]]).astype(np.float32), "VEC3"),
                          "NORMAL": add(rng.normal(scale=0.05, size=(g * g, 3)).astype(np.float32), "VEC3")}
                         for k in range(targets)]}
    ibm = np.stack([np.linalg.inv(np.array([[1, 0, 0, j], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]]))
                    for j in range(JOINTS)]).transpose(0, 2, 1).reshape(-1, 16).astype(np.float32)
    ibm_acc = add(ibm, "MAT4")
    times = np.linspace(0, 2, 9).astype(np.float32)
    t_acc = add(times, "SCALAR")
    samplers, channels, nodes, skins, roots = [], [], [], [], []
    phases = 8
    for p in range(phases):                 # one rotation sampler per (phase, joint)
        for j in range(1, JOINTS):
            q = [quat_y(0.4 * np.sin(2 * np.pi * t / 2 - 0.9 * j + p)) for t in times]
            samplers.append({"input": t_acc, "output": add(np.float32(q), "VEC4")})
    side = int(np.ceil(np.sqrt(instances)))
    for i in range(instances):
        base = len(nodes)
        nodes.append({"name": f"creature{i}", "mesh": 0, "skin": i})
        joint_nodes = []
        for j in range(JOINTS):
            node = {"name": f"c{i}j{j}", "translation": [1.0 if j else 6.0 * (i % side), 0.0,
                                                          0.0 if j else 1.2 * (i // side)]}
            if j < JOINTS - 1:
                node["children"] = [base + 2 + j]
            nodes.append(node)
            joint_nodes.append(base + 1 + j)
            if j:
                channels.append({"sampler": (i % phases) * (JOINTS - 1) + j - 1,
                                 "target": {"node": base + 1 + j, "path": "rotation"}})
        skins.append({"joints": joint_nodes, "inverseBindMatrices": ibm_acc})
        roots += [base, base + 1]
    wkeys = rng.uniform(0, 1, (len(times), targets)).astype(np.float32)
    samplers.append({"input": t_acc, "output": add(wkeys.reshape(-1), "SCALAR")})
    nodes.append({"name": "sheet", "mesh": 1, "translation": [0, -1, -6]})
    channels.append({"sampler": len(samplers) - 1, "target": {"node": len(nodes) - 1, "path": "weights"}})
    roots.append(len(nodes) - 1)
    doc = {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": roots}], "nodes": nodes,
           "meshes": [{"primitives": [body]}, {"primitives": [sheet], "weights": [0.0] * targets}],
           "materials": [{"pbrMetallicRoughness": {"baseColorFactor": [0.5, 0.7, 0.3, 1], "roughnessFactor": 0.5,
                                                   "metallicFactor": 0.0}},
                         {"pbrMetallicRoughness": {"baseColorFactor": [0.7, 0.7, 0.7, 1]}, "doubleSided": True}],
           "skins": skins, "animations": [{"samplers": samplers, "channels": channels}],
           "accessors": accessors, "bufferViews": views,
           "buffers": [{"byteLength": len(blob), "uri": path.stem + ".bin"}]}
    (path.parent / (path.stem + ".bin")).write_bytes(bytes(blob))
    path.write_text(json.dumps(doc))
    return path


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--vertices", type=int, default=1_000_000)
    ap.add_argument("--instances", type=int, default=256)
    ap.add_argument("--morph-vertices", type=int, default=50_000)
    ap.add_argument("--targets", type=int, default=8)
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--warmup", type=int, default=2)
    ap.add_argument("--frames", type=int, default=48)
    ap.add_argument("--size", default="640x360")
    ap.add_argument("--device", default=None)
    args = ap.parse_args(argv)
    from clrender import Renderer, load_scene
    from clrender.batch.jobs import render_frames
    from clrender.device.timestamps import elapsed_ms

    width, height = (int(v) for v in args.size.split("x"))
    with tempfile.TemporaryDirectory() as tmp:
        path = write_scene(Path(tmp) / "creatures.gltf", args.vertices, args.instances, args.morph_vertices, args.targets)
        t0 = time.perf_counter()
        scene = load_scene(path)
        load_s = time.perf_counter() - t0
        d = scene.deformation
        skinned = sum(x.count for x in d.deformers if x.skin >= 0)
        morphed = sum(x.count for x in d.deformers if x.targets)
        print(f"scene: {skinned:,} skinned vertices (4 influences, normals + tangents) in {len(d.skins)} skins, "
              f"{morphed:,} morph vertices x {args.targets} targets; {scene.triangle_count:,} triangles; "
              f"loaded in {load_s:.1f} s", flush=True)
        r = Renderer(width, height, device=args.device)
        queue = r.device.queue
        numpy_ms = []
        r.render(scene)                                  # builds, uploads the bind data

        def posing(times):
            """Device ms of the pose pass, host ms of scene.pose, upload bytes, per time (after warm-up)."""
            dev, host, sent = [], [], []
            for k, t in enumerate(times):
                h0 = time.perf_counter()
                scene.pose(t, dt=1 / 24)
                h1 = time.perf_counter()
                r._scene_resources(scene)                # the vertex pre-pass alone (what render() runs first)
                queue.finish()
                _, start, end = r.pipeline._pose_timing
                r.pipeline._pose_timing = None
                if k >= args.warmup:
                    dev.append(elapsed_ms(start, end))
                    host.append((h1 - h0) * 1e3)
                    sent.append(r.pipeline.pose_pass.bytes_per_frame)
            return dev, host, sent

        n = args.warmup + args.repeats
        # frames in any order: the previous pose (t - dt) is posed too
        dev_ms, host_pose_ms, sent_random = posing([0.05 + 0.11 * k for k in range(n)])
        # a frame sequence (t, t + dt, ...): the previous positions are the last frame's, copied
        seq_ms, _, sent_seq = posing([0.5 + k / 24 for k in range(n)])
        assert r.pipeline.pose_pass.kept_previous
        upload_bytes = statistics.median(sent_random)
        from clrender.passes.pose import device_layout
        bind_bytes = sum(a.nbytes for a in device_layout(d).values())
        for k in range(max(2, args.repeats // 2)):        # NumPy: the same posing (float64, vectorized)
            n0 = time.perf_counter()
            for i in range(len(d.deformers)):
                d.posed(i)
            numpy_ms.append((time.perf_counter() - n0) * 1e3)
        med, seq = statistics.median(dev_ms), statistics.median(seq_ms)
        millions = (skinned + morphed) / 1e6
        per_million, seq_per_million = med / millions, seq / millions
        print(f"posing (device, pose.cl), frames in any order (previous pose posed too): {med:.2f} ms per frame = "
              f"{per_million:.2f} ms per million deformed vertices (target <= 20)", flush=True)
        print(f"posing (device, pose.cl), a frame sequence (previous positions kept): {seq:.2f} ms per frame = "
              f"{seq_per_million:.2f} ms per million; upload {statistics.median(sent_seq):,.0f} bytes", flush=True)
        print(f"posing (NumPy, float64, clrender.scene.deform):    {statistics.median(numpy_ms):.1f} ms per frame "
              f"({statistics.median(numpy_ms) / med:.0f}x)", flush=True)
        print(f"scene.pose(t, dt) on the host (animation, joint matrices): {statistics.median(host_pose_ms):.1f} ms",
              flush=True)
        print(f"upload per posed frame: {upload_bytes:,} bytes (palette + weights, both poses) vs {bind_bytes:,} "
              f"bytes of bind data uploaded once", flush=True)
        b0 = time.perf_counter()
        result = render_frames(path, range(args.frames), Path(tmp) / "out", width=width, height=height,
                               device=args.device, quiet=True)
        batch_s = time.perf_counter() - b0
        print(f"batch: {args.frames} frames at {width}x{height} in {batch_s:.1f} s ({args.frames / batch_s:.2f} fps; "
              f"{result!r:.80})", flush=True)
        record = {"skinned_vertices": skinned, "morph_vertices": morphed, "targets": args.targets,
                  "skins": len(d.skins), "triangles": scene.triangle_count, "load_s": load_s,
                  "pose_device_ms": dev_ms, "pose_device_median_ms": med, "pose_ms_per_million": per_million,
                  "pose_sequence_ms": seq_ms, "pose_sequence_median_ms": seq,
                  "pose_sequence_ms_per_million": seq_per_million, "upload_bytes_sequence": statistics.median(sent_seq),
                  "pose_numpy_ms": numpy_ms, "pose_host_animation_ms": host_pose_ms,
                  "upload_bytes_per_frame": upload_bytes, "bind_bytes_once": bind_bytes,
                  "batch_frames": args.frames, "batch_size": [width, height], "batch_s": batch_s,
                  "device": r.device.name}
    print(f"wrote {write_record('skinning', record)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
