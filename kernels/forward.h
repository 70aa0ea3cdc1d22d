/* forward.h: forward shading and blending of one transparent fragment (docs/transparency.md),
 * shared by the A-buffer resolve (abuffer.cl) and depth peeling (peel.cl), so both give the
 * same bits for the same fragment.
 *
 * shade_fragment(): the fragment of prim `pi` at pixel (px, py) and view depth z is evaluated
 * unquantized (no G-buffer packing): perspective-correct barycentrics of the pixel center, the
 * interpolated vertex normal (geometric where that degenerates; flipped on back faces), the
 * base color (factor × trilinear texture; alpha includes the material's opacity), the
 * material's specular terms, and P = eye + z·dir(pixel) on the pixel's view ray as shade.cl
 * rebuilds it. Lit by lighting.h with the lights of the pixel's light-culling tile (the
 * report's light-indexed lists consumed by a forward pass), no SSAO:
 *     c = albedo·(ambient + diffuse) + specular.
 * blend_under(): front to back, acc += T·alpha·c, T *= 1 - alpha.
 *
 * Requires VEC == 1 (one pixel per work-item): fragments of neighbouring pixels belong to
 * different prims and lists of different lengths.
 * Kernel arguments: FORWARD_PARAMS below, in that order (clrender/passes/forward.py).
 */
#ifndef CLRENDER_FORWARD_H
#define CLRENDER_FORWARD_H
#if VEC != 1
#error "forward.h shades one pixel per work-item: build with VEC=1"
#endif
#include "surface.h"
#include "lighting.h"

#ifndef LIGHT_TILE
#define LIGHT_TILE 32             /* light-culling tile side (RenderConfig.light_tile_size) */
#endif
#ifndef TRANSMITTANCE_EPSILON
#define TRANSMITTANCE_EPSILON 1e-4f   /* fragments behind T < epsilon are not shaded */
#endif

#define FORWARD_PARAMS \
    global const Prim* prims, global const float* positions, global const float* normals, \
    global const float* uvs, global const int* triangles, global const Material* materials, \
    global const uint* texels, constant float* srgb_lut, global const TexInfo* tex_infos, \
    global const TexLevel* tex_levels, global const float* camera, int width, int height, float ambient, \
    global const Light* lights, int n_lights, global const int* tile_light_offsets, \
    global const int* tile_light_counts, global const int* tile_lights, int list_capacity, int light_tiles_x, \
    global const float* shadow_atlas, int atlas_stride, global const ShadowView* shadow_views, \
    float shadow_bias, float shadow_slope_bias, float shadow_normal_offset, \
    int has_sun, global const float* sun, int sun_cascades, int spot_view0, int spot_plane0

typedef struct {
    global const Prim* prims;
    global const float* positions;
    global const float* normals;
    global const float* uvs;
    global const int* triangles;
    global const Material* materials;
    Textures tx;
    global const float* camera;       /* eye, F, R·tan_x, U·tan_y (float4 each) */
    int width, height;
    float ambient;
    int n_lights;
    global const int* tile_light_offsets;
    global const int* tile_light_counts;
    int list_capacity, light_tiles_x;
    LightEnv env;
} Forward;

#if SHADOWS
#define FORWARD_ENV_SHADOWS , { shadow_atlas, atlas_stride, shadow_bias, shadow_slope_bias, shadow_normal_offset }, \
                            shadow_views, sun_cascades, spot_view0, spot_plane0
#else
#define FORWARD_ENV_SHADOWS
#endif
/* A `Forward` from FORWARD_PARAMS. */
#define FORWARD_INIT { prims, positions, normals, uvs, triangles, materials, \
                       { texels, srgb_lut, tex_infos, tex_levels }, camera, width, height, ambient, n_lights, \
                       tile_light_offsets, tile_light_counts, list_capacity, light_tiles_x, \
                       { lights, tile_lights, has_sun, sun FORWARD_ENV_SHADOWS } }

typedef struct {
    float3 color;      /* albedo·(ambient + diffuse) + specular, linear HDR */
    float alpha;
    float2 offset;     /* refraction: displacement of the lookup behind, pixels (x right, y down) */
} Fragment;

static inline float3 vertex_attr3(global const float* a, int i) { return vload3(i, a); }

