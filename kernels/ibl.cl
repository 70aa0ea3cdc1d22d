/* ibl.cl: image-based lighting precomputation, once per environment (clrender/passes/ibl.py,
 * docs/ibl.md); the shading kernels read the results through environment.h.
 *
 * Direction convention (environment.h): u = 0.5 + atan2(x, -z) / (2 pi), v = acos(y) / pi, texel
 * (i, j) of a w x h equirect level looks along theta = pi (j + 0.5) / h, phi = 2 pi ((i + 0.5) / w - 0.5):
 *     d = (sin theta sin phi, cos theta, -sin theta cos phi).
 *
 * Algorithm, kernel by kernel:
 *   ibl_box       box resize of one equirect level into another (any sizes) on the sphere: output texel
 *                 (i, j) covers the source rectangle [i sx, (i+1) sx) x [j sy, (j+1) sy), sx = sw / dw,
 *                 sy = sh / dh, and is the solid-angle-weighted mean of the source texels over it (the
 *                 weight of a source texel: its overlap in x times cos theta_a - cos theta_b of its overlap
 *                 in y). So a coarse texel holds the mean radiance of its part of the sphere and a small
 *                 bright source keeps its energy at every level (a plain image-area mean under-counts
 *                 sources near the equator: FIS then loses up to 30% of a sun at high roughness).
 *                 Makes the specular chain's level 0 (the environment at most max_width wide) and the
 *                 prefilter's source mip chain (halvings).
 *   ibl_copy      copies floats (the chain's level 0 into the mip chain's buffer; a kernel rather than
 *                 clEnqueueCopyBuffer, whose output Oclgrind 21.10's checker then reports as uninitialized).
 *   ibl_sh_rows   order-2 SH projection of the full-resolution environment, one work-item per row: the
 *                 row's sums over its texels of L(d) * (1, y, z, x, xy, yz, 3z^2 - 1, xz, x^2 - y^2) at the
 *                 texel centres (27 floats: coefficient-major, RGB), times the row's texel solid angle
 *                 dOmega = (2 pi / w) (cos theta_j - cos theta_{j+1}) = (2 pi / w) 2 sin(theta) sin(pi / 2h).
 *   ibl_sh_reduce sums the row partials in row order (one work-item per coefficient and channel) and
 *                 scales them by the basis constant and A_l / pi (A_0 = pi, A_1 = 2 pi / 3, A_2 = pi / 4,
 *                 Ramamoorthi & Hanrahan 2001): evaluating the result at n gives E(n) / pi.
 *   ibl_sample_table, ibl_prefilter: one level of the specular chain. Each texel, direction N = V = R,
 *                 is Karis's (2013) GGX-filtered radiance sum_i L(l_i) (n.l_i) / sum_i (n.l_i),
 *                 alpha = roughness^2, the half vectors importance-sampled from the S Hammersley points
 *                 (i / S -> phi_h, radical inverse of i -> theta_h), l = 2 (n.h) h - n; samples with n.l <= 0
 *                 skip (n.l = 2 (n.h)^2 - 1 is the same for every texel). Filtered importance sampling
 *                 (Krivanek & Colbert 2007): sample i reads the source mip chain trilinearly at
 *                 lod = 0.5 log2(Omega_s / Omega_p) + LOD_BIAS, Omega_s = 1 / (S pdf), pdf = D(n.h) / 4 (n = v),
 *                 Omega_p = (2 pi / w0) (pi / h0) the solid angle of an equator texel of the chain's level 0
 *                 (weighting it by the sample's sin theta, the texel's true solid angle, blurred the
 *                 polar regions and lost energy in the tests: docs/ibl.md). A row's texels are turns of one
 *                 another about +Y, and so are their samples: sample i of every texel of row y has the same
 *                 v and the same offset from the texel's own u. ibl_sample_table computes (v, du, lod, n.l)
 *                 per (row, sample) once (the trigonometry), ibl_prefilter sums the lookups of VEC texels
 *                 of a row at a time. The frame at phi = 0: N = (0, cos theta, -sin theta),
 *                 T = dN/dtheta = (0, -sin theta, -cos theta), B = dN/dphi / sin theta = (1, 0, 0).
 *   ibl_dfg       the environment-independent split-sum table (glTF 2.0 Appendix B BRDF): texel (i, j),
 *                 n.v = (i + 0.5) / n (n.v = 0 is degenerate), roughness r = j / (n - 1) (rows at 0 and 1
 *                 exactly), alpha = r^2, v = (sqrt(1 - n.v^2), 0, n.v):
 *                   A = int 4 Vis (n.l) (v.h) / (n.h) (1 - Fc) dP(h),  B = the same with Fc, Fc = (1 - v.h)^5,
 *                 over the GGX distribution of h (dP = D (n.h) dw_h), Vis the Smith height-correlated
 *                 visibility 0.5 / (n.l sqrt(n.v^2 (1 - a^2) + a^2) + n.v sqrt(n.l^2 (1 - a^2) + a^2)), and
 *                   C = (1/pi) int (1 - (1 - v.h)^5) (n.l) dw_l over the hemisphere (h = normalize(v + l)).
 *                 Deterministic product Gauss-Legendre quadrature, built to resolve what defeats sample
 *                 sequences at grazing n.v (Hammersley with 32768 points still missed A by 1.5e-3):
 *                 phi_h over [0, pi] (the integrands are even in phi) as two halves split at pi/2, kp nodes
 *                 each; for each phi, theta_h over exactly the part where n.l > 0,
 *                 theta_h < (atan2(vx cos phi, n.v) + pi/2) / 2, in the variable s = sqrt(1 - xi)
 *                 (xi the GGX CDF: tan theta_h = alpha sqrt(1 - s^2) / s, dP = 2 s ds dphi / (2 pi)), which
 *                 removes the 1 / (n.h) endpoint singularity, ks nodes. C: the same phi nodes, the cosine
 *                 distribution's t = sin^2 theta_l over [0, 1] with ks nodes. C does not depend on the row.
 *
 * Buffers: every image is float RGB interleaved (texel t at [3t, 3t + 3)), levels addressed by
 *   their offset in texels. ibl_box: src, dst. ibl_copy: src, dst (offsets in floats). ibl_sh_rows: the
 *   environment, partial float[27 h]. ibl_sh_reduce: partial, sh float[27]. ibl_sample_table: table float4[dh * S].
 *   ibl_prefilter: mips (the source chain), mip_levels int[4 * n_mips] (offset, width, height, 0), the
 *   table, dst (the specular level at dst_offset). ibl_dfg: dfg float[3 n n], texel (i, j) at 3 (j n + i);
 *   gl_s float2[ks], gl_phi float2[kp]: Gauss-Legendre (node, weight) pairs on [0, 1] from the host.
 * Work-groups: all any shape, no barriers, no local memory; results do not depend on the shape, and
 *   every sum runs in a fixed order: the same bits every run.
 *   ibl_box 2-D over (dw, dh), a texel per work-item. ibl_copy 1-D over n. ibl_sh_rows 1-D over h, a row per work-item, its
 *   texels taken VEC at a time (lanes summed in lane order at the end). ibl_sh_reduce 1-D over 27.
 *   ibl_sample_table 1-D over dh * S. ibl_prefilter 2-D over (ceil(dw / VEC), dh): a run of VEC adjacent
 *   texels of a row per work-item. ibl_dfg 2-D over (ceil(n / VEC), n): a run of VEC n.v values of a
 *   roughness row. All bounds-checked.
 */
