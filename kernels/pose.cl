/* pose.cl: the vertex pre-pass of skinned and morphing meshes (host side: clrender/passes/pose.py;
 * the rules: clrender/scene/deform.py, glTF 2.0 §3.7.2.2 and §3.7.3).
 *
 * Algorithm, two kernels:
 * `morph_targets`: one work-item per vertex of a mesh with morph targets: p = p0 + sum_t w_t dP_t
 *   (normals and tangent xyz alike, targets with weight 0 skipped), written to the `morphed`
 *   arrays (which hold the bind attributes for every other vertex), and the positions again with
 *   the previous weights when PREVIOUS. Its loop over targets has a data-dependent trip count, so it
 *   is kept out of the skinning kernel, whose work-item loop PoCL can then vectorize.
 * `skin_vertices`: one work-item per deformed vertex: linear blend skinning M = sum_k w_k J[j_k]
 *   over INFLUENCES slots (3x4 joint matrices as float4 rows; padding slots weigh 0), position
 *   M (p, 1), normal normalize(sign(det) cof(M) n) = normalize(M^-T n) without an inverse, tangent
 *   normalize(M t.xyz) with w kept (times sign(det) for a rigid deformer: a node transform, as
 *   static meshes do). A zero-length normal keeps the (morphed) bind one; a zero tangent stays
 *   zero. PREVIOUS: the same position at t - dt with the previous palette (velocity AOV).
 * No barrier, no local memory: results do not depend on the work-group size.
 *
 * Buffers: morphed_pos, morphed_prev_pos, morphed_nrm float[3N], morphed_tan float[4N] (the bind
 *          attributes, morphed where a mesh has targets); morph_vertex int[MV] (indices into N),
 *          vertex_deformer int[N]; deformers int[DEF_INTS·D] (DEF_* below); bind_pos, bind_nrm
 *          float[3N], bind_tan float[4N]; deltas float[3·M] for positions, normals, tangents
 *          (deformer d, target t, local vertex v at delta_offset + t·count + v); joints int[K·N]
 *          palette slots, weights float[K·N] (vertex-major, K = INFLUENCES); palette, prev_palette
 *          float4[3P]; morph_weights, prev_morph_weights float[W]; out positions, normals,
 *          prev_positions float[3V], tangents float[4V] (the scene's, at scene_first + v), and
 *          last_pose float[3N] (the positions again, compact: a frame sequence's next previous ones).
 * Work-groups: 1-D, POSE_WG work-items, global size rounded up (ids past the count return).
 */
#pragma OPENCL FP_CONTRACT OFF

#ifndef POSE_WG
#define POSE_WG 64
#endif
#ifndef INFLUENCES
#define INFLUENCES 4           /* joint slots per vertex (the scene's most; padding slots weigh 0) */
#endif
#ifndef TANGENTS
#define TANGENTS 1             /* the scene has tangents: write them */
#endif
#ifndef PREVIOUS
#define PREVIOUS 1             /* write the previous positions (velocity AOV) */
#endif

/* deformers[] record: DEF_INTS ints per deformer (clrender/passes/pose.py builds them) */
#define DEF_INTS 8
#define DEF_SCENE_FIRST 0      /* first vertex in the scene's arrays */
#define DEF_LOCAL_FIRST 1      /* first vertex in the bind arrays */
#define DEF_COUNT 2
#define DEF_TARGETS 3
#define DEF_WEIGHT_OFFSET 4    /* first of its morph weights */
#define DEF_DELTA_OFFSET 5     /* first of its deltas (target-major) */
#define DEF_FLAGS 6
#define DEF_MORPH_POSITION 1
#define DEF_MORPH_NORMAL 2
#define DEF_MORPH_TANGENT 4
#define DEF_RIGID 16           /* a node transform (tangent w follows the determinant's sign) */

/* bind value + sum_t w_t delta_t (targets with weight 0 skipped) */
inline float3 morphed(float3 value, global const float* deltas, global const float* morph_weights,
                      global const int* def, int lv)
{
    for (int t = 0; t < def[DEF_TARGETS]; t++) {
        const float w = morph_weights[def[DEF_WEIGHT_OFFSET] + t];
        if (w != 0.0f)
            value += w * vload3(def[DEF_DELTA_OFFSET] + t * def[DEF_COUNT] + lv, deltas);
    }
    return value;
}

