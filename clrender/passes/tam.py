"""Tonal art maps for the hatching post effect (Praun, Hoppe, Webb, Finkelstein 2001,
"Real-time hatching"; report IV.3 "Crayonnage"): kernels/hatching.cl picks, per pixel, two of
these tones from the luminance and blends them.

`tonal_art_map()` returns TONES = 7 tileable stroke textures of SIZE × SIZE texels (tone 0:
blank paper ... tone 6: darkest), each with its mip chain down to 1 × 1, as ink coverage in
[0, 1] (1 = fully inked). It is generated at first use, procedurally and deterministically, and
cached for the process.

Construction (Praun's stroke-nesting greedy, on a torus):

- One stroke list grows from tone to tone: tone t + 1 is tone t plus the strokes added until the
  mean coverage of level 0 reaches TARGETS[t + 1] (0.9·t/6: 0, 15, 30, ... 90 %). Tones 1-3 get
  strokes along the primary direction (about 45°, "/"), tones 4-5 cross-hatching along the
  perpendicular one ("\\"), tone 6 both, alternately.
- A stroke is a segment of random length (0.25-0.6 of the tile), direction jittered around its
  hatching direction, half-width 0.55-0.8 texels and darkness 0.75-1; its coverage of a texel is
  darkness·clamp(half-width + 0.5 - distance to the segment, 0, 1), quantized to 8 bits and
  wrapped around the tile edges (tileable). For each new stroke Praun's "best of several
  candidates" picks, among CANDIDATES random ones, the one adding most ink where the texture is
  still light, both at level 0 and on an 8 × 8-texel average (so strokes spread evenly).
- Strokes are composited with 8-bit "over": C' = 255 - round((255 - C)(255 - a) / 255), which
  never lowers a texel (C' >= C). Everything is integer arithmetic, IEEE-exact float ops (sqrt,
  divide) and a SplitMix64 stream of our own, so the map is bit-identical on every machine and
  NumPy version.
- Mip level l (SIZE >> l texels a side) is the exact box average of level 0's 8-bit coverage
  over 2^l × 2^l blocks: sum / (255·4^l), rounded once to float32.

Nesting, at every level: tone t + 1's level-0 coverage is tone t's after more "over"
compositing, so C[t+1] >= C[t] texel by texel; a level-l texel is a monotone function (a sum,
then one rounding) of its block of level-0 texels, so the order holds at every level too. In
particular every inked (coverage > 0) texel of tone t is inked in tone t + 1, at every level.
Because the order holds texel by texel, the kernel's linear blend between tones t and t + 1 and
between mip levels gives, at every pixel, ink that never decreases as the tone darkens.

Layout on the device (kernels/hatching.cl): float32[TONES][LEVEL_TEXELS], tone-major; within a
tone the levels follow each other from level 0, level l at texel offset
4·(SIZE² - (SIZE >> l)²) / 3, row-major (v·size + u).
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np

SIZE = 128                                  # level-0 texels per side (a power of two)
TONES = 7                                   # 0 = no ink ... 6 = darkest (report: "entre 0 et 6")
LEVELS = SIZE.bit_length()                  # 128, 64, ..., 1: 8 levels
LEVEL_TEXELS = sum((SIZE >> l) ** 2 for l in range(LEVELS))
TARGETS = (0.0, 1 / 6, 2 / 6, 3 / 6, 4 / 6, 5 / 6, 0.97)  # mean level-0 coverage of each tone
CANDIDATES = 8                              # Praun's best-of-N stroke candidates
SEED = 0x7A11_2001
PRIMARY, CROSS = -1.0, 1.0                  # direction slopes dy/dx (image y down): "/" and "\"
DEVICE_BYTES = 4 * TONES * LEVEL_TEXELS     # the uploaded map


def level_offset(level: int) -> int:
    """Texel offset of mip `level` inside one tone (levels stored from level 0)."""
    return 4 * (SIZE * SIZE - (SIZE >> level) ** 2) // 3


class _SplitMix64:
    """A tiny deterministic stream (SplitMix64), independent of NumPy's generator versions."""
    MASK = (1 << 64) - 1

    def __init__(self, seed: int):
        self.state = seed & self.MASK

    def uniform(self, lo: float = 0.0, hi: float = 1.0) -> float:
        self.state = (self.state + 0x9E3779B97F4A7C15) & self.MASK
        z = self.state
        z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & self.MASK
        z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & self.MASK
        z ^= z >> 31
        return lo + (hi - lo) * ((z >> 11) * 2.0 ** -53)


