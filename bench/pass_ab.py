"""Per-pass medians on Sponza (1280×720, bench.common.SPONZA_CAMERA, bench/lights.py's random lights:
radius 0.05 × the bounds diagonal, seed 1), optionally interleaved with a second copy of the
kernels (--baseline DIR, e.g. a copy of kernels/ from before a change): frames alternate A/B in
one process, so a shared machine's load hits both alike. Reports whether the G-buffer and
colour are bit-identical to the baseline and the colour's largest difference / peak.

    python -m bench.pass_ab --lights 0 1024 4096 --repeats 9 [--baseline /tmp/old_kernels]

The baseline renderer runs the current pass modules (clrender/passes) on the baseline kernels:
only kernel-side changes that keep the kernels' arguments and launch shapes compare."""
from __future__ import annotations

import argparse
import statistics
from pathlib import Path

import numpy as np

from bench.common import SPONZA, SPONZA_CAMERA, require_scene


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--lights", type=int, nargs="+", default=[0, 1024])
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--baseline", type=Path, default=None, help="a kernels/ directory to compare against")
    ap.add_argument("--size", type=int, nargs=2, default=(1280, 720))
    args = ap.parse_args(argv)

    import clrender
    import clrender.device.core as dv
    from clrender.render.pipeline import pass_ms

    renderers = {}
    if args.baseline is not None:
        renderers["baseline"] = clrender.Renderer(*args.size)
    renderers["current"] = clrender.Renderer(*args.size)
    current_dir = dv.kernels_dir

    def render(name, scene, camera):
        """Programs build lazily (at a pass's first launch): the baseline's frames run with
        kernels_dir pointing at the baseline copy, so whatever they build comes from there."""
        if name == "baseline":
            dv.kernels_dir = lambda: args.baseline
        try:
            return renderers[name].render(scene, camera)
        finally:
            dv.kernels_dir = current_dir

    scene = clrender.load_scene(require_scene(SPONZA))
    camera = clrender.Camera.look_at(**SPONZA_CAMERA)
    lo, hi = scene.bounds().astype(np.float64)
    radius = 0.05 * float(np.linalg.norm(hi - lo))
    base = scene.lights[:0].copy()
    for n in args.lights:
        scene.lights = base.copy()
        scene.add_random_lights(n, seed=1, radius=(radius, radius), intensity=1.0)
        frames = {k: render(k, scene, camera) for k in renderers}     # warm-up (builds)
        if "baseline" in frames:
            a, b = frames["baseline"], frames["current"]
            err = float(np.abs(a.color - b.color).max() / max(float(a.color.max()), 1e-30))
            print(f"{n} lights: gbuffer identical {np.array_equal(a.gbuffer, b.gbuffer)}, "
                  f"color identical {np.array_equal(a.color, b.color)}, max |diff| / peak {err:.3g}")
        samples = {k: [] for k in renderers}
        for _ in range(args.repeats):
            for k in renderers:
                samples[k].append(pass_ms(render(k, scene, camera).stats))
        print(f"{n} lights, medians of {args.repeats} (ms):")
        for p in samples["current"][0]:
            row = "  ".join(f"{k} {statistics.median(s[p] for s in samples[k]):8.2f}" for k in renderers)
            print(f"  {p:16s} {row}")


if __name__ == "__main__":
    main()
