/* edge_aa.cl: the report's edge-smoothing filter (section III.3, "edge-smoothing filter"), in
 * two passes on the tone-mapped linear planes (docs/post.md: tone map -> edge AA -> FXAA -> encode).
 *
 * Algorithm:
 *   edge_detect (pass 1, the report's "stencil"): a pixel and a neighbour are discontinuous when
 *     one is background and the other not (triangle id -1 vs >= 0), or, both foreground, when
 *     the relative view-depth jump |z1 - z0| > depth_threshold · min(z0, z1) (z the G-buffer's
 *     linear depth; the ratio does not depend on far), or when the decoded unit normals have
 *     dot(n0, n1) < cos_threshold (two equal normal codes are an angle of 0 and never an edge;
 *     normals are decoded only when the cheaper tests left the question open). Pass 1 tests
 *     the 4 direct neighbours (left, right, up, down; coordinates clamped at the image border,
 *     where a pixel is its own neighbour and never discontinuous): bit k of `flags` for neighbour
 *     k of OFFSETS, and `edges` = 1 when any is set: the mask Frame.edges shows.
 *   edge_blur (pass 2): unmarked pixels copy their value (one byte read, then the copy; the
 *     report: few accesses where the effect does not apply). A marked pixel also tests its 4
 *     diagonal neighbours, then takes a normalized 3×3 Gaussian of the ldr colour, anisotropic:
 *     its axes follow the edge. The direction across the edge g = (gx, gy) is the Sobel gradient
 *     of the 8 discontinuity flags (weight 2 for the direct neighbours, 1 for the diagonals; it points
 *     at the other surface); the tangent is t = (-gy, gx)/|g|. A neighbour at offset d weighs
 *     exp(-(d·t)² / 2σa² - (d·n)² / 2σc²), n = g/|g|, σa = EDGE_SIGMA_ALONG (1 pixel) along the
 *     edge and σc = EDGE_SIGMA_ACROSS (0.5) across it: mostly an average along the edge, with a
 *     small cross component that softens the stair steps. Where the flags cancel (g = 0, e.g.
 *     inside a one-pixel-thin bar) the blur is isotropic with σc. The sigmas were chosen on
 *     tests/test_aa.py's scene against a 16×16-supersampled truth.
 *
 * Buffers: gbuffer uint[GB_PLANES][H·W] (linear depth, normal, triangle id planes; layout by
 * gbuffer.h's GB_* defines; both passes); edges, flags uchar[H·W] (pass 1 out, pass 2 in); ldr,
 * out float[3][H·W] planes R, G, B (pass 2; out is a separate buffer: neighbours are read).
 * Work-groups: 2-D, one pixel per work-item, any size (clrender/passes/edge_aa.py uses 8 × 8); the
 * global size is rounded up and work-items outside the image return; no barriers, no local memory.
 */
#pragma OPENCL FP_CONTRACT OFF
#ifndef VEC
#define VEC 1           /* one pixel per work-item: vec.h's types are scalars */
#endif
#if VEC != 1
#error "edge_aa.cl processes one pixel per work-item (VEC 1)"
#endif
#include "gbuffer.h"

#ifndef EDGE_SIGMA_ALONG
#define EDGE_SIGMA_ALONG 1.0f
#endif
#ifndef EDGE_SIGMA_ACROSS
#define EDGE_SIGMA_ACROSS 0.5f
#endif
/* Neighbour k: (dx, dy), y down; 0..3 the direct neighbours, 4..7 the diagonals. */
constant int2 OFFSETS[8] = {(int2)(-1, 0), (int2)(1, 0), (int2)(0, -1), (int2)(0, 1),
                            (int2)(-1, -1), (int2)(1, -1), (int2)(-1, 1), (int2)(1, 1)};

/* Unit normal from its 24-bit octahedral code: decode, then divide by the length. */
static inline float3 edge_normal(uint oct)
{
    float x, y, z;
    unpack_oct12x2V(oct, &x, &y, &z);
    float inv = 1.0f / sqrt(x * x + y * y + z * z);
    return (float3)(x * inv, y * inv, z * inv);
}

