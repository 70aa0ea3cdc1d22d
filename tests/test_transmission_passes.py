"""The passes of the transmission path (issue 38, docs/transmission.md), tested on their own kernels:
the opaque colour's mip chain (kernels/transmission.cl) against a NumPy 2×2-box pyramid, the
composite's TRANSMISSION lookup (kernels/composite.cl) against a NumPy trilinear sampler written
from its documented coordinates, and a scene without transmissive materials building and
launching none of it. The kernel tests are in the Oclgrind tier (`-m oclgrind --device oclgrind`), where
any invalid access Oclgrind reports fails them."""
from __future__ import annotations

import numpy as np
import pyopencl.array as cla
import pytest

import clrender
from clrender.device.core import Device, lazy_kernels
from clrender.passes.base import Resources
from clrender.passes.composite import CompositePass
from clrender.passes.forward import LAYER_PLANES, TX_PLANES
from clrender.passes.transmission import TransmissionPass, mip_levels
from reference.raster import pixel_exact_camera
from test_memory import glass_scene

SIZES = [(64, 32), (37, 23), (1, 9), (16, 1), (5, 5)]


@pytest.fixture
def cl_device(device):
    return Device.get(device)


def assert_no_device_diagnostics(capfd):
    """Oclgrind prints each finding (an invalid access...) to stderr with a `Kernel:` line."""
    err = capfd.readouterr().err
    flagged = [ln for ln in err.splitlines() if "Kernel:" in ln or "oclgrind" in ln.lower() or "error" in ln.lower()]
    assert not flagged, "the OpenCL implementation reported problems:\n" + err[:4000]


