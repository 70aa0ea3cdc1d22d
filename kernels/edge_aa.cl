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
 *     all 8 neighbours (coordinates clamped at the image border, where a pixel is its own
 *     neighbour and never discontinuous): bit k of `flags` for neighbour k of OFFSETS (0..3 left,
 *     right, up, down; 4..7 the diagonals), and `edges` = 1 when a direct neighbour's bit is
 *     set: the mask Frame.edges shows.
 *   edge_blur (pass 2): unmarked pixels copy their value (one byte read, then the copy; the
 *     report: few accesses where the effect does not apply). A marked pixel takes a normalized
 *     3×3 Gaussian of the ldr colour, anisotropic: its axes follow the edge. The direction
 *     across the edge g = (gx, gy) is the Sobel gradient of the 8 discontinuity flags (weight 2
 *     for the direct neighbours, 1 for the diagonals; it points at the other surface); the
 *     tangent is t = (-gy, gx)/|g|. A neighbour at offset d weighs
 *     exp(-(d·t)² / 2σa² - (d·n)² / 2σc²), n = g/|g|, σa = EDGE_SIGMA_ALONG (1 pixel) along the
 *     edge and σc = EDGE_SIGMA_ACROSS (0.5) across it: mostly an average along the edge, with a
 *     small cross component that softens the stair steps. Where the flags cancel (g = 0, e.g.
 *     inside a one-pixel-thin bar) the blur is isotropic with σc. The sigmas were chosen on
 *     tests/test_aa.py's scene against a 16×16-supersampled truth.
 *
 * Buffers: gbuffer uint[GB_PLANES][H·W] (linear depth, normal, triangle id planes; layout by
 * gbuffer.h's GB_* defines; pass 1); edges, flags uchar[H·W] (pass 1 out, pass 2 in); ldr, out
 * float[3][H·W] planes R, G, B (pass 2; out is a separate buffer: neighbours are read).
 * Work-groups: 2-D, any size (clrender/passes/edge_aa.py: work_group(), one row of runs); work-item
 * (i, y) owns the run of VEC horizontally adjacent pixels x0 = i·VEC .. x0 + VEC - 1 of row y
 * (vec.h: VEC 8 or 16 on CPUs, 1 on GPUs), loaded and stored as vectors by row_run.h
 * (clamp-to-edge loads, stores of the lanes inside the row). Pass 1 evaluates the tests over the
 * lanes without branches (selects), loading the runs of rows y - 1 .. y + 1 at x0 - 1, x0,
 * x0 + 1; when a lane needs the normals it decodes those of the three rows' runs at x0 and of
 * the 6 pixels beside them (one more vector; VEC 8, 16: the shifted runs are lane shuffles),
 * each normal once. Pass 2 copies a run without a marked pixel (one vector of bytes read) and
 * blurs the others; it prefetches row y + 1 for them. The global size is rounded up; runs
 * starting outside the image return; no barriers, no local memory.
 */
#pragma OPENCL FP_CONTRACT OFF
#include "gbuffer.h"
/* VEC-wide runs (CPUs): row_run.h's loads (and the helpers here) inlined, not calls that spill
 * every live vector. Not with VEC 1: Oclgrind cannot run the inlined code at -O0. */
#if VEC > 1 && defined(__clang__)
#define ROW_RUN_INLINE __attribute__((always_inline))
#endif
#include "row_run.h"

#ifndef EDGE_SIGMA_ALONG
#define EDGE_SIGMA_ALONG 1.0f
#endif
#ifndef EDGE_SIGMA_ACROSS
#define EDGE_SIGMA_ACROSS 0.5f
#endif
/* Neighbour k: (dx, dy), y down; 0..3 the direct neighbours, 4..7 the diagonals. */
constant int2 OFFSETS[8] = {(int2)(-1, 0), (int2)(1, 0), (int2)(0, -1), (int2)(0, 1),
                            (int2)(-1, -1), (int2)(1, -1), (int2)(-1, 1), (int2)(1, 1)};

/* Unit normals from their 24-bit octahedral codes: decode, then divide by the length. */
typedef struct {
    floatV x, y, z;
} EdgeNormal;

static inline ROW_RUN_INLINE EdgeNormal edge_normal(uintV oct)
{
    EdgeNormal n;
    unpack_oct12x2V(oct, &n.x, &n.y, &n.z);
    floatV inv = 1.0f / sqrt(n.x * n.x + n.y * n.y + n.z * n.z);
    n.x *= inv;
    n.y *= inv;
    n.z *= inv;
    return n;
}

static inline ROW_RUN_INLINE floatV edge_dot(EdgeNormal a, EdgeNormal b)
{
    return a.x * b.x + a.y * b.y + a.z * b.z;
}

/* The G-buffer fields of one run (row clamped by the caller, columns clamped lane by lane). */
typedef struct {
    intV fg;                         /* foreground mask */
    floatV z;                        /* linear depth */
    uintV oct;                       /* 24-bit normal code */
} EdgeRun;

static inline ROW_RUN_INLINE EdgeRun edge_load(global const uint* gbuffer, int npix, int row, int x, int width)
{
    EdgeRun r;
    r.fg = as_intV(row_load_u(gbuffer + GB_TRIANGLE_ID_PLANE * npix + row, x, width) >> GB_TRIANGLE_ID_SHIFT) >= 0;
    r.z = as_floatV(row_load_u(gbuffer + GB_LINEAR_DEPTH_PLANE * npix + row, x, width) >> GB_LINEAR_DEPTH_SHIFT);
    r.oct = (row_load_u(gbuffer + GB_NORMAL_PLANE * npix + row, x, width) >> GB_NORMAL_SHIFT) & 0xffffffu;
    return r;
}

/* RUN_LEFT(a, h, k) / RUN_RIGHT(a, h, k) (VEC 8, 16): the run a shifted by one pixel, lane i holding
 * a[i - 1] (a[i + 1]), the lane shifted in taken from lane k of h. With clamp-to-edge loads, a run
 * at x0 shifted so is the run loaded at x0 - 1 (x0 + 1) when h's lane k holds that one's first
 * (last) lane. */
#if VEC == 8
#define LAST(v) ((v).s7)
#if defined(__clang__)
#define RUN_LEFT(a, h, k) __builtin_shufflevector((a), (h), 8 + (k), 0, 1, 2, 3, 4, 5, 6)
#define RUN_RIGHT(a, h, k) __builtin_shufflevector((a), (h), 1, 2, 3, 4, 5, 6, 7, 8 + (k))
#endif
#elif VEC == 16
#define LAST(v) ((v).sf)
#if defined(__clang__)
#define RUN_LEFT(a, h, k) __builtin_shufflevector((a), (h), 16 + (k), 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14)
#define RUN_RIGHT(a, h, k) \
    __builtin_shufflevector((a), (h), 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16 + (k))
#endif
#endif
#if VEC >= 8 && !defined(RUN_LEFT)
#define RUN_LEFT(a, h, k) shuffle2((a), (h), select(convert_uintV(LANES) - 1u, (uintV)(VEC + (k)), LANES == 0))
#define RUN_RIGHT(a, h, k) \
    shuffle2((a), (h), select(convert_uintV(LANES) + 1u, (uintV)(VEC + (k)), LANES == VEC - 1))
#endif
/* const EdgeNormal n = the normals a shifted left / right, lane k of h shifted in */
#define EDGE_LEFT(n, a, h, k) const EdgeNormal n = {RUN_LEFT((a).x, (h).x, k), RUN_LEFT((a).y, (h).y, k), \
                                                   RUN_LEFT((a).z, (h).z, k)}
