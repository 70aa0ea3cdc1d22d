"""clrender's on-disk cache (clrender/device/cache.py): least-recently-used pruning under a cap, PoCL's
program folders as entries, damaged entries rebuilt (never returned), an unusable folder said
once, and `clrender cache info|clear`. Pure Python: no OpenCL."""
from __future__ import annotations

import json
import os
import warnings

import pytest

from clrender.device import cache
from clrender.cli import app as cli

MB = 2**20


@pytest.fixture(autouse=True)
def folder(tmp_path, monkeypatch):
    monkeypatch.setenv(cache.ENV_CACHE_DIR, str(tmp_path / "cache"))
    monkeypatch.delenv(cache.ENV_CACHE_MAX_MB, raising=False)
    cache._reset_for_tests()
    yield tmp_path / "cache"
    cache._reset_for_tests()


def _age(path, seconds_ago):
    t = 1_700_000_000 - seconds_ago
    os.utime(path, (t, t))


def test_entries_round_trip_with_a_header(folder):
    assert cache.write_bytes("programs/a.bin", b"payload") and cache.read_bytes("programs/a.bin") == b"payload"
    raw = (folder / "programs" / "a.bin").read_bytes()
    assert raw.startswith(cache.MAGIC) and raw.endswith(b"payload") and len(raw) > len(b"payload")
    assert cache.write_json("probe/k.json", {"error": None}) and cache.read_json("probe/k.json") == {"error": None}
    assert cache.read_bytes("programs/missing.bin") is None


@pytest.mark.parametrize("damage", ["truncate", "flip", "no_header", "empty"])
def test_a_damaged_entry_is_a_miss_and_is_removed(folder, damage):
    cache.write_bytes("programs/a.bin", b"x" * 1000)
    path = folder / "programs" / "a.bin"
    raw = path.read_bytes()
    path.write_bytes({"truncate": raw[:-10], "flip": raw[:-1] + bytes([raw[-1] ^ 1]),
                      "no_header": b"x" * 1000, "empty": b""}[damage])
    assert cache.read_bytes("programs/a.bin") is None
    assert not path.exists()
    assert cache.write_bytes("programs/a.bin", b"again") and cache.read_bytes("programs/a.bin") == b"again"


def test_damaged_json_is_a_miss(folder):
    cache.write_bytes("probe/k.json", b"{not json")
    assert cache.read_json("probe/k.json") is None and not (folder / "probe" / "k.json").exists()


def test_prune_removes_least_recently_used_first(folder, monkeypatch):
    for i, name in enumerate(["old", "middle", "new"]):
        cache.write_bytes(f"programs/{name}.bin", b"x" * (400 * 1024))
        _age(folder / "programs" / f"{name}.bin", 1000 - 100 * i)
    assert cache.read_bytes("programs/old.bin") is not None          # a read makes it the most recent
    monkeypatch.setenv(cache.ENV_CACHE_MAX_MB, "1")
    freed = cache.prune()
    left = sorted(p.stem for p in (folder / "programs").iterdir())
    assert left == ["new", "old"] and freed > 400 * 1024


def test_pocl_program_folders_are_pruned_as_units(folder, monkeypatch):
    # PoCL 3.0's layout (kcache/XX/<hash>/...) and 3.1's (XX/<hash>/... at the top)
    for layout, base in (("3.0", folder / "pocl" / "kcache"),):
        for i in range(3):
            unit = base / f"A{i}" / f"hash{i}"
            (unit / "sub").mkdir(parents=True)
            (unit / "program.bc").write_bytes(b"b" * (300 * 1024))
            (unit / "sub" / "kernel.so").write_bytes(b"s" * (100 * 1024))
            for f in unit.rglob("*"):
                _age(f, 1000 - 100 * i)
    cache.write_bytes("probe/k.json", b"{}")
    record = cache.info()
    assert record["by_kind"]["pocl"] == {"entries": 3, "bytes": 3 * 400 * 1024}
    monkeypatch.setenv(cache.ENV_CACHE_MAX_MB, "1")
    cache.prune()
    survivors = sorted(p.name for p in (folder / "pocl" / "kcache").glob("*/*"))
    assert survivors == ["hash1", "hash2"]                       # the oldest program folder went whole
    assert (folder / "probe" / "k.json").exists()


def test_pocl_3_1_layout_counts(folder):
    unit = folder / "pocl" / "AB" / "cdef"
    unit.mkdir(parents=True)
    (unit / "x.so").write_bytes(b"1234")
    assert cache.info()["by_kind"]["pocl"] == {"entries": 1, "bytes": 4}


def test_a_write_past_the_cap_prunes(folder, monkeypatch):
    walks = []
    real_prune = cache.prune
    monkeypatch.setattr(cache, "prune", lambda *a: walks.append(1) or real_prune(*a))
    monkeypatch.setenv(cache.ENV_CACHE_MAX_MB, "1")
    cache.write_bytes("programs/a.bin", b"x" * (300 * 1024))           # a process's first write walks
    cache.write_bytes("programs/b.bin", b"x" * (300 * 1024))           # under the cap: no walk
    assert len(walks) == 1
    _age(folder / "programs" / "a.bin", 200)
    _age(folder / "programs" / "b.bin", 100)
    cache.write_bytes("programs/c.bin", b"x" * (500 * 1024))           # past the cap: walks, a.bin goes
    assert len(walks) == 2
    assert sorted(p.name for p in (folder / "programs").iterdir()) == ["b.bin", "c.bin"]


