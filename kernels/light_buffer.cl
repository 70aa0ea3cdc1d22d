/* light_buffer.cl: the light pre-pass's light buffer (report V.2, Engel's Light Pre-Pass /
 * Insomniac's pre-lighting; docs/variants.md), pass 2 of the "light_prepass" pipeline.
 *
 * Algorithm: one work-group per LTILE×LTILE light tile; each work-item a run of VEC adjacent
 * pixels (vec.h). From the thin G-buffer alone -- linear depth, normal, specular power; no
 * albedo, no specular intensity -- it rebuilds the world position on the pixel's view ray like
 * shade.cl and walks its tile's light list (or every light, BRUTE_FORCE) through lighting.h's
 * light loop with specular intensity 1, the sun and shadow maps included:
 *     D = sum A·S·vis·color·max(N·L, 0),   S = sum A·S·vis·color·max(N·H, 0)^p where N·L > 0
 * and stores the light buffer: D (RGB) and, with SPECULAR_RGB 1, S (RGB); with SPECULAR_RGB 0 the
 * classic LPP trade-off, S's luminance only (0.2126, 0.7152, 0.0722): the material pass then
 * colours it with the diffuse light's chromaticity. Background pixels store 0.
 * LB_HALF 1 stores IEEE halves (round to nearest even; values beyond 65504 saturate to it),
 * LB_HALF 0 floats. The light count and shadow visibility AOVs are written as shade.cl does.
 *
 * Buffers: gbuffer uint[GB_PLANES][H·W] (reads the depth, normal/power and id planes only);
 *          lights, tile lists, camera, shadow atlas and views, sun: as shade.cl.
 *          out: light_buffer float or half [LB_PLANES][H·W], LB_PLANES = 6 (D.rgb, S.rgb) or
 *          4 (D.rgb, S luminance), then with LB_GLTF T.rgb (or T's luminance): the glTF BRDF's
 *          sums (brdf.h), its lanes found through the triangle's material; light_count int[H·W]; shadow_out float[planes][H·W];
 *          light_pairs int[2][H·W] (pairs evaluated, useful: as shade.cl).
 * Work-groups: (LTILE/VEC, LTILE); global size = (tiles_x·LTILE/VEC, tiles_y·LTILE); no barriers.
 */
#pragma OPENCL FP_CONTRACT OFF
#include "structs.h"
#include "gbuffer.h"

#ifndef LTILE
#define LTILE 16
#endif
#ifndef SPECULAR_RGB
#define SPECULAR_RGB 1
#endif
#ifndef LB_HALF
#define LB_HALF 0
#endif
#ifndef LB_GLTF
#define LB_GLTF 0    /* 1: RenderConfig.shading = "auto": the glTF BRDF's third sum T (brdf.h) follows */
#endif
#include "lighting.h"
#include "gbuffer_decode.h"

#if LB_HALF
typedef half lb_t;
#else
typedef float lb_t;
#endif

/* Stores the run's `valid` lanes of v into light buffer plane `plane`. */
static inline void lb_store(global lb_t* lb, int plane, int npix, int p0, int valid, floatV v)
{
#if LB_HALF
    v = fmin(v, 65504.0f);
    if (valid == VEC) {
        vstore_halfV(v, 0, lb + plane * npix + p0);
        return;
    }
    for (int l = 0; l < valid; ++l) vstore_half_rte(LANE_F(v, l), plane * npix + p0 + l, lb);
#else
    store_plane(lb + plane * npix, p0, valid, v);
#endif
}

