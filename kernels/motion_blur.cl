/* motion_blur.cl: post-process motion blur of the linear HDR colour along the per-pixel velocity
 * (report IV.2), at the output resolution (docs/post.md: bloom -> motion blur -> tone map), by
 * McGuire et al.'s reconstruction filter ("A Reconstruction Filter for Plausible Motion Blur",
 * I3D 2012): tile max, neighbour max, then a depth-aware gather.
 *
 * Algorithm: the G-buffer velocity v (pixels, current position - previous position) is the motion
 * over one frame interval; the exposure is SHUTTER intervals centred on the current frame, so a
 * pixel's surface sweeps p + t·V, t in [-1, 1], with the half-vector V = v·shutter/2.
 *  1. `mb_velocity` (a work-item: a run of VEC pixels over the MB_TILE rows of one tile row): V
 *     per pixel; |2V| < MB_MIN_LENGTH (half a pixel: invisible, and below it lies the rounding
 *     noise of a static reprojection, ~1e-3 px) or not finite is exactly 0 (static); |V| above
 *     MB_MAX_RADIUS is shortened to it. Writes inv_len = 1 / max(|V|, 1/2) per pixel (McGuire's
 *     half-pixel minimum) and, per run and tile row, the longest V of those pixels: the partial
 *     tile maxima. "Longest" compares (|V|², V.x, V.y) lexicographically, a total order, so the
 *     maximum is the same whatever order the lanes, rows and tiles are reduced in.
 *  2. `mb_neighbor_max` (a work-item per MB_TILE² tile): the longest V over the partials of the
 *     3×3 tiles around it (MB_TILE >= MB_MAX_RADIUS: every pixel whose blur can reach this tile).
 *  3. `mb_gather` (a run of VEC pixels): tiles whose neighbour max is 0 copy their colour (a
 *     static frame is bit-identical). Otherwise, with M the tile's neighbour max, pixel X takes
 *         sum = C(X) / |V_X| + sum_i a_i C(Y_i),  weight = 1 / |V_X| + sum_i a_i,  out = sum / weight
 *     over S = motion_blur_samples taps Y_i = X + floor(t_i·M + 1/2) (per axis), t_i = (2i+1)/S - 1,
 *     coordinates clamped to the image. A tap that lands on X itself (t_i = 0 for odd S, an offset
 *     that rounds to 0, or a clamp at the border) is skipped: X counts once, with its own weight.
 *     With d = |Y - X| (pixels), z the linear depths and |V| >= 1/2 as above:
 *         a = f·cone(|V_Y|) + b·cone(|V_X|) + 2·cyl(|V_Y|)·cyl(|V_X|)
 *         cone(L) = clamp(1 - d/L, 0, 1),  cyl(L) = clamp((1.05 - d/L) · 10, 0, 1)
 *     (d/L is d · inv_len; McGuire's cylinder falls off by a smoothstep, a linear ramp here: the
 *     same ends for half the arithmetic).
 *         f = clamp(1 - r, 0, 1) (Y in front), b = clamp(1 + r, 0, 1) (Y behind),
 *         r = z_Y · (1 / (MB_SOFT_Z z_X)) - 1 / MB_SOFT_Z, i.e. (z_Y - z_X) / (MB_SOFT_Z z_X), and
 *         r = 0 where z_X = z_Y (background: z = +inf)
 *     A blurry foreground Y spreads over X up to its own |V_Y| (case f), a blurry X reveals what
 *     lies behind it (case b), and two blurry surfaces blend (the cylinders). Every lane of a run
 *     lies in one tile (VEC divides MB_TILE): all lanes share M and the offsets, so each tap is a
 *     contiguous row load; the lanes' own clamps give their d.
 *
 * Buffers: gbuffer uint[GB_PLANES][W·H] (velocity plane: half2, x low; linear depth plane: float);
 *          inv_len float[W·H]; partial float4[tiles_y][runs] (|V|², V.x, V.y, 0), runs =
 *          ceil(W / VEC); neighbor float2[tiles_y][tiles_x]; color float[3][W·H] -> out float[3][W·H].
 * Work-groups: 1-D or 2-D, any shape: mb_velocity and mb_gather take (runs, tile rows or rows), a
 *          run of VEC pixels per work-item (vec.h, row_run.h); mb_neighbor_max a tile per work-item.
 *          Global sizes are rounded up and bounds-checked; no barriers, no local memory.
 */
#pragma OPENCL FP_CONTRACT OFF
#include "gbuffer.h"
/* VEC-wide runs (CPUs): row_run.h's loads inlined, not calls that spill every live vector
 * (edge_aa.cl has the same; not with VEC 1: Oclgrind cannot run the inlined code at -O0). */
#if VEC > 1 && defined(__clang__)
#define ROW_RUN_INLINE __attribute__((always_inline))
#endif
#include "row_run.h"

