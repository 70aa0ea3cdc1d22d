"""Atomic output files: every file clrender writes goes to a temporary name in the destination
folder and is renamed into place (os.replace) only once complete, and removed on failure, so a
killed or failed job never leaves a truncated file under a final name; the leftovers of killed
writers are removed by the next write into their folder."""
from __future__ import annotations

import errno
import os
import re
import secrets
import time
from pathlib import Path
from typing import Callable

import numpy as np


def _umask() -> int:
    if "umask" not in _UMASK:
        _UMASK["umask"] = os.umask(0o022)
        os.umask(_UMASK["umask"])
    return _UMASK["umask"]


_UMASK: dict = {}


def temp_prefix(path) -> str:
    """The start of `atomic_write`'s temporary names for `path`: `.<stem>.<pid>.`; the rest is
    mkstemp's 8 random characters and `.tmp<suffix>`. The pid tells a leftover of a killed job
    (removed by `remove_stale_temps`) from a write in progress in another live process."""
    path = Path(path)
    return f".{path.stem}.{os.getpid()}."


# A leftover temporary file: .<stem>.[<pid>.]<8 mkstemp characters>.tmp<suffix> (without the pid:
# written before clrender named its temporaries by process).
_TEMP_NAME = re.compile(r"^\..+?\.(?:(\d+)\.)?[a-z0-9_]{8}\.tmp(?:\.[A-Za-z0-9]+)?$")
STALE_TEMP_S = 3600.0        # a leftover without a pid, or of a pid alive again, is stale after an hour
_SCANNED: set = set()        # folders this process has cleaned already


def _alive(pid: int) -> bool:
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:           # EPERM: someone else's live process
        return True
    return True


def remove_stale_temps(folder, force: bool = False) -> list[Path]:
    """Remove the temporary files that killed writers left in `folder` (a SIGKILL or power loss
    mid-write: `atomic_write` removes its own on any error it sees): those whose writing process is
    gone, or untouched for STALE_TEMP_S. Each folder is scanned once per process (`force`: again).
    Returns what was removed."""
    folder = Path(folder)
    key = os.path.abspath(folder)
    if key in _SCANNED and not force:
        return []
    _SCANNED.add(key)
    removed = []
    try:
        entries = list(os.scandir(folder))
    except OSError:
        return removed
    now = time.time()
    for entry in entries:
        m = _TEMP_NAME.match(entry.name)
        if m is None:
            continue
        try:
            if not entry.is_file(follow_symlinks=False):
                continue
            age = now - entry.stat(follow_symlinks=False).st_mtime
            pid = m.group(1)
            if (pid is not None and not _alive(int(pid))) or age > STALE_TEMP_S:
                os.unlink(entry.path)
                removed.append(Path(entry.path))
        except OSError:
            continue
    return removed


from clrender.errors import OutputError  # noqa: F401  (re-exported)


def _output_error(path: Path, exc: BaseException) -> OutputError:
    """One line naming the output `path` for a failed write: the OS's reason (a full disk, a
    read-only or missing folder), or a writer's own words (numpy: "19200 requested and 14304
    written") with the free space when the disk is full."""
    errno_ = getattr(exc, "errno", None)
    reason = getattr(exc, "strerror", None) or (str(exc).strip().splitlines() or [type(exc).__name__])[0]
    if errno_ is None:
        try:
            st = os.statvfs(path.parent)
            if st.f_bavail * st.f_frsize < 1 << 20:
                errno_, reason = 28, f"{os.strerror(28)} ({reason})"
        except OSError:
            pass
    return OutputError(errno_ or 5, f"cannot write {path}: {reason}")


def _create_temp(path: Path, names: list) -> str:
    """Create an empty temporary file for `path` (mkstemp's rule: O_EXCL, mode 0600), its name
    appended to `names` before the file exists: a Ctrl-C the moment after it is created still
    leaves the caller a name to remove (mkstemp returns it only afterwards)."""
    chars = "abcdefghijklmnopqrstuvwxyz0123456789_"
    for _ in range(100):
        name = temp_prefix(path) + "".join(secrets.choice(chars) for _ in range(8)) + f".tmp{path.suffix}"
        tmp = str(path.parent / name)
        names.append(tmp)
        try:
            os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600))
            return tmp
        except FileExistsError:
            names.pop()                  # someone else's: never the caller's to remove
            continue
    raise FileExistsError(errno.EEXIST, "no free temporary name", str(path))


def atomic_write(path, writer: Callable[[str], object]) -> Path:
    """Call `writer(tmp)` to write a temporary file in `path`'s folder (same suffix, so writers
    that go by the extension still work), then rename it to `path` with os.replace. On any
    failure (the writer's or the rename's) the temporary file is removed and the error raised
    (an OSError as `OutputError`, naming `path`); `path` is then untouched: absent, or its previous
    complete content. The first write into a folder removes the leftovers of killed writers there."""
    path = Path(path)
    names: list = []
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        remove_stale_temps(path.parent)
        tmp = _create_temp(path, names)
        writer(tmp)
        os.chmod(tmp, 0o666 & ~_umask())     # mkstemp makes 0600; give the usual permissions of a new file
        os.replace(tmp, path)
    except BaseException as exc:
        if names:
            try:
                os.unlink(names[-1])
            except OSError:
                pass
        if isinstance(exc, OSError) and not isinstance(exc, OutputError):
            raise _output_error(path, exc) from exc
        raise
    return path


# zlib level of 8-bit PNGs: 3 encodes a 640x360 frame in 14 ms against 45 ms at Pillow's default 6,
# for files 12 % larger (a batch job's frames were spending longer in PNG encoding than rendering).
PNG_COMPRESS_LEVEL = 3


def _imwrite(path, array, **kwargs) -> None:
    import imageio.v3 as iio
    path = Path(path)
    if path.suffix.lower() == ".png":
        kwargs.setdefault("compress_level", PNG_COMPRESS_LEVEL)
    # Encoded in memory, then written here: a writer that fails on a full disk while holding the
    # file retries its close in __del__ and prints tracebacks ("Exception ignored in ...")
    data = iio.imwrite("<bytes>", array, extension=path.suffix, **kwargs)
    atomic_write(path, lambda tmp: _write_bytes(tmp, data))


def _write_bytes(tmp, data: bytes) -> None:
    with open(tmp, "wb") as f:
        f.write(data)


def _save_npy(path, array) -> None:
    def write(tmp):
        with open(tmp, "wb") as f:          # a file object: np.save would append .npy to a name
            np.save(f, array)
    atomic_write(path, write)
