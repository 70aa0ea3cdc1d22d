/* material.cl: the light pre-pass's material pass (report V.2, pass 3 of "light_prepass";
 * docs/variants.md): the second geometry pass's visible surfaces times the light buffer, with
 * the report's anti-aliasing on the colour (III.3) when the raster ran at several sub-samples.
 *
 * Algorithm: each work-item owns VEC consecutive pixels (vec.h, rows wrap as in gbuffer.cl).
 * One launch per sub-sample s of `samples` (the sample's own visibility buffer and prims: the
 * raster of setup.cl's sample-shifted geometry, docs/raster_contract.md §10). Per lane, the
 * sample's surface (surface_vec.h: base colour × texture, specular intensity) is quantized
 * exactly as the G-buffer stores it (8-bit sRGB albedo, 8-bit intensity: every pipeline shades
 * the same surface) and combined with the light buffer at the pixel:
 *     c_s = albedo·(ambient·ao·occ + D) + s·S + e                       (SPECULAR_RGB 1)
 *     c_s = albedo·(ambient·ao·occ + D) + s·S_lum·D / lum(D) + e        (SPECULAR_RGB 0; 0 where lum(D) = 0)
 * with the material's occlusion occ and emission e (gbuffer_decode.h; unlit: c_s = albedo).
 * lum = (0.2126, 0.7152, 0.0722); background samples give 0. Like hardware multisampling, each
 * sample's surface is evaluated at the pixel centre (surface_at_offset, undoing the sample's
 * shift; outside its triangle on edge pixels, as without centroid sampling), so only coverage
 * is multisampled. Resolve, in sample order: color = c_0 at s = 0, the sum of c_s - c_0 in
 * `spread` after, color = c_0 + sum / samples at the last sample: a pixel covered by one
 * surface keeps c_0 exactly.
 * When `write_aov` is set (s = 0; with one sample its surface is the pixel centre's), the albedo
 * and specular intensity plane and the emissive/occlusion plane of the G-buffer (AOVs) are written from it, with the same bits
 * as gbuffer.cl; with several samples the pass-1 surface fills it instead (aov_prim / aov_prims).
 *
 * Buffers: vis_prim int[W·H] (the sample's), prims Prim[*] (the sample's); aov_prim int[W·H] and
 *          aov_prims Prim[*] (pass 1's, read when write_aov == 2); scene buffers and textures
 *          (surface_vec.h); light_buf float or half [LB_PLANES][W·H]; ao float[W·H] (read if SSAO);
 *          srgb_lut float[256], srgb_encode float2[4096]. out: color float[3][W·H]; spread
 *          float[3][W·H] (samples > 2 only); gbuffer
 *          uint[GB_PLANES][W·H] (albedo/specular plane only).
 * Work-groups: 1-D, work-item i covers pixels [i·VEC, i·VEC + VEC); no barriers.
 */
#pragma OPENCL FP_CONTRACT OFF
#include "structs.h"
#include "gbuffer.h"
#include "vec.h"
#ifndef GB_WRITE
#define GB_WRITE ((1 << GB_ALBEDO_PLANE) | (1 << GB_EMISSIVE_PLANE))
#endif
#include "gbuffer_pack.h"
#include "gbuffer_decode.h"

#ifndef SPECULAR_RGB
#define SPECULAR_RGB 1
#endif
#ifndef LB_HALF
#define LB_HALF 0
#endif
#ifndef SSAO
#define SSAO 0
#endif
#ifndef LB_GLTF
#define LB_GLTF 0    /* the light buffer holds the glTF BRDF's third sum T (light_buffer.cl) */
#endif
#include "ambient.h"
#if LB_HALF
typedef half lb_t;
#define LB_LOAD(plane, i) vload_halfV(0, light_buf + (plane) * npix + (i))
#define LB_LOAD1(plane, i) vload_half((plane) * npix + (i), light_buf)
#else
typedef float lb_t;
#define LB_LOAD(plane, i) vloadV(0, light_buf + (plane) * npix + (i))
#define LB_LOAD1(plane, i) light_buf[(plane) * npix + (i)]
#endif

