/* material.cl: the light pre-pass's material pass (report V.2, pass 3 of "light_prepass";
 * docs/variants.md): the second geometry pass's visible surfaces times the light buffer, with
 * the report's anti-aliasing on the colour (III.3) when the raster ran at several sub-samples.
 *
 * Algorithm: `material` evaluates sample 0 (or the only sample) at every pixel, VEC consecutive
 * pixels per work-item (vec.h, rows wrap as in gbuffer.cl): the sample's surface (surface_vec.h:
 * base colour × texture, specular intensity) is quantized exactly as the G-buffer stores it
 * (8-bit sRGB albedo, 8-bit intensity: every pipeline shades the same surface) and combined
 * with the light buffer at the pixel:
 *     c_s = albedo·(ambient·ao·occ + D) + s·S + e                       (SPECULAR_RGB 1)
 *     c_s = albedo·(ambient·ao·occ + D) + s·S_lum·D / lum(D) + e        (SPECULAR_RGB 0; 0 where lum(D) = 0)
 * with the material's occlusion occ and emission e (gbuffer_decode.h; unlit: c_s = albedo).
 * lum = (0.2126, 0.7152, 0.0722); background samples give 0 (or the environment).
 * With msaa, `material_samples` runs once per sub-sample s > 0 over the sample's visibility
 * buffer; every sample's prims are one buffer (docs/raster_contract.md §10,
 * clrender/passes/second_geometry.py). Like hardware multisampling, each sample's surface is
 * evaluated at the pixel centre (outside its triangle on edge pixels, as without centroid
 * sampling), so only coverage is multisampled, and a sample that sees sample 0's prim has
 * c_s = c_0 bit for bit: only the other pixels (edges, 13 % of Sponza's per sample) are listed
 * and evaluated, VEC at a time, and of those only the first sample to see each prim (71 % of
 * them at msaa 4, 49 % at msaa 8 on Sponza). Resolve, in sample order: color = c_0 at s = 0,
 * spread = the sum of c_s - c_0, color = c_0 + spread / samples at the last sample: a pixel
 * covered by one surface keeps c_0 exactly.
 * `write_aov` (one sample, whose surface is the pixel centre's): the albedo/specular and the
 * emissive/occlusion planes of the G-buffer, with the same bits as gbuffer.cl (with msaa pass 1
 * writes them, clrender/abi/gbuffer.py geometry_planes).
 *
 * Buffers: vis_prim int[W·H] (`material`), vis_prims int[samples][W·H] (`material_samples`;
 *          plane s is sample s's), prims Prim[*];
 *          scene buffers and textures (surface_vec.h); light_buf float or half [LB_PLANES][W·H];
 *          ao float[W·H] (read if SSAO); srgb_lut float[256], srgb_encode float2[4096].
 *          out: color float[3][W·H]; spread float[3][W·H] (samples > 1); deltas
 *          float[samples - 2][3][W·H] (samples > 2: c_s - c_0 where sample s was evaluated); gbuffer
 *          uint[GB_PLANES][W·H] (the two surface planes only).
 * Work-groups: 1-D; `material`: work-item i covers pixels [i·VEC, i·VEC + VEC);
 * `material_samples`: [i·VEC·SAMPLE_RUNS, +VEC·SAMPLE_RUNS). No barriers.
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

/* Light buffer plane `plane` at the lanes' pixels: the run pix0 .. pix0 + valid - 1 when
 * pix0 >= 0 (lanes past it read 0), else pixel pix per lane. */
#define LB_AT(out, plane)                                                        \
    if (pix0 >= 0 && valid == VEC) {                                             \
        out = LB_LOAD(plane, pix0);                                              \
    } else {                                                                     \
        out = 0.0f;                                                              \
        for (int l = 0; l < valid; ++l)                                          \
            LANE_F(out, l) = LB_LOAD1(plane, pix0 >= 0 ? pix0 + l : LANE_I(pix, l)); \
    }

typedef struct {
    floatV r, g, b;            /* the sample's colour c_s (the environment on background lanes) */
    uintV alb, eo;             /* its surface as the G-buffer packs it (albedo/specular, emissive/occlusion) */
} MaterialSample;

