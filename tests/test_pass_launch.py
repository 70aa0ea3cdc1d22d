"""Launch shapes that must not change a bit (issue 15): the raster pass's rows per work-item
(raster.cl RROWS) and the G-buffer pass's pixel blocks (passes/gbuffer.py GB_TILE_W/H) only
reorder independent per-pixel work, so every layout gives the default's exact visibility buffer
and G-buffer on textured, normal-mapped and near-clipped scenes."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import clrender
from clrender import Camera
from clrender.passes import gbuffer as gbuffer_pass
from reference.raster import near_floor_grid

HELMET = Path(__file__).resolve().parents[2] / "shared" / "scenes" / "khronos-DamagedHelmet" / "DamagedHelmet.gltf"


def scenes():
    out = [near_floor_grid(3)]
    if HELMET.is_file():
        cam = Camera.look_at(eye=(1.2, 0.5, 2.9), target=(0.0, 0.0, 0.0), up=(0, 1, 0), fov_y_deg=40.0,
                             near=0.05, far=20.0)
        out.append((clrender.load_scene(HELMET), cam, 203, 149))
    return out


def raster_pass(renderer):
    return next(p for p in renderer.pipeline.passes if p.name == "raster")


@pytest.mark.parametrize("rows", [1, 2, 8])
def test_raster_rows_per_work_item_change_nothing(device, rows):
    for scene, camera, w, h in scenes():
        ref = clrender.Renderer(w, h, device=device).render(scene, camera)
        r = clrender.Renderer(w, h, device=device)
        rp = raster_pass(r)
        if rp.vec == 1 and rows > 1:
            pytest.skip("a pixel per work-item device")
        rp.set_rows(rows)
        got = r.render(scene, camera)
        assert rp.rows == rows
        assert np.array_equal(got.gbuffer, ref.gbuffer)


@pytest.mark.parametrize("block", [(8, 1), (64, 4), (16, 16)])
def test_gbuffer_blocks_change_nothing(device, monkeypatch, block):
    for scene, camera, w, h in scenes():
        ref = clrender.Renderer(w, h, device=device).render(scene, camera)
        monkeypatch.setattr(gbuffer_pass, "GB_TILE_W", block[0])
        monkeypatch.setattr(gbuffer_pass, "GB_TILE_H", block[1])
        got = clrender.Renderer(w, h, device=device).render(scene, camera)
        monkeypatch.undo()
        assert np.array_equal(got.gbuffer, ref.gbuffer)
        assert np.array_equal(got.color, ref.color)
