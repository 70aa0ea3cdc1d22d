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
 * CHUNK_CULL=1 (clrender/passes/chunk_cull.py, kernels/chunk_cull.cl): the kernels run over
 * slots instead of triangles: slot i is triangle chunk_list[i / CHUNK]·CHUNK + i % CHUNK, the
 * visible chunks first (ascending, so prims keep triangle order) then the culled ones.
 * setup_count runs one work-group of CHUNK per slot chunk: a visible chunk's group sets up its
 * triangles and scans their counts in local memory (prim_local int[slots], chunk_prims
 * int[chunks]); a culled chunk's group only writes chunk_prims 0 and, when `write_status`,
 * the status setup would give each triangle (the chunk's verdict; a per-triangle near test
 * where it straddles the near plane). The host's prefix sum then runs over chunk_prims only
 * (chunks, not triangles), and setup_emit places slot i at chunk_offset[i / CHUNK] +
 * prim_local[i]. prim_count, prim_local and staged are indexed by slot.
 * SAMPLES > 1 (the light pre-pass's msaa, clrender/passes/second_geometry.py): a prim is kept
 * when it may cover a sample point up to SAMPLE_SPREAD/256 px from a pixel centre (samples.h),
 * not only a centre: one setup serves every sub-sample of raster.cl SAMPLES.
 * ORTHO=1 (shadow maps of the sun, clrender/passes/shadow.py; orthographic cameras,
 * docs/raster_contract.md §11): the matrix is orthographic
 * (clip.w = 1) and clip.z is the linear depth; the near plane is z >= near and Prim.inv_w
 * holds the vertex depths, which raster.cl then interpolates linearly in screen space.
 * Work-groups: 1-D, any size; no local memory, no barriers.
 */
#pragma OPENCL FP_CONTRACT OFF
#include "structs.h"

#include "samples.h"     /* SAMPLES (1): keep prims covering a sample up to SAMPLE_SPREAD from a centre */
#ifndef ORTHO
#define ORTHO 0
#endif
#if ORTHO
#define CLIP_DEPTH(c) ((c).z)
#else
#define CLIP_DEPTH(c) ((c).w)
#endif

#ifndef CHUNK_CULL
#define CHUNK_CULL 0
#endif
#ifndef CHUNK
#define CHUNK 128                /* as chunk_cull.cl's */
#endif
#define CHUNK_STRADDLES 7        /* chunk_cull.cl's verdict: culled, near plane crossed */
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
                     int width, int height, Prim* p)
{
    const ClipVert* v[3] = { &poly[0], &poly[k + 1], &poly[k + 2] };
    for (int i = 0; i < 3; ++i) {
        float w = v[i]->c.w;
        p->x[i] = snap(v[i]->c.x / w, (float)width);
        p->y[i] = snap_y(v[i]->c.y / w, (float)height);
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
    /* Pixel centers (256·i + 128) inside the bounding box widened by SAMPLE_SPREAD, clipped to the image. */
    int min_x = min(min(p->x[0], p->x[1]), p->x[2]) - SAMPLE_SPREAD, max_x = max(max(p->x[0], p->x[1]), p->x[2]) + SAMPLE_SPREAD;
    int min_y = min(min(p->y[0], p->y[1]), p->y[2]) - SAMPLE_SPREAD, max_y = max(max(p->y[0], p->y[1]), p->y[2]) + SAMPLE_SPREAD;
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
                          global Prim* dst, int room, uchar* status)
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
        last = make_prim(poly, k, t, material, mat_flags, select, width, height, &p);
        if (last != STATUS_EMITTED) continue;
        if (dst && emitted < room) dst[emitted] = p;
        ++emitted;
    }
    *status = (uchar)((emitted ? STATUS_EMITTED : last) | (outside ? STATUS_CLIPPED : 0));
    return emitted;
}

#if CHUNK_CULL
/* The status setup_triangle gives triangle t of a culled chunk (its verdict v): every vertex
 * is outside one side plane, so the trivial reject is taken; only where the chunk straddles
 * the near plane does it take the triangle's own vertices to tell culled_near from offscreen. */