def _candidates(rng: _SplitMix64, slope: float, n: int):
    """n random strokes around `slope`: (start xy, unit direction, length, half-width, darkness)."""
    out = []
    for _ in range(n):
        c = np.array([rng.uniform(0, SIZE), rng.uniform(0, SIZE)])
        m = slope + rng.uniform(-0.15, 0.15)
        d = np.array([1.0, m]) / np.sqrt(1.0 + m * m)
        length = rng.uniform(0.25, 0.6) * SIZE
        out.append((c - 0.5 * length * d, d, length, rng.uniform(0.55, 0.8), rng.uniform(0.75, 1.0)))
    return out


def _stroke(start, d, length, half_width, darkness):
    """(rows, cols, alpha): the stroke's 8-bit coverage over its bounding box, indices wrapped."""
    end = start + length * d
    reach = half_width + 1.0
    lo = np.floor(np.minimum(start, end) - reach).astype(np.int64)
    hi = np.ceil(np.maximum(start, end) + reach).astype(np.int64)
    xs = np.arange(lo[0], hi[0] + 1)
    ys = np.arange(lo[1], hi[1] + 1)
    px = (xs + 0.5)[None, :] - start[0]
    py = (ys + 0.5)[:, None] - start[1]
    along = np.clip(px * d[0] + py * d[1], 0.0, length)
    dx, dy = px - along * d[0], py - along * d[1]
    dist = np.sqrt(dx * dx + dy * dy)
    alpha = np.rint(255.0 * darkness * np.clip(half_width + 0.5 - dist, 0.0, 1.0)).astype(np.int64)
    return ys % SIZE, xs % SIZE, alpha


def _over(cov: np.ndarray, alpha: np.ndarray) -> np.ndarray:
    """8-bit 'over' of ink alpha onto coverage: never lowers a texel."""
    return 255 - ((255 - cov) * (255 - alpha) + 127) // 255


def _block_average(cov: np.ndarray, block: int) -> np.ndarray:
    """Integer mean over block × block tiles, expanded back to SIZE × SIZE (the evenness term)."""
    n = SIZE // block
    mean = cov.reshape(n, block, n, block).sum(axis=(1, 3)) // (block * block)
    return np.repeat(np.repeat(mean, block, axis=0), block, axis=1)


def _level0_tones() -> np.ndarray:
    """(TONES, SIZE, SIZE) int64 8-bit coverage, nested tone to tone."""
    rng = _SplitMix64(SEED)
    cov = np.zeros((SIZE, SIZE), np.int64)
    tones = [cov.copy()]
    added = 0
    for t in range(1, TONES):
        target = int(np.ceil(TARGETS[t] * 255 * SIZE * SIZE))
        first = True
        while first or int(cov.sum()) < target:
            first = False
            if t <= 3:
                slope = PRIMARY
            elif t <= 5:
                slope = CROSS
            else:
                slope = PRIMARY if added % 2 else CROSS
            coarse = _block_average(cov, 8)
            best, best_score = None, -1
            for cand in _candidates(rng, slope, CANDIDATES):
                rows, cols, alpha = _stroke(*cand)
                here = cov[np.ix_(rows, cols)]
                score = int((alpha * (255 - here)).sum() + (alpha * (255 - coarse[np.ix_(rows, cols)])).sum())
                if score > best_score:
                    best, best_score = (rows, cols, alpha), score
            rows, cols, alpha = best
            idx = np.ix_(rows, cols)
            cov[idx] = _over(cov[idx], alpha)
            added += 1
        tones.append(cov.copy())
    return np.stack(tones)


def _mip_chain(level0: np.ndarray) -> list[np.ndarray]:
    """Level l: exact box sums of the 8-bit level 0 over 2^l blocks / (255·4^l), as float32."""
    out = []
    for l in range(LEVELS):
        b, n = 1 << l, SIZE >> l
        sums = level0.reshape(n, b, n, b).sum(axis=(1, 3))
        out.append((sums / float(255 * b * b)).astype(np.float32))
    return out


@lru_cache(maxsize=1)
def tonal_art_map() -> tuple[tuple[np.ndarray, ...], ...]:
    """maps[tone][level]: float32 (SIZE >> level, SIZE >> level) ink coverage in [0, 1], read-only."""
    maps = []
    for level0 in _level0_tones():
        chain = _mip_chain(level0)
        for a in chain:
            a.setflags(write=False)
        maps.append(tuple(chain))
    return tuple(maps)


@lru_cache(maxsize=1)
def device_layout() -> np.ndarray:
    """The map as uploaded: float32[TONES · LEVEL_TEXELS] (see the module docstring)."""
    flat = np.concatenate([np.concatenate([lvl.ravel() for lvl in tone]) for tone in tonal_art_map()])
    assert flat.size == TONES * LEVEL_TEXELS
    flat.setflags(write=False)
    return flat
