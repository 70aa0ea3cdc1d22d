"""The pure logic of the implementations benchmark (bench/devices.py): which implementation a
platform is, the winner and slowest/fastest ratio of a row, and the table. No OpenCL, no timing."""
from __future__ import annotations

import math
import os
import sys

import pytest

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from bench.devices import FAR_BEHIND, compare, format_table, implementation_key  # noqa: E402


def test_implementation_key_tells_the_three_cpu_implementations_apart():
    debian = "OpenCL 3.0 PoCL 3.1+debian  Linux, None+Asserts, RELOC, SPIR, LLVM 15.0.6, SLEEF, DISTRO, POCL_DEBUG"
    pip = "OpenCL 3.0 PoCL 3.0-rc2  Linux, Release, RELOC, LLVM 14.0.6, SLEEF, DISTRO, POCL_DEBUG"
    assert implementation_key("Intel(R) OpenCL", "OpenCL 2.1 LINUX", "pip") == "intel"
    assert implementation_key("Portable Computing Language", debian, "system") == "pocl-debian"
    assert implementation_key("Portable Computing Language", pip, "pip") == "pocl-pip"
    assert implementation_key("Portable Computing Language", pip, None) == "pocl-pip"
    # Intel's GPU runtime and the simulator are not CPU implementations of this benchmark
    assert implementation_key("Intel(R) OpenCL Graphics", "OpenCL 3.0", "system") is None
    assert implementation_key("Oclgrind", "OpenCL 1.2 (Oclgrind 21.10)", "system") is None


def test_compare_ignores_missing_and_zero_values():
    assert compare({"a": 2.0, "b": 5.0, "c": 4.0}) == ("a", 2.5)
    # a zero reads as "no time measured" (markers without timestamps), never as a win
    assert compare({"a": 0.0, "b": 3.0, "c": 6.0}) == ("b", 2.0)
    assert compare({"a": None, "b": 3.0}) == ("b", None)
    assert compare({"a": None, "b": float("nan")}) == (None, None)


def test_format_table_shows_winner_ratio_and_flags_far_behind_rows():
    impls = ["pocl-debian", "intel"]
    rows = [("shade", {"pocl-debian": 30.0, "intel": 10.0}),
            ("tonemap", {"pocl-debian": 1.0, "intel": 1.2}),
            ("raster", {"pocl-debian": 4.0, "intel": None})]
    lines = format_table("Sponza 1280x720, 1024 lights", rows, impls)
    text = "\n".join(lines)
    assert lines[0].startswith("Sponza 1280x720, 1024 lights")
    header = lines[1].split()
    assert header[:3] == ["ms", "pocl-debian", "intel"] and "winner" in header
    shade = next(ln for ln in lines if ln.startswith("shade"))
    assert shade.split()[1:] == ["30.00", "10.00", "intel", "3.00x", "*"]
    tonemap = next(ln for ln in lines if ln.startswith("tonemap"))
    assert tonemap.split()[1:] == ["1.00", "1.20", "pocl-debian", "1.20x"]
    raster = next(ln for ln in lines if ln.startswith("raster"))
    assert raster.split()[1:] == ["4.00", "-", "pocl-debian", "-"]
    assert f"* slowest >= {FAR_BEHIND:g}x the fastest" in text


def test_format_table_does_not_rank_rows_too_small_to_measure():
    # a pass of a few microseconds: a 3x "ratio" there is timer noise, not a kernel to tune
    lines = format_table("t", [("ibl", {"a": 0.001, "b": 0.004}), ("shade", {"a": 2.0, "b": 1.0})], ["a", "b"],
                         floor=0.05)
    ibl = next(ln for ln in lines if ln.startswith("ibl"))
    assert ibl.split()[1:] == ["0.00", "0.00", "-", "-"]
    shade = next(ln for ln in lines if ln.startswith("shade"))
    assert shade.split()[1:] == ["2.00", "1.00", "b", "2.00x", "*"]
    assert "under 0.05" in "\n".join(lines)


def test_format_table_says_why_a_cell_is_empty():
    lines = format_table("cold", [("demo cold s", {"a": 12.5, "b": "exit 1"})], ["a", "b"])
    row = next(ln for ln in lines if ln.startswith("demo cold s"))
    assert "exit 1" in row and "12.50" in row
    assert math.isclose(FAR_BEHIND, 1.5)


if __name__ == "__main__":
    sys.exit(pytest.main([__file__, "-q"]))
