/* setup.cl: vertex transform, clipping, culling and triangle setup.
 *
 * Algorithm (docs/raster_contract.md §1-4): one work-item per input triangle. Transform the
 * three vertices to clip space; clip the polygon against the near plane (w >= near) and, only
 * when a vertex lies outside it, against the guard band |x|,|y| <= G·w that keeps fixed-point
 * edge functions inside 64 bits; fan-triangulate; snap each piece to 24.8 fixed point; orient
 * it so area > 0; drop degenerate, back-facing (single-sided materials) and off-screen pieces.
 * `setup_count` writes how many prims each triangle yields (and why it yields none) and stages
 * the first prim per triangle; a prefix sum turns counts into offsets; `setup_emit` copies the
 * staged prim of single-prim triangles and recomputes only the rare multi-prim (clipped) ones.
 *
 * Which triangles (`select`, docs/transparency.md): SELECT_ALL (shadow maps), SELECT_OPAQUE
 * (the camera with A-buffer or depth peeling: BLEND triangles get STATUS_TRANSPARENT and no
 * prim), SELECT_BLEND (the transparency pass: only BLEND triangles), SELECT_DITHER (screen
 * door: every triangle; BLEND prims are flagged PRIM_MASKED | PRIM_DITHER for raster.cl).
 *
 * Buffers: positions float[3V] world space; triangles int[3T]; tri_material int[T];
 *          materials Material[M]; view_proj float[16] row-major.
 *          out: prim_count int[T], status uchar[T] (STATUS_*), staged Prim[T], prims Prim[capacity].
 * ORTHO=1 (shadow maps of the sun, clrender/passes/shadow.py; orthographic cameras,
 * docs/raster_contract.md §11): the matrix is orthographic
 * (clip.w = 1) and clip.z is the linear depth; the near plane is z >= near and Prim.inv_w
 * holds the vertex depths, which raster.cl then interpolates linearly in screen space.
 * Work-groups: 1-D, any size; no local memory, no barriers.
 */
#pragma OPENCL FP_CONTRACT OFF
#include "structs.h"

#ifndef ORTHO
#define ORTHO 0
#endif
#if ORTHO
#define CLIP_DEPTH(c) ((c).z)
#else
#define CLIP_DEPTH(c) ((c).w)
#endif

#ifndef GUARD_PIXELS
#define GUARD_PIXELS 262144.0f   /* 2^18: |snapped coordinate| < 2^27, edge functions < 2^56 */
#endif
/* Trivial-reject bits beside the clip planes' (bit 0 near, 1..4 guard band): the viewport's
 * sides x = ±w, y = ±w, which nothing is clipped against. */
#define SIDE_RIGHT (1 << 5)
#define SIDE_LEFT (1 << 6)
#define SIDE_TOP (1 << 7)
#define SIDE_BOTTOM (1 << 8)
#define ALL_PLANES 511
#define SELECT_ALL 0
#define SELECT_OPAQUE 1
#define SELECT_BLEND 2
#define SELECT_DITHER 3
#define MAX_POLY 9               /* 3 vertices + one per clip plane (near + 4 guard planes) + 1 */

typedef struct {
    float4 c;        /* clip-space position */
    float b1, b2;    /* barycentric coordinates in the input triangle */
} ClipVert;

/* Signed distance to clip plane `plane` (0 = near, 1..4 = guard band). */
static float plane_distance(int plane, float4 c, float near, float gx, float gy)
{
    switch (plane) {
    case 0: return CLIP_DEPTH(c) - near;
    case 1: return gx * c.w - c.x;
    case 2: return gx * c.w + c.x;
    case 3: return gy * c.w - c.y;
    default: return gy * c.w + c.y;
    }
}

/* The point where edge a-b crosses the plane, computed from the inside endpoint `a`
 * so that two triangles sharing the edge get the same vertex. */
static ClipVert intersect(ClipVert a, float da, ClipVert b, float db)
{
    float t = da / (da - db);
    ClipVert q;
    q.c.x = a.c.x + t * (b.c.x - a.c.x);
    q.c.y = a.c.y + t * (b.c.y - a.c.y);
    q.c.z = a.c.z + t * (b.c.z - a.c.z);
    q.c.w = a.c.w + t * (b.c.w - a.c.w);
    q.b1 = a.b1 + t * (b.b1 - a.b1);
    q.b2 = a.b2 + t * (b.b2 - a.b2);
    return q;
}

