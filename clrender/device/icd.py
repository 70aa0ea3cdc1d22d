"""Which OpenCL implementations pip installed, registered for this process; ICD files that do not load.

The OpenCL loader (ocl-icd, pyopencl's and the distributions') finds implementations through *.icd
files, each naming one library, in /etc/OpenCL/vendors ($OPENCL_VENDOR_PATH), or instead in the
folder $OCL_ICD_VENDORS names. pip installs libraries but cannot register them there (no root), so
clrender does it for its own process: `register()`, called by clrender/device/core.py before the first
OpenCL call (the loader reads the variables at the first clGetPlatformIDs, not at import), writes

    <cache>/icd/<hash of the contents>/   copies of every system *.icd + one .icd per pip implementation

(the cache folder of clrender/device/cache.py; a private temporary folder when that is unusable) and sets
$OCL_ICD_VENDORS to it, so child processes (the device probe, Dask workers) inherit the same view.
The system's ICD files are copied because $OCL_ICD_VENDORS replaces their folder. Known pip
implementations: Intel's CPU runtime (`pip install opencl-rt`, the `intel` extra). pip's PoCL
(`pocl-binary-distribution`) needs no registration: pyopencl's bundled loader always loads it.

A user's own $OCL_ICD_VENDORS wins: left alone (said at debug level on the "clrender" logger).
$CLRENDER_REGISTER_ICDS=0 turns registration off (the system's view only).

The loader skips an ICD whose library does not load without a word; `icd_problems()` says which,
one line each (`clrender devices` prints them, "no OpenCL device found" errors append them).
"""
from __future__ import annotations

import atexit
import ctypes
import hashlib
import logging
import os
import shutil
import sys
import tempfile
from pathlib import Path
from typing import NamedTuple, Optional

from clrender.device import cache

ENV_REGISTER = "CLRENDER_REGISTER_ICDS"
ENV_VENDORS = "OCL_ICD_VENDORS"
ENV_VENDOR_PATH = "OPENCL_VENDOR_PATH"
ENV_REGISTERED = "CLRENDER_ICD_VENDORS"     # the folder clrender set $OCL_ICD_VENDORS to (children inherit it)
SYSTEM_VENDORS = "/etc/OpenCL/vendors"
log = logging.getLogger("clrender")
note: Optional[str] = None                  # what register() did, for `clrender devices` (its log comes too early)


class PipImplementation(NamedTuple):
    name: str               # "intel", "pocl": also a --device name that picks it
    library: Path
    needs_icd: bool         # False: the loader finds it without an ICD file of clrender's


# (name, distribution, library file name, whether clrender must register it)
_KNOWN = (("intel", "opencl-rt", "libintelocl.so", True),
          ("pocl", "pocl-binary-distribution", "libpocl", False))


def _library_of(distribution: str, stem: str) -> Optional[Path]:
    """The installed file of `distribution` whose name starts with `stem` (its RECORD, which covers
    venvs and --user installs; opencl-rt's libraries are data files: <prefix>/lib)."""
    from importlib import metadata
    try:
        dist = metadata.distribution(distribution)
    except metadata.PackageNotFoundError:
        return None
    candidates = [dist.locate_file(f) for f in dist.files or () if f.name.startswith(stem)
                  and (f.name.endswith(".so") or f.name == stem)]
    if stem.endswith(".so"):                                   # no RECORD: where pip puts data files
        candidates.append(Path(sys.prefix) / "lib" / stem)
    for path in candidates:
        path = Path(os.path.normpath(path))
        if path.is_file():
            return path
    return None


def pip_implementations() -> list[PipImplementation]:
    """The OpenCL implementations pip installed that clrender knows (no library is loaded)."""
    found = []
    for name, distribution, stem, needs_icd in _KNOWN:
        library = _library_of(distribution, stem)
        if library is not None:
            found.append(PipImplementation(name, library, needs_icd))
    return found


def system_vendor_dir() -> Path:
    return Path(os.environ.get(ENV_VENDOR_PATH) or SYSTEM_VENDORS)


def _icd_files(folder: Path) -> dict[str, bytes]:
    """name -> contents of the folder's *.icd files (what the loader reads; symlinks followed)."""
    files = {}
    try:
        names = sorted(os.listdir(folder))
    except OSError:
        return files
    for name in names:
        if name.endswith(".icd"):
            try:
                files[name] = (folder / name).read_bytes()
            except OSError:
                continue
    return files


def _named_library(contents: bytes) -> str:
    """The library an ICD file names: its first line (ocl-icd reads one line)."""
    lines = contents.decode(errors="replace").splitlines()
    return lines[0].strip() if lines else ""


def register() -> Optional[Path]:
    """Point $OCL_ICD_VENDORS at a folder holding the system's ICD files plus one per pip
    implementation that needs it; returns that folder, or None when nothing was registered (the
    user set the variable, registration is off, or nothing needs it). Call before any OpenCL call."""
    global note
    if os.environ.get(ENV_REGISTER, "").strip() == "0":
        return None
    user = os.environ.get(ENV_VENDORS)
    if user:                                  # ocl-icd treats an empty value as unset
        if user != os.environ.get(ENV_REGISTERED):
            wanted = [p.name for p in pip_implementations() if p.needs_icd]
            if wanted:
                note = (f"{ENV_VENDORS}={user} is set: clrender leaves it alone and does not register pip's "
                        f"OpenCL implementation(s) {', '.join(wanted)} (add their .icd files there to see them)")
                log.debug(note)
        return None
    system = _icd_files(system_vendor_dir())
    named = [_named_library(c) for c in system.values()]
    registered = {os.path.realpath(lib) for lib in named if os.path.isabs(lib)}
    wanted = [p for p in pip_implementations()
              if p.needs_icd and os.path.realpath(p.library) not in registered]
    if not wanted:
        return None
    files = dict(system)
    for p in wanted:
        name = f"clrender-pip-{p.name}.icd"
        while name in files:
            name = "_" + name
        files[name] = f"{p.library}\n".encode()
    folder = _write_folder(files)
    if folder is None:
        return None
    os.environ[ENV_VENDORS] = os.environ[ENV_REGISTERED] = str(folder)
    note = (f"registered pip's OpenCL implementation(s) "
            f"{', '.join(f'{p.name} ({p.library})' for p in wanted)}: {ENV_VENDORS}={folder}")
    log.debug(note)
    return folder