#pragma OPENCL FP_CONTRACT OFF

#include "vec.h"
#include "environment.h"

#ifndef LOD_BIAS
#define LOD_BIAS 0.5f      /* Krivanek & Colbert's +1 blurs more than needed at these sample counts */
#endif

#define IBL_PI 3.14159265358979f

/* Radical inverse of i in base 2 (Hammersley's second coordinate), in [0, 1). */
static inline float radical_inverse(uint bits)
{
    bits = (bits << 16) | (bits >> 16);
    bits = ((bits & 0x55555555u) << 1) | ((bits & 0xAAAAAAAAu) >> 1);
    bits = ((bits & 0x33333333u) << 2) | ((bits & 0xCCCCCCCCu) >> 2);
    bits = ((bits & 0x0F0F0F0Fu) << 4) | ((bits & 0xF0F0F0F0u) >> 4);
    bits = ((bits & 0x00FF00FFu) << 8) | ((bits & 0xFF00FF00u) >> 8);
    return fmin((float)(bits >> 8) * 5.9604644775390625e-8f, 0x1.fffffep-1f);   /* 24 bits: exact */
}

/* GGX half vector in the tangent frame (n = z): cos and sin of theta_h for xi2. */
static inline void ggx_half(float a2, float xi2, float* cos_h, float* sin_h)
{
    const float c2 = (1.0f - xi2) / (1.0f + (a2 - 1.0f) * xi2);
    *cos_h = sqrt(c2);
    *sin_h = sqrt(fmax(1.0f - c2, 0.0f));
}