#ifndef MB_MAX_RADIUS
#define MB_MAX_RADIUS 32      /* pixels: the longest half blur |V| */
#endif
#ifndef MB_TILE
#define MB_TILE 32            /* pixels: tile side; >= MB_MAX_RADIUS, a multiple of VEC */
#endif
#ifndef MB_MIN_LENGTH
#define MB_MIN_LENGTH 0.5f    /* pixels: a shorter motion over the exposure is static */
#endif
#ifndef MB_SOFT_Z
#define MB_SOFT_Z 0.02f       /* relative depth over which "in front" fades to "behind" */
#endif
#if MB_TILE < MB_MAX_RADIUS || MB_TILE % VEC != 0
#error "MB_TILE must be at least MB_MAX_RADIUS and a multiple of VEC"
#endif
#if GB_LINEAR_DEPTH_SHIFT != 0 || GB_VELOCITY_SHIFT != 0
#error "motion_blur.cl reads the linear depth and velocity planes as whole 32-bit words"
#endif

/* (l2, vx, vy) > (b2, bx, by) lexicographically, lane by lane: a mask for select. */
#define MB_LONGER(l2, vx, vy, b2, bx, by) \
    (((l2) > (b2)) | (((l2) == (b2)) & (((vx) > (bx)) | (((vx) == (bx)) & ((vy) > (by))))))

static inline void mb_keep_longer(float4* best, float4 v)
{
    if (MB_LONGER(v.x, v.y, v.z, best->x, best->y, best->z)) *best = v;
}

/* The velocity halves (x, y interleaved) of pixels at .. at + VEC - 1 as two vectors; pixels
 * past `last` (the row's end) read it. */
static inline void mb_load_velocity(global const half* vel, int at, int last, floatV* vx, floatV* vy)
{
#if VEC == 1
    const float2 v = vload_half2(at, vel);
    *vx = v.x;
    *vy = v.y;
#else
    if (at + VEC - 1 <= last) {
#if VEC == 4
        const float8 v = vload_half8(0, vel + 2 * at);
        *vx = v.even;
        *vy = v.odd;
#elif VEC == 8
        const float16 v = vload_half16(0, vel + 2 * at);
        *vx = v.even;
        *vy = v.odd;
#else
        const float16 a = vload_half16(0, vel + 2 * at), b = vload_half16(0, vel + 2 * at + 16);
        *vx = (floatV)(a.even, b.even);
        *vy = (floatV)(a.odd, b.odd);
#endif
        return;
    }
    for (int i = 0; i < VEC; ++i) {
        const float2 v = vload_half2(min(at + i, last), vel);
        LANE_F(*vx, i) = v.x;
        LANE_F(*vy, i) = v.y;
    }
#endif
}

/* The cylinder's fall-off at x = d / L: 1 below 0.95, 0 above 1.05, linear between. */
static inline floatV mb_cylinder(floatV x)
{
    return clamp((1.05f - x) * 10.0f, 0.0f, 1.0f);
}

kernel void mb_velocity(global const uint* gbuffer, int width, int height, float shutter, global float* inv_len,
                        global float4* partial)
{
    const int run = get_global_id(0), tile_y = get_global_id(1);
    const int runs = (width + VEC - 1) / VEC;
    if (run >= runs || tile_y * MB_TILE >= height) return;
    const int x0 = run * VEC;
    const intV inside = (intV)x0 + LANES < width;
    global const half* vel = (global const half*)(gbuffer + GB_VELOCITY_PLANE * width * height);
    const float min2 = 0.25f * MB_MIN_LENGTH * MB_MIN_LENGTH;          /* |V| = |2V| / 2 */
    const float max_len = (float)MB_MAX_RADIUS;
    floatV b2 = 0.0f, bx = 0.0f, by = 0.0f;
    for (int y = tile_y * MB_TILE; y < min(tile_y * MB_TILE + MB_TILE, height); ++y) {
        const int at = y * width + x0;
        floatV vx, vy;
        mb_load_velocity(vel, at, y * width + width - 1, &vx, &vy);
        const float half_shutter = 0.5f * shutter;
        vx *= half_shutter;
        vy *= half_shutter;
        floatV l2 = vx * vx + vy * vy;
        const intV moving = (l2 >= min2) & (l2 < INFINITY) & inside;      /* NaN compares false */
        vx = select((floatV)0.0f, vx, moving);
        vy = select((floatV)0.0f, vy, moving);
        l2 = select((floatV)0.0f, l2, moving);
        const intV capped = l2 > max_len * max_len;
        const floatV scale = max_len / sqrt(l2);
        vx = select(vx, vx * scale, capped);
        vy = select(vy, vy * scale, capped);
        l2 = select(l2, vx * vx + vy * vy, capped);
        row_store_f(1.0f / fmax(sqrt(l2), 0.5f), inv_len + y * width, x0, width);
        const intV longer = MB_LONGER(l2, vx, vy, b2, bx, by);
        b2 = select(b2, l2, longer);
        bx = select(bx, vx, longer);
        by = select(by, vy, longer);
    }
    float4 best = (float4)(0.0f);
    for (int i = 0; i < VEC; ++i) mb_keep_longer(&best, (float4)(LANE_F(b2, i), LANE_F(bx, i), LANE_F(by, i), 0.0f));
    partial[tile_y * runs + run] = best;
}