/* c_s for the lanes' prims pidx (fg: pidx >= 0) at pixels (px, py) = pix (see LB_AT). */
static MaterialSample material_sample(const SceneV* scene, intV pidx, intV fg, intV px, intV py, intV pix,
                                      int pix0, int valid, int npix, int width, int height,
                                      global const lb_t* light_buf, float ambient, global const float* ao,
                                      constant float2* srgb_encode, global const float* camera, int has_env,
                                      int env_background, const EnvMaps* envmaps)
{
    global const Material* materials = scene->materials;
    constant float* srgb_lut = scene->srgb_lut;
    MaterialSample c = { 0.0f, 0.0f, 0.0f, 0u, 0u };
    if (ANY(fg)) {
        const SurfaceV sf = surface_at(scene, select((intV)0, pidx, fg), fg, px, py);
        c.alb = (pack_srgb8x3V(sf.r, sf.g, sf.b, srgb_encode) << GB_ALBEDO_SHIFT)
                | (unormV(sf.spec_i, 8) << GB_SPECULAR_INTENSITY_SHIFT);
        c.eo = (pack_srgb8x3V(sf.er, sf.eg, sf.eb, srgb_encode) << GB_EMISSIVE_SHIFT)
               | (unormV(sf.occlusion, 8) << GB_OCCLUSION_SHIFT);
        const SurfaceExtrasV x = material_extras(c.eo, sf.mat, fg, materials, srgb_lut);
        floatV ar, ag, ab, spec_i;
        decode_albedo(c.alb, srgb_lut, &ar, &ag, &ab, &spec_i);
        floatV dr, dg, db, sr, sg, sb, tr = 0.0f, tg = 0.0f, tb = 0.0f;
        LB_AT(dr, 0) LB_AT(dg, 1) LB_AT(db, 2)
#if SPECULAR_RGB
        LB_AT(sr, 3) LB_AT(sg, 4) LB_AT(sb, 5)
#if LB_GLTF
        LB_AT(tr, 6) LB_AT(tg, 7) LB_AT(tb, 8)
#endif
#else
        floatV s_lum;
        LB_AT(s_lum, 3)
        const floatV d_lum = 0.2126f * dr + 0.7152f * dg + 0.0722f * db;
        const floatV k = select((floatV)0.0f, s_lum / d_lum, d_lum > 0.0f);   /* the diffuse light's colour */
        sr = k * dr; sg = k * dg; sb = k * db;
#if LB_GLTF
        floatV t_lum;
        LB_AT(t_lum, 4)
        const floatV kt = select((floatV)0.0f, t_lum / d_lum, d_lum > 0.0f);
        tr = kt * dr; tg = kt * dg; tb = kt * db;
#endif
#endif
#if SSAO
        floatV ao_v = 0.0f;
        if (pix0 >= 0) ao_v = as_floatV(load_plane((global const uint*)ao, pix0, valid, 0u));
        else for (int l = 0; l < valid; ++l) LANE_F(ao_v, l) = ao[LANE_I(pix, l)];
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
            amb = ambient_light(1, envmaps, &m, ambient_ao, ao_v, sf.n.x, sf.n.y, sf.n.z, vx, vy, vz);
        } else {
            amb = constant_ambient(ambient_ao);
        }
        compose_lit(&m, fg, ar, ag, ab, spec_i, &amb, 1, x.er, x.eg, x.eb, x.occlusion, x.unlit, dr, dg, db,
                    select(spec_i * sr, sr, gltf), select(spec_i * sg, sg, gltf), select(spec_i * sb, sb, gltf),
                    tr, tg, tb, &c.r, &c.g, &c.b);
    }
    if (has_env && env_background && ANY(!fg)) {   /* the environment behind the geometry */
        floatV vx, vy, vz;
        view_vectors(camera, width, height, px, py, &vx, &vy, &vz);
        environment_background(1, 1, envmaps, fg, vx, vy, vz, &c.r, &c.g, &c.b);
    }
    return c;
}

/* Sample 0 (or the only sample) at every pixel: color = c_0; with several samples the running
 * sum `spread` starts at 0. write_aov (one sample): the G-buffer's surface planes. */
kernel void material(global const int* vis_prim, int width, int height, SCENE_PARAMS(prims),
                     constant float2* srgb_encode, global const lb_t* light_buf, float ambient, global const float* ao,
                     int samples, int write_aov, global const float* camera, int has_env, int env_background, ENV_PARAMS,
                     global float* color, global float* spread, global uint* gbuffer)
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
    const EnvMaps envmaps = ENV_INIT;
    const intV pidx = as_intV(load_plane((global const uint*)vis_prim, pix0, valid, 0xffffffffu));
    intV fg = pidx >= 0;
#if VEC == 1
    fg = fg ? 1 : 0;
#endif
    const MaterialSample c = material_sample(&scene, pidx, fg, px, py, (intV)pix0 + LANES, pix0, valid, npix, width,
                                             height, light_buf, ambient, ao, srgb_encode, camera, has_env,
                                             env_background, &envmaps);
    if (write_aov) {                     /* one sample: the pixel centre's surface */
        uintV planes[GB_PLANES];
        gbuffer_background(planes);
        planes[GB_ALBEDO_PLANE] = select((uintV)0u, c.alb, as_uintV(fg) != 0u);
        planes[GB_EMISSIVE_PLANE] = select((uintV)0u, c.eo, as_uintV(fg) != 0u);
        gbuffer_store(gbuffer, npix, pix0, valid, planes);
    }
    for (int ch = 0; ch < 3; ++ch) {
        const floatV v = ch == 0 ? c.r : (ch == 1 ? c.g : c.b);
        if (valid == VEC) {
            vstoreV(v, 0, color + ch * npix + pix0);
            if (samples > 1) vstoreV((floatV)0.0f, 0, spread + ch * npix + pix0);
        } else {
            for (int l = 0; l < valid; ++l) {
                color[ch * npix + pix0 + l] = LANE_F(v, l);
                if (samples > 1) spread[ch * npix + pix0 + l] = 0.0f;
            }
        }
    }
}

