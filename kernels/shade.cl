/* shade.cl: deferred shading from the G-buffer (report II.4, the light buffer), with the
 * report's Blinn-Phong or the glTF 2.0 BRDF per material (brdf.h, docs/shading.md).
 *
 * Algorithm: one work-group per LTILE×LTILE light tile; each work-item shades a run of VEC
 * adjacent pixels (vec.h). It decodes the G-buffer (normal, the material bytes, linear depth;
 * a pixel's model from its triangle's material when gltf_scene), rebuilds the world position
 * from the linear depth and the pixel's view ray ("Question du Z"), then walks its tile's light
 * list (or, with BRUTE_FORCE, every light) in index order through lighting.h, accumulating the
 * light sums D, S (and T on glTF lanes), and composes (compose.h): Blinn-Phong
 * color = albedo·(ambient + D) + S (the report's "global multiply"), glTF
 * color = albedo·(1 − F0)·(ambient_d + D) + F0·(ambient_s + S) + ambient_t + T.
 * The ambient term (the report's ambient pass, III.1) is the constant `ambient`, or with an
 * environment (has_env: ENV_PARAMS, ambient.h) its irradiance and split-sum specular; SSAO (SSAO 1)
 * multiplies it (ao read from the ssao pass's buffer). With surface_extras (a scene with
 * emissive, occlusion-mapped or unlit materials), the emissive_occlusion plane and the material
 * through the triangle id add the emission, scale the ambient term by the material's occlusion
 * and give unlit pixels their albedo alone (docs/materials.md). Background pixels get 0, or the
 * environment along their view ray (env_background). The loop over lights is uniform across the
 * run's lanes, so light records are scalar loads and the math is VEC-wide.
 * Shadows (SHADOWS 1, report II.4): a spot light with `shadow` >= 0 multiplies its A·S by its
 * shadow map's visibility (shadow.h) where A·S > 0; the sun (has_sun: a directional light, no
 * attenuation, every foreground pixel) by its cascade's visibility, the cascade picked per
 * pixel from its view depth and the cascades' splits. Each visibility is also written to its
 * plane of shadow_out (sun first), left at 1 (the host's fill) where the light does not reach.
 * Stencil (STENCIL 1, report V.1, after light_stencil.cl): the light loop walks the tile list
 * by the pixels' stencil bits (lighting.h): a lane takes entry k only where its bit is set, a
 * light no lane takes is skipped, and the distance test is not made.
 * Pair statistics: per pixel, the (pixel, light) pairs the loop evaluates (the list length on
 * foreground pixels; with STENCIL the set bits) and the useful ones (d² < r², inside a spot's
 * cone: lighting.h light_reach) go to light_pairs; the host sums the planes on the device.
 *
 * Buffers: gbuffer uint[GB_PLANES][H·W]; lights Light[n]; camera float[16] = eye, F, R·tan_x,
 *          U·tan_y (float4 each, world space); tile_light_offsets/counts int[tiles],
 *          tile_lights int[list_capacity]; srgb_lut float[256]; ao float[H·W] (read if SSAO).
 *          shadow_atlas float[], shadow_views ShadowView[] (sun cascades, then spots from
 *          spot_view0); sun_dir/sun_color float[3] (direction the light travels, linear RGB).
 *          out: color float[3][H·W] (linear HDR planes), light_count int[H·W],
 *          shadow_out float[shadow_planes][H·W] (visibility; spots from plane spot_plane0),
 *          light_pairs int[2][H·W] (evaluated, useful). stencil uint[stencil_words][H·W]
 *          (read if STENCIL: bit k of word k/32 of a pixel = list entry k reaches it).
 *          tri_material int[T], materials Material[M] (read if surface_extras or gltf_scene);
 *          ENV_PARAMS (environment.h; read if has_env).
 * Work-groups: (LTILE/VEC, LTILE); global size = (tiles_x·LTILE/VEC, tiles_y·LTILE).
 */
#pragma OPENCL FP_CONTRACT OFF
#include "structs.h"
#include "gbuffer.h"

#ifndef LTILE
#define LTILE 16
#endif
#ifndef SSAO
#define SSAO 0
#endif
#ifndef STENCIL
#define STENCIL 0
#endif
#include "lighting.h"
#include "gbuffer_decode.h"
#include "ambient.h"

