"""The first run (issue 23): programs build only when a render needs them, explicit launch shapes
(a new image size compiles nothing new), the device probe asks only the device that will be used,
and slow builds report progress (a bar in the CLI, silent with -q, the logger in the library)."""
from __future__ import annotations

import logging
from pathlib import Path

import numpy as np
import pytest

import clrender
from clrender.cli import app as cli
from clrender.device import probe as device_probe
from clrender import progress
from clrender.device.core import Device, LazyKernel, lazy_kernels

REPO = Path(__file__).resolve().parent.parent


def _quad_scene(shadow: bool = False) -> clrender.Scene:
    v = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], np.float32)
    scene = clrender.Scene.from_arrays(v, np.array([[0, 1, 2], [0, 2, 3]]))
    scene.add_point_light((0, 0, 1), (1, 1, 1), 4.0)
    if shadow:
        scene.set_sun((0.2, -0.3, -1), (1, 1, 1), shadow=True, shadow_map_size=64)   # orthographic maps
    return scene


CAMERA = clrender.Camera.look_at((0, 0, 3), (0, 0, 0))


@pytest.fixture
def fresh_programs(monkeypatch):
    """An empty process-wide program cache for the test (restored after), so what a render builds
    can be counted. Builds hit PoCL's kernel cache: cheap."""
    monkeypatch.setattr(Device, "_programs", {})


def _pass_specs(pipeline, passes) -> set:
    return {k.spec for p in passes for k in lazy_kernels(p)}


def test_a_renderer_builds_nothing_until_it_renders(device, fresh_programs):
    r = clrender.Renderer(16, 16, device=device.id)
    assert Device._programs == {}, "constructing a Renderer must not build programs"
    assert all(not k.built for p in r.pipeline.passes for k in lazy_kernels(p))


def test_a_render_builds_exactly_the_programs_of_the_passes_it_runs(device, fresh_programs):
    r = clrender.Renderer(16, 16, device=device.id)
    frame = r.render(_quad_scene(), CAMERA)
    assert frame.image.any()
    dev = r.device
    built = {spec for spec, _ in dev.built[-len(Device._programs):]}
    ran = [p for p in r.pipeline.passes if f"{p.name}_ms" in frame.stats]
    expected = _pass_specs(r.pipeline, ran)
    # Where markers carry no time (Intel's runtime) the pass-time stamp kernel is built too, once per
    # device: by this test or an earlier one
    stamp = clrender.device.timestamps.SPEC
    assert stamp not in built or not clrender.device.capabilities.markers_carry_time(dev.cl_device)
    assert built - {stamp} == expected, (sorted(map(str, (built - {stamp}) ^ expected)))
    assert len(Device._programs) - int(stamp in built) == len(expected)
    # no BLEND triangle, no particles, no shadowed light: those passes built nothing
    skipped = [p for p in r.pipeline.passes if f"{p.name}_ms" not in frame.stats]
    assert {p.name for p in skipped} >= {"particles", "shadow"} and "fragments" in {p.name for p in skipped}
    for p in skipped:
        assert not any(k.built for k in lazy_kernels(p) if k.spec not in expected), p.name


def test_a_shadowed_light_builds_the_shadow_programs_then(device, fresh_programs):
    r = clrender.Renderer(16, 16, device=device.id)
    r.render(_quad_scene(), CAMERA)
    before = set(Device._programs)
    frame = r.render(_quad_scene(shadow=True), CAMERA)
    assert "shadow_ms" in frame.stats and frame.shadow.shape[-1] == 1
    assert set(Device._programs) > before, "the sun's (ORTHO) programs are built when first needed"


def test_launch_shapes_do_not_depend_on_the_image_size(device, monkeypatch):
    """Every launch names its local size, and the same one at any image size: PoCL compiles a
    kernel per local size, so a new size must compile nothing new."""
    shapes: dict = {}
    real = LazyKernel.__call__

    def record(self, queue, gsize, lsize, *args, **kw):
        shapes.setdefault(self.size_key, set()).add((self.spec.filename, self.name,
                                                      None if lsize is None else tuple(lsize)))
        return real(self, queue, gsize, lsize, *args, **kw)

    monkeypatch.setattr(LazyKernel, "__call__", record)
    for w, h in ((64, 48), (200, 120)):
        monkeypatch.setattr(LazyKernel, "size_key", (w, h), raising=False)
        scene = clrender.load_scene(REPO / "scenes" / "demo.toml")      # uploaded (mips) per size too
        clrender.Renderer(w, h, device=device.id).render(scene)
    small, large = shapes[(64, 48)], shapes[(200, 120)]
    assert not [s for s in small | large if s[2] is None], "launches that leave the local size to the driver"
    assert small == large


def test_the_probe_asks_only_the_device_that_will_be_used(monkeypatch, tmp_path):
    from clrender.device.core import list_devices, preference_order
    devices = list_devices()
    if not devices:
        pytest.skip("no OpenCL device")
    monkeypatch.setenv("CLRENDER_CACHE_DIR", str(tmp_path))
    monkeypatch.delenv("CLRENDER_DEVICE", raising=False)
    monkeypatch.setattr(device_probe, "_answers", {})
    asked = []
    monkeypatch.setattr(device_probe, "_ask_child", lambda info: asked.append(info.id))
    first = [d for d in preference_order(devices) if not d.is_simulator][0]
    assert device_probe.default_device_info().id == first.id
    assert asked == [first.id]
    # the answer is kept on disk: a new process (an empty memo) asks no child
    monkeypatch.setattr(device_probe, "_answers", {})
    assert device_probe.default_device_info().id == first.id and asked == [first.id]


