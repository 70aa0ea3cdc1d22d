/* surface_layers.cl: the glTF surface layers (KHR_materials_ior, _specular, _clearcoat, _sheen,
 * _iridescence, _anisotropy, _diffuse_transmission; docs/shading.md "Surface layers"), shaded after the pipeline's
 * opaque pass over the pixels whose material has layers; every other pixel keeps its colour.
 *
 * Algorithm: the visibility buffer already names each pixel's prim, so the surface is rebuilt
 * from it: in the deferred pipeline (FROM_GBUFFER) the G-buffer's base colour, metallic,
 * roughness, normal, emission and occlusion, as shade.cl decodes them, plus the prim's
 * barycentrics; in the others, whose thin G-buffers lack some of these, surface_vec.h's
 * evaluation (the resolve's own code, unquantized). The layer parameters are read from the
 * material's MaterialExt record and its layer textures here, at shading time: the G-buffer is not
 * widened and a scene without layers runs (and builds) none of this. Per lane, layered_brdf.h's
 * model: each light of the pixel's light-culling tile (the same list, falloff, spot cone and
 * shadow-map visibility as lighting.h), the sun and its cascades, then the ambient term (the
 * environment's split-sum lookups, or the constant ambient) times occlusion and SSAO, and the
 * emission under the clearcoat:  colour = Σ lights + ambient + emission·(1 − cc·Fc).
 * The pixel's colour plane values are replaced on those lanes only.
 * sheen_albedo_lut: the sheen's directional albedo table E(µ, roughness) (layered_brdf.h), made
 * once per device by one work-item per entry.
 *
 * Buffers: vis_prim int[W·H], vis_depth float[W·H] (view depth) (the pipeline's final raster);
 *          the scene (SCENE_PARAMS); material_ext MaterialExt[]; camera float[16]; lights,
 *          tile lists, shadow atlas and views, sun: as shade.cl; ao float[W·H] (read if SSAO);
 *          has_env, env_background (unused: the background keeps its colour), ENV_PARAMS (read if
 *          has_env); sheen_lut float[SHEEN_LUT_SIZE²]; gbuffer uint[GB_PLANES][W·H] (read if
 *          FROM_GBUFFER), far.
 *          in/out: color float[3][W·H].
 * Work-groups: (LTILE/VEC, LTILE) over light tiles (a run of VEC pixels lies in one tile), as
 *          shade.cl; no barriers.
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
#ifndef MULTISCATTER
#define MULTISCATTER 0     /* RenderConfig.multiscatter: Fdez-Agüera's energy compensation (ambient) */
#endif
#ifndef FROM_GBUFFER
#define FROM_GBUFFER 0     /* 1 (deferred): base colour, metallic, roughness, normal, emission and occlusion
                              from the G-buffer, as shade.cl reads them; 0: evaluated again from the prim */
#endif
#include "lighting.h"
#include "gbuffer_decode.h"
#include "ambient.h"
#include "layer_shading.h"
#include "sheen_table.h"        /* kernel sheen_albedo_lut */