kernel __attribute__((reqd_work_group_size(LTILE / VEC, LTILE, 1)))
void light_buffer(global const uint* gbuffer, int width, int height, float far, global const float* camera,
                  global const Light* lights, int n_lights,
                  global const int* tile_light_offsets, global const int* tile_light_counts,
                  global const int* tile_lights, int list_capacity, int tiles_x,
                  global const float* shadow_atlas, int atlas_stride, global const ShadowView* shadow_views,
                  float shadow_bias, float shadow_slope_bias, float shadow_normal_offset,
                  int has_sun, global const float* sun, int sun_cascades, int spot_view0, int spot_plane0,
                  global const int* tri_material, global const Material* materials, int gltf_scene,
                  global lb_t* light_buf, global int* light_count, global float* shadow_out, global int* light_pairs)
{
    const int px0 = get_global_id(0) * VEC, py = get_global_id(1);
    if (py >= height || px0 >= width) return;
    const int npix = width * height;
    const int p0 = py * width + px0;
    const int valid = min(VEC, width - px0);
    const int tile = get_group_id(1) * tiles_x + get_group_id(0);

    /* The thin G-buffer; the world position on the pixel's view ray, V towards the eye. */
    const intV tri = as_intV(load_plane(gbuffer + GB_TRIANGLE_ID_PLANE * npix, p0, valid, 0xffffffffu));
    const intV fg = tri >= 0;
#if LB_GLTF
    const intV gltf = gltf_lanes_of(tri, fg, gltf_scene, tri_material, materials);
#else
    const intV gltf = 0;
#endif
    const LitPointV s = decode_lit_point(load_plane(gbuffer + GB_NORMAL_PLANE * npix, p0, valid, 0u),
                                         load_plane(gbuffer + GB_LINEAR_DEPTH_PLANE * npix, p0, valid, 0u), fg, far,
                                         gltf);
    const ViewPointV v = view_point(camera, width, height, px0, py, s.depth);
    const BrdfV m = brdf_inputs(gltf, (floatV)1.0f, s.spec_p, s.nx, s.ny, s.nz, v.vx, v.vy, v.vz);

    floatV dr = 0.0f, dg = 0.0f, db = 0.0f, sr = 0.0f, sg = 0.0f, sb = 0.0f, tr = 0.0f, tg = 0.0f, tb = 0.0f;
    const int2 range = tile_light_range(tile_light_offsets, tile_light_counts, list_capacity, tile, n_lights);
    const int first = range.x, count = range.y;
    const LightEnv env = LIGHT_ENV_INIT;
    intV evaluated = 0, useful = 0;           /* (pixel, light) pairs: walked, reached (light_pairs) */
    if (ANY(fg))
        accumulate_lights_counted(&env, first, count, fg, 0, 0, &evaluated, &useful, v.px, v.py, v.pz, s.nx, s.ny,
                                  s.nz, v.vx, v.vy, v.vz, &m, s.depth, px0 + LANES, py, shadow_out,
                                  p0, valid, npix, &dr, &dg, &db, &sr, &sg, &sb, &tr, &tg, &tb);
    const floatV zero = 0.0f;
    lb_store(light_buf, 0, npix, p0, valid, select(zero, dr, fg));
    lb_store(light_buf, 1, npix, p0, valid, select(zero, dg, fg));
    lb_store(light_buf, 2, npix, p0, valid, select(zero, db, fg));
#if SPECULAR_RGB
    lb_store(light_buf, 3, npix, p0, valid, select(zero, sr, fg));
    lb_store(light_buf, 4, npix, p0, valid, select(zero, sg, fg));
    lb_store(light_buf, 5, npix, p0, valid, select(zero, sb, fg));
#if LB_GLTF
    lb_store(light_buf, 6, npix, p0, valid, select(zero, tr, fg));
    lb_store(light_buf, 7, npix, p0, valid, select(zero, tg, fg));
    lb_store(light_buf, 8, npix, p0, valid, select(zero, tb, fg));
#endif
#else
    lb_store(light_buf, 3, npix, p0, valid, select(zero, 0.2126f * sr + 0.7152f * sg + 0.0722f * sb, fg));
#if LB_GLTF
    lb_store(light_buf, 4, npix, p0, valid, select(zero, 0.2126f * tr + 0.7152f * tg + 0.0722f * tb, fg));
#endif
#endif
    store_light_counts(light_count, light_pairs, npix, p0, valid, count, evaluated, useful);
}
