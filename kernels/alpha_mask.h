/* alpha_mask.h: a prim's base-colour alpha along a run of VEC pixels, for raster.cl's alpha-MASK and
 * screen-door tests (docs/raster_contract.md §7): perspective-correct barycentrics from the exact
 * integer edge functions at each sample point and one pixel right and down of it, the UVs there
 * (with the slot's texture transform), GL's LOD from their change and the trilinear footprint of
 * texture_vec.h; the vertex colour's alpha when the mesh has colours. Shadow maps run the same test.
 */
#ifndef CLRENDER_ALPHA_MASK_H
#define CLRENDER_ALPHA_MASK_H
#include "structs.h"
#include "vec.h"
#include "texture_vec.h"

#ifndef ORTHO
#define ORTHO 0          /* 1: orthographic prims (setup.cl): inv_w holds depths, weights are affine */
#endif

typedef struct {
    global const uint* texels;
    global const TexInfo* infos;
    global const TexLevel* levels;
    global const float* colors;       /* float4 per vertex (COLOR_0), read if has_colors */
    int n_vertices;                   /* uv set k of vertex i at uvs[2 (k·n_vertices + i)] */
    int has_colors;
} Textures;

/* The base-colour alpha of prim p at the run's sample points (sx0 + 256 l, sy), l < VEC: factor ×
 * vertex-colour alpha × the texture's trilinear alpha; only the alpha channel is decoded. Lanes
 * outside `active` read valid texels and return anything. */
static floatV prim_alpha_run(const Prim* p, int sx0, int sy, Material m, global const float* uvs,
                             global const int* triangles, Textures tx, intV active)
{
    const floatV base = (floatV)m.base_color[3];
    const TexSlot slot = m.slots[SLOT_BASE];
    if (slot.texture < 0 && !tx.has_colors) return base;
    /* barycentrics at the lanes and one pixel right and down: exact integer edges, then weights */
    const longV sx = (longV)((long)sx0) + CONVERT_V(LANES, longV) * 256;
    longV e[3], ex[3], ey[3];
    for (int k = 0; k < 3; ++k) {
        const int k1 = (k + 1) % 3;
        const long dx = p->x[k1] - p->x[k], dy = p->y[k1] - p->y[k];
        e[k] = (longV)(dx * ((long)sy - p->y[k])) - (longV)dy * (sx - (longV)((long)p->x[k]));
        ex[k] = e[k] - (longV)(dy * 256);
        ey[k] = e[k] + (longV)(dx * 256);
    }
    floatV b[3][3];                       /* [centre, right, down][vertex] */
    for (int j = 0; j < 3; ++j) {
        const longV* E = j == 0 ? e : (j == 1 ? ex : ey);
#if ORTHO
        const floatV w0 = CONVERT_V(E[1], floatV), w1 = CONVERT_V(E[2], floatV), w2 = CONVERT_V(E[0], floatV);
#else
        const floatV w0 = CONVERT_V(E[1], floatV) * p->inv_w[0], w1 = CONVERT_V(E[2], floatV) * p->inv_w[1];
        const floatV w2 = CONVERT_V(E[0], floatV) * p->inv_w[2];
#endif
        const floatV inv = 1.0f / ((w0 + w1) + w2);
        const floatV x = w0 * inv, y = w1 * inv, z = w2 * inv;
        const floatV b1 = x * p->bary1[0] + y * p->bary1[1] + z * p->bary1[2];
        const floatV b2 = x * p->bary2[0] + y * p->bary2[1] + z * p->bary2[2];
        b[j][0] = 1.0f - b1 - b2; b[j][1] = b1; b[j][2] = b2;
    }
    const int i0 = triangles[3 * p->tri], i1 = triangles[3 * p->tri + 1], i2 = triangles[3 * p->tri + 2];
    floatV alpha = base;
    if (tx.has_colors)
        alpha = alpha * ((b[0][0] * tx.colors[4 * i0 + 3] + b[0][1] * tx.colors[4 * i1 + 3]) + b[0][2] * tx.colors[4 * i2 + 3]);
    if (slot.texture < 0) return alpha;
    /* uv at the sample and at b + (b_right - b), b + (b_down - b): the screen derivatives */
    const int set = slot.texcoord * tx.n_vertices;
    const float2 uv0 = vload2(set + i0, uvs), uv1 = vload2(set + i1, uvs), uv2 = vload2(set + i2, uvs);
    const float* t = slot.uv;
    floatV u[3], v[3];
    for (int j = 0; j < 3; ++j) {
        floatV c0 = b[0][0], c1 = b[0][1], c2 = b[0][2];
        if (j) { c0 = c0 + (b[j][0] - c0); c1 = c1 + (b[j][1] - c1); c2 = c2 + (b[j][2] - c2); }
        const floatV iu = (c0 * uv0.x + c1 * uv1.x) + c2 * uv2.x, iv = (c0 * uv0.y + c1 * uv1.y) + c2 * uv2.y;
        u[j] = (t[0] * iu + t[1] * iv) + t[2];
        v[j] = (t[3] * iu + t[4] * iv) + t[5];
    }
    const FootprintV fp = footprint(tx.infos, tx.levels, (intV)slot.texture, active, u[0], v[0],
                                    u[1] - u[0], v[1] - v[0], u[2] - u[0], v[2] - v[0]);
    floatV level_alpha[2];
    for (int j = 0; j < 2; ++j) {             /* bilinear alpha of levels l0 and l1 */
        const BilinearV* q = j ? &fp.b : &fp.a;
        const intV on = j ? fp.active_b : active;
        floatV a4[4];
        for (int k = 0; k < 4; ++k)
            a4[k] = convert_floatV(GATHER_U(tx.texels, select((intV)0, q->idx[k], on)) >> 24) * (1.0f / 255.0f);
        const floatV top = a4[0] + (a4[1] - a4[0]) * q->ax, bottom = a4[2] + (a4[3] - a4[2]) * q->ax;
        level_alpha[j] = top + (bottom - top) * q->ay;
        if (!ANY(fp.active_b)) { level_alpha[1] = level_alpha[0]; break; }
    }
    const floatV tri = select(level_alpha[0] + (level_alpha[1] - level_alpha[0]) * fp.f, level_alpha[0], fp.f == 0.0f);
    return alpha * tri;
}
#endif