/* Light buffer plane `plane` at the run's pixels (lanes past npix read 0). */
#define LB_RUN(out, plane)                                                       \
    if (valid == VEC) {                                                          \
        out = LB_LOAD(plane, pix0);                                              \
    } else {                                                                     \
        out = 0.0f;                                                              \
        for (int l = 0; l < valid; ++l) LANE_F(out, l) = LB_LOAD1(plane, pix0 + l); \
    }

kernel void material(global const int* vis_prim, int width, int height, SCENE_PARAMS(prims),
                     constant float2* srgb_encode, global const lb_t* light_buf, float ambient, global const float* ao,
                     int sample, int samples, int sample_x, int sample_y, int write_aov,
                     global const float* camera, int has_env, int env_background, ENV_PARAMS,
                     global const int* aov_prim, global const Prim* aov_prims, global float* color,
                     global float* spread, global uint* gbuffer)
{
    const int npix = width * height;
    const int pix0 = get_global_id(0) * VEC;
    if (pix0 >= npix) return;
    const int valid = min(VEC, npix - pix0);
    intV px, py;
    int cx = pix0 % width, cy = pix0 / width;
    for (int l = 0; l < VEC; ++l) {
        LANE_I(px, l) = cx; LANE_I(py, l) = cy;
        if (++cx == width) { cx = 0; ++cy; }
    }
    const SceneV scene = SCENE_INIT(prims);

    const intV pidx = as_intV(load_plane((global const uint*)vis_prim, pix0, valid, 0xffffffffu));
    intV fg = pidx >= 0;
#if VEC == 1
    fg = fg ? 1 : 0;
#endif
    floatV cr = 0.0f, cg = 0.0f, cb = 0.0f;
    uintV w_alb = 0u, w_eo = 0u;
    const EnvMaps envmaps = ENV_INIT;
    if (ANY(fg)) {
        const SurfaceV sf = surface_at_offset(&scene, select((intV)0, pidx, fg), fg, px, py, -sample_x, -sample_y);
        w_alb = (pack_srgb8x3V(sf.r, sf.g, sf.b, srgb_encode) << GB_ALBEDO_SHIFT)
                | (unormV(sf.spec_i, 8) << GB_SPECULAR_INTENSITY_SHIFT);
        w_eo = (pack_srgb8x3V(sf.er, sf.eg, sf.eb, srgb_encode) << GB_EMISSIVE_SHIFT)
               | (unormV(sf.occlusion, 8) << GB_OCCLUSION_SHIFT);
        const SurfaceExtrasV x = material_extras(w_eo, sf.mat, fg, materials, srgb_lut);
        floatV ar, ag, ab, spec_i;
        decode_albedo(w_alb, srgb_lut, &ar, &ag, &ab, &spec_i);
        floatV dr, dg, db, sr, sg, sb, tr = 0.0f, tg = 0.0f, tb = 0.0f;
        LB_RUN(dr, 0) LB_RUN(dg, 1) LB_RUN(db, 2)
#if SPECULAR_RGB
        LB_RUN(sr, 3) LB_RUN(sg, 4) LB_RUN(sb, 5)
#if LB_GLTF
        LB_RUN(tr, 6) LB_RUN(tg, 7) LB_RUN(tb, 8)
#endif
#else
        floatV s_lum;
        LB_RUN(s_lum, 3)
        const floatV d_lum = 0.2126f * dr + 0.7152f * dg + 0.0722f * db;
        const floatV k = select((floatV)0.0f, s_lum / d_lum, d_lum > 0.0f);   /* the diffuse light's colour */
        sr = k * dr; sg = k * dg; sb = k * db;
#if LB_GLTF
        floatV t_lum;
        LB_RUN(t_lum, 4)
        const floatV kt = select((floatV)0.0f, t_lum / d_lum, d_lum > 0.0f);
        tr = kt * dr; tg = kt * dg; tb = kt * db;
#endif
#endif
#if SSAO
        const floatV ao_v = as_floatV(load_plane((global const uint*)ao, pix0, valid, 0u));
        const floatV ambient_ao = ambient * ao_v;
#else
        const floatV ao_v = 1.0f;
        const floatV ambient_ao = ambient;
#endif
        /* Blinn-Phong lanes: the light buffer's S was summed with intensity 1 (light_buffer.cl). */
        const intV gltf = gltf_lanes(sf.mat_flags, fg);
        BrdfV m = { gltf, ANY(gltf) ? 1 : 0 };
        AmbientV amb;
        if (has_env) {                  /* the material's own roughness, N and V at the pixel centre */
            floatV vx, vy, vz;
            view_vectors(camera, width, height, px, py, &vx, &vy, &vz);
            m = brdf_inputs(gltf, spec_i, sf.spec_p, sf.n.x, sf.n.y, sf.n.z, vx, vy, vz);
            amb = ambient_light(1, &envmaps, &m, ambient_ao, ao_v, sf.n.x, sf.n.y, sf.n.z, vx, vy, vz);
        } else {
            amb = constant_ambient(ambient_ao);
        }
        compose_lit(&m, fg, ar, ag, ab, spec_i, &amb, 1, x.er, x.eg, x.eb, x.occlusion, x.unlit, dr, dg, db,
                    select(spec_i * sr, sr, gltf), select(spec_i * sg, sg, gltf), select(spec_i * sb, sb, gltf),
                    tr, tg, tb, &cr, &cg, &cb);
    }
    if (has_env && env_background && ANY(!fg)) {   /* the environment behind the geometry */
        floatV vx, vy, vz;
        view_vectors(camera, width, height, px, py, &vx, &vy, &vz);
        environment_background(1, 1, &envmaps, fg, vx, vy, vz, &cr, &cg, &cb);
    }
    if (write_aov) {
        uintV planes[GB_PLANES];
        gbuffer_background(planes);
        if (write_aov == 1) {            /* this sample is the pixel centre's surface */
            planes[GB_ALBEDO_PLANE] = select((uintV)0u, w_alb, as_uintV(fg) != 0u);
            planes[GB_EMISSIVE_PLANE] = select((uintV)0u, w_eo, as_uintV(fg) != 0u);
        } else {                         /* pass 1's surface at the centre */
            const intV ai = as_intV(load_plane((global const uint*)aov_prim, pix0, valid, 0xffffffffu));
            intV afg = ai >= 0;
#if VEC == 1
            afg = afg ? 1 : 0;
#endif
            if (ANY(afg)) {
                const SceneV centre = SCENE_INIT(aov_prims);
                const SurfaceV sf = surface_at(&centre, select((intV)0, ai, afg), afg, px, py);
                const uintV w = (pack_srgb8x3V(sf.r, sf.g, sf.b, srgb_encode) << GB_ALBEDO_SHIFT)
                                | (unormV(sf.spec_i, 8) << GB_SPECULAR_INTENSITY_SHIFT);
                const uintV eo = (pack_srgb8x3V(sf.er, sf.eg, sf.eb, srgb_encode) << GB_EMISSIVE_SHIFT)
                                 | (unormV(sf.occlusion, 8) << GB_OCCLUSION_SHIFT);
                planes[GB_ALBEDO_PLANE] = select((uintV)0u, w, as_uintV(afg) != 0u);
                planes[GB_EMISSIVE_PLANE] = select((uintV)0u, eo, as_uintV(afg) != 0u);
            }
        }
        gbuffer_store(gbuffer, npix, pix0, valid, planes);
    }
    /* Resolve: color = c_0 + (sum_{s>0} (c_s - c_0)) / samples, so a pixel whose samples all
     * see the same surface keeps c_0 bit for bit. `spread` holds the running sum. */
    for (int c = 0; c < 3; ++c) {
        const floatV v = c == 0 ? cr : (c == 1 ? cg : cb);
        global float* dst = color + c * npix + pix0;
        global float* acc = spread + c * npix + pix0;
        floatV out = v, sum = 0.0f;
        if (sample > 0) {
            const floatV c0 = as_floatV(load_plane((global const uint*)dst, 0, valid, 0u));
            sum = v - c0;
            if (sample > 1) sum = as_floatV(load_plane((global const uint*)acc, 0, valid, 0u)) + sum;
            out = c0 + sum * (1.0f / (float)samples);
        }
        if (sample == 0 || sample == samples - 1) {
            if (valid == VEC) {
                vstoreV(out, 0, dst);
            } else {
                for (int l = 0; l < valid; ++l) dst[l] = LANE_F(out, l);
            }
        }
        if (sample > 0 && sample < samples - 1) {
            if (valid == VEC) {
                vstoreV(sum, 0, acc);
            } else {
                for (int l = 0; l < valid; ++l) acc[l] = LANE_F(sum, l);
            }
        }
    }
}