kernel void ibl_box(global const float* src, int src_offset, int sw, int sh,
                    global float* dst, int dst_offset, int dw, int dh)
{
    const int i = get_global_id(0), j = get_global_id(1);
    if (i >= dw || j >= dh) return;
    const float sx = (float)sw / (float)dw, sy = (float)sh / (float)dh;
    const float x0 = (float)i * sx, x1 = (float)(i + 1) * sx, y0 = (float)j * sy, y1 = (float)(j + 1) * sy;
    const int kx0 = max((int)floor(x0), 0), kx1 = min((int)ceil(x1), sw);
    const int ky0 = max((int)floor(y0), 0), ky1 = min((int)ceil(y1), sh);
    float r = 0.0f, g = 0.0f, b = 0.0f, wsum = 0.0f;
    const float rad = IBL_PI / (float)sh;              /* source rows' theta step */
    for (int ky = ky0; ky < ky1; ++ky) {
        const float ya = fmax((float)ky, y0), yb = fmin((float)(ky + 1), y1);
        if (yb <= ya) continue;
        /* the overlap's share of the sphere: cos(theta_a) - cos(theta_b), written without cancellation */
        const float wy = 2.0f * sin(0.5f * (ya + yb) * rad) * sin(0.5f * (yb - ya) * rad);
        for (int kx = kx0; kx < kx1; ++kx) {
            const float wx = fmin((float)(kx + 1), x1) - fmax((float)kx, x0);
            if (wx <= 0.0f) continue;
            const float w = wx * wy;
            const int t = 3 * (src_offset + ky * sw + kx);
            r += src[t] * w; g += src[t + 1] * w; b += src[t + 2] * w;
            wsum += w;
        }
    }
    const float inv = 1.0f / wsum;
    const int o = 3 * (dst_offset + j * dw + i);
    dst[o] = r * inv; dst[o + 1] = g * inv; dst[o + 2] = b * inv;
}

kernel void ibl_copy(global const float* src, int src_offset, global float* dst, int dst_offset, int n)
{
    const int i = get_global_id(0);
    if (i < n) dst[dst_offset + i] = src[src_offset + i];
}

kernel void ibl_sh_rows(global const float* texels, int w, int h, global float* partial)
{
    const int j = get_global_id(0);
    if (j >= h) return;
    const float theta = IBL_PI * ((float)j + 0.5f) / (float)h;
    const float st = sin(theta), ct = cos(theta);
    floatV acc[27];
    for (int k = 0; k < 27; ++k) acc[k] = (floatV)0.0f;
    const int row = j * w;
    for (int x0 = 0; x0 < w; x0 += VEC) {
        const intV x = (intV)x0 + LANES;
        const intV inside = x < w;
        const intV xc = min(x, (intV)(w - 1));
        const floatV keep = select((floatV)0.0f, (floatV)1.0f, inside);
        const floatV phi = 2.0f * IBL_PI * ((convert_floatV(xc) + 0.5f) / (float)w - 0.5f);
        const floatV sp = sin(phi), cp = cos(phi);      /* not sincos: Oclgrind's checker stops at it */
        const floatV dx = st * sp, dy = (floatV)ct, dz = -st * cp;
        const intV t = 3 * (row + xc);
        const floatV L[3] = { GATHER_F(texels, t) * keep, GATHER_F(texels, t + 1) * keep,
                              GATHER_F(texels, t + 2) * keep };
        const floatV Y[9] = { (floatV)1.0f, dy, dz, dx, dx * dy, dy * dz, 3.0f * dz * dz - 1.0f, dx * dz,
                              dx * dx - dy * dy };
        for (int k = 0; k < 9; ++k)
            for (int c = 0; c < 3; ++c)
                acc[3 * k + c] += L[c] * Y[k];
    }
    const float domega = (2.0f * IBL_PI / (float)w) * 2.0f * st * sin(0.5f * IBL_PI / (float)h);
    for (int k = 0; k < 27; ++k) {
        float s = 0.0f;
        for (int lane = 0; lane < VEC; ++lane) s += LANE_F(acc[k], lane);
        partial[27 * j + k] = s * domega;
    }
}