/* Sutherland-Hodgman against one plane; returns the new vertex count. */
static int clip_against(int plane, const ClipVert* in, int n, ClipVert* out, float near, float gx, float gy)
{
    int m = 0;
    for (int i = 0; i < n; ++i) {
        ClipVert a = in[i], b = in[(i + 1) % n];
        float da = plane_distance(plane, a.c, near, gx, gy);
        float db = plane_distance(plane, b.c, near, gx, gy);
        if (da >= 0.0f) out[m++] = a;
        if ((da >= 0.0f) != (db >= 0.0f))
            out[m++] = (da >= 0.0f) ? intersect(a, da, b, db) : intersect(b, db, a, da);
    }
    return m;
}

static float4 transform(global const float* m, float x, float y, float z)
{
    float4 c;
    c.x = ((m[0] * x + m[1] * y) + m[2] * z) + m[3];
    c.y = ((m[4] * x + m[5] * y) + m[6] * z) + m[7];
    c.z = ((m[8] * x + m[9] * y) + m[10] * z) + m[11];
    c.w = ((m[12] * x + m[13] * y) + m[14] * z) + m[15];
    return c;
}

static int snap(float ndc, float size)   /* 24.8 fixed point, round half to even */
{
    return (int)rint(((ndc + 1.0f) * 0.5f) * size * 256.0f);
}

static int snap_y(float ndc, float size)
{
    return (int)rint(((1.0f - ndc) * 0.5f) * size * 256.0f);
}

static int floor_div256(int v) { return v >> 8; }   /* arithmetic shift = floor for negatives */

/* Builds prim `k` of the fan into *p; returns its status (STATUS_EMITTED when kept). */
static int make_prim(const ClipVert* poly, int k, int tri, int material, uint mat_flags, int select,
                     int width, int height, int2 sample, Prim* p)
{
    const ClipVert* v[3] = { &poly[0], &poly[k + 1], &poly[k + 2] };
    for (int i = 0; i < 3; ++i) {
        float w = v[i]->c.w;
        p->x[i] = snap(v[i]->c.x / w, (float)width) - sample.x;     /* sub-sample: contract §10 */
        p->y[i] = snap_y(v[i]->c.y / w, (float)height) - sample.y;
#if ORTHO
        p->inv_w[i] = v[i]->c.z;          /* depth itself: interpolated linearly */
#else
        p->inv_w[i] = 1.0f / w;
#endif
        p->bary1[i] = v[i]->b1;
        p->bary2[i] = v[i]->b2;
    }
    long area = (long)(p->x[1] - p->x[0]) * (long)(p->y[2] - p->y[0])
              - (long)(p->x[2] - p->x[0]) * (long)(p->y[1] - p->y[0]);
    if (area == 0) return STATUS_DEGENERATE;
    p->flags = (mat_flags & MAT_MASK) ? PRIM_MASKED : 0u;
    if ((mat_flags & MAT_BLEND) && select == SELECT_DITHER) p->flags = PRIM_MASKED | PRIM_DITHER;
    if (area > 0) {                       /* clockwise in NDC: a back face */
        if (!(mat_flags & MAT_DOUBLE_SIDED)) return STATUS_BACKFACE;
        p->flags |= PRIM_BACKFACE;
    } else {                              /* front face: swap v1, v2 so that area > 0 */
        int t; float f;
        t = p->x[1]; p->x[1] = p->x[2]; p->x[2] = t;
        t = p->y[1]; p->y[1] = p->y[2]; p->y[2] = t;
        f = p->inv_w[1]; p->inv_w[1] = p->inv_w[2]; p->inv_w[2] = f;
        f = p->bary1[1]; p->bary1[1] = p->bary1[2]; p->bary1[2] = f;
        f = p->bary2[1]; p->bary2[1] = p->bary2[2]; p->bary2[2] = f;
        area = -area;
    }
    /* Pixel centers (256·i + 128) inside the bounding box, clipped to the image. */
    int min_x = min(min(p->x[0], p->x[1]), p->x[2]), max_x = max(max(p->x[0], p->x[1]), p->x[2]);
    int min_y = min(min(p->y[0], p->y[1]), p->y[2]), max_y = max(max(p->y[0], p->y[1]), p->y[2]);
    int px0 = max(floor_div256(min_x - 128 + 255), 0), px1 = min(floor_div256(max_x - 128), width - 1);
    int py0 = max(floor_div256(min_y - 128 + 255), 0), py1 = min(floor_div256(max_y - 128), height - 1);
    if (px0 > px1 || py0 > py1) return STATUS_OFFSCREEN;
    p->tri = tri;
    p->material = material;
    p->area = area;
    return STATUS_EMITTED;
}

