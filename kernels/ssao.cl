/* ssao.cl: screen-space ambient occlusion from the G-buffer (report III.1, after Quilez 2008).
 *
 * Algorithm: for each pixel, the position P (the linear depth along the pixel's view ray) and
 * the normal N come from the G-buffer, both taken to view space. SSAO_DIRECTIONS = 8 directions lie in the tangent plane of N
 * (the report's "directions that depend on the normal"), spaced 45° apart and rotated per pixel
 * by a hash of (x, y) (16 rotations, 16 step offsets: deterministic, no banding). Along each
 * direction SSAO_STEPS points P + t·D, t = radius·(j + jitter)/SSAO_STEPS, are projected to
 * the screen; the G-buffer depth there gives the visible surface point Q, H = Q - P. As in
 * horizon-based AO, a sample occludes the direction's slice (the plane of N and D) up to its
 * elevation, measured in that slice, and only as far as the rays of length `radius` reach:
 *     sin_e = clamp((N·H / |(N·H, D·H)| - SSAO_BIAS) / (1 - SSAO_BIAS), 0, 1)
 *             (0 where N·H < SSAO_BIAS·|H|: a sample must also rise above the plane in 3-D),
 *     reach = 1 - (|H|² - (N·H)²) / radius²      (horizontal distance: far occluders fade out),
 *     c = max(min(sin_e, reach), 0);  horizon = max of c along the direction;
 *     ao = clamp(1 - strength · Σ_directions horizon / 8, 0, 1).
 * sin_e is the occluded share of a slice weighted by solid angle; the bias keeps flat and
 * gently curved surfaces (normal quantisation, depth rounding) at exactly 1.
 * Samples off screen, behind the eye, on the background or on the pixel itself occlude
 * nothing. Only IEEE +,-,*,/,sqrt (no trig, exp or rsqrt): with correctly rounded divide and
 * sqrt every conforming device computes the same bits.
 *
 * ORTHO (orthographic camera): view rays are parallel, so P = (x·tan_x, y·tan_y, depth) and a
 * point projects to the screen without the division by its depth (tan_x, tan_y: the view
 * box's half-extents, world units).
 * Buffers: gbuffer uint[GB_PLANES][H·W]; camera float[16] = eye, F, R·tan_x, U·tan_y (float4
 *          each, world space); out: ao float[H·W] in [0, 1], 1 = unoccluded and on background.
 * Work-groups: (SSAO_WG_X, SSAO_WG_Y), each work-item a run of VEC pixels of one row (vec.h);
 *          global size rounded up to the group; no barriers, no local memory. On PoCL the
 *          time goes to the depth gathers (one vgatherdps per step) and the divides.
 */
#pragma OPENCL FP_CONTRACT OFF
#include "gbuffer.h"

#ifndef SSAO_STEPS
#define SSAO_STEPS 4
#endif
#ifndef SSAO_BIAS
#define SSAO_BIAS 0.1f     /* sin of the elevation below which a sample does not occlude (flat surfaces) */
#endif
#ifndef SSAO_WG_X
#define SSAO_WG_X 2
#endif
#ifndef SSAO_WG_Y
#define SSAO_WG_Y 8
#endif
#define SSAO_DIRECTIONS 8
#ifndef ORTHO
#define ORTHO 0      /* 1: orthographic camera: parallel view rays, tan_x, tan_y are half-extents */
#endif

/* (cos, sin) of the per-pixel rotation, (i + 0.5)/16 of 45°, and of the 8 directions k·45°. */
constant float2 SSAO_ROTATIONS[16] = {
    (float2)(0.999698819f, 0.024541229f), (float2)(0.997290457f, 0.073564564f),
    (float2)(0.992479535f, 0.122410675f), (float2)(0.985277642f, 0.170961889f),
    (float2)(0.975702130f, 0.219101240f), (float2)(0.963776066f, 0.266712757f),
    (float2)(0.949528181f, 0.313681740f), (float2)(0.932992799f, 0.359895037f),
    (float2)(0.914209756f, 0.405241314f), (float2)(0.893224301f, 0.449611330f),
    (float2)(0.870086991f, 0.492898192f), (float2)(0.844853565f, 0.534997620f),
    (float2)(0.817584813f, 0.575808191f), (float2)(0.788346428f, 0.615231591f),
    (float2)(0.757208847f, 0.653172843f), (float2)(0.724247083f, 0.689540545f)};
