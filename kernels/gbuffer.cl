/* gbuffer.cl: resolve the visibility buffer into the packed G-buffer.
 *
 * Algorithm: one work-item per pixel. The winning prim's edge functions at the pixel center
 * (and its right and lower neighbours) give perspective-correct barycentrics in the input
 * triangle and their screen derivatives; from them: the interpolated world normal (flipped on
 * visible back faces), UVs and a trilinear base-color sample (LOD from the derivatives),
 * the material's specular terms, linear depth = view depth / far, and the screen-space motion
 * against the previous frame's view-projection. Everything is packed per the layout table
 * (clrender/gbuffer.py, kernels/gbuffer.h).
 *
 * Buffers: vis_depth float[W·H], vis_prim int[W·H]; prims Prim[*]; scene positions/normals
 *          float[3V], uvs float[2V], triangles int[3T], materials Material[M]; textures;
 *          prev_view_proj float[16]. out: gbuffer uint[GB_PLANES][H][W].
 * Work-groups: 1-D over pixels, any size; no barriers.
 */
#pragma OPENCL FP_CONTRACT OFF
#include "surface.h"
#include "gbuffer.h"

static inline float3 vload_vec3(global const float* a, int i) { return vload3(i, a); }

kernel void gbuffer_resolve(global const float* vis_depth, global const int* vis_prim,
                            global const Prim* prims, int width, int height, float far,
                            global const float* positions, global const float* normals,
                            global const float* uvs, global const int* triangles,
                            global const Material* materials,
                            global const uint* texels, constant float* srgb_lut, constant float* srgb_bounds,
                            global const TexInfo* tex_infos, global const TexLevel* tex_levels,
                            global const float* prev_view_proj, int has_prev,
                            global uint* gbuffer)
{
    const int pix = get_global_id(0);
    const int npix = width * height;
    if (pix >= npix) return;
    const int px = pix % width, py = pix / width;
    uint planes[GB_PLANES];
    for (int i = 0; i < GB_PLANES; ++i) planes[i] = 0u;

    const int prim_index = vis_prim[pix];
    if (prim_index < 0) {
        GB_PUT(planes, LINEAR_DEPTH, as_uint(INFINITY));
        GB_PUT(planes, TRIANGLE_ID, 0xffffffffu);
    } else {
        const Prim p = prims[prim_index];
        const Material m = materials[p.material];
        const Textures tx = { texels, srgb_lut, tex_infos, tex_levels };
        float3 b, b_dx, b_dy;
        prim_barycentrics_with_derivatives(&p, px, py, &b, &b_dx, &b_dy);
        const int i0 = triangles[3 * p.tri], i1 = triangles[3 * p.tri + 1], i2 = triangles[3 * p.tri + 2];

        float3 n = b.x * vload_vec3(normals, i0) + b.y * vload_vec3(normals, i1) + b.z * vload_vec3(normals, i2);
        float3 p0 = vload_vec3(positions, i0), p1 = vload_vec3(positions, i1), p2 = vload_vec3(positions, i2);
        if (!(dot(n, n) > 1e-20f)) n = cross(p1 - p0, p2 - p0);      /* no usable vertex normal */
        if (!(dot(n, n) > 0.0f)) n = (float3)(0.0f, 0.0f, 1.0f);
        n = normalize(n);
        if (p.flags & PRIM_BACKFACE) n = -n;

        float4 color = vload4(0, m.base_color);
        if (m.texture >= 0) {
            float2 uv = interp_uv(uvs, triangles, p.tri, b);
            float2 uv_dx = interp_uv(uvs, triangles, p.tri, b + b_dx) - uv;
            float2 uv_dy = interp_uv(uvs, triangles, p.tri, b + b_dy) - uv;
            color *= sample_trilinear(texels, srgb_lut, tex_infos, tex_levels, m.texture, uv, uv_dx, uv_dy);
        }

        float2 velocity = (float2)(0.0f, 0.0f);
        if (has_prev) {
            float3 wp = b.x * p0 + b.y * p1 + b.z * p2;
            global const float* M = prev_view_proj;
            float cx = M[0] * wp.x + M[1] * wp.y + M[2] * wp.z + M[3];
            float cy = M[4] * wp.x + M[5] * wp.y + M[6] * wp.z + M[7];
            float cw = M[12] * wp.x + M[13] * wp.y + M[14] * wp.z + M[15];
            if (cw > 0.0f) {
                float2 prev = (float2)((cx / cw + 1.0f) * 0.5f * (float)width, (1.0f - cy / cw) * 0.5f * (float)height);
                velocity = (float2)((float)px + 0.5f, (float)py + 0.5f) - prev;
            }
        }

        GB_PUT(planes, ALBEDO, pack_srgb8x3(color.xyz, srgb_bounds));
        GB_PUT(planes, SPECULAR_INTENSITY, pack_unorm8(m.spec_intensity));
        GB_PUT(planes, LINEAR_DEPTH, as_uint(vis_depth[pix] / far));
        GB_PUT(planes, NORMAL, pack_oct12x2(n));
        GB_PUT(planes, SPECULAR_POWER, pack_log2unorm8(m.spec_power));
        GB_PUT(planes, VELOCITY, pack_half2(velocity));
        GB_PUT(planes, TRIANGLE_ID, (uint)p.tri);
    }
    for (int i = 0; i < GB_PLANES; ++i) gbuffer[i * npix + pix] = planes[i];
}
