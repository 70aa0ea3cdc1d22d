"""The device prefix sum (kernels/scan.cl) against NumPy's cumsum: exact, on every device.

Sizes cover one partial block, exact block multiples, two and three recursion levels, and
the empty input; scratch reuse across sizes is exercised by running them in one process."""
import numpy as np
import pytest

SIZES = (1, 7, 1023, 1024, 1025, 4096, 70001, 1024 * 1024 + 3)


def run_scan(device, counts, size=None):
    import pyopencl.array as cla
    from clrender.device.core import Device
    from clrender.device.scan import prefix_sum_for
    dev = Device.get(device)
    q = dev.queue
    c = cla.to_device(q, counts)
    offsets = cla.empty(q, max(len(counts), 1), np.int32)
    offsets.fill(-7)
    total = cla.empty(q, 1, np.int32)
    total.fill(-7)
    prefix_sum_for(dev)(c, offsets, total, size=size, queue=q)
    return offsets.get(), int(total.get()[0])


@pytest.mark.parametrize("n", SIZES)
def test_exclusive_scan_and_total_match_numpy(device, n):
    counts = np.random.default_rng(n).integers(0, 50, n).astype(np.int32)
    offsets, total = run_scan(device, counts)
    np.testing.assert_array_equal(offsets, np.concatenate([[0], np.cumsum(counts)[:-1]]))
    assert total == counts.sum()


def test_size_limits_the_scan_and_zero_size_gives_zero_total(device):
    counts = np.arange(1, 3001, dtype=np.int32)
    offsets, total = run_scan(device, counts, size=2000)
    np.testing.assert_array_equal(offsets[:2000], np.concatenate([[0], np.cumsum(counts[:1999])]))
    assert (offsets[2000:] == -7).all() and total == counts[:2000].sum()
    _, total = run_scan(device, counts, size=0)
    assert total == 0


def test_size_beyond_the_buffers_is_an_error(device):
    with pytest.raises(ValueError, match="scan of 11 items"):
        run_scan(device, np.ones(10, np.int32), size=11)


@pytest.mark.oclgrind
def test_multi_block_scan_is_simulator_clean(device, capfd):
    """Three blocks: both kernels and one recursion level, under Oclgrind's checks."""
    from test_oclgrind_tier import assert_no_device_diagnostics
    counts = np.random.default_rng(3).integers(0, 9, 3000).astype(np.int32)
    offsets, total = run_scan(device, counts)
    np.testing.assert_array_equal(offsets, np.concatenate([[0], np.cumsum(counts)[:-1]]))
    assert total == counts.sum()
    assert_no_device_diagnostics(capfd)


def test_scan_shape_follows_device_limits():
    from types import SimpleNamespace
    from clrender.device.capabilities import SCAN_ITEMS, scan_shape

    def dev(wg, local):
        return SimpleNamespace(max_work_group_size=wg, max_work_item_sizes=[wg, wg, wg], local_mem_size=local)

    assert scan_shape(dev(4096, 2 << 20)) == (128, SCAN_ITEMS)
    assert scan_shape(dev(64, 2 << 20)) == (64, SCAN_ITEMS)          # small work-groups
    wg, items = scan_shape(dev(1024, 4096))                             # 4 KiB local memory
    assert (wg * items + 2 * wg) * 4 <= 2048 and wg == 32
    assert scan_shape(dev(1, 64))[0] == 1
