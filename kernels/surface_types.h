/* surface_types.h: the types and small helpers a surface evaluation at VEC lanes shares between
 * surface_vec.h (surface_at) and material_eval.h (evaluate_material): vec3V, the scene buffers
 * (SceneV, SCENE_PARAMS/SCENE_INIT), the barycentrics (BaryV) and the surface (SurfaceV). In their
 * own header so the two include it and neither includes the other (no include circle).
 */
#ifndef CLRENDER_SURFACE_TYPES_H
#define CLRENDER_SURFACE_TYPES_H
#include "structs.h"
#include "vec.h"
#include "texture_vec.h"       /* VINLINE */

typedef struct { floatV x, y, z; } vec3V;

static inline floatV dot3V(vec3V a, vec3V b) { return a.x * b.x + a.y * b.y + a.z * b.z; }

/* Gathers a float3 attribute of vertex idx[l] for every lane. */
static inline VINLINE vec3V gather3(global const float* a, intV idx)
{
    intV i3 = idx * 3;
    vec3V r = { GATHER_FS(a, i3), GATHER_FS(a, i3 + 1), GATHER_FS(a, i3 + 2) };
    return r;
}

static inline vec3V interp3(vec3V a, vec3V b, vec3V c, floatV b0, floatV b1, floatV b2)
{
    vec3V r = { b0 * a.x + b1 * b.x + b2 * c.x, b0 * a.y + b1 * b.y + b2 * c.y, b0 * a.z + b1 * b.z + b2 * c.z };
    return r;
}

/* The scene buffers a surface is evaluated from. */
typedef struct {
    global const Prim* prims;
    global const float* positions;
    global const float* normals;
    global const float* uvs;          /* uv sets one after another: set k of vertex i at 2 (k·n_vertices + i) */
    global const int* triangles;
    global const Material* materials;
    global const texel_t* texels;     /* the texture pool (texture_vec.h TEXELS_LINEAR) */
    constant float* srgb_lut;         /* texel decode tables (LUT_SRGB, LUT_LINEAR) */
    global const TexInfo* tex_infos;
    global const TexLevel* tex_levels;
    global const float* tangents;     /* float4 per vertex (xyz, handedness w); read by normal-mapped materials */
    global const float* colors;       /* float4 per vertex, linear RGBA; read if has_colors */
    int n_vertices;
    int has_colors;
} SceneV;

/* The kernel parameters a SceneV is built from (host: clrender/passes/base.py scene_args). */
#define SCENE_PARAMS(prims) \
    global const Prim* prims, global const float* positions, global const float* normals, \
    global const float* uvs, global const int* triangles, global const Material* materials, \
    global const texel_t* texels, constant float* srgb_lut, global const TexInfo* tex_infos, \
    global const TexLevel* tex_levels, global const float* tangents, global const float* colors, \
    int n_vertices, int has_colors
#define SCENE_INIT(prims) { prims, positions, normals, uvs, triangles, materials, texels, srgb_lut, tex_infos, \
                            tex_levels, tangents, colors, n_vertices, has_colors }

/* Perspective-correct barycentrics of the pixel centre in the input triangle and their values
 * one pixel right (x) and one pixel down (y): the screen derivatives texture LODs need. */
typedef struct {
    intV i0, i1, i2;            /* the triangle's vertex indices */
    floatV c0, c1, c2;
    floatV c1x, c2x, c1y, c2y;
} BaryV;

typedef struct {
    intV tri, flags, mat;
    intV mat_flags;             /* Material.flags (MAT_*) */
    intV i0, i1, i2;            /* the triangle's vertex indices */
    floatV c0, c1, c2;          /* barycentrics of the pixel center in the input triangle */
    vec3V n;                    /* unit shading normal (normal map applied), flipped on back faces */
    floatV r, g, b, a;          /* linear diffuse albedo (base × (1 - metallic)); alpha (docs/materials.md) */
    floatV spec_i, spec_p;
    floatV er, eg, eb;          /* emissive factor × texture, [0, 1] (before emissive_strength) */
    floatV occlusion;           /* material ambient occlusion, 1 = open */
} SurfaceV;
#endif
