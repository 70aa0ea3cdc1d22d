"""The raster autotune (clrender/render/autotune.py; its choice kept by clrender/device/tuning.py):
its decision rule on fake timings, its cache round trip, what overrides it, and that no choice it can make changes a pixel."""
from __future__ import annotations

import numpy as np
import pytest

from clrender.config import RenderConfig
from clrender.device import cache, capabilities, tuning
from clrender.device.tuning import Choice
from clrender.render import autotune
from clrender.render.autotune import decide


# -- the decision: a pure function of interleaved timings --------------------------------------------

def test_a_candidate_replaces_the_default_only_beyond_the_margin():
    default = (8, 8)
    base = [10.0, 12.0, 9.0, 11.0, 10.0]
    assert decide({default: base, (4, 8): [t * 0.85 for t in base]}, default) == (4, 8)     # 15 % faster
    assert decide({default: base, (4, 8): [t * 0.97 for t in base]}, default) == default    # 3 %: noise
    assert decide({default: base, (4, 8): [t * 0.9 for t in base]}, default, margin=0.1) == default  # at the margin: kept
    assert decide({default: base, (4, 8): [t * 0.85 for t in base]}, default, margin=0.2) == default
    assert 0.0 < autotune.MARGIN < 0.15


def test_ties_and_slower_candidates_keep_the_default():
    base = [5.0] * 7
    assert decide({(8, 8): base, (4, 8): base, (8, 16): base}, (8, 8)) == (8, 8)
    assert decide({(8, 8): base, (4, 8): [6.0] * 7}, (8, 8)) == (8, 8)
    assert decide({32: base, 16: base}, 32) == 32


def test_the_fastest_of_several_winners_is_chosen():
    base = [10.0] * 5
    timings = {(8, 8): base, (4, 8): [8.5] * 5, (8, 16): [7.0] * 5, (16, 16): [8.0] * 5}
    assert decide(timings, (8, 8)) == (8, 16)


def test_rounds_are_compared_pairwise_so_load_drift_cancels():
    """The machine slows down 3x halfway: per-round ratios still see the candidate 20 % faster,
    while its plain median (10.4) would not beat the default's (12)."""
    default = [10, 10, 10, 30, 30, 30, 12]
    faster = [8, 8, 8, 24, 24, 24, 9.6]
    assert decide({"d": default, "c": faster}, "d") == "c"
    one_outlier = [8, 8, 8, 60, 24, 24, 9.6]           # a spike in one round moves no median
    assert decide({"d": default, "c": one_outlier}, "d") == "c"


def test_an_unmeasured_default_wins():
    assert decide({(4, 8): [1.0]}, (8, 8)) == (8, 8)
    assert decide({}, 32) == 32


# -- what the passes run with -------------------------------------------------------------------------

@pytest.fixture
def cpu(device, monkeypatch):
    """The test device's clrender Device, with the tune's switches unset: CPU paths only."""
    from clrender.device.core import Device
    monkeypatch.delenv("CLRENDER_VEC", raising=False)
    monkeypatch.delenv(tuning.ENV_TUNE, raising=False)
    if capabilities.pixel_vector_width(device.cl_device) == 1:
        pytest.skip("a pixel per work-item (GPU, Oclgrind): not tuned")
    return Device.get(device)


@pytest.fixture
def fresh(monkeypatch, tmp_path):
    """An empty tune cache and no choice in this process, the probe answered by an earlier one
    (a cold start does not tune: see test_a_cold_start_leaves_the_tune_to_the_next_run)."""
    from clrender.device import probe
    monkeypatch.setenv(cache.ENV_CACHE_DIR, str(tmp_path))
    monkeypatch.setattr(tuning, "_choices", {})
    monkeypatch.setattr(tuning, "_complete", set())
    monkeypatch.setattr(probe, "_probed_here", set())