#ifndef SAMPLE_RUNS
#define SAMPLE_RUNS 8    /* runs of VEC pixels per work-item in material_samples */
#endif

/* Sample s > 0: work-item i owns pixels [i·VEC·SAMPLE_RUNS, +VEC·SAMPLE_RUNS). Only the pixels whose
 * sample s sees another prim than sample 0 (or background where sample 0 does not) can change
 * the colour, and of those, a pixel whose sample s sees the prim an earlier sample t > 0 saw has
 * c_s = c_t: it adds the delta c_t - c_0 kept in `deltas` (plane t - 1; every sample but the
 * last keeps the deltas it evaluates). The rest are listed, in pixel order, and evaluated VEC
 * at a time (an edge pixel costs one lane, not the run around it); spread += c_s - c_0 for each,
 * in sample order, so the sum is the one every sample evaluated would give, bit for bit. At the
 * last sample every pixel of the block resolves: color = c_0 + spread / samples. */
kernel void material_samples(global const int* vis_prims, int width, int height,
                             SCENE_PARAMS(prims), constant float2* srgb_encode, global const lb_t* light_buf,
                             float ambient, global const float* ao, int sample, int samples,
                             global const float* camera, int has_env, int env_background, ENV_PARAMS,
                             global float* color, global float* spread, global float* deltas)
{
    const int npix = width * height;
    const int b0 = get_global_id(0) * (VEC * SAMPLE_RUNS);
    if (b0 >= npix) return;
    const int b1 = min(b0 + VEC * SAMPLE_RUNS, npix);
    global const int* vis_prim = vis_prims + sample * npix;
    global const int* vis_prim0 = vis_prims;
    global float* keep = sample < samples - 1 ? deltas + (sample - 1) * 3 * npix : 0;   /* this sample's deltas */
    int list[VEC * SAMPLE_RUNS], list_x[VEC * SAMPLE_RUNS], list_y[VEC * SAMPLE_RUNS];  /* pixel, column, row */
    int n = 0;
    for (int p = b0, x = b0 % width, y = b0 / width; p < b1; ++p) {
        const int v = vis_prim[p];
        if (v != vis_prim0[p]) {
            int seen = 0;                        /* the first earlier sample t > 0 with this prim */
            for (int t = 1; t < sample && !seen; ++t)
                if (vis_prims[t * npix + p] == v) seen = t;
            if (seen) {
                global const float* d = deltas + (seen - 1) * 3 * npix;
                for (int ch = 0; ch < 3; ++ch) spread[ch * npix + p] = spread[ch * npix + p] + d[ch * npix + p];
            } else {
                list[n] = p; list_x[n] = x; list_y[n] = y;
                ++n;
            }
        }
        if (++x == width) { x = 0; ++y; }
    }
    const SceneV scene = SCENE_INIT(prims);
    const EnvMaps envmaps = ENV_INIT;
    for (int k = 0; k < n; k += VEC) {
        const int m = min(VEC, n - k);
        intV pix, px, py;
        for (int l = 0; l < VEC; ++l) {
            const int j = k + min(l, m - 1);
            LANE_I(pix, l) = list[j]; LANE_I(px, l) = list_x[j]; LANE_I(py, l) = list_y[j];
        }
        const intV pidx = GATHER_I(vis_prim, pix);
        intV fg = pidx >= 0;
#if VEC == 1
        fg = fg ? 1 : 0;
#endif
        const MaterialSample c = material_sample(&scene, pidx, fg, px, py, pix, -1, m, npix, width, height,
                                                 light_buf, ambient, ao, srgb_encode, camera, has_env,
                                                 env_background, &envmaps);
        for (int ch = 0; ch < 3; ++ch) {
            const floatV v = ch == 0 ? c.r : (ch == 1 ? c.g : c.b);
            for (int l = 0; l < m; ++l) {
                const int q = ch * npix + LANE_I(pix, l);
                const float d = LANE_F(v, l) - color[q];
                spread[q] = spread[q] + d;
                if (keep) keep[q] = d;
            }
        }
    }
    if (sample == samples - 1) {
        for (int ch = 0; ch < 3; ++ch)
            for (int p = b0; p < b1; ++p)
                color[ch * npix + p] = color[ch * npix + p] + spread[ch * npix + p] * (1.0f / (float)samples);
    }
}
