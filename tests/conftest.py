"""Shared pytest configuration: OpenCL device selection and the renderer factory.

--device NAME|all   which OpenCL devices the `device` fixture runs on (default: $CLRENDER_TEST_DEVICE,
                    else the device a Renderer picks, clrender.device.probe.default_device_info;
                    `all` = every device except simulators such as Oclgrind, which only run when
                    named). NAME is a case-insensitive substring of "platform / device" or "P:D".

OpenCL is touched only when a collected test actually uses `device` (directly or through
`make_renderer`), so the pure-NumPy tests collect and run without it.
"""
from __future__ import annotations

import json
import os
import sys
import time

import pytest

# tests/ on sys.path so `from reference.raster import ...` works under any import mode.
_TESTS_DIR = os.path.dirname(os.path.abspath(__file__))
if _TESTS_DIR not in sys.path:
    sys.path.insert(0, _TESTS_DIR)

ENV_TEST_DEVICE = "CLRENDER_TEST_DEVICE"


# Oclgrind's checks for the simulator tier: out-of-bounds accesses are always reported; these add
# data races, uses of uninitialized values and invalid OpenCL API calls. Read when the
# simulator loads, so they are set before any OpenCL call.
OCLGRIND_CHECKS = {"OCLGRIND_DATA_RACES": "1", "OCLGRIND_UNINITIALIZED": "1", "OCLGRIND_CHECK_API": "1"}


def pytest_configure(config):
    spec, _ = _device_spec(config)
    # The raster autotune (clrender/render/autotune.py) times candidates on a device's first runs;
    # tests run today's defaults so that their stats and timings do not depend on the machine's
    # load. tests/test_autotune.py unsets this, measures, and renders every candidate bit-identically.
    os.environ.setdefault("CLRENDER_TUNE", "0")
    if "oclgrind" in spec.lower():
        for name, value in OCLGRIND_CHECKS.items():
            os.environ.setdefault(name, value)
        _retain_device_arrays()
    _quiet_pyopencl_vendor_probe()


_RETAINED: list = []


def _retain_device_arrays():
    """Oclgrind 21.10's uninitialized-value checker keeps stale state when a released buffer's
    slot goes to a new buffer, and then reports reads of the new, fully written buffer as
    uninitialized (reproduced with two renderers and two scenes, the first scene released).
    The simulator tier's frames are tiny, so it keeps every device array alive instead."""
    import pyopencl.array as cla
    init = cla.Array.__init__
    if getattr(init, "_clrender_retain", False):
        return

    def retaining_init(self, *args, **kwargs):
        init(self, *args, **kwargs)
        _RETAINED.append(self)

    retaining_init._clrender_retain = True
    cla.Array.__init__ = retaining_init


def _quiet_pyopencl_vendor_probe():
    """pyopencl asks every device for CL_DEVICE_COMPUTE_CAPABILITY_MAJOR_NV at each program
    build and kernel-argument setup; off NVIDIA that query is invalid, and Oclgrind's API
    checker reports it. Answer None (what pyopencl concludes from the failed query) without
    asking, for platforms that are not NVIDIA's."""
    try:
        import pyopencl.characterize as characterize
    except ImportError:
        return
    ask = characterize.nv_compute_capability
    if getattr(ask, "_clrender_shim", False):
        return

    def nv_compute_capability(dev):
        return ask(dev) if "nvidia" in dev.platform.name.lower() else None

    nv_compute_capability._clrender_shim = True
    characterize.nv_compute_capability = nv_compute_capability


def pytest_addoption(parser):
    parser.addoption(
        "--device", action="store", default=None, metavar="NAME|all",
        help=f"OpenCL device(s) for device tests: 'all' (no simulators), or a case-insensitive substring "
             f"of 'platform / device', or 'P:D'. Default: ${ENV_TEST_DEVICE}, else the default device.")


def _device_spec(config) -> tuple[str, bool]:
    """(spec, explicit): explicit when given by --device or the environment; else "default"."""
    spec = config.getoption("--device")
    if spec:
        return spec, True
    spec = os.environ.get(ENV_TEST_DEVICE, "").strip()
    if spec:
        return spec, True
    return "default", False


def _selected_devices(config):
    """[(DeviceInfo, None)] or [(None, reason to skip)]; computed once per session. "default": the
    device a Renderer picks (only that one is probed); "all": every device but simulators."""
    cached = getattr(config, "_clrender_devices", None)
    if cached is not None:
        return cached
    spec, explicit = _device_spec(config)
    try:
        from clrender.device.probe import default_device_info, select_devices     # lazy: imports pyopencl
    except ImportError as exc:
        result = [(None, f"OpenCL unavailable ({exc})")]
    else:
        try:
            devices = [default_device_info()] if spec == "default" else list(select_devices(spec))
        except Exception as exc:                        # no platform / no match
            if explicit and spec.lower() != "all":
                raise pytest.UsageError(f"--device {spec!r}: {exc}") from None
            result = [(None, f"no OpenCL device: {exc}")]
        else:
            if not devices:
                if explicit and spec.lower() != "all":
                    raise pytest.UsageError(f"--device {spec!r} matches no OpenCL device")
                result = [(None, "no OpenCL device found")]
            else:
                result = [(d, None) for d in devices]
    config._clrender_devices = result
    return result