def test_explicit_options_and_the_environment_override_the_tune(cpu, monkeypatch):
    dev = cpu.cl_device
    monkeypatch.setitem(tuning._choices, dev.int_ptr, Choice(vec=4, tile=16, shadow_tile=16))
    cfg = RenderConfig()
    assert cfg.tile_size is None and cfg.shadow_tile_size is None
    assert tuning.camera_tile_size(dev, cfg) == 16
    assert tuning.shadow_tile_size(dev, cfg) == 16
    assert tuning.raster_vector_width(dev, 16) == 4
    explicit = RenderConfig(tile_size=8, shadow_tile_size=32)
    assert tuning.camera_tile_size(dev, explicit) == 8 and tuning.shadow_tile_size(dev, explicit) == 32
    monkeypatch.setenv("CLRENDER_VEC", "8")              # a forced width: no tune at all, today's defaults
    assert tuning.choice(dev) is None
    assert tuning.raster_vector_width(dev, 16) == 8 and tuning.camera_tile_size(dev, cfg) == 8
    monkeypatch.delenv("CLRENDER_VEC")
    monkeypatch.setenv(tuning.ENV_TUNE, "0")
    assert tuning.choice(dev) is None
    assert tuning.camera_tile_size(dev, cfg) == capabilities.DEFAULT_TILE
    assert tuning.shadow_tile_size(dev, cfg) == capabilities.DEFAULT_SHADOW_TILE_CPU
    assert tuning.raster_vector_width(dev, 8) == capabilities.pixel_vector_width(dev)


def test_candidates_fit_their_tiles(cpu):
    cands = autotune.camera_candidates(cpu.cl_device)
    d = tuning.default_choice(cpu.cl_device)
    assert cands[0] == (d.vec, d.tile) and len(set(cands)) == len(cands)
    assert all(v <= t and v in (4, 8, 16) and t in (8, 16) for v, t in cands)
    assert (16 in {v for v, _ in cands}) == capabilities.compiler_has_512bit_vectors(cpu.cl_device)
    assert autotune.shadow_candidates(cpu.cl_device) == [16, 32]
    assert autotune.steps(cpu.cl_device)[-1] == ("shadow", "shadow", [32, 16])     # the default first


def _fake_measure(calls, ms: dict):
    """measure() stand-in: candidate -> a fixed time per round; records each step asked."""
    def measure(device, step, vec=None, **_):
        calls.append(step)
        return {c: [ms[c]] * 7 for c in step[1]}
    return measure


def test_the_tune_is_cached_with_what_it_measured(cpu, fresh, monkeypatch):
    """ensure() runs steps within its budget (at least one a process), caches the choice and the
    timings; later processes run the rest; once complete nothing is measured again."""
    monkeypatch.setattr(autotune, "BUDGET_S", -1.0)           # one step per process
    dev = cpu.cl_device
    d = tuning.default_choice(dev)
    steps = autotune.steps(dev)
    calls = []
    ms = {(d.vec, d.tile): 10.0, (4, d.tile): 7.0, (d.vec, 16): 9.8, (16, 16): 12.0, 32: 5.0, 16: 4.9}
    monkeypatch.setattr(autotune, "measure", _fake_measure(calls, ms))
    # run 1: VEC 4 only, 30 % faster: chosen at once
    assert autotune.ensure(cpu) == Choice(4, d.tile, d.shadow_tile) and len(calls) == 2    # a win: measured twice
    assert tuning.cached_record(dev)["complete"] is False
    assert tuning.summary(dev)["tuned"] and not tuning.summary(dev)["complete"]
    for run in range(2, len(steps) + 1):                       # later processes: one step each
        monkeypatch.setattr(tuning, "_choices", {})
        autotune.ensure(cpu)
        assert len(calls) == run + 1                          # (no other win: measured once)
    assert calls == [(kind, cands) for _, kind, cands in steps[:1] + steps]
    record = tuning.cached_record(dev)
    assert record["complete"] and record["runs"] == len(steps)
    assert record["choice"] == {"vec": 4, "tile": d.tile, "shadow_tile": 32}     # tile 16 2 %, shadow 16 2 %: noise
    assert record["measured_ms"][f"vec4_tile{d.tile}"][f"vec4_tile{d.tile}"] == [7.0] * 14
    assert record["measured_ms"]["shadow"]["tile16"] == [4.9] * 7
    monkeypatch.setattr(tuning, "_choices", {})             # a later process reads, measures nothing
    assert autotune.ensure(cpu) == Choice(4, d.tile, 32) and len(calls) == len(steps) + 1
    monkeypatch.setattr(tuning, "_choices", {})
    assert tuning.choice(dev) == Choice(4, d.tile, 32)
    summary = tuning.summary(dev)
    assert summary["complete"] and (summary["vec"], summary["tile"], summary["shadow_tile"]) == (4, d.tile, 32)
    from clrender.device import report
    assert report._raster_cell(summary) == f"4/{d.tile}/32 tuned"
    monkeypatch.setattr(tuning, "_choices", {})
    monkeypatch.setenv(tuning.ENV_TUNE, "0")                # off: nothing read, nothing measured
    assert autotune.ensure(cpu) is None and tuning.choice(dev) is None and len(calls) == len(steps) + 1


