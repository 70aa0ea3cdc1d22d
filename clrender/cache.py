"""clrender's on-disk cache: one folder, one size cap, least-recently-used pruning.

    $CLRENDER_CACHE_DIR (else ~/.cache/clrender)
        probe/<key>.json      the device probe's answers (clrender/device_probe.py)
        programs/<key>.bin    program binaries of drivers other than PoCL (clrender/device.py)
        pocl/                 PoCL's own kernel cache, when POCL_CACHE_DIR was not set (configure_pocl_cache)

Every entry clrender writes carries a header (magic, payload length, sha256 of the payload): a
truncated or corrupted file is detected on read, deleted and treated as a miss, so a damaged entry
is rebuilt and never handed to a driver (a truncated program binary can crash one). Writes are
atomic (temporary file, then rename). The whole folder, PoCL's part included, is kept under
$CLRENDER_CACHE_MAX_MB (default 1024; 0: no cache) by deleting the least recently used entries
after a write; reads touch an entry. A folder that cannot be created or written works as no cache,
said once per process. `clrender cache info|clear` shows and empties it.
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
KINDS = ("probe", "programs", "pocl")
log = logging.getLogger("clrender")
_warned = False


def cache_dir() -> Path:
    return Path(os.environ.get(ENV_CACHE_DIR) or Path.home() / ".cache" / "clrender")


def cap_bytes() -> int:
    text = os.environ.get(ENV_CACHE_MAX_MB, "").strip()
    try:
        mb = float(text) if text else DEFAULT_MAX_MB
    except ValueError:
        mb = DEFAULT_MAX_MB
    return max(int(mb * 2**20), 0)


def usable_dir() -> Optional[Path]:
    """The folder, created, when it is writable and the cap is not 0; else None (said once)."""
    if cap_bytes() == 0:
        return None
    folder = cache_dir()
    try:
        folder.mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=folder, prefix=".probe-write-"):
            pass
        return folder
    except OSError as exc:
        _warn_once(f"clrender's cache folder {folder} is not usable ({exc.strerror or exc}); "
                   f"working without a cache (set {ENV_CACHE_DIR} to a writable folder)")
        return None


def _warn_once(message: str) -> None:
    global _warned
    if not _warned:
        _warned = True
        log.warning(message)
        warnings.warn(message, stacklevel=4)


def _reset_for_tests() -> None:
    global _warned
    _warned = False


def read_bytes(name: str) -> Optional[bytes]:
    """The payload of entry `name` ("programs/ab12.bin"), or None when missing or damaged (a
    damaged entry is deleted). A hit marks the entry used (its mtime)."""
    if cap_bytes() == 0:
        return None
    path = cache_dir() / name
    try:
        data = path.read_bytes()
    except OSError:
        return None
    payload = _unwrap(data)
    if payload is None:
        log.info("cache entry %s is damaged: removed, it will be rebuilt", path)
        _remove(path)
        return None
    try:
        os.utime(path)
    except OSError:
        pass
    return payload


def _unwrap(data: bytes) -> Optional[bytes]:
    if len(data) < _HEADER.size:
        return None
    magic, length, digest = _HEADER.unpack_from(data)
    payload = data[_HEADER.size:]
    if magic != MAGIC or length != len(payload) or hashlib.sha256(payload).digest() != digest:
        return None
    return payload


def write_bytes(name: str, payload: bytes) -> bool:
    """Store `payload` as entry `name` atomically, then prune to the cap; False when not stored."""
    folder = usable_dir()
    if folder is None:
        return False
    path = folder / name
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.")
        try:
            with os.fdopen(fd, "wb") as f:
                f.write(_HEADER.pack(MAGIC, len(payload), hashlib.sha256(payload).digest()))
                f.write(payload)
            os.replace(tmp, path)
        except BaseException:
            _remove(Path(tmp))
            raise
    except OSError as exc:
        log.info("cache entry %s not written: %s", path, exc)
        return False
    _prune_after_write()
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


def _entries(folder: Path) -> list[tuple[float, int, Path, str]]:
    """(last use, bytes, path, kind) of every entry: clrender's files, and each of PoCL's program
    folders as one entry (its newest file's mtime: PoCL does not touch what it reads)."""
    out = []
    for old in folder.glob("probe-*.json"):          # earlier versions kept probe answers at the top
        size, newest = _measure(old)
        if size is not None:
            out.append((newest, size, old, "probe"))
    for kind in KINDS:
        root = folder / kind
        if not root.is_dir() or root.is_symlink():
            continue
        units = _pocl_units(root) if kind == "pocl" else [p for p in root.rglob("*") if p.is_file()]
        for unit in units:
            size, newest = _measure(unit)
            if size is not None:
                out.append((newest, size, unit, kind))
    return out


def _pocl_units(root: Path) -> list[Path]:
    """PoCL's cache: kcache/XX/<program hash>/ (PoCL 3.0), or <XX>/<program hash>/ straight under
    the folder (PoCL 3.1): every folder two levels below the top or below kcache/."""
    base = root / "kcache" if (root / "kcache").is_dir() else root
    units = []
    for top in _children(base):
        if top.is_dir() and not top.is_symlink():
            units += [p for p in _children(top) if not p.is_symlink()]
        elif top.is_file():
            units.append(top)
    return units


def _children(path: Path) -> list[Path]:
    try:
        return list(path.iterdir())
    except OSError:
        return []


def _measure(path: Path) -> tuple[Optional[int], float]:
    """(bytes, newest mtime) of a file or folder; (None, 0) if it vanished meanwhile."""
    try:
        if path.is_file():
            st = path.stat()
            return st.st_size, st.st_mtime
        size, newest = 0, 0.0
        for p in path.rglob("*"):
            if p.is_file() and not p.is_symlink():
                st = p.stat()
                size, newest = size + st.st_size, max(newest, st.st_mtime)
        return size, newest
    except OSError:
        return None, 0.0


def _remove(path: Path) -> int:
    size, _ = _measure(path)
    try:
        if path.is_dir() and not path.is_symlink():
            shutil.rmtree(path)
        else:
            path.unlink()
    except OSError:
        return 0
    return size or 0


_last_prune = -1e9


def _prune_after_write() -> None:
    """Walking the folder costs milliseconds: after a write, a prune at most once a minute (the
    first write of a process always prunes)."""
    global _last_prune
    now = time.monotonic()
    if now - _last_prune >= 60.0:
        _last_prune = now
        prune()


def prune(max_bytes: Optional[int] = None) -> int:
    """Delete least-recently-used entries until the folder holds at most `max_bytes` (default: the
    cap); returns the bytes freed."""
    cap = cap_bytes() if max_bytes is None else max_bytes
    entries = sorted(_entries(cache_dir()))
    total = sum(size for _, size, _, _ in entries)
    freed = 0
    for _, size, path, _ in entries:
        if total - freed <= cap:
            break
        freed += _remove(path)
    if freed:
        log.info("clrender cache: %d bytes of least recently used entries removed (cap %d)", freed, cap)
    return freed


def info() -> dict:
    folder = cache_dir()
    by_kind = {kind: {"entries": 0, "bytes": 0} for kind in KINDS}
    for _, size, _, kind in _entries(folder) if folder.is_dir() else []:
        by_kind[kind]["entries"] += 1
        by_kind[kind]["bytes"] += size
    return {"dir": str(folder), "exists": folder.is_dir(), "writable": folder.is_dir() and os.access(folder, os.W_OK),
            "cap_bytes": cap_bytes(), "total_bytes": sum(k["bytes"] for k in by_kind.values()),
            "entries": sum(k["entries"] for k in by_kind.values()), "by_kind": by_kind,
            "pocl_cache_dir": os.environ.get("POCL_CACHE_DIR")}


def clear() -> int:
    """Remove everything clrender keeps there (the folder itself stays); returns the bytes freed."""
    return sum(_remove(path) for _, _, path, _ in _entries(cache_dir()))


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
    stamp = folder / ".last-prune"
    try:
        if time.time() - stamp.stat().st_mtime < 3600:
            return
    except OSError:
        pass
    try:
        stamp.touch()
    except OSError:
        return
    prune()