kernel void ibl_sh_reduce(global const float* partial, int rows, global float* sh)
{
    const int k = get_global_id(0);
    if (k >= 27) return;
    float s = 0.0f;
    for (int j = 0; j < rows; ++j) s += partial[27 * j + k];
    /* basis constant x (A_l / pi): A_0 / pi = 1, A_1 / pi = 2/3, A_2 / pi = 1/4; Y_k = K_k x the
     * polynomial, evaluated at n with the same K_k (environment.h): the product of both */
    const int m = k / 3;
    float kk, al;
    if (m == 0) { kk = ENV_SH_K0; al = 1.0f; }
    else if (m <= 3) { kk = ENV_SH_K1; al = 2.0f / 3.0f; }
    else if (m == 6) { kk = ENV_SH_K3; al = 0.25f; }
    else if (m == 8) { kk = ENV_SH_K4; al = 0.25f; }
    else { kk = ENV_SH_K2; al = 0.25f; }
    sh[k] = s * kk * al;
}

/* Bilinear RGB of a w x h level at offset `off` at per-lane u (in [0, 1)) on a row position v
 * shared by the lanes (environment.h's env_bilinearV with uniform rows). */
static inline ENV_INLINE void bilinear_row(global const float* texels, int off, int w, int h, floatV u, float v,
                                           floatV* r, floatV* g, floatV* b)
{
    const floatV fx = u * (float)w - 0.5f;
    const float fy = v * (float)h - 0.5f;
    const intV x0 = convert_intV(fx + 1.0f) - 1;
    const int y0 = (int)(fy + 1.0f) - 1;
    const floatV ax = fx - convert_floatV(x0);
    const float ay = fy - (float)y0;
    const intV xa = select(x0, x0 + w, x0 < 0);
    const intV xb = select(x0 + 1, (intV)0, x0 + 1 >= w);
    const int ra = off + max(y0, 0) * w, rb = off + min(y0 + 1, h - 1) * w;
    const intV i00 = 3 * (ra + xa), i01 = 3 * (ra + xb), i10 = 3 * (rb + xa), i11 = 3 * (rb + xb);
#define ROW_BILERP(out, c) { \
        const floatV t00 = GATHER_F(texels, i00 + c), t01 = GATHER_F(texels, i01 + c); \
        const floatV t10 = GATHER_F(texels, i10 + c), t11 = GATHER_F(texels, i11 + c); \
        const floatV top = t00 + (t01 - t00) * ax, bot = t10 + (t11 - t10) * ax; \
        *(out) = top + (bot - top) * ay; }
    ROW_BILERP(r, 0) ROW_BILERP(g, 1) ROW_BILERP(b, 2)
#undef ROW_BILERP
}

/* The sample table of one specular level: entry (y, i) = (v, du, lod, n.l) of sample i of the
 * texels of row y (n.l <= 0: skipped). A row's texels are turns of one another about +Y, and so
 * are their samples: sample i of every texel of the row has the v and the u offset (from the
 * texel's own u) of sample i of the row's texel at phi = 0, N = (0, cos theta, -sin theta),
 * T = dN/dtheta = (0, -sin theta, -cos theta), B = dN/dphi / sin theta = (1, 0, 0). */
