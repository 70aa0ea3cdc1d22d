"""clrender's on-disk cache: one folder, one size cap, least-recently-used pruning.

    $CLRENDER_CACHE_DIR (else ~/.cache/clrender)
        probe/<key>.json      the device probe's answers (clrender/device/probe.py)
        programs/<key>.bin    program binaries of drivers other than PoCL (clrender/device/core.py)
        pocl/                 PoCL's own kernel cache, when POCL_CACHE_DIR was not set (configure_pocl_cache)
        icd/<hash>/           ICD files registering pip's OpenCL implementations (clrender/device/icd.py):
                              a few bytes, neither counted nor pruned (a running process reads them)

Every entry clrender writes carries a header (magic, payload length, sha256 of the payload): a
truncated or corrupted file is detected on read, deleted and treated as a miss, so a damaged entry
is rebuilt and never handed to a driver (a truncated program binary can crash one). Writes are
atomic (temporary file, then rename). The whole folder, PoCL's part included, is kept under
$CLRENDER_CACHE_MAX_MB (default 1024; 0: no cache) by deleting the least recently used entries
after a write; reads touch an entry. A folder that cannot be created or written works as no cache,
said once per process. Walks never follow symlinks and skip what vanishes meanwhile (another
process pruning). `clrender cache info|clear` shows and empties it.
"""
from __future__ import annotations

import hashlib
import json
import logging
import os
import shutil
import struct
import tempfile
import time
import warnings
from pathlib import Path
from typing import Optional

ENV_CACHE_DIR = "CLRENDER_CACHE_DIR"
ENV_CACHE_MAX_MB = "CLRENDER_CACHE_MAX_MB"
DEFAULT_MAX_MB = 1024
MAGIC = b"CLRC1\0"
_HEADER = struct.Struct("<6sQ32s")        # magic, payload length, sha256(payload)
KINDS = ("programs", "probe", "pocl")
_STAMP = ".last-prune"
_WALK_EVERY = 64                          # writes between walks even under the cap (PoCL grows unseen)
log = logging.getLogger("clrender")
_warned = False
_estimate: Optional[int] = None           # bytes in the folder: the last walk's total + writes since
_writes = 0


def cache_dir() -> Path:
    return Path(os.environ.get(ENV_CACHE_DIR) or Path.home() / ".cache" / "clrender")


def cap_bytes() -> int:
    try:
        return max(int(float(os.environ.get(ENV_CACHE_MAX_MB) or DEFAULT_MAX_MB) * 2**20), 0)
    except ValueError:
        return DEFAULT_MAX_MB * 2**20


def usable_dir() -> Optional[Path]:
    """The folder, created, when it is writable and the cap is not 0; else None (said once)."""
    global _warned
    if cap_bytes() == 0:
        return None
    folder = cache_dir()
    try:
        folder.mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=folder, prefix=".probe-write-"):
            pass                          # mkdir succeeds on an existing read-only folder: try a file
        return folder
    except OSError as exc:
        if not _warned:                   # once per process, not once per program build
            _warned = True
            message = (f"clrender's cache folder {folder} is not usable ({exc.strerror or exc}); "
                       f"working without a cache (set {ENV_CACHE_DIR} to a writable folder)")
            log.warning(message)
            warnings.warn(message, stacklevel=3)
        return None


def _reset_for_tests() -> None:
    global _warned, _estimate, _writes
    _warned, _estimate, _writes = False, None, 0


def _entry_path(folder: Path, name: str) -> Optional[Path]:
    """`folder/name` when `name` stays inside the folder ("programs/ab.bin"; no "..", not absolute)."""
    rel = Path(name)
    return None if rel.is_absolute() or ".." in rel.parts or not rel.parts else folder / rel


def read_bytes(name: str) -> Optional[bytes]:
    """The payload of entry `name` ("programs/ab12.bin"), or None when missing or damaged (a
    damaged entry is deleted). A hit marks the entry used (its mtime): pruning is by last use."""
    path = _entry_path(cache_dir(), name) if cap_bytes() else None
    if path is None:
        return None
    try:                                  # O_NOFOLLOW: an entry that is a symlink is a miss
        with os.fdopen(os.open(path, os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0)), "rb") as f:
            data = f.read()
    except OSError:
        return None
    magic, length, digest = _HEADER.unpack_from(data) if len(data) >= _HEADER.size else (b"", -1, b"")
    payload = data[_HEADER.size:]
    if magic != MAGIC or length != len(payload) or hashlib.sha256(payload).digest() != digest:
        log.info("cache entry %s is damaged: removed, it will be rebuilt", path)
        _remove(path)
        return None
    try:
        os.utime(path)
    except OSError:
        pass
    return payload


def write_bytes(name: str, payload: bytes) -> bool:
    """Store `payload` as entry `name` atomically, then prune if needed; False when not stored."""
    folder = usable_dir()
    path = _entry_path(folder, name) if folder is not None else None
    if path is None:
        return False
    payload = bytes(payload)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
        try:
            with os.fdopen(fd, "wb") as f:
                f.write(_HEADER.pack(MAGIC, len(payload), hashlib.sha256(payload).digest()))
                f.write(payload)
            os.replace(tmp, path)         # readers see the old entry or the new one, never half
        except BaseException:
            _remove(Path(tmp))
            raise
    except OSError as exc:
        log.info("cache entry %s not written: %s", path, exc)
        return False
    _prune_after_write(_HEADER.size + len(payload))
    return True


def read_json(name: str):
    payload = read_bytes(name)
    if payload is None:
        return None
    try:
        return json.loads(payload)
    except ValueError:
        _remove(cache_dir() / name)
        return None


def write_json(name: str, obj) -> bool:
    return write_bytes(name, json.dumps(obj).encode())