kernel void mb_neighbor_max(global const float4* partial, int width, int tiles_x, int tiles_y, global float2* neighbor)
{
    const int tx = get_global_id(0), ty = get_global_id(1);
    if (tx >= tiles_x || ty >= tiles_y) return;
    const int runs = (width + VEC - 1) / VEC, per_tile = MB_TILE / VEC;
    const int r0 = max(tx - 1, 0) * per_tile, r1 = min((tx + 2) * per_tile, runs);
    float4 best = (float4)(0.0f);
    for (int j = max(ty - 1, 0); j <= min(ty + 1, tiles_y - 1); ++j)
        for (int r = r0; r < r1; ++r) mb_keep_longer(&best, partial[j * runs + r]);
    neighbor[ty * tiles_x + tx] = best.yz;
}

kernel void mb_gather(global const float* color, global const uint* gbuffer, global const float* inv_len,
                      global const float2* neighbor, int width, int height, int tiles_x, int samples,
                      global float* out)
{
    const int run = get_global_id(0), y = get_global_id(1);
    const int x0 = run * VEC;
    if (x0 >= width || y >= height) return;
    const int plane = width * height, row = y * width;
    const float2 m = neighbor[(y / MB_TILE) * tiles_x + x0 / MB_TILE];
    const floatV cr = row_load_f(color + row, x0, width), cg = row_load_f(color + plane + row, x0, width),
                 cb = row_load_f(color + 2 * plane + row, x0, width);
    if (m.x == 0.0f && m.y == 0.0f) {             /* nothing moves near this tile */
        row_store_f(cr, out + row, x0, width);
        row_store_f(cg, out + plane + row, x0, width);
        row_store_f(cb, out + 2 * plane + row, x0, width);
        return;
    }
    global const float* depth = (global const float*)(gbuffer + GB_LINEAR_DEPTH_PLANE * plane);
    const floatV zx = row_load_f(depth + row, x0, width), ix = row_load_f(inv_len + row, x0, width);
    const floatV kx = 1.0f / (MB_SOFT_Z * zx);     /* r = (z_Y - z_X) / (MB_SOFT_Z z_X) = z_Y kx - 1/MB_SOFT_Z */
    const intV xs = (intV)x0 + LANES;
    floatV weight = ix, sr = cr * ix, sg = cg * ix, sb = cb * ix;
    for (int i = 0; i < samples; ++i) {
        const float t = (float)(2 * i + 1) / (float)samples - 1.0f;
        const int ox = (int)floor(t * m.x + 0.5f), oy = (int)floor(t * m.y + 0.5f);
        if (ox == 0 && oy == 0) continue;          /* the pixel itself: counted once, above */
        const int yy = ROW_CLAMP(y + oy, height), yrow = yy * width, xq = x0 + ox;
        floatV d, zy, iy, qr, qg, qb;
        intV self = 0;                             /* lanes clamped onto the pixel itself */
        if (yy == y + oy && xq >= 0 && xq + VEC <= width) {     /* no clamp: all lanes at (ox, oy) */
            d = sqrt((float)(ox * ox + oy * oy));
            zy = vloadV(0, depth + yrow + xq);
            iy = vloadV(0, inv_len + yrow + xq);
            qr = vloadV(0, color + yrow + xq);
            qg = vloadV(0, color + plane + yrow + xq);
            qb = vloadV(0, color + 2 * plane + yrow + xq);
        } else {
            const intV dxi = clamp(xs + ox, 0, width - 1) - xs;
            const floatV dx = convert_floatV(dxi), dy = (float)(yy - y);
            d = sqrt(dx * dx + dy * dy);
            self = (dxi == 0) & ((intV)(yy - y) == 0);
            zy = row_load_f(depth + yrow, xq, width);
            iy = row_load_f(inv_len + yrow, xq, width);
            qr = row_load_f(color + yrow, xq, width);
            qg = row_load_f(color + plane + yrow, xq, width);
            qb = row_load_f(color + 2 * plane + yrow, xq, width);
        }
        const floatV r = select(zy * kx - 1.0f / MB_SOFT_Z, (floatV)0.0f, zy == zx);
        const floatV front = clamp(1.0f - r, 0.0f, 1.0f), behind = clamp(1.0f + r, 0.0f, 1.0f);
        const floatV cone_y = clamp(1.0f - d * iy, 0.0f, 1.0f), cone_x = clamp(1.0f - d * ix, 0.0f, 1.0f);
        floatV a = front * cone_y + behind * cone_x + 2.0f * (mb_cylinder(d * iy) * mb_cylinder(d * ix));
        a = select(a, (floatV)0.0f, self);
        weight += a;
        sr += a * qr;
        sg += a * qg;
        sb += a * qb;
    }
    row_store_f(sr / weight, out + row, x0, width);
    row_store_f(sg / weight, out + plane + row, x0, width);
    row_store_f(sb / weight, out + 2 * plane + row, x0, width);
}
