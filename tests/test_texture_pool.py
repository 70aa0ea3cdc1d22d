"""The texture pool (clrender/render/texture_pool.py, kernels/mipmap.cl): mip levels built on the device are
bit-identical to the host definition `mip_chain` (PIL's BOX resize in linear space, 8-bit encoding),
for odd sizes, 1xN and Nx1, tall images (PIL's other pass order), sRGB and linear; the pieces the
kernel relies on (PIL's pass order, the encoder thresholds and table) are checked against PIL and
the host encoder. Also: the program binary cache (clrender/device/core.py) and the binning pass's
initial tile-list room."""
from __future__ import annotations

import numpy as np
import pytest
from PIL import Image

from clrender.render import texture_pool as tp
from clrender.scene.model import Texture

# odd, even, 1xN, Nx1, tall (columns first in PIL), wide, square, prime, 3-tap axes
SIZES = [(1, 1), (1, 2), (2, 1), (1, 7), (9, 1), (3, 3), (5, 3), (37, 23), (23, 37), (64, 64), (64, 16),
         (257, 129), (40, 9), (2, 64), (130, 31)]


def _textures(seed=1):
    rng = np.random.default_rng(seed)
    out = []
    for k, (h, w) in enumerate(SIZES):
        y, x = np.mgrid[0:h, 0:w]
        smooth = np.stack([(x * 255 // max(w - 1, 1)), (y * 255 // max(h - 1, 1)), (x + y) % 256,
                           255 - (x * y) % 256], -1).astype(np.uint8)       # gradients: many near-ties
        noise = rng.integers(0, 256, (h, w, 4), dtype=np.uint8)
        for srgb in (True, False):
            out.append(Texture(f"s{k}{srgb}", smooth, srgb=srgb))
            out.append(Texture(f"n{k}{srgb}", noise, srgb=srgb))
    return out


def _device(device):
    from clrender.device.core import Device
    return Device.get(device)


def test_device_pool_equals_the_host_mip_chains(device):
    d = _device(device)
    if not tp.device_builds_mips(d):
        pytest.skip(f"{device.label} has no doubles: the pool is built on the host")
    textures = _textures()
    texels, infos, levels = tp.texture_pool(textures)
    got = tp.upload_pool(d, textures)
    assert np.array_equal(got["tex_infos"].get(), infos) and np.array_equal(got["tex_levels"].get(), levels)
    assert np.array_equal(got["texels"].get(), texels)
    assert np.array_equal(got["srgb_lut"].get(), tp.decode_tables())


def test_host_path_without_doubles_gives_the_same_pool(device, monkeypatch):
    d = _device(device)
    textures = _textures(2)[:12]
    monkeypatch.setenv(tp.ENV_HOST_MIPS, "1")
    assert not tp.device_builds_mips(d)
    assert np.array_equal(tp.upload_pool(d, textures)["texels"].get(), tp.texture_pool(textures)[0])


def test_a_changed_texture_gets_new_levels(device):
    """Nothing is cached by content: a new Texture with other texels gets its own mip levels."""
    d = _device(device)
    rgba = np.full((8, 8, 4), 200, np.uint8)
    a = tp.upload_pool(d, [Texture("a", rgba)])["texels"].get()
    rgba2 = rgba.copy()
    rgba2[0, 0] = 0
    b = tp.upload_pool(d, [Texture("a", rgba2)])["texels"].get()
    assert np.array_equal(b, tp.texture_pool([Texture("a", rgba2)])[0]) and not np.array_equal(a[64:], b[64:])


def test_pool_layout_matches_the_host_pool():
    textures = _textures()[:8]
    _, infos, levels = tp.texture_pool(textures)
    infos2, levels2, total = tp.pool_layout(textures)
    assert np.array_equal(infos, infos2) and np.array_equal(levels, levels2)
    assert total == sum(level.shape[0] * level.shape[1] for t in textures for level in tp.mip_chain(t))


def _resize(a, taps, axis):
    """One PIL pass as the kernel computes it: double sums in tap order, rounded to float."""
    a = np.moveaxis(a, axis, 0).astype(np.float64)
    out = []
    for first, ws in taps:
        s = np.zeros(a.shape[1:])
        for i, w in enumerate(ws):
            s = s + a[first + i] * w
        out.append(s.astype(np.float32))
    return np.moveaxis(np.stack(out), 0, axis)


@pytest.mark.parametrize("h,w", [(h, w) for w in (2, 3, 4, 5, 10, 33, 64) for h in range(max(2, 2 * w - 3), 2 * w + 6)]
                         + [(1024, 256), (256, 1024), (2048, 512), (37, 23), (23, 37), (5, 3), (9, 2), (100, 7)])
def test_pil_pass_order_and_taps(h, w):
    """PIL's half-size BOX resize of a float image equals the two passes from `box_taps` in the
    order `pil_vertical_first` says (the orders round differently: the other one must differ
    somewhere on random data, else the case says nothing)."""
    rng = np.random.default_rng(h * 1000 + w)
    a = rng.random((h, w), dtype=np.float32)
    h2, w2 = max(h // 2, 1), max(w // 2, 1)
    pil = np.asarray(Image.fromarray(a, mode="F").resize((w2, h2), Image.BOX))
    rows_first = _resize(_resize(a, tp.box_taps(w, w2), 1), tp.box_taps(h, h2), 0)
    cols_first = _resize(_resize(a, tp.box_taps(h, h2), 0), tp.box_taps(w, w2), 1)
    want, other = (cols_first, rows_first) if tp.pil_vertical_first(h, w) else (rows_first, cols_first)
    assert np.array_equal(pil, want)


def test_box_taps_of_odd_sizes():
    assert tp.box_taps(4, 2) == [(0, [0.5, 0.5]), (2, [0.5, 0.5])]
    assert tp.box_taps(5, 2) == [(0, [1 / 3] * 3), (3, [0.5, 0.5])]
    assert tp.box_taps(3, 1) == [(0, [1 / 3] * 3)]
    assert tp.box_taps(1, 1) == [(0, [1.0])]


def _near_thresholds(t):
    bits = t[1:].view(np.uint32).astype(np.int64)
    near = np.concatenate([bits - 2, bits - 1, bits, bits + 1, bits + 2])
    one = int(np.float32(1).view(np.uint32))
    return np.unique(np.clip(near, 0, one)).astype(np.uint32).view(np.float32)


@pytest.mark.parametrize("srgb", [True, False])
def test_thresholds_reproduce_the_host_encoder(srgb):
    """encode8(x) = #{k: t[k] <= x} next to every threshold and on 2M random floats in [0, 1]
    (the check over all 1.07e9 floats in [0, 1] passed once; it takes minutes)."""
    t = tp.code_thresholds()[0 if srgb else 1]
    assert np.all(np.diff(t[1:]) > 0)
    rng = np.random.default_rng(7)
    x = np.concatenate([_near_thresholds(t), rng.random(2_000_000, dtype=np.float32),
                        np.float32([0.0, 1.0, 1e-30, 0.5])])
    assert np.array_equal(np.searchsorted(t[1:], x, side="right"), tp.encode8(x, srgb))


def test_encode_table_reproduces_the_srgb_encoder():
    t = tp.code_thresholds()[0]
    table = tp.encode_table()
    rng = np.random.default_rng(8)
    x = np.concatenate([_near_thresholds(t), rng.random(2_000_000, dtype=np.float32), np.float32([0.0])])
    e = table[np.clip((x * np.float32(tp.ENCODE_INTERVALS)).astype(np.int64), 0, tp.ENCODE_INTERVALS - 1)]
    codes = np.where(x >= 1.0, 255, e[:, 1].astype(np.int64) + (x >= e[:, 0]))
    assert np.array_equal(codes, tp.encode8(x, True))


@pytest.mark.oclgrind
def test_mip_kernels_are_simulator_clean(device, capfd):
    from test_oclgrind_tier import assert_no_device_diagnostics
    d = _device(device)
    if not tp.device_builds_mips(d):
        pytest.skip(f"{device.label} has no doubles")
    rng = np.random.default_rng(4)
    textures = [Texture(f"t{h}x{w}", rng.integers(0, 256, (h, w, 4), dtype=np.uint8), srgb=bool(k % 2))
                for k, (h, w) in enumerate([(5, 3), (8, 4), (1, 6), (9, 2)])]
    assert np.array_equal(tp.upload_pool(d, textures)["texels"].get(), tp.texture_pool(textures)[0])
    assert_no_device_diagnostics(capfd)


# -- the program binary cache (clrender/device/core.py) ---------------------------------------------------
def test_program_binaries_are_cached_and_a_bad_one_is_rebuilt(device, tmp_path, monkeypatch):
    from clrender.device.core import Device
    monkeypatch.setenv("CLRENDER_CACHE_DIR", str(tmp_path))
    d = _device(device)
    monkeypatch.setattr(d, "keep_binaries", True)     # off on PoCL by default (clrender/device/core.py): test the store
    defines = {"ENCODE_INTERVALS": 4096, "CACHE_TEST": 1}   # a key no other test built
    saved = dict(Device._programs)
    try:
        first = d.program("mipmap.cl", defines)
        files = list((tmp_path / "programs").glob("*.bin"))
        assert len(files) == 1 and files[0].stat().st_size > 0
        Device._programs.clear()
        built = []
        real = d._cached_binary
        monkeypatch.setattr(d, "_cached_binary", lambda *a: built.append(real(*a)) or built[-1])
        second = d.program("mipmap.cl", defines)
        assert built[-1] is second and second is not first          # loaded from the binary
        files[0].write_bytes(b"not a program binary")
        Device._programs.clear()
        third = d.program("mipmap.cl", defines)                      # refused: rebuilt from source
        assert built[-1] is None and third is not None
        assert files[0].read_bytes() != b"not a program binary"
        monkeypatch.setenv("CLRENDER_PROGRAM_CACHE", "0")
        assert d._binary_name("x", []) is None
    finally:
        Device._programs.clear()
        Device._programs.update(saved)


def test_program_from_a_binary_runs_like_the_source_build(device, tmp_path, monkeypatch):
    """The pool built by kernels loaded from cached binaries equals the host's."""
    from clrender.device.core import Device
    d = _device(device)
    if not tp.device_builds_mips(d):
        pytest.skip(f"{device.label} has no doubles")
    monkeypatch.setenv("CLRENDER_CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(d, "keep_binaries", True)
    saved = dict(Device._programs)
    textures = _textures(3)[:10]
    try:
        Device._programs.clear()
        tp.upload_pool(d, textures)                  # source builds, binaries stored
        Device._programs.clear()
        got = tp.upload_pool(d, textures)["texels"].get()      # from the binaries
        assert np.array_equal(got, tp.texture_pool(textures)[0])
    finally:
        Device._programs.clear()
        Device._programs.update(saved)


# -- binning: the initial tile-list room -----------------------------------------------------------
def test_tile_list_starts_from_the_scene_size(device):
    from clrender.device.core import Device
    from clrender.passes.base import Resources
    from clrender.passes.binning import LIST_PER_TILE, BinningPass
    from clrender.render.renderer import RenderConfig

    p = BinningPass(Device.get(device), RenderConfig(tile_size=16))
    p.allocate(64, 48)
    tiles = 4 * 3
    assert p.list_capacity == 8 * tiles
    p.prepare_scene(Resources(buffers={}, values={"n_tris": 10}))
    assert p.list_capacity == 8 * tiles                          # 2 per triangle: less than it has
    p.prepare_scene(Resources(buffers={}, values={"n_tris": 100}))
    assert p.list_capacity == 200
    p.prepare_scene(Resources(buffers={}, values={"n_tris": 10**6}))
    assert p.list_capacity == LIST_PER_TILE * 4 * tiles            # bounded per pixel: 64 per 8x8 pixels
    p.allocate(64, 48)
    assert p.list_capacity == 8 * tiles
