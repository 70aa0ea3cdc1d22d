"""KTX2 (`KHR_texture_basisu`) fixtures for tests/test_ktx2.py, of our own making: a seeded NumPy
image encoded by Basis Universal's encoder (through the `alktx2` wheel, used only here):

    python tests/ktx2_files.py      # pip install alktx2; writes tests/data/ktx2/*.ktx2

The tests need only the committed files and `source_image()` (the same seeded pixels), so neither
CI nor a user needs the encoder. opengl_basisu, clrender's decoder, has no encoder.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

FIXTURES = Path(__file__).resolve().parent / "data" / "ktx2"
W, H = 32, 24          # multiples of 4, as KHR_texture_basisu requires
# file -> the encoder's settings (alpha unless opaque; one mip level unless mipmaps)
FILES = {
    "uastc.ktx2": dict(codec="uastc", quality=100, effort=10),
    "uastc_zstd.ktx2": dict(codec="uastc", quality=100, effort=10, zstd_supercompression_level=6),
    "etc1s.ktx2": dict(codec="etc1s", quality=255, effort=5),
    "etc1s_mips.ktx2": dict(codec="etc1s", quality=255, effort=5, mipmaps=True),     # a full chain
    "etc1s_rgb.ktx2": dict(codec="etc1s", quality=255, effort=5, opaque=True),
}


def source_image(opaque: bool = False) -> np.ndarray:
    """(H, W, 4) uint8: a smooth random field (a seeded 3 x 3 grid of RGBA values in [32, 224),
    bilinearly interpolated; each channel its own gradient), the kind of content block codecs are
    made for; alpha 255 when `opaque`."""
    coarse = np.random.default_rng(37).integers(32, 224, (3, 3, 4)).astype(np.float64)
    ys, xs = np.linspace(0, 2, H), np.linspace(0, 2, W)
    rows = np.stack([[np.interp(xs, np.arange(3), coarse[j, :, c]) for c in range(4)] for j in range(3)])
    img = np.stack([[np.interp(ys, np.arange(3), rows[:, c, i]) for i in range(W)] for c in range(4)])
    rgba = np.round(img.transpose(2, 1, 0)).astype(np.uint8)
    if opaque:
        rgba[..., 3] = 255
    return rgba


def write_fixtures(folder: Path = FIXTURES) -> None:
    import alktx2
    folder.mkdir(parents=True, exist_ok=True)
    for name, settings in FILES.items():
        settings = dict(settings)
        opaque = settings.pop("opaque", False)
        rgba = source_image(opaque)
        data = alktx2.encode_raw_rgba_to_ktx2(rgba.tobytes(), W, H, has_alpha=not opaque, srgb=True,
                                              threads=1, **settings)
        (folder / name).write_bytes(data)


if __name__ == "__main__":
    write_fixtures()
    for p in sorted(FIXTURES.glob("*.ktx2")):
        print(p.name, p.stat().st_size, "bytes")