def test_a_process_runs_the_steps_that_start_within_its_budget(cpu, fresh, monkeypatch):
    dev = cpu.cl_device
    d = tuning.default_choice(dev)
    calls = []
    ms = {(d.vec, d.tile): 10.0, (4, d.tile): 10.0, (d.vec, 16): 10.0, (16, 16): 10.0, 32: 5.0, 16: 4.0}
    monkeypatch.setattr(autotune, "measure", _fake_measure(calls, ms))
    assert autotune.ensure(cpu) == Choice(d.vec, d.tile, 16)  # all within the budget: shadow 16 20 % faster
    assert len(calls) == len(autotune.steps(dev)) + 1 and tuning.cached_record(dev)["complete"]


def test_a_win_that_does_not_repeat_keeps_the_default(cpu, fresh, monkeypatch):
    """The first set says VEC 4 is 30 % faster, the second 20 % slower: over both, no clear win."""
    dev = cpu.cl_device
    d = tuning.default_choice(dev)
    sets = iter([0.7, 1.2])
    def measure(device, step, vec=None, **_):
        default, cand = step[1]
        r = next(sets) if cand == (4, d.tile) else 1.0
        return {default: [10.0] * 7, cand: [10.0 * r] * 7}
    monkeypatch.setattr(autotune, "measure", measure)
    assert autotune.ensure(cpu) == d
    assert tuning.cached_record(dev)["measured_ms"][f"vec4_tile{d.tile}"][f"vec4_tile{d.tile}"] == [7.0] * 7 + [12.0] * 7


def test_a_cold_start_leaves_the_tune_to_the_next_run(cpu, fresh, monkeypatch):
    """The process that probed the device (new machine or kernels) renders with the defaults and
    measures nothing; the next process tunes."""
    from clrender.device import probe
    calls = []
    monkeypatch.setattr(autotune, "measure", _fake_measure(calls, {c: 1.0 for _, _, cs in autotune.steps(cpu.cl_device) for c in cs}))
    probe._probed_here.add(cpu.cl_device.int_ptr)
    assert autotune.ensure(cpu) is None and not calls and tuning.cached_record(cpu.cl_device) is None
    probe._probed_here.clear()                                # the next process
    assert autotune.ensure(cpu) == tuning.default_choice(cpu.cl_device) and calls


def test_a_damaged_cache_entry_is_measured_again(cpu, fresh, monkeypatch):
    dev = cpu.cl_device
    cache.write_json(tuning.entry_name(dev), {"choice": {"vec": "x"}, "complete": True})
    calls = []
    monkeypatch.setattr(autotune, "measure", _fake_measure(calls, {c: 1.0 for _, _, cs in autotune.steps(dev) for c in cs}))
    assert autotune.ensure(cpu) == tuning.default_choice(dev) and calls


def test_the_real_measurement_times_every_candidate(cpu, monkeypatch):
    """A short run of the real workload (2 rounds) for each step: every candidate has its timings."""
    for _, kind, cands in autotune.steps(cpu.cl_device):
        times = autotune.measure(cpu, (kind, cands), rounds=2)
        assert set(times) == set(cands) and all(len(ts) == 2 and min(ts) > 0 for ts in times.values())


# -- no choice changes a pixel ------------------------------------------------------------------------

def _candidates(dev) -> list[Choice]:
    """The default, then each VEC, camera tile and shadow tile the tune may pick, each changed."""
    d = tuning.default_choice(dev)
    out = [d, Choice(4, 8, 16), Choice(8, 16, 32), Choice(4, 16, 16)]
    if capabilities.compiler_has_512bit_vectors(dev):
        out.append(Choice(16, 16, 32))
    return list(dict.fromkeys(out))