constant float SSAO_OCTANT_COS[8] = {1.0f, 0.707106781f, 0.0f, -0.707106781f, -1.0f, -0.707106781f, 0.0f, 0.707106781f};
constant float SSAO_OCTANT_SIN[8] = {0.0f, 0.707106781f, 1.0f, 0.707106781f, 0.0f, -0.707106781f, -1.0f, -0.707106781f};

/* lowbias32 (Wellons): a well-mixed integer hash, identical on every device. */
static inline uintV ssao_hash(uintV h)
{
    h ^= h >> 16;
    h *= 0x7feb352du;
    h ^= h >> 15;
    h *= 0x846ca68bu;
    h ^= h >> 16;
    return h;
}

kernel __attribute__((reqd_work_group_size(SSAO_WG_X, SSAO_WG_Y, 1)))
void ssao(global const uint* gbuffer, int width, int height, float far, global const float* camera,
          float tan_x, float tan_y, float radius, float strength, global float* ao)
{
    const int px0 = get_global_id(0) * VEC, py = get_global_id(1);
    if (py >= height || px0 >= width) return;
    const int npix = width * height;
    const int p0 = py * width + px0;
    const int valid = min(VEC, width - px0);
    global const float* depth_plane = (global const float*)(gbuffer + GB_LINEAR_DEPTH_PLANE * npix);

    intV tri = as_intV(load_plane(gbuffer + GB_TRIANGLE_ID_PLANE * npix, p0, valid, 0xffffffffu));
    intV fg = tri >= 0;
    floatV out = 1.0f;
    if (ANY(fg)) {
        floatV lin = as_floatV(load_plane(gbuffer + GB_LINEAR_DEPTH_PLANE * npix, p0, valid, 0u));
        floatV depth = select((floatV)1.0f, lin * far, fg);    /* background lanes: any finite depth */
        floatV fx, fy, fz;
        unpack_oct12x2V(load_plane(gbuffer + GB_NORMAL_PLANE * npix, p0, valid, 0u) >> GB_NORMAL_SHIFT,
                        &fx, &fy, &fz);
        floatV len = sqrt(fx * fx + fy * fy + fz * fz);
        floatV nx = fx / len, ny = fy / len, nz = fz / len;

        /* Everything below is in view space (R, U, F): the camera buffer holds F and R·tan_x, U·tan_y. */
        const float3 F = vload4(1, camera).xyz, Rs = vload4(2, camera).xyz, Us = vload4(3, camera).xyz;
        const float3 R = Rs / tan_x, U = Us / tan_y;
        floatV wx = nx, wy = ny, wz = nz;
        nx = wx * R.x + wy * R.y + wz * R.z;
        ny = wx * U.x + wy * U.y + wz * U.z;
        nz = wx * F.x + wy * F.y + wz * F.z;

        /* Tangent frame of N (Duff et al. 2017): T, B, N orthonormal, continuous but at nz = 0. */
        floatV sgn = select((floatV)-1.0f, (floatV)1.0f, nz >= 0.0f);
        floatV a = -1.0f / (sgn + nz);
        floatV b = nx * ny * a;
        floatV tx = 1.0f + sgn * nx * nx * a, ty = sgn * b, tz = -sgn * nx;
        floatV bx = b, by = sgn + ny * ny * a, bz = -ny;

        /* P on the pixel's view ray at its depth; pixel centre x maps to x·(2/W)·tan_x - tan_x, less
         * the principal point (ox, oy in NDC: camera[3], camera[7]; lighting.h pixel_positions). */
        const float kx = 2.0f * tan_x / (float)width, ky = 2.0f * tan_y / (float)height;
        const float ox = camera[3], oy = camera[7];
#if ORTHO
        floatV px_ = (convert_floatV(px0 + LANES) + 0.5f) * kx - tan_x * (1.0f + ox);
        floatV py_ = (floatV)(tan_y * (1.0f - oy) - ((float)py + 0.5f) * ky);
#else
        floatV px_ = depth * ((convert_floatV(px0 + LANES) + 0.5f) * kx - tan_x * (1.0f + ox));
        floatV py_ = depth * (tan_y * (1.0f - oy) - ((float)py + 0.5f) * ky);
#endif
        floatV pz_ = depth;

        uintV h = ssao_hash(convert_uintV(px0 + LANES) | ((uint)py << 16));
        intV rot = as_intV(h & 15u);
        floatV rc = GATHER_M(floatV, SSAO_ROTATIONS, rot, x), rs = GATHER_M(floatV, SSAO_ROTATIONS, rot, y);
        floatV jitter = (convert_floatV((h >> 4) & 15u) + 0.5f) * (1.0f / 16.0f);
        const float inv_r2 = 1.0f / (radius * radius);
        const float half_w = 0.5f * (float)width, half_h = 0.5f * (float)height;
        const float to_px_x = half_w / tan_x, to_px_y = half_h / tan_y;
        const float centre_x = half_w * (1.0f + ox), centre_y = half_h * (1.0f - oy);  /* principal point, px */

        floatV occlusion = 0.0f;
        for (int k = 0; k < SSAO_DIRECTIONS; ++k) {
            floatV c = rc * SSAO_OCTANT_COS[k] - rs * SSAO_OCTANT_SIN[k];
            floatV s = rs * SSAO_OCTANT_COS[k] + rc * SSAO_OCTANT_SIN[k];
            floatV dx = c * tx + s * bx, dy = c * ty + s * by, dz = c * tz + s * bz;
            floatV horizon = 0.0f;
            for (int j = 0; j < SSAO_STEPS; ++j) {
                floatV dist = radius * (((float)j + jitter) * (1.0f / SSAO_STEPS));
                floatV z = pz_ + dist * dz;
#if ORTHO
                floatV fxp = (px_ + dist * dx) * to_px_x + centre_x;
                floatV fyp = centre_y - (py_ + dist * dy) * to_px_y;
#else
                floatV inv_z = 1.0f / z;
                floatV fxp = (px_ + dist * dx) * inv_z * to_px_x + centre_x;
                floatV fyp = centre_y - (py_ + dist * dy) * inv_z * to_px_y;
#endif
                intV inside = fg & (z > 0.0f) & (fxp >= 0.0f) & (fxp < (float)width)
                              & (fyp >= 0.0f) & (fyp < (float)height);
                /* Out-of-range (or NaN) lanes read pixel 0 and are masked below. */
                intV ix = convert_intV(select((floatV)0.0f, floor(fxp), inside));
                intV iy = convert_intV(select((floatV)0.0f, floor(fyp), inside));
                inside &= (ix != px0 + LANES) | (iy != py);
                floatV dq = GATHER_F(depth_plane, iy * width + ix) * far;
                inside &= isfinite(dq);
                dq = select((floatV)0.0f, dq, inside);
#if ORTHO
                floatV hx = ((convert_floatV(ix) + 0.5f) * kx - tan_x * (1.0f + ox)) - px_;
                floatV hy = (tan_y * (1.0f - oy) - (convert_floatV(iy) + 0.5f) * ky) - py_;
#else
                floatV hx = dq * ((convert_floatV(ix) + 0.5f) * kx - tan_x * (1.0f + ox)) - px_;
                floatV hy = dq * (tan_y * (1.0f - oy) - (convert_floatV(iy) + 0.5f) * ky) - py_;
#endif
                floatV hz = dq - pz_;
                floatV h2 = hx * hx + hy * hy + hz * hz;
                floatV nh = nx * hx + ny * hy + nz * hz;
                floatV dh = dx * hx + dy * hy + dz * hz;
                floatV sin_slice = nh / sqrt(fmax(nh * nh + dh * dh, 1e-30f));
                floatV sin_e = clamp((sin_slice - SSAO_BIAS) * (1.0f / (1.0f - SSAO_BIAS)), 0.0f, 1.0f);
                sin_e = select(sin_e, (floatV)0.0f, nh * nh < (SSAO_BIAS * SSAO_BIAS) * h2);
                floatV reach = 1.0f - (h2 - nh * nh) * inv_r2;
                floatV cval = fmax(fmin(sin_e, reach), 0.0f);
                horizon = fmax(horizon, select((floatV)0.0f, cval, inside));
            }
            occlusion += horizon;
        }
        out = select((floatV)1.0f, clamp(1.0f - strength * (occlusion * (1.0f / SSAO_DIRECTIONS)), 0.0f, 1.0f), fg);
    }
    if (valid == VEC) {
        vstoreV(out, 0, ao + p0);
    } else {
        for (int l = 0; l < valid; ++l) ao[p0 + l] = LANE_F(out, l);
    }
}