def box_pyramid(img: np.ndarray) -> list:
    """float64 pyramid of (3, H, W) `img`: each level the 2×2 means of the previous one, whose odd
    last row/column is repeated (edge padding), down to 1×1."""
    levels = [img.astype(np.float64)]
    while levels[-1].shape[1:] != (1, 1):
        a = levels[-1]
        h, w = a.shape[1:]
        a = np.pad(a, ((0, 0), (0, h % 2), (0, w % 2)), mode="edge")
        levels.append(a.reshape(3, a.shape[1] // 2, 2, a.shape[2] // 2, 2).mean(axis=(2, 4)))
    return levels


def run_mips(dev, opaque: np.ndarray):
    """TransmissionPass over (3, H, W) float32 `opaque`: (the pass, its Resources after the run)."""
    _, h, w = opaque.shape
    p = TransmissionPass(dev, clrender.RenderConfig())
    p.allocate(w, h)
    res = Resources(buffers={"color": cla.to_device(dev.queue, opaque.reshape(-1))},
                    values={"transmissive_materials": 1})
    assert p.active(res)
    p.publish(res)
    p.clear_stage_events()
    p.run(res)
    return p, res


@pytest.mark.oclgrind
@pytest.mark.parametrize("w,h", SIZES)
def test_mip_chain_is_the_box_pyramid(cl_device, capfd, w, h):
    rng = np.random.default_rng(w * 100 + h)
    img = rng.uniform(0.0, 4.0, (3, h, w)).astype(np.float32)
    p, res = run_mips(cl_device, img)
    ref = box_pyramid(img)
    table = res["opaque_mip_levels"].get().reshape(-1, 4)
    assert res["opaque_mip_count"] == len(ref) == len(table)
    assert [tuple(r[1:3]) for r in table] == [(lv.shape[2], lv.shape[1]) for lv in ref]
    mips = res["opaque_mips"].get()
    expected_offset = 0
    for (offset, lw, lh, _), lv in zip(table[1:], ref[1:]):
        assert offset == expected_offset                # levels packed one after another, 3 planes each
        got = mips[offset: offset + 3 * lw * lh].reshape(3, lh, lw)
        np.testing.assert_allclose(got, lv, rtol=1e-6, atol=1e-6)
        expected_offset += 3 * lw * lh
    assert p.stage_stats()["transmission_mips_ms"] >= 0
    assert_no_device_diagnostics(capfd)


def test_even_sizes_keep_the_mean_on_every_level(cl_device):
    img = np.random.default_rng(5).uniform(0.0, 10.0, (3, 32, 64)).astype(np.float32)
    _, res = run_mips(cl_device, img)
    mips = res["opaque_mips"].get()
    mean = img.astype(np.float64).mean(axis=(1, 2))
    for offset, lw, lh in mip_levels(64, 32)[1:]:
        level = mips[offset: offset + 3 * lw * lh].reshape(3, lh, lw).astype(np.float64)
        np.testing.assert_allclose(level.mean(axis=(1, 2)), mean, rtol=1e-6)


def trilinear(levels: list, lod: float, c: int, sx: float, sy: float) -> float:
    """Channel c of the float64 pyramid at pixel-index position (sx, sy) of level 0 (pixel x's centre
    at x): on level l the point lies at (s + 0.5)/2^l - 0.5, clamped to the level's pixel centres,
    read bilinearly; lod is clamped to the chain and blends its two nearest levels."""
    def bilinear(l):
        a = levels[l][c]
        h, w = a.shape
        u = min(max((sx + 0.5) / 2.0 ** l - 0.5, 0.0), w - 1.0)
        v = min(max((sy + 0.5) / 2.0 ** l - 0.5, 0.0), h - 1.0)
        x0, y0 = int(np.floor(u)), int(np.floor(v))
        x1, y1 = min(x0 + 1, w - 1), min(y0 + 1, h - 1)
        fx, fy = u - x0, v - y0
        return ((a[y0, x0] * (1 - fx) + a[y0, x1] * fx) * (1 - fy) + (a[y1, x0] * (1 - fx) + a[y1, x1] * fx) * fy)
    lod = min(lod, len(levels) - 1.0)
    l0 = int(np.floor(lod))
    f = lod - l0
    return bilinear(l0) if f == 0 else bilinear(l0) * (1 - f) + bilinear(l0 + 1) * f


def composite(dev, opaque, layers, tx=None, refraction=False):
    """CompositePass over the planes (TRANSMISSION when `tx` is given); (its colour (3, H, W), the pass)."""
    _, h, w = opaque.shape
    comp = CompositePass(dev, clrender.RenderConfig(refraction=refraction))
    comp.allocate(w, h)
    res = Resources(buffers={"color": cla.to_device(dev.queue, opaque.reshape(-1)),
                             "layers": cla.to_device(dev.queue, layers.reshape(-1))},
                    values={"width": w, "height": h})
    if tx is not None:
        _, mres = run_mips(dev, opaque)
        res.buffers.update(tx_planes=cla.to_device(dev.queue, tx.reshape(-1)), opaque_mips=mres["opaque_mips"],
                           opaque_mip_levels=mres["opaque_mip_levels"])
        res.values["opaque_mip_count"] = mres["opaque_mip_count"]
    comp.publish(res)
    comp.run(res)
    return res["color"].get().reshape(3, h, w), comp


def random_planes(rng, w, h):
    opaque = rng.uniform(0.0, 3.0, (3, h, w)).astype(np.float32)
    layers = rng.uniform(0.0, 1.0, (LAYER_PLANES, h, w)).astype(np.float32)
    tx = rng.uniform(0.0, 1.0, (TX_PLANES, h, w)).astype(np.float32)
    return opaque, layers, tx


@pytest.mark.oclgrind
@pytest.mark.parametrize("refraction", [False, True])
@pytest.mark.parametrize("w,h", [(48, 40), (37, 23)])
def test_composite_transmission_lookup(cl_device, capfd, w, h, refraction):
    """lod >= 0: acc_c + T_c × the trilinear sample at (x + ox_c, y + oy_c); lod -1: the pixel itself;
    lod -2: the REFRACTION displaced lookup (the pixel itself without REFRACTION)."""
    rng = np.random.default_rng(w + 7 * refraction)
    opaque, layers, tx = random_planes(rng, w, h)
    n_levels = len(box_pyramid(opaque))
    # offsets on a 1/64 grid (exact sums in float32, some past the image edge), lods on a 1/8 grid
    # from 0 to past the chain's end; a quarter of the pixels without lookup, a quarter legacy
    for plane in (4, 5, 6, 7):
        tx[plane] = rng.integers(-30 * 64, 30 * 64, (h, w)) / 64.0
    layers[4:6] = rng.integers(-30 * 64, 30 * 64, (2, h, w)) / 64.0
    lod = rng.integers(0, 8 * (n_levels + 1), (h, w)) / 8.0
    kind = rng.integers(0, 4, (h, w))
    lod[kind == 0], lod[kind == 1] = -1.0, -2.0
    layers[4:6, :3, :3] = 0.0                       # legacy pixels with a zero offset: not displaced
    lod[:3, :3] = -2.0
    tx[3] = lod
    got, _ = composite(cl_device, opaque, layers, tx, refraction)
    levels = box_pyramid(opaque)
    offsets = (tx[4:6], layers[4:6], tx[6:8])
    expect = np.empty((3, h, w))
    for y in range(h):
        for x in range(w):
            for c in range(3):
                if lod[y, x] >= 0:
                    ox, oy = offsets[c][0, y, x], offsets[c][1, y, x]
                    behind = trilinear(levels, float(lod[y, x]), c, x + float(ox), y + float(oy))
                elif lod[y, x] == -2 and refraction:      # the legacy lookup: level 0, G's offset
                    behind = trilinear(levels[:1], 0.0, c, x + float(layers[4, y, x]), y + float(layers[5, y, x]))
                else:
                    behind = float(opaque[c, y, x])
                expect[c, y, x] = layers[c, y, x] + tx[c, y, x] * behind
    np.testing.assert_allclose(got, expect, rtol=2e-6, atol=2e-6)
    # and with offsets anywhere (not on the grid): within float32 rounding of the coordinates
    for plane in (4, 5, 6, 7):
        tx[plane] = rng.uniform(-20.0, 20.0, (h, w))
    tx[3] = np.where(lod >= 0, rng.uniform(0.0, n_levels, (h, w)), lod)
    got, _ = composite(cl_device, opaque, layers, tx, refraction)
    sel = tx[3] >= 0
    ys, xs = np.nonzero(sel)
    for c in range(3):
        ox, oy = (tx[4], tx[5]) if c == 0 else (layers[4], layers[5]) if c == 1 else (tx[6], tx[7])
        ref = [layers[c, y, x] + tx[c, y, x] * trilinear(levels, float(tx[3, y, x]), c, x + float(ox[y, x]),
                                                          y + float(oy[y, x])) for y, x in zip(ys, xs)]
        np.testing.assert_allclose(got[c][sel], ref, rtol=1e-4, atol=1e-4)
    assert_no_device_diagnostics(capfd)


@pytest.mark.oclgrind
@pytest.mark.parametrize("refraction", [False, True])
def test_without_lookup_the_transmission_composite_is_the_plain_one(cl_device, capfd, refraction):
    """T_c = the layers' transmittance and lod -1 (no transmissive fragment): the plain composite bit
    for bit; with REFRACTION, lod -2 everywhere (BLEND refraction only) is too. The plain composite
    is acc + T × opaque in float32, bit for bit."""
    w, h = 41, 27
    rng = np.random.default_rng(11)
    opaque, layers, tx = random_planes(rng, w, h)
    layers[4:6] = rng.uniform(-6.0, 6.0, (2, h, w))
    layers[4:6, ::3] = 0.0
    tx[0:3] = layers[3]
    plain, comp = composite(cl_device, opaque, layers, refraction=refraction)
    assert "kernel_transmission" not in vars(comp)
    if not refraction:
        np.testing.assert_array_equal(plain, layers[:3] + layers[3] * opaque)
    for lod in ((-1.0, -2.0) if not refraction else (-2.0,)):
        tx[3] = lod
        got, comp = composite(cl_device, opaque, layers, tx, refraction)
        assert "TRANSMISSION" in dict(comp.kernel_transmission.spec.defines)
        np.testing.assert_array_equal(got, plain)
    if refraction:              # lod -1 under REFRACTION: not displaced, unlike the plain composite
        tx[3] = -1.0
        got, _ = composite(cl_device, opaque, layers, tx, refraction)
        np.testing.assert_array_equal(got, layers[:3] + layers[3] * opaque)
        assert not np.array_equal(got, plain)
    assert_no_device_diagnostics(capfd)


@pytest.mark.parametrize("mode", ["abuffer", "depth_peeling"])
def test_no_transmissive_material_builds_and_launches_nothing_new(device, mode):
    """A BLEND scene (no transmissive material): no TRANSMISSION variant, no mip kernel launched, no tx
    planes or mip chain allocated, no transmission entry in the stats; the depth is the G-buffer's."""
    dev = Device.get(device)
    built_before = len(dev.built)
    r = clrender.Renderer(96, 64, device=device.id, transparency=mode)
    frame = r.render(glass_scene(), camera=pixel_exact_camera())
    assert frame.stats["fragments"] > 0
    assert not any(k.startswith("transmission") for k in frame.stats)
    kernels = [k for p in r.pipeline.passes for k in lazy_kernels(p)]
    assert not [k for k in kernels if "TRANSMISSION" in dict(k.spec.defines)]
    mip = [k for k in kernels if k.spec.filename == "transmission.cl"]
    assert len(mip) == 1 and mip[0]._kernel is None           # made with the pass, never resolved
    new = [str(spec) for spec, _ in dev.built[built_before:]]
    assert not [s for s in new if "TRANSMISSION" in s or s.startswith("transmission.cl")], new
    by_owner = frame.stats["device_bytes_by_owner"]
    assert by_owner["transmission"] == 0
    transparency = [p for p in r.pipeline.passes if p.name in ("abuffer", "peel")]
    assert len(transparency) == 1 and transparency[0].tx_planes is None
    assert "transmission_depth" not in frame.readback.names()
    np.testing.assert_array_equal(frame.depth, frame.linear_depth * np.float32(frame.far))


def glass_over_wall(transmissive: bool = True):
    """A thin-walled glass quad (z = -4, view pixels 16..47 of 64) over an unlit checkerboard wall
    (z = -10) that covers the left half of the view only: the glass's right half is over background.
    transmissive=False: the quad is a BLEND material instead."""
    from transparency_cases import build_scene, quad
    white = clrender.Material("white", (0.9, 0.9, 0.9, 1.0), unlit=True)
    black = clrender.Material("black", (0.1, 0.1, 0.1, 1.0), unlit=True)
    parts = [(quad(-10.0 + 2.5 * i, -7.5 + 2.5 * i, -10.0 + 2.5 * j, -7.5 + 2.5 * j, -10.0), None,
              white if (i + j) % 2 else black) for i in range(4) for j in range(8)]
    glass = clrender.Material.from_metallic_roughness("glass", (0.9, 0.6, 0.3, 1.0), 0.0, 0.0, transmission=1.0)
    if not transmissive:
        glass = clrender.Material("glass", (0.9, 0.6, 0.3, 0.5), alpha_mode="BLEND")
    parts.append((quad(-2.0, 2.0, -2.0, 2.0, -4.0), None, glass))
    return build_scene(parts, ambient=0.0)


@pytest.mark.parametrize("opts", [dict(), dict(transparency="depth_peeling"), dict(supersample=2)],
                         ids=["abuffer", "depth_peeling", "supersample2"])
def test_transmissive_frame_depth_buffers_and_stats(device, opts):
    """A glass quad: Frame.depth is the glass's view depth where it is the nearest surface (over the
    wall and over the background), the wall's elsewhere; `position` lies on the glass there; the mip
    pass shows in the stats; the tx planes and the chain are what the passes declare (memory.estimate)."""
    from clrender.render import memory, plan
    w = h = 64
    scene = glass_over_wall()
    r = clrender.Renderer(w, h, device=device.id, **opts)
    frame = r.render(scene, camera=pixel_exact_camera(far=50.0))
    assert frame.stats["transmission_ms"] > 0 and "transmission_mips_ms" in frame.stats
    glass = np.zeros((h, w), bool)
    glass[16:48, 16:48] = True
    wall = np.zeros((h, w), bool)
    wall[:, :32] = True
    np.testing.assert_allclose(frame.depth[glass], 4.0, rtol=1e-6)
    np.testing.assert_allclose(frame.depth[wall & ~glass], 10.0, rtol=1e-6)
    assert np.isinf(frame.depth[~wall & ~glass]).all()
    np.testing.assert_allclose(frame.position[glass][:, 2], -4.0, rtol=1e-6)
    assert np.isnan(frame.position[~wall & ~glass]).all()
    assert (frame.object_id[glass] >= 0).all() and (frame.linear_depth[glass & ~wall] > 1e30).all()
    # behind the glass: the wall's colour tinted (thin-walled, roughness 0: no offset, no blur)
    inner = glass & wall
    assert frame.color[inner].max() > 0.3 and np.all(frame.color[inner][:, 0] > frame.color[inner][:, 2])
    k = r.config.supersample
    held = frame.stats["device_bytes_by_owner"]
    for p in r.pipeline.passes:
        if p.name in ("transmission", "abuffer", "peel"):
            declared = type(p).buffer_bytes(k * w, k * h, r.config, scene)
            tx = {n: b for n, b in declared.items() if "tx_planes" in n or n.startswith("transmission.")}
            assert tx and sum(tx.values()) > 0
            assert 0 <= held[p.name] - sum(declared.values()) <= 256, (p.name, held[p.name], declared)
    with_tx = memory.estimate(w, h, r.config, scene)["total"]
    plain = memory.estimate(w, h, r.config, glass_over_wall(transmissive=False))["total"]
    stage = [cls for cls in plan.pass_classes(r.config) if cls.name in ("transmission", "abuffer", "peel")]
    extra = sum(b for cls in stage for n, b in cls.buffer_bytes(k * w, k * h, r.config, scene).items()
                if "tx_planes" in n or n.startswith("transmission."))
    assert extra >= (9 * 4 + 4) * k * w * k * h        # the 9 planes and the chain (about 4 bytes a pixel)
    assert with_tx - plain == extra
