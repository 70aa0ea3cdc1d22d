/* gbuffer_pack.h: a surface packed into the G-buffer's planes (the layout table,
 * clrender/abi/gbuffer.py and gbuffer.h), shared by the passes that write G-buffer planes:
 * the G-buffer resolve (gbuffer.cl; all planes for the deferred pipeline, the thin planes for
 * the light pre-pass, depth and id for light-indexed) and the passes that write the remaining
 * planes as AOVs after shading (material.cl, forward_shade.cl), so every pipeline's Frame
 * decodes the same bits.
 *
 * GB_WRITE (build option): bit i set = plane i is written by this kernel (default: all).
 */
#ifndef CLRENDER_GBUFFER_PACK_H
#define CLRENDER_GBUFFER_PACK_H
#include "gbuffer.h"
#include "surface_vec.h"

#ifndef GB_WRITE
#define GB_WRITE ((1 << GB_PLANES) - 1)
#endif

/* Screen-space motion in pixels (current - previous) of the surface points sf at pixels
 * (px, py): the point interpolated from the previous frame's vertex positions, projected by the
 * previous view-projection; 0 without a previous frame or behind its camera. */
static inline uintV pack_velocity(const SurfaceV* sf, global const float* prev_view_proj,
                                  global const float* prev_positions, int has_prev, int width, int height,
                                  intV px, intV py)
{
    floatV vx = 0.0f, vy = 0.0f;
    if (has_prev) {
        vec3V wp = interp3(gather3(prev_positions, sf->i0), gather3(prev_positions, sf->i1),
                           gather3(prev_positions, sf->i2), sf->c0, sf->c1, sf->c2);
        global const float* M = prev_view_proj;
        floatV qx = M[0] * wp.x + M[1] * wp.y + M[2] * wp.z + M[3];
        floatV qy = M[4] * wp.x + M[5] * wp.y + M[6] * wp.z + M[7];
        floatV qw = M[12] * wp.x + M[13] * wp.y + M[14] * wp.z + M[15];
        intV ahead = qw > 0.0f;
        floatV prev_x = (qx / qw + 1.0f) * 0.5f * (float)width, prev_y = (1.0f - qy / qw) * 0.5f * (float)height;
        vx = select((floatV)0.0f, convert_floatV(px) + 0.5f - prev_x, ahead);
        vy = select((floatV)0.0f, convert_floatV(py) + 0.5f - prev_y, ahead);
    }
    return pack_half2V(vx, vy);
}

/* The specular power's byte (log2unorm8), or on glTF-BRDF materials the roughness's (unorm8). */
static inline uintV pack_spec_byte(intV mat_flags, floatV spec_p)
{
    const uintV log2p = pack_log2unorm8V(spec_p);
    const intV gltf = (mat_flags & (int)MAT_GLTF_BRDF) != 0;
    if (!ANY(gltf)) return log2p;
    return select(log2p, unormV(spec_p, 8), as_uintV(gltf) != 0u);
}

/* Every plane of the surface sf (linear depth = view depth / far, packed velocity `vel`). */
static inline void gbuffer_pack(const SurfaceV* sf, floatV linear_depth, uintV vel, constant float2* srgb_encode,
                                uintV planes[GB_PLANES])
{
    for (int i = 0; i < GB_PLANES; ++i) planes[i] = 0;
    GB_PUT(planes, ALBEDO, pack_srgb8x3V(sf->r, sf->g, sf->b, srgb_encode));
    GB_PUT(planes, SPECULAR_INTENSITY, unormV(sf->spec_i, 8));
    GB_PUT(planes, LINEAR_DEPTH, as_uintV(linear_depth));
    GB_PUT(planes, NORMAL, pack_oct12x2V(sf->n.x, sf->n.y, sf->n.z));
    GB_PUT(planes, SPECULAR_POWER, pack_spec_byte(sf->mat_flags, sf->spec_p));
    GB_PUT(planes, VELOCITY, vel);
    GB_PUT(planes, TRIANGLE_ID, as_uintV(sf->tri));
    GB_PUT(planes, EMISSIVE, pack_srgb8x3V(sf->er, sf->eg, sf->eb, srgb_encode));
    GB_PUT(planes, OCCLUSION, unormV(sf->occlusion, 8));
}

/* The background's planes: depth +inf, triangle id -1, everything else 0. */
static inline void gbuffer_background(uintV planes[GB_PLANES])
{
    for (int i = 0; i < GB_PLANES; ++i) planes[i] = 0;
    GB_PUT(planes, LINEAR_DEPTH, as_uintV((floatV)INFINITY));
    GB_PUT(planes, TRIANGLE_ID, (uintV)0xffffffffu);
}

/* Stores the GB_WRITE planes of the pixels p0 .. p0 + valid - 1 (a run of one row). */
static inline void gbuffer_store(global uint* gbuffer, int npix, int p0, int valid, const uintV planes[GB_PLANES])
{
    for (int i = 0; i < GB_PLANES; ++i) {
        if (!(GB_WRITE & (1 << i))) continue;
        global uint* dst = gbuffer + i * npix + p0;
        if (valid == VEC) {
            vstoreV(planes[i], 0, dst);
        } else {
            for (int l = 0; l < valid; ++l) dst[l] = (uint)LANE_I(planes[i], l);
        }
    }
}
#endif