def pytest_generate_tests(metafunc):
    if "device" not in metafunc.fixturenames:
        return
    params, ids = [], []
    for info, why in _selected_devices(metafunc.config):
        if info is None:
            if os.environ.get("CLRENDER_CI", "").strip() not in ("", "0"):
                raise pytest.UsageError(f"CI: {why}: the device tests cannot run")   # not a silent skip
            params.append(pytest.param(None, marks=pytest.mark.skip(reason=why)))
            ids.append("no-device")
        else:
            params.append(info)
            ids.append(info.label)
    metafunc.parametrize("device", params, ids=ids, indirect=True, scope="session")


@pytest.fixture(scope="session")
def device(request):
    """One selected OpenCL device (a clrender.device.core.DeviceInfo: `.id` "P:D", `.label`)."""
    return request.param


@pytest.fixture(scope="session")
def make_renderer(device):
    """Factory `make_renderer(width, height, **opts) -> clrender.Renderer` on `device`.

    Renderers are cached per (width, height, opts) for the session (building one compiles
    the kernels); render() must not depend on earlier calls, which the determinism test checks."""
    import clrender

    cache = {}

    def factory(width, height, **opts):
        key = (int(width), int(height), repr(sorted(opts.items())))
        if key not in cache:
            cache[key] = clrender.Renderer(width=width, height=height, device=device.id, **opts)
        return cache[key]

    return factory


def pytest_terminal_summary(terminalreporter):
    """How many OpenCL programs this session built, by kernel file (docs/variants.md counts them)."""
    import sys
    device_module = sys.modules.get("clrender.device.core")
    if device_module is None or not device_module.Device.build_count:
        return
    per_file: dict = {}
    for spec in device_module.Device.session_specs():
        per_file[spec.filename] = per_file.get(spec.filename, 0) + 1
    files = ", ".join(f"{name} {n}" for name, n in sorted(per_file.items(), key=lambda kv: (-kv[1], kv[0])))
    terminalreporter.write_line(f"clrender: {device_module.Device.build_count} OpenCL program builds "
                                f"({sum(per_file.values())} distinct programs: {files})")


ENV_BUILD_LOG = "CLRENDER_BUILD_LOG"


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item, nextitem):
    """$CLRENDER_BUILD_LOG=PATH: one JSON line per test (setup + call + teardown): its wall
    seconds, start/end times, the programs it built (file, defines, build seconds) and those it
    used (built by an earlier test or not; docs/testing.md, cold CI time). PoCL
    compiles each kernel at its first launch, inside the test's time but not in the build seconds:
    its cache's file times (program.bc, <kernel>.so) place those compiles between start and end."""
    path = os.environ.get(ENV_BUILD_LOG)
    core = sys.modules.get("clrender.device.core") if path else None
    before = {id(d): len(d.built) for d in core._opened} if core else {}
    if core is not None and not getattr(core.Device.has_program, "_clrender_log", False):
        _log_program_uses(core.Device)     # loaded at collection by the device parametrization
    _USED.clear()
    t0, wall0 = time.perf_counter(), time.time()
    yield
    if not path:
        return
    core = sys.modules.get("clrender.device.core")
    built = [{"file": spec.filename, "defines": dict(spec.defines), "s": round(s, 3), "device": d.info.id}
             for d in (core._opened if core else []) for spec, s in d.built[before.get(id(d), 0):]]
    used = sorted(str(spec) for spec in _USED)
    with open(path, "a") as f:
        f.write(json.dumps({"test": item.nodeid, "s": round(time.perf_counter() - t0, 3), "start": wall0,
                            "end": time.time(), "built": built, "used": used}) + "\n")


_USED: set = set()


def _log_program_uses(device_class):
    """Record each spec a test asks for (a frame's up-front build asks has_program of each)."""
    has = device_class.has_program

    def has_program(self, spec):
        _USED.add(spec)
        return has(self, spec)

    has_program._clrender_log = True
    device_class.has_program = has_program


def blinn_phong_renderer_fixture():
    """A module's `make_renderer` that defaults to shading="blinn_phong" (tests of the report's
    mapping of metallic-roughness materials): `make_renderer = blinn_phong_renderer_fixture()`."""
    @pytest.fixture(name="make_renderer")
    def _make_renderer(make_renderer):
        def factory(width, height, **opts):
            opts.setdefault("shading", "blinn_phong")
            return make_renderer(width, height, **opts)
        return factory
    return _make_renderer
