"""Multi-layer OpenEXR: one float32 file holding the colour and every requested float AOV, each
as its channels from the AOV table (clrender/abi/aovs.py: color.R/G/B, depth.Z, normal.X/Y/Z, ao...).
The maintained `OpenEXR` binding (PyPI `OpenEXR` >= 3.2, optional extra clrender[outputs]) is
imported when something is written (clrender/outputs/aov_io.py says why this binding)."""
from __future__ import annotations

from pathlib import Path
from typing import Sequence

import numpy as np

from clrender.abi.aovs import AOVS, TABLE, exr_suffixes
from clrender.outputs.atomic import atomic_write

# {AOV: channel letters} of the AOVs whose channels are lettered (color.R, depth.Z); the table's `exr`
EXR_CHANNELS = {a.name: a.exr for a in TABLE if a.exr and a.exr.isalpha()}

_EXR_STATE: dict = {"available": None}


def exr_available() -> bool:
    """Whether the OpenEXR binding is installed (`pip install OpenEXR` or clrender[outputs])."""
    if _EXR_STATE["available"] is None:
        try:
            import OpenEXR  # noqa: F401
            _EXR_STATE["available"] = True
        except ImportError:
            _EXR_STATE["available"] = False
    return _EXR_STATE["available"]


EXR_MISSING = "OpenEXR output needs the OpenEXR package: pip install OpenEXR (or clrender[outputs])"


def exr_channels(name: str, data: np.ndarray) -> dict:
    """The float32 EXR channels of AOV `name`: {"color.R": (H, W), ...}; one-channel AOVs are
    named by themselves ("ao"); `shadow` (H, W, K) gives shadow.0 .. shadow.K-1."""
    a = np.asarray(data)
    if a.ndim == 2:
        suffix = exr_suffixes(name, None)[0]
        key = f"{name}.{suffix}" if suffix else name
        return {key: np.ascontiguousarray(a, np.float32)}
    return {f"{name}.{c}": np.ascontiguousarray(a[..., i], np.float32)
            for i, c in enumerate(exr_suffixes(name, a.shape[2]))}


def exr_layers(frame, aovs: Sequence[str]) -> list[str]:
    """The AOVs the multi-layer EXR holds: colour first, then every requested float AOV."""
    in_exr = [a for a in aovs if a not in AOVS or AOVS[a].exr is not None]    # the table's exr: None for ints
    return list(dict.fromkeys(["color", *in_exr]))


def write_exr(path, frame, aovs: Sequence[str] = ()) -> Path:
    """One multi-layer OpenEXR file (float32, ZIP compression) with `exr_layers(frame, aovs)`."""
    if not exr_available():
        raise RuntimeError(EXR_MISSING)
    import OpenEXR

    channels: dict = {}
    for aov in exr_layers(frame, aovs):
        channels.update(exr_channels(aov, frame.aov(aov)))
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    # OpenEXR.File replaces the dict's arrays by Channel objects: give it a copy.
    atomic_write(path, lambda tmp: OpenEXR.File(header, dict(channels)).write(str(tmp)))
    return Path(path)


def read_exr(path) -> dict:
    """{channel name: (H, W) array} of an EXR file, each channel as stored."""
    import OpenEXR
    with OpenEXR.File(str(path), separate_channels=True) as f:
        return {name: np.array(ch.pixels) for name, ch in f.channels().items()}