kernel void ibl_sample_table(global float4* table, int dh, int samples, float alpha, int w0, int h0, int n_mips)
{
    const int k = get_global_id(0);
    if (k >= dh * samples) return;
    const int y = k / samples, i = k - y * samples;
    const float theta = IBL_PI * ((float)y + 0.5f) / (float)dh;
    const float st = sin(theta), ct = cos(theta);
    const float a2 = alpha * alpha;
    float ch, sh;
    ggx_half(a2, radical_inverse((uint)i), &ch, &sh);
    const float nl = 2.0f * ch * ch - 1.0f;             /* n = v: the same for every texel */
    const float ph = 2.0f * IBL_PI * (float)i / (float)samples;
    const float sph = sin(ph), cph = cos(ph);
    const float hx = sh * cph, hy = sh * sph;
    /* h = T hx + B hy + N ch; l = 2 (n.h) h - n */
    const float Hx = hy, Hy = ct * ch - st * hx, Hz = -ct * hx - st * ch;
    const float k2 = 2.0f * ch;
    const float lx = k2 * Hx, ly = k2 * Hy - ct, lz = k2 * Hz + st;
    const float len = sqrt(lx * lx + ly * ly + lz * lz);
    const float cl = fmin(fmax(ly / len, -1.0f), 1.0f);
    const float v = acos(cl) * ENV_INV_PI;
    const float du = atan2(lx, -lz) * ENV_INV_2PI;
    /* lod = 0.5 log2(Omega_s / Omega_p) + LOD_BIAS, Omega_s = 1 / (S pdf), pdf = D / 4,
     * Omega_p = (2 pi / w0) (pi / h0): a level-0 texel's solid angle at the equator */
    const float dd = ch * ch * (a2 - 1.0f) + 1.0f;
    const float D = a2 / (IBL_PI * dd * dd);
    const float omega_s = 4.0f / ((float)samples * D);
    const float omega_p = 2.0f * IBL_PI * IBL_PI / ((float)w0 * (float)h0);
    const float lod = fmin(fmax(0.5f * log2(omega_s / omega_p) + LOD_BIAS, 0.0f), (float)(n_mips - 1));
    table[k] = (float4)(v, du, lod, nl > 0.0f ? nl : 0.0f);
}

kernel void ibl_prefilter(global const float* mips, global const int* mip_levels, int n_mips,
                          global const float4* table, int samples,
                          global float* dst, int dst_offset, int dw, int dh)
{
    const int gx = get_global_id(0), y = get_global_id(1);
    const int x0 = gx * VEC;
    if (x0 >= dw || y >= dh) return;
    const intV x = min((intV)x0 + LANES, (intV)(dw - 1));
    const floatV u_n = (convert_floatV(x) + 0.5f) / (float)dw;     /* the lanes' own u */
    global const float4* row = table + y * samples;
    floatV sr = (floatV)0.0f, sg = (floatV)0.0f, sb = (floatV)0.0f;
    float wsum = 0.0f;
    for (int i = 0; i < samples; ++i) {
        const float4 e = row[i];
        const float nl = e.w;
        if (nl <= 0.0f) continue;
        floatV u = u_n + e.y;
        u = u - floor(u);
        u = fmin(u, 0x1.fffffep-1f);
        const int m0 = (int)e.z, m1 = min(m0 + 1, n_mips - 1);
        const float f = e.z - (float)m0;
        global const int* la = mip_levels + ENV_LEVEL_STRIDE * m0;
        floatV r0, g0, b0;
        bilinear_row(mips, la[0], la[1], la[2], u, e.x, &r0, &g0, &b0);
        if (f > 0.0f) {
            global const int* lb = mip_levels + ENV_LEVEL_STRIDE * m1;
            floatV r1, g1, b1;
            bilinear_row(mips, lb[0], lb[1], lb[2], u, e.x, &r1, &g1, &b1);
            r0 += (r1 - r0) * f; g0 += (g1 - g0) * f; b0 += (b1 - b0) * f;
        }
        sr += r0 * nl; sg += g0 * nl; sb += b0 * nl;
        wsum += nl;
    }
    const float inv = 1.0f / wsum;
    sr *= inv; sg *= inv; sb *= inv;
    for (int lane = 0; lane < VEC; ++lane) {
        if (x0 + lane >= dw) break;
        const int o = 3 * (dst_offset + y * dw + x0 + lane);
        dst[o] = LANE_F(sr, lane); dst[o + 1] = LANE_F(sg, lane); dst[o + 2] = LANE_F(sb, lane);
    }
}