/* Runs the whole setup of triangle `t`; writes up to `room` prims to dst (when non-null). */
static int setup_triangle(int t, global const float* positions, global const int* triangles,
                          global const int* tri_material, global const Material* materials,
                          global const float* view_proj, int width, int height, float near, int select,
                          int2 sample, global Prim* dst, int room, uchar* status)
{
    const int material = tri_material[t];
    const uint mat_flags = materials[material].flags;
    if ((select == SELECT_OPAQUE && (mat_flags & MAT_BLEND)) || (select == SELECT_BLEND && !(mat_flags & MAT_BLEND))) {
        *status = STATUS_TRANSPARENT;      /* the other geometry pass's triangle */
        return 0;
    }
    ClipVert poly_a[MAX_POLY], poly_b[MAX_POLY];
    const float gx = GUARD_PIXELS * 2.0f / (float)width, gy = GUARD_PIXELS * 2.0f / (float)height;
    int outside = 0, all_outside = ALL_PLANES;
    for (int i = 0; i < 3; ++i) {
        int vi = triangles[3 * t + i];
        float x = positions[3 * vi], y = positions[3 * vi + 1], z = positions[3 * vi + 2];
        if (!(isfinite(x) && isfinite(y) && isfinite(z))) { *status = STATUS_INVALID; return 0; }
        poly_a[i].c = transform(view_proj, x, y, z);
        poly_a[i].b1 = (i == 1) ? 1.0f : 0.0f;
        poly_a[i].b2 = (i == 2) ? 1.0f : 0.0f;
        const float4 c = poly_a[i].c;
        int out_i = 0;
        for (int plane = 0; plane < 5; ++plane)
            if (plane_distance(plane, c, near, gx, gy) < 0.0f) out_i |= 1 << plane;
        out_i |= (c.w - c.x < 0.0f ? SIDE_RIGHT : 0) | (c.w + c.x < 0.0f ? SIDE_LEFT : 0)
               | (c.w - c.y < 0.0f ? SIDE_TOP : 0) | (c.w + c.y < 0.0f ? SIDE_BOTTOM : 0);
        outside |= out_i & 31;
        all_outside &= out_i;
    }
    /* Trivial reject (contract §2): all three vertices outside one plane, so is every point of
     * the triangle; no clipping, snapping or facing test. Most of a scene seen from a spot light. */
    if (all_outside & 1) { *status = STATUS_CULLED_NEAR; return 0; }
    if (all_outside) { *status = STATUS_OFFSCREEN; return 0; }
    int n = 3;
    ClipVert* poly = poly_a;
    if (outside) {
        ClipVert* other = poly_b;
        for (int plane = 0; plane < 5 && n > 0; ++plane) {
            if (!(outside & (1 << plane))) continue;
            n = clip_against(plane, poly, n, other, near, gx, gy);
            ClipVert* tmp = poly; poly = other; other = tmp;
        }
        if (n < 3) { *status = (outside & 1) ? STATUS_CULLED_NEAR : STATUS_OFFSCREEN; return 0; }
    }
    int emitted = 0, last = STATUS_DEGENERATE;
    for (int k = 0; k + 2 < n; ++k) {
        Prim p;
        last = make_prim(poly, k, t, material, mat_flags, select, width, height, sample, &p);
        if (last != STATUS_EMITTED) continue;
        if (dst && emitted < room) dst[emitted] = p;
        ++emitted;
    }
    *status = (uchar)((emitted ? STATUS_EMITTED : last) | (outside ? STATUS_CLIPPED : 0));
    return emitted;
}

kernel void setup_count(global const float* positions, global const int* triangles,
                        global const int* tri_material, global const Material* materials,
                        global const float* view_proj, int n_tris, int width, int height, float near,
                        int select, int sample_x, int sample_y, global int* prim_count, global uchar* status,
                        global Prim* staged)
{
    int t = get_global_id(0);
    if (t >= n_tris) return;
    uchar s;
    prim_count[t] = setup_triangle(t, positions, triangles, tri_material, materials, view_proj,
                                   width, height, near, select, (int2)(sample_x, sample_y), staged + t, 1, &s);
    status[t] = s;
}

kernel void setup_emit(global const float* positions, global const int* triangles,
                       global const int* tri_material, global const Material* materials,
                       global const float* view_proj, int n_tris, int width, int height, float near,
                       int select, int sample_x, int sample_y, global const int* prim_offset,
                       global const int* prim_count,
                       global const Prim* staged, int capacity, global Prim* prims)
{
    int t = get_global_id(0);
    if (t >= n_tris || prim_count[t] == 0) return;
    int offset = prim_offset[t];
    int room = capacity - offset;       /* overflow is detected on the host from the total */
    if (room <= 0) return;
    if (prim_count[t] == 1) {
        prims[offset] = staged[t];
        return;
    }
    uchar s;
    setup_triangle(t, positions, triangles, tri_material, materials, view_proj,
                   width, height, near, select, (int2)(sample_x, sample_y), prims + offset, room, &s);
}
