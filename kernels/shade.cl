/* shade.cl: deferred Blinn-Phong shading from the G-buffer (report II.4, the light buffer).
 *
 * Algorithm: one work-group per LTILE×LTILE light tile; each work-item shades a run of VEC
 * adjacent pixels (vec.h). It decodes the G-buffer (normal, albedo, specular terms, linear
 * depth), rebuilds the world position from the linear depth and the pixel's view ray
 * ("Question du Z"), then walks its tile's light list (or, with BRUTE_FORCE, every light) in
 * index order, accumulating the light buffer's diffuse and specular sums:
 *     A = (1 - (d/r)^2)^3 for d < r, else 0;  S = 1, or t^2 for spots with
 *     t = clamp((dot(-L, dir) - cos_outer) / max(cos_inner - cos_outer, 1e-4), 0, 1);
 *     diffuse += A·S·color·max(N·L, 0);  specular += A·S·color·s·max(N·H, 0)^p where N·L > 0;
 * and applies the "global multiply": color = albedo·(ambient + diffuse) + specular. With SSAO
 * the ambient pass is the report's occlusion pass (III.1): ambient becomes ambient·ao, ao read
 * from the ssao pass's buffer; without it (SSAO 0) ao is not read and the arithmetic is unchanged.
 * Background pixels get 0. The loop over lights is uniform across the run's lanes, so light
 * records are scalar loads and the math is VEC-wide.
 * Shadows (SHADOWS 1, report II.4): a spot light with `shadow` >= 0 multiplies its A·S by its
 * shadow map's visibility (shadow.h) where A·S > 0; the sun (has_sun: a directional light, no
 * attenuation, every foreground pixel) by its cascade's visibility, the cascade picked per
 * pixel from its view depth and the cascades' splits. Each visibility is also written to its
 * plane of shadow_out (sun first), left at 1 (the host's fill) where the light does not reach.
 *
 * Buffers: gbuffer uint[GB_PLANES][H·W]; lights Light[n]; camera float[16] = eye, F, R·tan_x,
 *          U·tan_y (float4 each, world space); tile_light_offsets/counts int[tiles],
 *          tile_lights int[list_capacity]; srgb_lut float[256]; ao float[H·W] (read if SSAO).
 *          shadow_atlas float[], shadow_views ShadowView[] (sun cascades, then spots from
 *          spot_view0); sun_dir/sun_color float[3] (direction the light travels, linear RGB).
 *          out: color float[3][H·W] (linear HDR planes), light_count int[H·W],
 *          shadow_out float[shadow_planes][H·W] (visibility; spots from plane spot_plane0).
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
#include "lighting.h"

kernel __attribute__((reqd_work_group_size(LTILE / VEC, LTILE, 1)))
void shade(global const uint* gbuffer, int width, int height, float far, global const float* camera,
           global const Light* lights, int n_lights, float ambient, global const float* ao,
           global const int* tile_light_offsets, global const int* tile_light_counts,
           global const int* tile_lights, int list_capacity, int tiles_x,
           constant float* srgb_lut,
           global const float* shadow_atlas, int atlas_stride, global const ShadowView* shadow_views,
           float shadow_bias, float shadow_slope_bias, float shadow_normal_offset,
           int has_sun, global const float* sun, int sun_cascades, int spot_view0, int spot_plane0,
           global float* color, global int* light_count, global float* shadow_out)
{
    const int px0 = get_global_id(0) * VEC, py = get_global_id(1);
    if (py >= height || px0 >= width) return;
    const int npix = width * height;
    const int p0 = py * width + px0;
    const int valid = min(VEC, width - px0);
    const int tile = get_group_id(1) * tiles_x + get_group_id(0);

    /* Decode the G-buffer. */
    intV tri = as_intV(load_plane(gbuffer + GB_TRIANGLE_ID_PLANE * npix, p0, valid, 0xffffffffu));
    intV fg = tri >= 0;
    uintV w_alb = load_plane(gbuffer + GB_ALBEDO_PLANE * npix, p0, valid, 0u);
    uintV w_nrm = load_plane(gbuffer + GB_NORMAL_PLANE * npix, p0, valid, 0u);
    floatV lin = as_floatV(load_plane(gbuffer + GB_LINEAR_DEPTH_PLANE * npix, p0, valid, 0u));
    floatV depth = select((floatV)0.0f, lin * far, fg);

    uintV alb = w_alb >> GB_ALBEDO_SHIFT;
    floatV ar = GATHER_F(srgb_lut, as_intV(alb & 255u));
    floatV ag = GATHER_F(srgb_lut, as_intV((alb >> 8) & 255u));
    floatV ab = GATHER_F(srgb_lut, as_intV((alb >> 16) & 255u));
    floatV spec_i = convert_floatV((w_alb >> GB_SPECULAR_INTENSITY_SHIFT) & 255u) * (1.0f / 255.0f);
    floatV spec_p = exp2(convert_floatV((w_nrm >> GB_SPECULAR_POWER_SHIFT) & 255u) * (SPEC_POWER_LOG2_MAX / 255.0f));
    floatV fx, fy, fz;
    unpack_oct12x2V(w_nrm >> GB_NORMAL_SHIFT, &fx, &fy, &fz);
    floatV inv_n = rsqrt(fx * fx + fy * fy + fz * fz);
    floatV nx = fx * inv_n, ny = fy * inv_n, nz = fz * inv_n;

    /* World position on the pixel's view ray at the stored depth; V points to the eye. */
    const float3 eye = vload4(0, camera).xyz, F = vload4(1, camera).xyz;
    const float3 Rs = vload4(2, camera).xyz, Us = vload4(3, camera).xyz;
    floatV xn = (convert_floatV(px0 + LANES) + 0.5f) * (2.0f / (float)width) - 1.0f;
    floatV yn = 1.0f - ((float)py + 0.5f) * (2.0f / (float)height);
    floatV dx = F.x + xn * Rs.x + yn * Us.x, dy = F.y + xn * Rs.y + yn * Us.y, dz = F.z + xn * Rs.z + yn * Us.z;
    floatV px = eye.x + depth * dx, py_ = eye.y + depth * dy, pz = eye.z + depth * dz;
    floatV inv_d = rsqrt(dx * dx + dy * dy + dz * dz);
    floatV vx = -dx * inv_d, vy = -dy * inv_d, vz = -dz * inv_d;

    floatV dr = 0.0f, dg = 0.0f, db = 0.0f, sr = 0.0f, sg = 0.0f, sb = 0.0f;