def _holds(folder: Path, files: dict[str, bytes]) -> bool:
    return folder.is_dir() and _icd_files(folder) == files


def _write_folder(files: dict[str, bytes]) -> Optional[Path]:
    """A folder holding exactly `files`: <cache>/icd/<hash>/, made by renaming a complete temporary
    folder into place (concurrent processes each see a whole folder, and the same one)."""
    h = hashlib.sha256()
    for name, contents in sorted(files.items()):
        h.update(name.encode() + b"\0" + hashlib.sha256(contents).digest())
    base = cache.usable_dir()
    if base is not None:
        final = base / "icd" / h.hexdigest()[:20]
        if _holds(final, files):
            return final
        try:
            final.parent.mkdir(parents=True, exist_ok=True)
            tmp = Path(tempfile.mkdtemp(dir=final.parent, prefix=".tmp-"))
            _fill(tmp, files)
            try:
                os.rename(tmp, final)
            except OSError:                   # another process renamed its copy first
                shutil.rmtree(tmp, ignore_errors=True)
            if _holds(final, files):
                return final
        except OSError as exc:
            log.info("ICD folder not written under %s (%s): using a temporary one", final.parent, exc)
    try:                                      # private (mkdtemp: 0700), removed at exit
        tmp = Path(tempfile.mkdtemp(prefix="clrender-icd-"))
        _fill(tmp, files)
    except OSError as exc:
        log.warning("clrender could not write an ICD folder (%s): pip's OpenCL implementations are "
                    "not registered", exc)
        return None
    pid = os.getpid()                         # a forked child exiting must not remove the parent's
    atexit.register(lambda: os.getpid() == pid and shutil.rmtree(tmp, ignore_errors=True))
    return tmp


def _fill(folder: Path, files: dict[str, bytes]) -> None:
    for name, contents in files.items():
        (folder / name).write_bytes(contents)
    folder.chmod(0o755)


def loader_icd_files() -> tuple[list[tuple[str, str]], Optional[str]]:
    """([(ICD file, library it names)], note): what the loader reads now. `note` is a line when
    $OCL_ICD_VENDORS names nothing usable."""
    value = os.environ.get(ENV_VENDORS)
    if not value:
        folder = system_vendor_dir()
    elif os.path.isdir(value):
        folder = Path(value)
    elif os.path.isfile(value):               # ocl-icd: one .icd file, or a library itself
        if value.endswith(".icd"):
            try:
                return [(value, _named_library(Path(value).read_bytes()))], None
            except OSError as exc:
                return [], f"{ENV_VENDORS}={value} cannot be read ({exc.strerror or exc})"
        return [(f"{ENV_VENDORS}={value}", value)], None
    else:
        return [], (f"{ENV_VENDORS}={value} is neither a folder nor a file: the OpenCL loader finds "
                    f"no implementation through it")
    return [(str(folder / name), _named_library(c)) for name, c in _icd_files(folder).items()], None


def _load_error(library: str) -> Optional[str]:
    """Why `library` does not load (None when it does). A name without "/" is looked up as the
    loader's dlopen does (the library search path)."""
    if not library:
        return "the file names no library"
    if "/" in library and not os.path.exists(library):
        return "file not found"
    try:
        ctypes.CDLL(library, mode=os.RTLD_LAZY)
    except OSError as exc:
        text = str(exc)
        if text.startswith(library + ": "):  # dlerror repeats the path
            text = text[len(library) + 2:]
        if "No such file" in text:
            # pyopencl's bundled loader also searches pyopencl/.libs (its extension's RPATH, which
            # dlopen applies): pip PoCL's own pocl.icd names "libpocl-<hash>.so" found there
            return None if "/" not in library and (_pyopencl_libs() / library).is_file() else "file not found"
        return text
    return None


def _pyopencl_libs() -> Path:
    from importlib.util import find_spec
    spec = find_spec("pyopencl")
    return Path(list(spec.submodule_search_locations)[0]) / ".libs" if spec else Path("/nonexistent")


def icd_problems(consequence: Optional[str] = "the other devices are used") -> list[str]:
    """One line per ICD file the loader reads whose library does not load (missing, not a library,
    another architecture), ending with `consequence`. The loader skips those silently."""
    entries, note = loader_icd_files()
    lines = [note] if note else []
    for icd, library in entries:
        error = _load_error(library)
        if error is not None:
            lines.append(f"OpenCL ICD {icd} names {library or '(nothing)'}, which does not load ({error})"
                         + (f"; {consequence}" if consequence else ""))
    return lines


def explain(message: str) -> str:
    """`message` plus the ICD problems, if any, in one line (for "no OpenCL device found")."""
    problems = icd_problems(consequence=None)
    return message + ("; " + "; ".join(problems) if problems else "")