kernel void ibl_dfg(global float* dfg, int n, global const float2* gl_s, int ks, global const float2* gl_phi, int kp)
{
    const int gx = get_global_id(0), j = get_global_id(1);
    const int x0 = gx * VEC;
    if (x0 >= n || j >= n) return;
    const intV i = min((intV)x0 + LANES, (intV)(n - 1));
    const floatV nv = (convert_floatV(i) + 0.5f) / (float)n;
    const floatV vx = sqrt(1.0f - nv * nv);
    const float r = (float)j / (float)max(n - 1, 1);      /* rows span [0, 1]: roughness 0 and 1 are rows */
    const float a2 = r * r * r * r, alpha = r * r;
    const floatV gv = sqrt(nv * nv * (1.0f - a2) + a2);    /* Smith's view term */
    floatV A = (floatV)0.0f, B = (floatV)0.0f, C = (floatV)0.0f;
    for (int side = 0; side < 2; ++side) {
        for (int p = 0; p < kp; ++p) {
            const float2 np_ = gl_phi[p];
            const float phi = 0.5f * IBL_PI * ((float)side + np_.x);
            const float wphi = 0.5f * np_.y;                   /* (1/pi) dphi over [0, pi], halves of pi/2 */
            const float cp = cos(phi);
            /* n.l > 0 exactly for theta_h < tmax = (delta + pi/2) / 2, delta = atan2(vx cos phi, n.v) */
            const floatV tmax = 0.5f * (atan2(vx * cp, nv) + 0.5f * IBL_PI);
            const floatV st = sin(tmax), ct = cos(tmax);
            const floatV smin = ct * alpha / sqrt(st * st + ct * ct * a2);
            const floatV span = 1.0f - smin;
            for (int k = 0; k < ks; ++k) {
                const float2 q = gl_s[k];
                /* xi = 1 - s^2 (GGX: tan theta_h = alpha sqrt(1 - s^2) / s) */
                const floatV s = smin + q.x * span;
                const floatV s2 = s * s;
                const floatV den = a2 + s2 * (1.0f - a2);
                const floatV ch = sqrt(s2 / den), sh = sqrt(a2 * (1.0f - s2) / den);
                const floatV w = (q.y * wphi) * span * 2.0f * s;
                const floatV vh = vx * sh * cp + nv * ch;
                const floatV nl = fmax(2.0f * vh * ch - nv, 0.0f);
                const floatV gl = sqrt(nl * nl * (1.0f - a2) + a2);
                const floatV g = w * (4.0f * 0.5f / (nl * gv + nv * gl)) * nl * vh / ch;
                const floatV m = 1.0f - clamp(vh, 0.0f, 1.0f);
                const floatV fc = (m * m) * (m * m) * m;
                A += g * (1.0f - fc);
                B += g * fc;
            }
            /* C: l cosine-distributed, t = sin^2 theta_l, v.h = sqrt((1 + v.l) / 2) */
            for (int k = 0; k < ks; ++k) {
                const float2 q = gl_s[k];
                const float sl = sqrt(q.x), cl = sqrt(1.0f - q.x);
                const floatV vl = vx * (sl * cp) + nv * cl;
                const floatV dh = sqrt(fmax(0.5f * (1.0f + vl), 0.0f));
                const floatV md = 1.0f - dh;
                C += (q.y * wphi) * (1.0f - (md * md) * (md * md) * md);
            }
        }
    }
    for (int lane = 0; lane < VEC; ++lane) {
        if (x0 + lane >= n) break;
        const int o = 3 * (j * n + x0 + lane);
        dfg[o] = LANE_F(A, lane); dfg[o + 1] = LANE_F(B, lane); dfg[o + 2] = LANE_F(C, lane);
    }
}