#if BRUTE_FORCE
    const int first = 0, count = n_lights;
#else
    const int first = tile_light_offsets[tile];
    const int count = max(min(tile_light_counts[tile], list_capacity - first), 0);
#endif
#if SHADOWS
    const LightEnv env = { lights, tile_lights, has_sun, sun,
                           { shadow_atlas, atlas_stride, shadow_bias, shadow_slope_bias, shadow_normal_offset },
                           shadow_views, sun_cascades, spot_view0, spot_plane0 };
#else
    const LightEnv env = { lights, tile_lights, has_sun, sun };
#endif
    if (ANY(fg))
        accumulate_lights(&env, first, count, fg, px, py_, pz, nx, ny, nz, vx, vy, vz, spec_i, spec_p, depth,
                          px0 + LANES, py, shadow_out, p0, valid, npix, &dr, &dg, &db, &sr, &sg, &sb);
#if SSAO
    floatV ambient_ao = ambient * as_floatV(load_plane((global const uint*)ao, p0, valid, 0u));
#else
    const float ambient_ao = ambient;
#endif
    floatV cr = select((floatV)0.0f, ar * (ambient_ao + dr) + sr, fg);
    floatV cg = select((floatV)0.0f, ag * (ambient_ao + dg) + sg, fg);
    floatV cb = select((floatV)0.0f, ab * (ambient_ao + db) + sb, fg);
    if (valid == VEC) {
        vstoreV(cr, 0, color + p0);
        vstoreV(cg, 0, color + npix + p0);
        vstoreV(cb, 0, color + 2 * npix + p0);
        vstoreV((intV)count, 0, light_count + p0);
    } else {
        for (int l = 0; l < valid; ++l) {
            color[p0 + l] = LANE_F(cr, l);
            color[npix + p0 + l] = LANE_F(cg, l);
            color[2 * npix + p0 + l] = LANE_F(cb, l);
            light_count[p0 + l] = count;
        }
    }
}
