"""sha256 of what a render produces, to show a refactor changed no output.

    python -m bench.hashes [--json OUT]

Renders the bundled demo, DamagedHelmet and Sponza (64 seeded lights) through the three pipelines
(deferred, light pre-pass, light-indexed) on the default device and prints one line per
(scene, pipeline, array): the sha256 of Frame.image, Frame.color and the packed G-buffer. Uses
only the public API (clrender.load_scene, Renderer, RenderConfig), so the same script runs on
the code before and after a change; two lists that differ in any line mean the output changed.
"""
from __future__ import annotations

import argparse
import hashlib
import json
import sys

import numpy as np

from bench.common import HELMET, HELMET_CAMERA, REPO, SPONZA, SPONZA_CAMERA

PIPELINES = ("deferred", "light_prepass", "light_indexed")
SIZE = (320, 180)
SPONZA_LIGHTS, SPONZA_SEED = 64, 7


def scenes():
    import clrender
    demo = clrender.load_scene(REPO / "scenes" / "demo.toml")
    yield "demo", demo, demo.camera
    for name, path, camera in (("DamagedHelmet", HELMET, HELMET_CAMERA), ("Sponza", SPONZA, SPONZA_CAMERA)):
        if not path.is_file():
            raise SystemExit(f"{path} not found: the shared scenes live in ../shared/scenes")
        scene = clrender.load_scene(path)
        if name == "Sponza":
            scene.add_random_lights(SPONZA_LIGHTS, seed=SPONZA_SEED, radius=(2.0, 2.0), intensity=4.0)
        yield name, scene, clrender.Camera(**camera)


def digest(array: np.ndarray) -> str:
    array = np.ascontiguousarray(array)
    head = f"{array.dtype.str}{array.shape}".encode()
    return hashlib.sha256(head + array.tobytes()).hexdigest()


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", help="also write the list here")
    args = parser.parse_args(argv)
    import clrender
    lines = {}
    for name, scene, camera in scenes():
        for pipeline in PIPELINES:
            renderer = clrender.Renderer(*SIZE, pipeline=pipeline, ssao=pipeline != "light_indexed")
            frame = renderer.render(scene, camera)
            for array in ("image", "color", "gbuffer"):
                key = f"{name} {pipeline} {array}"
                lines[key] = digest(getattr(frame, array))
                print(f"{key:40s} {lines[key]}", flush=True)
    if args.json:
        with open(args.json, "w") as f:
            json.dump(lines, f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