#define EDGE_RIGHT(n, a, h, k) const EdgeNormal n = {RUN_RIGHT((a).x, (h).x, k), RUN_RIGHT((a).y, (h).y, k), \
                                                    RUN_RIGHT((a).z, (h).z, k)}

kernel void edge_detect(global const uint* gbuffer, int width, int height, float depth_threshold,
                        float cos_threshold, global uchar* edges, global uchar* flags)
{
    const int x0 = get_global_id(0) * VEC, y = get_global_id(1);
    if (x0 >= width || y >= height) return;
    const int npix = width * height;
    const int up = ROW_CLAMP(y - 1, height), down = ROW_CLAMP(y + 1, height);
    const intV xs = (intV)x0 + LANES;
    /* clamped at the border a neighbour is the pixel itself, never discontinuous */
    const intV self_l = xs == 0, self_r = xs >= width - 1;
    const intV self_u = (intV)y == 0, self_d = (intV)y == height - 1;
    /* the runs of rows y-1 (u), y (c), y+1 (d) at x0 - 1 (l), x0, x0 + 1 (r) */
    const EdgeRun ul = edge_load(gbuffer, npix, up * width, x0 - 1, width);
    const EdgeRun uc = edge_load(gbuffer, npix, up * width, x0, width);
    const EdgeRun ur = edge_load(gbuffer, npix, up * width, x0 + 1, width);
    const EdgeRun cl = edge_load(gbuffer, npix, y * width, x0 - 1, width);
    const EdgeRun p = edge_load(gbuffer, npix, y * width, x0, width);
    const EdgeRun cr = edge_load(gbuffer, npix, y * width, x0 + 1, width);
    const EdgeRun dl = edge_load(gbuffer, npix, down * width, x0 - 1, width);
    const EdgeRun dc = edge_load(gbuffer, npix, down * width, x0, width);
    const EdgeRun dr = edge_load(gbuffer, npix, down * width, x0 + 1, width);
    /* Neighbour k (OFFSETS) in run n: its discontinuity where the cheap tests decide (d_k: foreground
     * against background; both foreground: the depth jump), and where the normals must (need_k:
     * both foreground, no depth jump, different codes; the same code is an angle of 0). Masks are
     * -1/0 per lane (VEC 1: 1/0), combined bitwise (`~m & x` is !m && x for either kind). */
#define EDGE_CHEAP(k, n, self)                                                                          \
    const intV dz##k = fabs(n.z - p.z) > depth_threshold * fmin(p.z, n.z);                              \
    intV d##k = ~(self) & ((n.fg != p.fg) | (p.fg & dz##k));                                          \
    const intV need##k = ~(self) & p.fg & n.fg & ~dz##k & (n.oct != p.oct)
    EDGE_CHEAP(0, cl, self_l);
    EDGE_CHEAP(1, cr, self_r);
    EDGE_CHEAP(2, uc, self_u);
    EDGE_CHEAP(3, dc, self_d);
    EDGE_CHEAP(4, ul, self_u & self_l);
    EDGE_CHEAP(5, ur, self_u & self_r);
    EDGE_CHEAP(6, dl, self_d & self_l);
    EDGE_CHEAP(7, dr, self_d & self_r);
#undef EDGE_CHEAP
    if (ANY(need0 | need1 | need2 | need3 | need4 | need5 | need6 | need7)) {
        const EdgeNormal n_c = edge_normal(p.oct);
#define EDGE_NORMAL(k, n) d##k |= need##k & (edge_dot(n_c, n) < cos_threshold)
#if VEC >= 8
        /* each normal decoded once: the runs of rows y - 1 .. y + 1 at x0, and the 6 pixels beside
         * them in one more vector (`halo`), shuffled in for the runs at x0 ± 1 */
        const EdgeNormal n_uc = edge_normal(uc.oct), n_dc = edge_normal(dc.oct);
        uintV halo = 0u;
        halo.s0 = ul.oct.s0;
        halo.s1 = cl.oct.s0;
        halo.s2 = dl.oct.s0;
        halo.s3 = LAST(ur.oct);
        halo.s4 = LAST(cr.oct);
        halo.s5 = LAST(dr.oct);
        const EdgeNormal h = edge_normal(halo);
        EDGE_LEFT(n_ul, n_uc, h, 0);
        EDGE_LEFT(n_cl, n_c, h, 1);
        EDGE_LEFT(n_dl, n_dc, h, 2);
        EDGE_RIGHT(n_ur, n_uc, h, 3);
        EDGE_RIGHT(n_cr, n_c, h, 4);
        EDGE_RIGHT(n_dr, n_dc, h, 5);
        EDGE_NORMAL(0, n_cl);
        EDGE_NORMAL(1, n_cr);
        EDGE_NORMAL(2, n_uc);
        EDGE_NORMAL(3, n_dc);
        EDGE_NORMAL(4, n_ul);
        EDGE_NORMAL(5, n_ur);
        EDGE_NORMAL(6, n_dl);
        EDGE_NORMAL(7, n_dr);
#else
        /* a neighbour's normals decoded only where needed */
        if (ANY(need0)) EDGE_NORMAL(0, edge_normal(cl.oct));
        if (ANY(need1)) EDGE_NORMAL(1, edge_normal(cr.oct));
        if (ANY(need2)) EDGE_NORMAL(2, edge_normal(uc.oct));
        if (ANY(need3)) EDGE_NORMAL(3, edge_normal(dc.oct));
        if (ANY(need4)) EDGE_NORMAL(4, edge_normal(ul.oct));
        if (ANY(need5)) EDGE_NORMAL(5, edge_normal(ur.oct));
        if (ANY(need6)) EDGE_NORMAL(6, edge_normal(dl.oct));
        if (ANY(need7)) EDGE_NORMAL(7, edge_normal(dr.oct));
#endif
#undef EDGE_NORMAL
    }
#define EDGE_BIT(k) select((uintV)0u, (uintV)(1u << k), d##k)
    const uintV direct = EDGE_BIT(0) | EDGE_BIT(1) | EDGE_BIT(2) | EDGE_BIT(3);
    row_store_uc(select((uintV)0u, (uintV)1u, direct != 0u), edges + y * width, x0, width);
    row_store_uc(direct | EDGE_BIT(4) | EDGE_BIT(5) | EDGE_BIT(6) | EDGE_BIT(7), flags + y * width, x0, width);
#undef EDGE_BIT
}