kernel __attribute__((reqd_work_group_size(POSE_WG, 1, 1)))
void morph_targets(int n, global const int* morph_vertex, global const int* vertex_deformer,
                   global const int* deformers, global const float* bind_pos, global const float* bind_nrm,
                   global const float* bind_tan, global const float* delta_pos, global const float* delta_nrm,
                   global const float* delta_tan, global const float* morph_weights,
                   global const float* prev_morph_weights, global float* morphed_pos, global float* morphed_nrm,
                   global float* morphed_tan, global float* morphed_prev_pos)
{
    const int k = get_global_id(0);
    if (k >= n)
        return;
    const int i = morph_vertex[k];
    global const int* def = deformers + DEF_INTS * vertex_deformer[i];
    const int lv = i - def[DEF_LOCAL_FIRST];
    const int flags = def[DEF_FLAGS];
    if (flags & DEF_MORPH_POSITION) {
        vstore3(morphed(vload3(i, bind_pos), delta_pos, morph_weights, def, lv), i, morphed_pos);
#if PREVIOUS
        vstore3(morphed(vload3(i, bind_pos), delta_pos, prev_morph_weights, def, lv), i, morphed_prev_pos);
#endif
    }
    if (flags & DEF_MORPH_NORMAL)
        vstore3(morphed(vload3(i, bind_nrm), delta_nrm, morph_weights, def, lv), i, morphed_nrm);
#if TANGENTS
    if (flags & DEF_MORPH_TANGENT) {
        const float4 t = vload4(i, bind_tan);
        vstore4((float4)(morphed(t.xyz, delta_tan, morph_weights, def, lv), t.w), i, morphed_tan);
    }
#endif
}

/* the vertex's blended 3x4 matrix, rows r[0..2]: every slot read, no branch */
inline void blend_matrix(global const float4* palette, global const int* joints, global const float* weights,
                         int i, float4 r[3])
{
    r[0] = r[1] = r[2] = (float4)(0.0f);
    for (int j = 0; j < INFLUENCES; j++) {
        const float w = weights[i * INFLUENCES + j];
        const int s = 3 * joints[i * INFLUENCES + j];
        r[0] += w * palette[s];
        r[1] += w * palette[s + 1];
        r[2] += w * palette[s + 2];
    }
}

inline float3 transform_point(const float4 r[3], float3 p)
{
    return (float3)(r[0].x * p.x + r[0].y * p.y + r[0].z * p.z + r[0].w,
                    r[1].x * p.x + r[1].y * p.y + r[1].z * p.z + r[1].w,
                    r[2].x * p.x + r[2].y * p.y + r[2].z * p.z + r[2].w);
}

inline float3 transform_vector(const float4 r[3], float3 v)
{
    return (float3)(r[0].x * v.x + r[0].y * v.y + r[0].z * v.z,
                    r[1].x * v.x + r[1].y * v.y + r[1].z * v.z,
                    r[2].x * v.x + r[2].y * v.y + r[2].z * v.z);
}

kernel __attribute__((reqd_work_group_size(POSE_WG, 1, 1)))
void skin_vertices(int n, global const int* vertex_deformer, global const int* deformers,
                   global const float* morphed_pos, global const float* morphed_nrm, global const float* morphed_tan,
                   global const float* morphed_prev_pos, global const int* joints, global const float* weights,
                   global const float4* palette, global const float4* prev_palette,
                   global float* positions, global float* normals, global float* tangents,
                   global float* prev_positions, global float* last_pose)
{
    const int i = get_global_id(0);
    if (i >= n)
        return;
    global const int* def = deformers + DEF_INTS * vertex_deformer[i];
    const int out = def[DEF_SCENE_FIRST] + i - def[DEF_LOCAL_FIRST];

    float4 m[3];
    blend_matrix(palette, joints, weights, i, m);
    const float3 p = transform_point(m, vload3(i, morphed_pos));
    vstore3(p, out, positions);
    vstore3(p, i, last_pose);          /* the next frame's previous positions, when it is t + dt */

    /* M^-T n up to the factor det: the columns' cross products (cofactor matrix) */
    const float3 c0 = (float3)(m[0].x, m[1].x, m[2].x), c1 = (float3)(m[0].y, m[1].y, m[2].y),
                 c2 = (float3)(m[0].z, m[1].z, m[2].z);
    const float3 x12 = cross(c1, c2);
    const float det = dot(c0, x12);
    const float3 nb = vload3(i, morphed_nrm);
    const float3 nn = (nb.x * x12 + nb.y * cross(c2, c0) + nb.z * cross(c0, c1)) * (det < 0.0f ? -1.0f : 1.0f);
    const float nl2 = dot(nn, nn);
    vstore3(nl2 > 0.0f ? nn * (1.0f / sqrt(nl2)) : nb * (1.0f / sqrt(dot(nb, nb))), out, normals);
#if TANGENTS
    const float4 t = vload4(i, morphed_tan);
    const float3 tt = transform_vector(m, t.xyz);
    const float tl2 = dot(tt, tt);
    const float flip = (def[DEF_FLAGS] & DEF_RIGID) && det < 0.0f ? -1.0f : 1.0f;
    vstore4((float4)(tl2 > 0.0f ? tt * (1.0f / sqrt(tl2)) : (float3)(0.0f), flip * t.w), out, tangents);
#endif
#if PREVIOUS
    blend_matrix(prev_palette, joints, weights, i, m);
    vstore3(transform_point(m, vload3(i, morphed_prev_pos)), out, prev_positions);
#endif
}