/* Discontinuity bits of pixel (x, y) with neighbours k0 .. k1-1 of OFFSETS (bit k). */
static inline uint edge_bits(global const uint* gbuffer, int x, int y, int width, int height, float depth_threshold,
                             float cos_threshold, int k0, int k1)
{
    const int npix = width * height, p = y * width + x;
    global const uint* ids = gbuffer + GB_TRIANGLE_ID_PLANE * npix;
    global const uint* depths = gbuffer + GB_LINEAR_DEPTH_PLANE * npix;
    global const uint* normals = gbuffer + GB_NORMAL_PLANE * npix;
    const int fg = (int)(ids[p] >> GB_TRIANGLE_ID_SHIFT) >= 0;
    const float z = as_float(depths[p] >> GB_LINEAR_DEPTH_SHIFT);
    const uint oct = (normals[p] >> GB_NORMAL_SHIFT) & 0xffffffu;
    float3 n = (float3)(0.0f);
    int have_n = 0;                  /* the centre's normal is decoded once, when first needed */
    uint bits = 0u;
    for (int k = k0; k < k1; ++k) {
        int qx = clamp(x + OFFSETS[k].x, 0, width - 1), qy = clamp(y + OFFSETS[k].y, 0, height - 1);
        int q = qy * width + qx;
        int d;
        if (q == p) {
            d = 0;                   /* clamped at the border: the pixel itself */
        } else if (((int)(ids[q] >> GB_TRIANGLE_ID_SHIFT) >= 0) != fg) {
            d = 1;                   /* foreground against background */
        } else if (!fg) {
            d = 0;                   /* background on both sides */
        } else {
            float zq = as_float(depths[q] >> GB_LINEAR_DEPTH_SHIFT);
            uint octq = (normals[q] >> GB_NORMAL_SHIFT) & 0xffffffu;
            d = fabs(zq - z) > depth_threshold * fmin(z, zq);
            if (!d && octq != oct) { /* the same code: angle 0, never above the threshold */
                if (!have_n) {
                    n = edge_normal(oct);
                    have_n = 1;
                }
                float3 m = edge_normal(octq);
                d = n.x * m.x + n.y * m.y + n.z * m.z < cos_threshold;
            }
        }
        bits |= (uint)d << k;
    }
    return bits;
}

kernel void edge_detect(global const uint* gbuffer, int width, int height, float depth_threshold,
                        float cos_threshold, global uchar* edges, global uchar* flags)
{
    const int x = get_global_id(0), y = get_global_id(1);
    if (x >= width || y >= height) return;
    const int p = y * width + x;
    const uint bits = edge_bits(gbuffer, x, y, width, height, depth_threshold, cos_threshold, 0, 4);
    edges[p] = (uchar)(bits != 0u);
    flags[p] = (uchar)bits;
}

kernel void edge_blur(global const float* ldr, global const uchar* edges, global const uchar* flags,
                      global const uint* gbuffer, int width, int height, float depth_threshold, float cos_threshold,
                      global float* out)
{
    const int x = get_global_id(0), y = get_global_id(1);
    if (x >= width || y >= height) return;
    const int npix = width * height, p = y * width + x;
    if (!edges[p]) {
        out[p] = ldr[p];
        out[npix + p] = ldr[npix + p];
        out[2 * npix + p] = ldr[2 * npix + p];
        return;
    }
    /* the direct neighbours' bits from pass 1, the diagonals' tested here (marked pixels only) */
    const uint bits = (uint)flags[p]
                      | edge_bits(gbuffer, x, y, width, height, depth_threshold, cos_threshold, 4, 8);
    int gx = 0, gy = 0;
    for (int k = 0; k < 8; ++k) {
        if (bits & (1u << k)) {
            int w = (OFFSETS[k].x == 0 || OFFSETS[k].y == 0) ? 2 : 1;
            gx += w * OFFSETS[k].x;
            gy += w * OFFSETS[k].y;
        }
    }
    /* g = 0: any frame, both axes with sigma across (isotropic) */
    float nx = 1.0f, ny = 0.0f, ka = 0.5f / (EDGE_SIGMA_ACROSS * EDGE_SIGMA_ACROSS), kc = ka;
    if (gx != 0 || gy != 0) {
        float inv = 1.0f / sqrt((float)(gx * gx + gy * gy));
        nx = (float)gx * inv;
        ny = (float)gy * inv;
        ka = 0.5f / (EDGE_SIGMA_ALONG * EDGE_SIGMA_ALONG);
    }
    float sr = 0.0f, sg = 0.0f, sb = 0.0f, sw = 0.0f;
    for (int dy = -1; dy <= 1; ++dy) {
        for (int dx = -1; dx <= 1; ++dx) {
            float across = (float)dx * nx + (float)dy * ny;      /* d·n */
            float along = (float)dy * nx - (float)dx * ny;       /* d·t, t = (-ny, nx) */
            float w = exp(-(along * along * ka + across * across * kc));
            int q = clamp(y + dy, 0, height - 1) * width + clamp(x + dx, 0, width - 1);
            sr += w * ldr[q];
            sg += w * ldr[npix + q];
            sb += w * ldr[2 * npix + q];
            sw += w;
        }
    }
    out[p] = sr / sw;
    out[npix + p] = sg / sw;
    out[2 * npix + p] = sb / sw;
}