static uchar culled_status(int t, int v, global const float* positions, global const int* triangles,
                           global const int* tri_material, global const Material* materials,
                           global const float* view_proj, float near, int select)
{
    if (select == SELECT_OPAQUE || select == SELECT_BLEND) {
        const uint mat_flags = materials[tri_material[t]].flags;
        if ((select == SELECT_OPAQUE) == ((mat_flags & MAT_BLEND) != 0)) return STATUS_TRANSPARENT;
    }
    if (v != CHUNK_STRADDLES) return (uchar)v;
    for (int i = 0; i < 3; ++i) {
        const int vi = triangles[3 * t + i];
        const float4 c = transform(view_proj, positions[3 * vi], positions[3 * vi + 1], positions[3 * vi + 2]);
        if (!(plane_distance(0, c, near, 0.0f, 0.0f) < 0.0f)) return STATUS_OFFSCREEN;
    }
    return STATUS_CULLED_NEAR;
}
#endif

#if !CHUNK_CULL
kernel void setup_count(global const float* positions, global const int* triangles,
                        global const int* tri_material, global const Material* materials,
                        global const float* view_proj, int n_tris, int width, int height, float near,
                        int select, global int* prim_count, global uchar* status,
                        global Prim* staged)
{
    int t = get_global_id(0);
    if (t >= n_tris) return;
    uchar s;
    prim_count[t] = setup_triangle(t, positions, triangles, tri_material, materials, view_proj,
                                   width, height, near, select, staged + t, 1, &s);
    status[t] = s;
}

kernel void setup_emit(global const float* positions, global const int* triangles,
                       global const int* tri_material, global const Material* materials,
                       global const float* view_proj, int n_tris, int width, int height, float near,
                       int select, global const int* prim_offset,
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
                   width, height, near, select, prims + offset, room, &s);
}

#else
/* Slot kernels: one work-group of CHUNK work-items per entry of chunk_list. */
kernel __attribute__((reqd_work_group_size(CHUNK, 1, 1)))
void setup_count(global const float* positions, global const int* triangles,
                 global const int* tri_material, global const Material* materials,
                 global const float* view_proj, int n_tris, int width, int height, float near,
                 int select, global int* prim_count, global uchar* status,
                 global Prim* staged, global const int* chunk_list, global const int* chunk_count,
                 global const uchar* chunk_status, int write_status, global int* prim_local, global int* chunk_prims)
{
    local int sum[CHUNK];
    const int i = get_global_id(0), lid = get_local_id(0), rank = get_group_id(0);
    const int chunk = chunk_list[rank], t = chunk * CHUNK + lid;
    if (rank >= chunk_count[0]) {          /* a culled chunk (the whole work-group) */
        if (lid == 0) chunk_prims[rank] = 0;
        if (write_status && t < n_tris)
            status[t] = culled_status(t, chunk_status[chunk], positions, triangles, tri_material, materials,
                                      view_proj, near, select);
        return;
    }
    int count = 0;
    if (t < n_tris) {                      /* past n_tris: the partial last chunk's spare slots */
        uchar s;
        count = setup_triangle(t, positions, triangles, tri_material, materials, view_proj,
                               width, height, near, select, staged + i, 1, &s);
        status[t] = s;
    }
    sum[lid] = count;                      /* inclusive Hillis-Steele scan of the chunk's counts */
    barrier(CLK_LOCAL_MEM_FENCE);
    for (int d = 1; d < CHUNK; d <<= 1) {
        const int x = (lid >= d) ? sum[lid - d] : 0;
        barrier(CLK_LOCAL_MEM_FENCE);
        sum[lid] += x;
        barrier(CLK_LOCAL_MEM_FENCE);
    }
    prim_count[i] = count;
    prim_local[i] = sum[lid] - count;
    if (lid == CHUNK - 1) chunk_prims[rank] = sum[lid];
}

/* Slot i of a visible chunk: its prims go to chunk_offset[rank] + prim_local[i]. */
kernel void setup_emit(global const float* positions, global const int* triangles,
                       global const int* tri_material, global const Material* materials,
                       global const float* view_proj, int n_tris, int width, int height, float near,
                       int select, global const int* prim_local,
                       global const int* prim_count,
                       global const Prim* staged, int capacity, global Prim* prims,
                       global const int* chunk_list, global const int* chunk_count, global const int* chunk_offset,
                       int n_slots)
{
    const int i = get_global_id(0), rank = i / CHUNK;
    if (i >= n_slots || rank >= chunk_count[0] || prim_count[i] == 0) return;
    const int t = chunk_list[rank] * CHUNK + i % CHUNK;
    const int offset = chunk_offset[rank] + prim_local[i];
    const int room = capacity - offset;    /* overflow is detected on the host from the total */
    if (room <= 0) return;
    if (prim_count[i] == 1) {
        prims[offset] = staged[i];
        return;
    }
    uchar s;
    setup_triangle(t, positions, triangles, tri_material, materials, view_proj,
                   width, height, near, select, prims + offset, room, &s);
}
#endif