/* Weight of the neighbour at (dx, dy) for the blur frame (n, ka, kc). */
static inline ROW_RUN_INLINE floatV edge_weight(int dx, int dy, floatV nx, floatV ny, floatV ka, floatV kc)
{
    floatV across = (float)dx * nx + (float)dy * ny;      /* d·n */
    floatV along = (float)dy * nx - (float)dx * ny;       /* d·t, t = (-ny, nx) */
    return exp(-(along * along * ka + across * across * kc));
}

kernel void edge_blur(global const float* ldr, global const uchar* edges, global const uchar* flags, int width,
                      int height, global float* out)
{
    const int x0 = get_global_id(0) * VEC, y = get_global_id(1);
    if (x0 >= width || y >= height) return;
    const int npix = width * height, row = y * width;
    const int up = ROW_CLAMP(y - 1, height) * width, down = ROW_CLAMP(y + 1, height) * width;
    for (int c = 0; c < 3; ++c) ROW_PREFETCH(ldr + c * npix + down + x0);   /* for marked runs: rows y ± 1 */
    const intV marked = row_load_uc(edges + row, x0, width) != 0u;
    if (!ANY(marked)) {
        for (int c = 0; c < 3; ++c)
            row_store_f(row_load_f(ldr + c * npix + row, x0, width), out + c * npix + row, x0, width);
        return;
    }
    const uintV bits = row_load_uc(flags + row, x0, width);
    intV gx = 0, gy = 0;
    for (int k = 0; k < 8; ++k) {
        const int w = (OFFSETS[k].x == 0 || OFFSETS[k].y == 0) ? 2 : 1;
        const intV set = (bits & (1u << k)) != 0u;
        gx += select((intV)0, (intV)(w * OFFSETS[k].x), set);
        gy += select((intV)0, (intV)(w * OFFSETS[k].y), set);
    }
    /* g = 0: any frame, both axes with sigma across (isotropic) */
    const intV has_g = gx != 0 || gy != 0;
    const floatV inv = 1.0f / sqrt(convert_floatV(select((intV)1, gx * gx + gy * gy, has_g)));
    const floatV nx = select((floatV)1.0f, convert_floatV(gx) * inv, has_g);
    const floatV ny = select((floatV)0.0f, convert_floatV(gy) * inv, has_g);
    const floatV kc = 0.5f / (EDGE_SIGMA_ACROSS * EDGE_SIGMA_ACROSS);
    const floatV ka = select(kc, (floatV)(0.5f / (EDGE_SIGMA_ALONG * EDGE_SIGMA_ALONG)), has_g);
    /* w(-d) = w(d) exactly (d·n and d·t only change sign): 5 distinct weights */
    const floatV w_ul = edge_weight(-1, -1, nx, ny, ka, kc), w_u = edge_weight(0, -1, nx, ny, ka, kc);
    const floatV w_ur = edge_weight(1, -1, nx, ny, ka, kc), w_l = edge_weight(-1, 0, nx, ny, ka, kc);
    const floatV w_c = edge_weight(0, 0, nx, ny, ka, kc);
    floatV sw = 0.0f;
    sw += w_ul;
    sw += w_u;
    sw += w_ur;
    sw += w_l;
    sw += w_c;
    sw += w_l;
    sw += w_ur;
    sw += w_u;
    sw += w_ul;
    for (int c = 0; c < 3; ++c) {
        global const float* plane = ldr + c * npix;
        const floatV centre = row_load_f(plane + row, x0, width);
        floatV sum = 0.0f;
        sum += w_ul * row_load_f(plane + up, x0 - 1, width);
        sum += w_u * row_load_f(plane + up, x0, width);
        sum += w_ur * row_load_f(plane + up, x0 + 1, width);
        sum += w_l * row_load_f(plane + row, x0 - 1, width);
        sum += w_c * centre;
        sum += w_l * row_load_f(plane + row, x0 + 1, width);       /* w(1, 0) = w(-1, 0) */
        sum += w_ur * row_load_f(plane + down, x0 - 1, width);     /* w(-1, 1) = w(1, -1) */
        sum += w_u * row_load_f(plane + down, x0, width);
        sum += w_ul * row_load_f(plane + down, x0 + 1, width);
        row_store_f(select(centre, sum / sw, marked), out + c * npix + row, x0, width);
    }
}