def test_a_failing_default_device_falls_back_with_one_warning(monkeypatch, tmp_path):
    from clrender.device.core import DeviceInfo
    real = [d for d in clrender.device.core.list_devices() if not d.is_simulator]
    if not real:
        pytest.skip("no OpenCL device")
    broken = DeviceInfo("9:9", "Broken Platform", "broken cpu", real[0].cl_device)
    monkeypatch.setenv("CLRENDER_CACHE_DIR", str(tmp_path))
    monkeypatch.delenv("CLRENDER_DEVICE", raising=False)
    monkeypatch.setattr(device_probe, "_answers", {})
    monkeypatch.setattr(device_probe, "list_devices", lambda: [broken, real[0]])
    monkeypatch.setattr(device_probe, "preference_order", lambda ds: list(ds))
    monkeypatch.setattr(device_probe, "_key", lambda info: info.id.replace(":", "-"))   # both share one cl_device
    monkeypatch.setattr(device_probe, "_ask_child", lambda info: "driver crashed" if info.id == "9:9" else None)
    with pytest.warns(UserWarning, match=r"9:9 .*driver crashed.*next device"):
        assert device_probe.default_device_info().id == real[0].id
    monkeypatch.setattr(device_probe, "_ask_child", lambda info: "driver crashed")
    monkeypatch.setattr(device_probe, "_answers", {})
    monkeypatch.setenv("CLRENDER_CACHE_DIR", str(tmp_path / "again"))
    with pytest.raises(clrender.device.core.DeviceError, match="no OpenCL device runs clrender's kernels"):
        device_probe.default_device_info()


def test_a_probe_child_that_fails_is_one_line(monkeypatch, tmp_path):
    """A real child for a device that is not there: its last line is the reason, the caller lives."""
    from clrender.device.core import DeviceInfo, list_devices
    devices = list_devices()
    if not devices:
        pytest.skip("no OpenCL device")
    ghost = DeviceInfo("99:0", "No Platform", "no such device", devices[0].cl_device)
    error = device_probe._ask_child(ghost)
    assert error == "device 99:0 (no such device) not found"


def test_cli_shows_build_progress_and_q_silences_it(device, tmp_path, capsys, monkeypatch, fresh_programs):
    monkeypatch.setattr(progress, "BAR_DELAY_S", 0.0)
    obj = tmp_path / "quad.obj"
    obj.write_text("v -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\nf 1 2 3\nf 1 3 4\n")
    args = ["render", str(obj), "-o", str(tmp_path / "a.png"), "--width", "16", "--height", "12",
            "--device", device.id]
    assert cli.main(args) == 0
    err = capsys.readouterr().err
    assert "building OpenCL programs for" in err and "first run only, cached afterwards" in err
    monkeypatch.setattr(Device, "_programs", {})
    assert cli.main(args + ["-q"]) == 0
    assert capsys.readouterr().err == ""


def test_the_library_logs_builds_and_prints_nothing(device, capsys, caplog, monkeypatch, fresh_programs):
    monkeypatch.setattr(progress, "BAR_DELAY_S", 0.0)
    with caplog.at_level(logging.INFO, logger="clrender"):
        clrender.Renderer(16, 16, device=device.id).render(_quad_scene(), CAMERA)
    out = capsys.readouterr()
    assert out.err == "" and out.out == ""
    assert any("building OpenCL programs" in r.getMessage() for r in caplog.records)
    assert any(r.getMessage().startswith("building OpenCL programs") and "done in" in r.getMessage()
               for r in caplog.records)


def test_a_build_error_names_the_program_and_device(device, tmp_path, monkeypatch, fresh_programs):
    kernels = tmp_path / "kernels"
    kernels.mkdir()
    for f in (REPO / "kernels").iterdir():
        if f.is_file():
            (kernels / f.name).write_bytes(f.read_bytes())
    (kernels / "broken.cl").write_text("kernel void broken(global int* x) { x[0] = undefined_name; }\n")
    monkeypatch.setattr(clrender.device.core, "kernels_dir", lambda: kernels)
    dev = Device.get(device.id)
    with pytest.raises(clrender.device.core.DeviceError) as info:
        dev.kernel("broken.cl", "broken").get_work_group_info
    message = str(info.value)
    assert "\n" not in message and "broken.cl" in message and dev.name in message


def test_clrender_warmup_builds_what_typical_scenes_run(device, capsys, fresh_programs):
    dev = Device.get(device.id)
    before = len(dev.built)
    assert cli.main(["warmup", "--device", device.id]) == 0
    assert "warmed up" in capsys.readouterr().err
    files = {spec.filename for spec, _ in dev.built[before:]}
    # the check's cases: textures, transparency, shadowed spot and sun, particles, on top of the nine
    assert {"mipmap.cl", "fragments.cl", "abuffer.cl", "particles.cl", "shade.cl"} <= files
    built = len(Device._programs)
    assert cli.main(["warmup", "--device", device.id, "-q"]) == 0
    assert len(Device._programs) == built and capsys.readouterr().err == ""     # warm: nothing new, silent


def test_dask_workers_warm_up_when_they_start(device, fresh_programs):
    pytest.importorskip("distributed")
    import asyncio
    from clrender.batch.dask_plugin import WarmupPlugin
    dev = Device.get(device.id)
    before = len(dev.built)
    asyncio.run(WarmupPlugin(device.id, {"ssao": True}).setup(worker=None))
    names = {spec.filename for spec, _ in dev.built[before:]}
    assert {"setup.cl", "raster.cl", "shade.cl", "ssao.cl"} <= names