def test_names_and_symlinks_never_lead_out_of_the_folder(folder, tmp_path):
    outside = tmp_path / "outside"
    (outside / "dir").mkdir(parents=True)
    (outside / "keep.bin").write_bytes(b"k" * 1000)
    (outside / "dir" / "keep.so").write_bytes(b"k" * 1000)
    assert not cache.write_bytes("../escape.bin", b"x") and not (tmp_path / "escape.bin").exists()
    assert cache.read_bytes("../outside/keep.bin") is None
    cache.write_bytes("programs/a.bin", b"x")
    (folder / "programs" / "link.bin").symlink_to(outside / "keep.bin")
    (folder / "pocl" / "kcache" / "AB").mkdir(parents=True)
    (folder / "pocl" / "kcache" / "AB" / "link").symlink_to(outside / "dir")
    assert cache.read_bytes("programs/link.bin") is None
    assert cache.info()["entries"] == 1                                # the links are not entries
    cache.prune(0)
    cache.clear()
    assert (outside / "keep.bin").stat().st_size == 1000 and (outside / "dir" / "keep.so").exists()


def test_cap_zero_means_no_cache(folder, monkeypatch):
    monkeypatch.setenv(cache.ENV_CACHE_MAX_MB, "0")
    assert not cache.write_bytes("programs/a.bin", b"x")
    assert cache.read_bytes("programs/a.bin") is None and not folder.exists()


def test_an_unusable_folder_works_without_a_cache_and_says_so_once(tmp_path, monkeypatch, caplog):
    blocker = tmp_path / "a-file"
    blocker.write_text("not a folder")
    monkeypatch.setenv(cache.ENV_CACHE_DIR, str(blocker / "cache"))     # mkdir fails, even as root
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        assert not cache.write_bytes("programs/a.bin", b"x")
        assert not cache.write_json("probe/k.json", {})
        assert cache.read_bytes("programs/a.bin") is None
    said = [w for w in seen if "working without a cache" in str(w.message)]
    assert len(said) == 1 and str(blocker / "cache") in str(said[0].message)
    assert sum("working without a cache" in r.getMessage() for r in caplog.records) == 1
    monkeypatch.delenv("POCL_CACHE_DIR", raising=False)
    cache.configure_pocl_cache()
    assert "POCL_CACHE_DIR" not in os.environ


def test_configure_pocl_cache_respects_the_users_folder(folder, monkeypatch):
    monkeypatch.setenv("POCL_CACHE_DIR", "/somewhere/else")
    cache.configure_pocl_cache()
    assert os.environ["POCL_CACHE_DIR"] == "/somewhere/else"
    monkeypatch.delenv("POCL_CACHE_DIR")
    cache.configure_pocl_cache()
    assert os.environ["POCL_CACHE_DIR"] == str(folder / "pocl")


def test_info_and_clear(folder):
    cache.write_bytes("programs/a.bin", b"x" * 100)
    cache.write_json("probe/k.json", {"error": None})
    (folder / "probe-legacy.json").write_text("{}")               # an earlier version's probe answer
    record = cache.info()
    assert record["entries"] == 3 and record["by_kind"]["programs"]["entries"] == 1
    assert record["total_bytes"] == sum(p.stat().st_size for p in folder.rglob("*") if p.is_file())
    assert cache.clear() == record["total_bytes"]
    assert cache.info()["entries"] == 0 and folder.is_dir()


def test_cli_cache_info_and_clear(folder, capsys):
    cache.write_bytes("programs/a.bin", b"x" * 100)
    assert cli.main(["cache", "info", "--json"]) == 0
    record = json.loads(capsys.readouterr().out)
    assert record["dir"] == str(folder) and record["entries"] == 1
    assert cli.main(["cache", "info"]) == 0
    text = capsys.readouterr().out
    assert str(folder) in text and "programs" in text
    assert cli.main(["cache", "clear"]) == 0
    assert "freed" in capsys.readouterr().out and cache.info()["entries"] == 0


def test_pocls_part_is_pruned_at_process_start_at_most_hourly(folder, monkeypatch):
    """PoCL fills pocl/ without clrender writing anything: configure_pocl_cache prunes it, once an hour."""
    unit = folder / "pocl" / "AB" / "old"
    unit.mkdir(parents=True)
    (unit / "k.so").write_bytes(b"x" * (600 * 1024))
    _age(unit / "k.so", 100)
    monkeypatch.setenv(cache.ENV_CACHE_MAX_MB, "0.5")
    monkeypatch.delenv("POCL_CACHE_DIR", raising=False)
    cache.configure_pocl_cache()
    assert not unit.exists() and (folder / ".last-prune").exists()
    unit.mkdir(parents=True)
    (unit / "k.so").write_bytes(b"x" * (600 * 1024))
    monkeypatch.delenv("POCL_CACHE_DIR", raising=False)
    cache.configure_pocl_cache()                      # within the hour: no walk, nothing removed
    assert unit.exists()