def test_every_candidate_renders_the_check_cases_identically(cpu, monkeypatch):
    from clrender.render.renderer import Renderer
    from clrender.tools.check import AOVS, default_cases
    width, height = 96, 64
    cases = default_cases(width, height)
    frames = {}
    monkeypatch.setattr(tuning, "_complete", {cpu.cl_device.int_ptr})      # planted: no tune runs
    for c in _candidates(cpu.cl_device):
        monkeypatch.setitem(tuning._choices, cpu.cl_device.int_ptr, c)
        r = Renderer(width, height, device=cpu.info, ssao=True)
        assert (r.pipeline.raster.vec, r.pipeline.raster.tile, r.pipeline.binning.tile) == (c.vec, c.tile, c.tile)
        for name, scene, camera in cases:
            frames[c, name] = r.render(scene, camera, time=0.5)
        stages = r.pipeline.shadow.stages.values() if r.pipeline.shadow is not None else ()
        assert {(st.binning.tile, st.raster.tile, st.raster.vec) for st in stages} == {
            (c.shadow_tile, c.shadow_tile, min(c.vec, c.shadow_tile))}      # the soup's shadow maps
    base = _candidates(cpu.cl_device)[0]
    for c in _candidates(cpu.cl_device)[1:]:
        for name, _, _ in cases:
            for aov in AOVS:
                a, b = getattr(frames[base, name], aov), getattr(frames[c, name], aov)
                a, b = np.asarray(a), np.asarray(b)
                assert a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes(), \
                    f"{c} changes {aov} of check case {name}"


def test_a_renderer_tunes_its_device_and_runs_the_choice(cpu, fresh, monkeypatch):
    """Renderer() is where the tune runs (the render layer): its config then names what runs."""
    from clrender.render.renderer import Renderer
    dev = cpu.cl_device
    d = tuning.default_choice(dev)
    ms = {c: 10.0 for _, _, cs in autotune.steps(dev) for c in cs}
    ms[(d.vec, 16)] = 8.0                                       # tile 16: 20 % faster
    calls = []
    monkeypatch.setattr(autotune, "measure", _fake_measure(calls, ms))
    r = Renderer(32, 32, device=cpu.info)
    assert calls and tuning.cached_record(dev)["choice"]["tile"] == 16
    assert (r.config.tile_size, r.pipeline.binning.tile, r.pipeline.raster.tile) == (16, 16, 16)
    assert r.config.shadow_tile_size == d.shadow_tile
    assert Renderer(32, 32, device=cpu.info, tile_size=8).pipeline.raster.tile == 8     # explicit wins


def _screen_areas(scene, camera, width, height):
    """Pixel areas of the triangles with a vertex in front of the camera and a bounding box on
    screen (NumPy: the projection written out, not clrender's setup)."""
    vp = camera.projection_matrix(width / height) @ camera.view_matrix()
    clip = np.c_[scene.positions, np.ones(len(scene.positions))] @ vp.T
    t = clip[scene.triangles]
    front = (t[..., 3] > 1e-6).all(1)
    ndc = t[..., :2] / np.where(front[:, None, None], t[..., 3:4], 1.0)
    on = front & (ndc.max(1) > -1).all(1) & (ndc.min(1) < 1).all(1)
    x, y = (ndc[..., 0] + 1) * width / 2, (ndc[..., 1] + 1) * height / 2
    area = 0.5 * np.abs((x[:, 1] - x[:, 0]) * (y[:, 2] - y[:, 0]) - (x[:, 2] - x[:, 0]) * (y[:, 1] - y[:, 0]))
    return area[on], on


def test_the_workload_has_the_statistics_it_was_made_to():
    """tune_workload's doc: Sponza's 0.23 triangles per pixel, log-normal areas (median 1.3 px,
    90th percentile ~19), 13 % alpha-masked; a seeded scene, the same every time."""
    from clrender.render import tune_workload
    w, h = autotune.SIZE
    scene, camera = tune_workload.workload((w, h))
    again, _ = tune_workload.workload((w, h))
    assert scene.positions.tobytes() == again.positions.tobytes()
    area, on = _screen_areas(scene, camera, w, h)
    assert 0.18 < on.sum() / (w * h) < 0.28
    p50, p90 = np.percentile(area, [50, 90])
    assert 0.8 < p50 < 2.0 and 10 < p90 < 40
    masked = np.array([m.alpha_mode == "MASK" for m in scene.materials])[scene.triangle_material]
    assert 0.11 < masked.mean() < 0.15
    assert not scene.materials[0].double_sided and scene.textures[scene.materials[1].base_color_texture].rgba[..., 3].std() > 0