static Fragment shade_fragment(const Forward* f, int pi, float z, int px, int py)
{
    const Prim p = f->prims[pi];
    const Material m = f->materials[p.material];
    /* Barycentrics at the pixel and its right and lower neighbours: normal, UVs and texture LOD. */
    float3 b, b_dx, b_dy;
    prim_barycentrics_with_derivatives(&p, px, py, &b, &b_dx, &b_dy);
    float4 base = vload4(0, m.base_color);
    if (m.texture >= 0) {
        const float2 uv = interp_uv(f->uvs, f->triangles, p.tri, b);
        base *= sample_trilinear(f->tx.texels, f->tx.srgb_lut, f->tx.infos, f->tx.levels, m.texture, uv,
                                 interp_uv(f->uvs, f->triangles, p.tri, b + b_dx) - uv,
                                 interp_uv(f->uvs, f->triangles, p.tri, b + b_dy) - uv);
    }
    const int i0 = f->triangles[3 * p.tri], i1 = f->triangles[3 * p.tri + 1], i2 = f->triangles[3 * p.tri + 2];
    float3 n = b.x * vertex_attr3(f->normals, i0) + b.y * vertex_attr3(f->normals, i1)
             + b.z * vertex_attr3(f->normals, i2);
    if (!(dot(n, n) > 1e-20f)) {
        const float3 p0 = vertex_attr3(f->positions, i0);
        n = cross(vertex_attr3(f->positions, i1) - p0, vertex_attr3(f->positions, i2) - p0);
    }
    const float len2 = dot(n, n);
    n = len2 > 0.0f ? n * rsqrt(len2) : (float3)(0.0f, 0.0f, 1.0f);
    if (p.flags & PRIM_BACKFACE) n = -n;

    const float3 eye = vload4(0, f->camera).xyz, F = vload4(1, f->camera).xyz;
    const float3 Rs = vload4(2, f->camera).xyz, Us = vload4(3, f->camera).xyz;
    const float xn = ((float)px + 0.5f) * (2.0f / (float)f->width) - 1.0f;
    const float yn = 1.0f - ((float)py + 0.5f) * (2.0f / (float)f->height);
    const float3 dir = F + xn * Rs + yn * Us;
    const float3 P = eye + z * dir;
    const float3 V = -dir * rsqrt(dot(dir, dir));

#if BRUTE_FORCE
    const int first = 0, count = f->n_lights;
#else
    const int tile = (py / LIGHT_TILE) * f->light_tiles_x + px / LIGHT_TILE;
    const int first = f->tile_light_offsets[tile];
    const int count = max(min(f->tile_light_counts[tile], f->list_capacity - first), 0);
#endif
    float dr = 0.0f, dg = 0.0f, db = 0.0f, sr = 0.0f, sg = 0.0f, sb = 0.0f;
    accumulate_lights(&f->env, first, count, 1, P.x, P.y, P.z, n.x, n.y, n.z, V.x, V.y, V.z,
                      m.spec_intensity, m.spec_power, z, px, py, 0, 0, 1, 0, &dr, &dg, &db, &sr, &sg, &sb);
    Fragment out;
    out.color = (float3)(base.x * (f->ambient + dr) + sr, base.y * (f->ambient + dg) + sg,
                         base.z * (f->ambient + db) + sb);
    out.alpha = clamp(base.w, 0.0f, 1.0f);
    out.offset = (float2)(0.0f, 0.0f);
    if (m.refraction > 0.0f) {    /* view-space normal (x right, y up) -> screen displacement, y down */
        const float nx = dot(n, normalize(Rs)), ny = dot(n, normalize(Us));
        out.offset = (float2)(nx, -ny) * (m.refraction * (float)f->height);
    }
    return out;
}

/* Front-to-back "under" blending: acc.xyz += T·alpha·c, acc.w = T *= 1 - alpha. */
static inline float4 blend_under(float4 acc, Fragment fr)
{
    const float t_alpha = acc.w * fr.alpha;
    return (float4)(acc.x + t_alpha * fr.color.x, acc.y + t_alpha * fr.color.y, acc.z + t_alpha * fr.color.z,
                    acc.w * (1.0f - fr.alpha));
}

/* Stores the blended layers of pixel p: acc planes, transmittance, refraction offset. */
static inline void store_layers(global float* layers, int npix, int p, float4 acc, float2 offset)
{
    layers[p] = acc.x;
    layers[npix + p] = acc.y;
    layers[2 * npix + p] = acc.z;
    layers[3 * npix + p] = acc.w;
    layers[4 * npix + p] = offset.x;
    layers[5 * npix + p] = offset.y;
}
#endif