def _scandir(path) -> list:
    try:
        with os.scandir(path) as it:
            return list(it)
    except OSError:                       # vanished, or not a folder
        return []


def _entries(folder: Path) -> list[tuple[float, int, str, str]]:
    """(last use, bytes, path, kind) of every entry: clrender's files, and each of PoCL's program
    folders as one entry (its newest file's mtime: PoCL does not touch what it reads)."""
    units = [(e.path, "probe") for e in _scandir(folder)      # earlier versions: probe-*.json at the top
             if e.name.startswith("probe-") and e.name.endswith(".json")]
    for kind in ("programs", "probe"):                        # os.walk: into no symlink, errors skipped
        for top, _, files in [] if os.path.islink(folder / kind) else os.walk(folder / kind):
            units += [(os.path.join(top, f), kind) for f in files]
    units += [(p, "pocl") for p in _pocl_units(folder / "pocl")]
    measured = [(_measure(path), path, kind) for path, kind in units]
    return [(newest, size, path, kind) for (size, newest), path, kind in measured if size is not None]


def _pocl_units(root: Path) -> list[str]:
    """PoCL's cache: kcache/XX/<program hash>/ (PoCL 3.0), or XX/<program hash>/ straight under
    the folder (PoCL 3.1): each folder (or stray file) two levels down is one entry."""
    tops = [] if os.path.islink(root) else _scandir(root)
    kcache = [e for e in tops if e.name == "kcache" and e.is_dir(follow_symlinks=False)]
    units = []
    for top in _scandir(kcache[0].path) if kcache else tops:
        if top.is_dir(follow_symlinks=False):
            units += [e.path for e in _scandir(top.path) if not e.is_symlink()]
        elif top.is_file(follow_symlinks=False):
            units.append(top.path)
    return units


def _measure(path) -> tuple[Optional[int], float]:
    """(bytes, newest mtime) of a file or of a folder's files, symlinks not followed; (None, 0)
    for a symlink or a file that vanished."""
    if os.path.islink(path):
        return None, 0.0
    isdir = os.path.isdir(path)
    files = [os.path.join(t, f) for t, _, fs in os.walk(path) for f in fs] if isdir else [path]
    size, newest = (0 if isdir else None), 0.0
    for f in files:
        try:
            st = os.lstat(f)
        except OSError:
            continue
        size, newest = (size or 0) + st.st_size, max(newest, st.st_mtime)
    return size, newest


def _remove(path) -> int:
    size, _ = _measure(path)
    try:
        if os.path.isdir(path) and not os.path.islink(path):
            shutil.rmtree(path, ignore_errors=True)
        else:
            os.unlink(path)
    except OSError:
        return 0
    return size or 0


def _prune_after_write(written: int) -> None:
    """A walk costs milliseconds: walk on a process's first write, then whenever the estimate goes
    past the cap (so a write that overflows the cap always prunes), else every _WALK_EVERY writes."""
    global _estimate, _writes
    _writes += 1
    if _estimate is not None:
        _estimate += written
    if _estimate is None or _estimate > cap_bytes() or _writes >= _WALK_EVERY:
        prune()


def prune(max_bytes: Optional[int] = None) -> int:
    """Delete least-recently-used entries, oldest first across kinds, until the folder holds at
    most `max_bytes` (default: the cap); returns the bytes freed."""
    global _estimate, _writes
    cap = cap_bytes() if max_bytes is None else max_bytes
    entries = sorted(_entries(cache_dir()))
    total = sum(size for _, size, _, _ in entries)
    freed = 0
    for _, size, path, _ in entries:
        if total - freed <= cap:
            break
        freed += _remove(path)
    _estimate, _writes = total - freed, 0
    if freed:
        log.info("clrender cache: %d bytes of least recently used entries removed (cap %d)", freed, cap)
    return freed


def info() -> dict:
    folder = cache_dir()
    by_kind = {kind: {"entries": 0, "bytes": 0} for kind in KINDS}
    for _, size, _, kind in _entries(folder):
        by_kind[kind]["entries"] += 1
        by_kind[kind]["bytes"] += size
    return {"dir": str(folder), "exists": folder.is_dir(), "writable": folder.is_dir() and os.access(folder, os.W_OK),
            "cap_bytes": cap_bytes(), "total_bytes": sum(k["bytes"] for k in by_kind.values()),
            "entries": sum(k["entries"] for k in by_kind.values()), "by_kind": by_kind,
            "pocl_cache_dir": os.environ.get("POCL_CACHE_DIR")}


def clear() -> int:
    """Remove everything clrender keeps there (the folder itself stays); returns the bytes freed."""
    global _estimate
    freed = sum(_remove(path) for _, _, path, _ in _entries(cache_dir()))
    _remove(cache_dir() / _STAMP)
    _estimate = 0
    return freed


def configure_pocl_cache() -> None:
    """Put PoCL's kernel cache under clrender's folder (and cap) unless the user placed it: called
    before the process's first OpenCL call, which is when PoCL reads POCL_CACHE_DIR."""
    if os.environ.get("POCL_CACHE_DIR"):
        return
    folder = usable_dir()
    if folder is not None:
        os.environ["POCL_CACHE_DIR"] = str(folder / "pocl")
        _prune_hourly(folder)


def _prune_hourly(folder: Path) -> None:
    """PoCL fills its part of the folder without clrender writing anything: prune at process start,
    at most once an hour across processes (a stamp file's mtime; a prune walk costs ~30 ms)."""
    stamp = folder / _STAMP
    try:
        if stamp.exists() and time.time() - stamp.stat().st_mtime < 3600:
            return
        stamp.touch()
    except OSError:
        return
    prune()
