/* gbuffer.cl: resolve the visibility buffer into the packed G-buffer.
 *
 * Algorithm: each work-item owns VEC consecutive pixels (see vec.h). Per lane it takes the
 * winning prim; surface_vec.h evaluates, as VEC-wide vector math, its surface there (the
 * barycentrics from the prim's edge functions at the pixel center and its right and lower
 * neighbours, the interpolated world normal flipped on visible back faces, a trilinear
 * base-color sample with the LOD from the derivatives, the material's specular terms: the
 * same code shades transparent fragments, forward.h); then linear depth = view depth / far
 * and the motion: the surface point interpolated from the previous frame's vertex positions
 * (prev_positions: the scene's own positions unless objects moved, Scene.set_transform) and
 * projected by the previous frame's view-projection. Everything is packed per
 * the layout table (clrender/gbuffer.py, kernels/gbuffer.h).
 *
 * Buffers: vis_depth float[W·H], vis_prim int[W·H]; prims Prim[*]; scene positions/normals
 *          float[3V], uvs float[2V], triangles int[3T], materials Material[M]; textures;
 *          prev_view_proj float[16], prev_positions float[3V]; srgb_lut float[256] (decode),
 *          srgb_encode float2[4096].
 *          out: gbuffer uint[GB_PLANES][H·W].
 * Work-groups: 1-D, work-item i covers pixels [i·VEC, i·VEC + VEC); no barriers.
 */
#pragma OPENCL FP_CONTRACT OFF
#include "structs.h"
#include "gbuffer.h"
#include "vec.h"

#include "surface_vec.h"

kernel void gbuffer_resolve(global const float* vis_depth, global const int* vis_prim,
                            global const Prim* prims, int width, int height, float far,
                            global const float* positions, global const float* normals,
                            global const float* uvs, global const int* triangles,
                            global const Material* materials,
                            global const uint* texels, constant float* srgb_lut, constant float2* srgb_encode,
                            global const TexInfo* tex_infos, global const TexLevel* tex_levels,
                            global const float* prev_view_proj, global const float* prev_positions, int has_prev,
                            global uint* gbuffer)
{
    const int npix = width * height;
    const int pix0 = get_global_id(0) * VEC;
    if (pix0 >= npix) return;

    /* Gather the winning prims (vector gathers over the Prim array seen as 32-bit words;
     * background lanes read prim 0 and are masked out). */
    intV px, py;
    int cx = pix0 % width, cy = pix0 / width;
    for (int l = 0; l < VEC; ++l) {
        LANE_I(px, l) = cx; LANE_I(py, l) = cy;
        if (++cx == width) { cx = 0; ++cy; }
    }
    const int valid = min(VEC, npix - pix0);
    intV pidx;
    floatV depth;
    if (valid == VEC) {
        pidx = vloadV(0, vis_prim + pix0);
        depth = vloadV(0, vis_depth + pix0);
    } else {
        pidx = -1; depth = INFINITY;
        for (int l = 0; l < valid; ++l) { LANE_I(pidx, l) = vis_prim[pix0 + l]; LANE_F(depth, l) = vis_depth[pix0 + l]; }
    }
    intV fg = pidx >= 0;
#if VEC == 1
    fg = fg ? 1 : 0;
#endif
    intV w = select((intV)0, pidx, fg);
    uintV planes[GB_PLANES];            /* background unless a lane has a prim */
    for (int i = 0; i < GB_PLANES; ++i) planes[i] = 0;
    GB_PUT(planes, LINEAR_DEPTH, as_uintV((floatV)INFINITY));
    GB_PUT(planes, TRIANGLE_ID, (uintV)0xffffffffu);
    if (ANY(fg)) {
        const SceneV scene = { prims, positions, normals, uvs, triangles, materials, texels, srgb_lut,
                               tex_infos, tex_levels };
        const SurfaceV sf = surface_at(&scene, w, fg, px, py);
        const floatV c0 = sf.c0, c1 = sf.c1, c2 = sf.c2;
        const intV i0 = sf.i0, i1 = sf.i1, i2 = sf.i2, tri = sf.tri;
        const vec3V n = sf.n;
        const floatV cr = sf.r, cg = sf.g, cb = sf.b, spec_i = sf.spec_i, spec_p = sf.spec_p;

        floatV vx = 0.0f, vy = 0.0f;
        if (has_prev) {
            vec3V wp = interp3(gather3(prev_positions, i0), gather3(prev_positions, i1), gather3(prev_positions, i2),
                               c0, c1, c2);
            global const float* M = prev_view_proj;
            floatV qx = M[0] * wp.x + M[1] * wp.y + M[2] * wp.z + M[3];
            floatV qy = M[4] * wp.x + M[5] * wp.y + M[6] * wp.z + M[7];
            floatV qw = M[12] * wp.x + M[13] * wp.y + M[14] * wp.z + M[15];
            intV ahead = qw > 0.0f;
            floatV prev_x = (qx / qw + 1.0f) * 0.5f * (float)width, prev_y = (1.0f - qy / qw) * 0.5f * (float)height;
            vx = select((floatV)0.0f, convert_floatV(px) + 0.5f - prev_x, ahead);
            vy = select((floatV)0.0f, convert_floatV(py) + 0.5f - prev_y, ahead);
        }
        uintV vel = pack_half2V(vx, vy);

        uintV ufg = as_uintV(fg);
#if VEC == 1
        ufg = fg ? 0xffffffffu : 0u;
#endif
        uintV planes_fg[GB_PLANES];
        for (int i = 0; i < GB_PLANES; ++i) planes_fg[i] = 0;
        GB_PUT(planes_fg, ALBEDO, pack_srgb8x3V(cr, cg, cb, srgb_encode));
        GB_PUT(planes_fg, SPECULAR_INTENSITY, unormV(spec_i, 8));
        GB_PUT(planes_fg, LINEAR_DEPTH, as_uintV(depth / far));
        GB_PUT(planes_fg, NORMAL, pack_oct12x2V(n.x, n.y, n.z));
        GB_PUT(planes_fg, SPECULAR_POWER, pack_log2unorm8V(spec_p));
        GB_PUT(planes_fg, VELOCITY, vel);
        GB_PUT(planes_fg, TRIANGLE_ID, as_uintV(tri));
        for (int i = 0; i < GB_PLANES; ++i) planes[i] = select(planes[i], planes_fg[i], ufg);
    }
    for (int i = 0; i < GB_PLANES; ++i) {
        global uint* dst = gbuffer + i * npix + pix0;
        if (pix0 + VEC <= npix) {
            vstoreV(planes[i], 0, dst);
        } else {
            for (int l = 0; l < VEC && pix0 + l < npix; ++l) dst[l] = (uint)LANE_I(planes[i], l);
        }
    }
}