kernel __attribute__((reqd_work_group_size(LTILE / VEC, LTILE, 1)))
void shade(global const uint* gbuffer, int width, int height, float far, global const float* camera,
           global const Light* lights, int n_lights, float ambient, global const float* ao,
           global const int* tile_light_offsets, global const int* tile_light_counts,
           global const int* tile_lights, int list_capacity, int tiles_x,
           constant float* srgb_lut,
           global const float* shadow_atlas, int atlas_stride, global const ShadowView* shadow_views,
           float shadow_bias, float shadow_slope_bias, float shadow_normal_offset,
           int has_sun, global const float* sun, int sun_cascades, int spot_view0, int spot_plane0,
           global const uint* stencil, int stencil_words,
           int surface_extras, global const int* tri_material, global const Material* materials, int gltf_scene,
           int has_env, int env_background, ENV_PARAMS, global float* color, global int* light_count, global float* shadow_out, global int* light_pairs)
{
    const int px0 = get_global_id(0) * VEC, py = get_global_id(1);
    if (py >= height || px0 >= width) return;
    const int npix = width * height;
    const int p0 = py * width + px0;
    const int valid = min(VEC, width - px0);
    const int tile = get_group_id(1) * tiles_x + get_group_id(0);

    /* Decode the G-buffer; the world position on the pixel's view ray, V towards the eye. */
    const intV tri = as_intV(load_plane(gbuffer + GB_TRIANGLE_ID_PLANE * npix, p0, valid, 0xffffffffu));
    const intV fg = tri >= 0;
    const intV gltf = gltf_lanes_of(tri, fg, gltf_scene, tri_material, materials);
    const LitPointV s = decode_lit_point(load_plane(gbuffer + GB_NORMAL_PLANE * npix, p0, valid, 0u),
                                         load_plane(gbuffer + GB_LINEAR_DEPTH_PLANE * npix, p0, valid, 0u), fg, far,
                                         gltf);
    floatV ar, ag, ab, spec_i;
    decode_albedo(load_plane(gbuffer + GB_ALBEDO_PLANE * npix, p0, valid, 0u), srgb_lut, &ar, &ag, &ab, &spec_i);
    const ViewPointV v = view_point(camera, width, height, px0, py, s.depth);
    const BrdfV m = brdf_inputs(gltf, spec_i, s.spec_p, s.nx, s.ny, s.nz, v.vx, v.vy, v.vz);

    floatV dr = 0.0f, dg = 0.0f, db = 0.0f, sr = 0.0f, sg = 0.0f, sb = 0.0f, tr = 0.0f, tg = 0.0f, tb = 0.0f;
    const int2 range = tile_light_range(tile_light_offsets, tile_light_counts, list_capacity, tile, n_lights);
    const int first = range.x, count = range.y;
    const LightEnv env = LIGHT_ENV_INIT;
    intV evaluated = 0, useful = 0;           /* (pixel, light) pairs: walked, reached (light_pairs) */
    if (ANY(fg))
        accumulate_lights_counted(&env, first, count, fg, stencil, stencil_words, &evaluated, &useful,
                                  v.px, v.py, v.pz, s.nx, s.ny, s.nz, v.vx, v.vy, v.vz, &m, s.depth,
                                  px0 + LANES, py, shadow_out, p0, valid, npix, &dr, &dg, &db, &sr, &sg, &sb,
                                  &tr, &tg, &tb);
#if SSAO
    const floatV ao_v = as_floatV(load_plane((global const uint*)ao, p0, valid, 0u));
    floatV ambient_ao = ambient * ao_v;
#else
    const floatV ao_v = 1.0f;
    const floatV ambient_ao = ambient;
#endif
    const EnvMaps envmaps = ENV_INIT;
    const AmbientV amb = ambient_light(has_env, &envmaps, &m, ambient_ao, ao_v, s.nx, s.ny, s.nz, v.vx, v.vy, v.vz);
    SurfaceExtrasV x;
    if (surface_extras)            /* emission, occlusion, unlit (docs/materials.md) */
        x = decode_extras(load_plane(gbuffer + GB_EMISSIVE_PLANE * npix, p0, valid, 0u), tri, fg,
                          tri_material, materials, srgb_lut);
    floatV cr, cg, cb;
    compose_lit(&m, fg, ar, ag, ab, spec_i, &amb, surface_extras, x.er, x.eg, x.eb, x.occlusion, x.unlit,
                dr, dg, db, sr, sg, sb, tr, tg, tb, &cr, &cg, &cb);
    environment_background(has_env, env_background, &envmaps, fg, v.vx, v.vy, v.vz, &cr, &cg, &cb);
    store_plane(color, p0, valid, cr);
    store_plane(color + npix, p0, valid, cg);
    store_plane(color + 2 * npix, p0, valid, cb);
    store_light_counts(light_count, light_pairs, npix, p0, valid, count, evaluated, useful);
}
