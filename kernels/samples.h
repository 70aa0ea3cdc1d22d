/* samples.h: the sub-sample points of a pixel for SAMPLES = 1, 2, 4, 8 (docs/raster_contract.md
 * §10): Direct3D's standard multisample patterns, offsets from the pixel centre in 1/16 pixel
 * (y down), times 16 for the raster's 1/256-pixel fixed point. SAMPLE_SPREAD is the largest
 * |offset| of the pattern: how far setup.cl and binning.cl must look past the pixel centres.
 * clrender/passes/second_geometry.py SAMPLE_PATTERNS is the same table (tests compare them).
 */
#ifndef CLRENDER_SAMPLES_H
#define CLRENDER_SAMPLES_H
#ifndef SAMPLES
#define SAMPLES 1
#endif

#if SAMPLES == 1
#define SAMPLE_PATTERN 0, 0
#define PATTERN_SPREAD 0
#elif SAMPLES == 2
#define SAMPLE_PATTERN 4, 4, -4, -4
#define PATTERN_SPREAD 4
#elif SAMPLES == 4
#define SAMPLE_PATTERN -2, -6, 6, -2, -6, 2, 2, 6
#define PATTERN_SPREAD 6
#elif SAMPLES == 8
#define SAMPLE_PATTERN 1, -3, -1, 3, 5, 1, -3, -5, -5, 5, -7, -1, 3, 7, 7, -7
#define PATTERN_SPREAD 7
#else
#error "SAMPLES must be 1, 2, 4 or 8"
#endif

constant int SAMPLE_OFFSETS[2 * SAMPLES] = { SAMPLE_PATTERN };
#define SAMPLE_DX(s) (16 * SAMPLE_OFFSETS[2 * (s)])
#define SAMPLE_DY(s) (16 * SAMPLE_OFFSETS[2 * (s) + 1])

#ifndef SAMPLE_SPREAD
#define SAMPLE_SPREAD (16 * PATTERN_SPREAD)
#endif
#endif