kernel __attribute__((reqd_work_group_size(LTILE / VEC, LTILE, 1)))
void surface_layers(global const int* vis_prim, global const float* vis_depth, int width, int height,
            SCENE_PARAMS(prims), global const MaterialExt* material_ext, int has_tangents,
            global const float* camera, global const Light* lights, int n_lights, float ambient, global const float* ao,
            global const int* tile_light_offsets, global const int* tile_light_counts,
            global const int* tile_lights, int list_capacity, int tiles_x,
            global const float* shadow_atlas, int atlas_stride, global const ShadowView* shadow_views,
            float shadow_bias, float shadow_slope_bias, float shadow_normal_offset,
            int has_sun, global const float* sun, int sun_cascades, int spot_view0, int spot_plane0,
            int has_env, int env_background, ENV_PARAMS, global const float* sheen_lut,
            global const uint* gbuffer, float far, global float* color)
{
    const int px0 = get_global_id(0) * VEC, py = get_global_id(1);
    if (py >= height || px0 >= width) return;
    const int npix = width * height;
    const int p0 = py * width + px0;
    const int valid = min(VEC, width - px0);
    const int tile = get_group_id(1) * tiles_x + get_group_id(0);

    const intV pidx = as_intV(load_plane((global const uint*)vis_prim, p0, valid, 0xffffffffu));
    intV fg = pidx >= 0;
#if VEC == 1
    fg = fg ? 1 : 0;
#endif
    if (!ANY(fg)) return;
    const intV w = select((intV)0, pidx, fg);
    const intV ext = select((intV)-1, GATHER_MS(intV, materials, GATHER_MS(intV, prims, w, material), ext), fg);
    intV on = ext >= 0;
#if VEC == 1
    on = on ? 1 : 0;
#endif
    if (!ANY(on)) return;                       /* most runs of a mixed scene */

    const SceneV scene = SCENE_INIT(prims);
    const intV px = px0 + LANES;
    BaryV bary;
#if FROM_GBUFFER
    /* The G-buffer's surface (the resolve evaluated the material there): only the barycentrics
     * for the layer textures and the geometric frame are rebuilt. */
    SurfaceV sf;
    prim_geometry(&scene, select((intV)0, w, on), on, px, (intV)py, &sf, &bary);
    const LitPointV lp = decode_lit_point(load_plane(gbuffer + GB_NORMAL_PLANE * npix, p0, valid, 0u),
                                          load_plane(gbuffer + GB_LINEAR_DEPTH_PLANE * npix, p0, valid, 0u), on,
                                          far, on);
    sf.n.x = lp.nx; sf.n.y = lp.ny; sf.n.z = lp.nz;
    sf.spec_p = lp.spec_p;
    decode_albedo(load_plane(gbuffer + GB_ALBEDO_PLANE * npix, p0, valid, 0u), srgb_lut, &sf.r, &sf.g, &sf.b,
                  &sf.spec_i);
    const uintV eo = load_plane(gbuffer + GB_EMISSIVE_PLANE * npix, p0, valid, 0u), e = eo >> GB_EMISSIVE_SHIFT;
    sf.er = GATHER_F(srgb_lut, as_intV(e & 255u));
    sf.eg = GATHER_F(srgb_lut, as_intV((e >> 8) & 255u));
    sf.eb = GATHER_F(srgb_lut, as_intV((e >> 16) & 255u));
    sf.occlusion = convert_floatV((eo >> GB_OCCLUSION_SHIFT) & 255u) * (1.0f / 255.0f);
#else
    const SurfaceV sf = surface_bary_at(&scene, select((intV)0, w, on), on, px, (intV)py, &bary);
#endif
    const floatV z = as_floatV(load_plane((global const uint*)vis_depth, p0, valid, 0u));
    const ViewPointV vp = view_point(camera, width, height, px0, py, select((floatV)0.0f, z, on));
    const vec3V v = { vp.vx, vp.vy, vp.vz };
    const int2 range = tile_light_range(tile_light_offsets, tile_light_counts, list_capacity, tile, n_lights);
    const LightEnv env = LIGHT_ENV_INIT;
#if SSAO
    const floatV ao_v = as_floatV(load_plane((global const uint*)ao, p0, valid, 0u));
#else
    const floatV ao_v = 1.0f;
#endif
    const EnvMaps envmaps = ENV_INIT;
    floatV cr, cg, cb;
    shade_layered(&scene, &bary, &sf, material_ext, ext, on, has_tangents, sheen_lut, &env, range.x, range.y,
                  vp.px, vp.py, vp.pz, z, v, px, py, has_env, &envmaps, ambient, ao_v, 1.0f, MULTISCATTER, &cr,
                  &cg, &cb);     /* diffuse weight 1: opaque pixels have no KHR_materials_transmission */

    for (int c = 0; c < 3; ++c) {
        global float* plane = color + c * npix;
        const floatV v_new = c == 0 ? cr : (c == 1 ? cg : cb);
        for (int l = 0; l < valid; ++l)
            if (LANE_I(on, l)) plane[p0 + l] = LANE_F(v_new, l);
    }
}
