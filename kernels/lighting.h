/* lighting.h: the light loop, shared by the deferred pass (shade.cl, from the G-buffer), the
 * light pre-pass's light buffer (light_buffer.cl), the light-indexed forward pass
 * (forward_shade.cl) and the forward passes over transparent fragments (abuffer.cl, peel.cl: the
 * report's Light-Indexed idea, light lists consumed by a forward pass).
 *
 * accumulate_lights(): for surface points P (world), unit normals N, unit view vectors V and
 * the lanes' BRDF inputs m (brdf.h), walks `count` lights from `first` of the tile's list (or,
 * with BRUTE_FORCE, every light) in index order, then the sun, adding to three RGB sums D, S, T:
 *     A = (1 - (d/r)^2)^3 for d < r, else 0 (the report's falloff, Light.falloff 0), or
 *     KHR_lights_punctual's clamp(1 - (d/r)^4, 0, 1)^2 / d^2 (falloff 1) or 1/d^2 (falloff 2);
 *     S = 1, or t^2 for spots with t = clamp((dot(-L, dir) - cos_outer) / max(cos_inner - cos_outer, 1e-4), 0, 1);
 *     Blinn-Phong lanes: D += A·S·vis·color·max(N·L, 0);  S += A·S·vis·color·s·max(N·H, 0)^p where N·L > 0;
 *     glTF lanes: brdf.h's D, S, T (k = A·S·vis·color·max(N·L, 0) times the BRDF's factors).
 * The sun has no falloff: A = 1, color = the irradiance.
 * vis (SHADOWS 1): a shadowed spot's map visibility where A·S > 0; the sun's cascade picked
 * from the view depth. When `shadow_out` is not null each visibility is also written to its
 * plane (the opaque pass's Frame.shadow); fragments pass null.
 * VEC-wide (vec.h): the loop is uniform across lanes, light records are scalar loads.
 *
 * accumulate_lights_counted(): the same, for shade.cl, which also counts per lane the (pixel,
 * light) pairs it evaluates and the useful ones (docs/light_accumulation.md): a pair is useful
 * where light_reach() holds, d² < r² and, for a spot, dot(-L, dir) > cos_outer (A·S can be > 0).
 * With STENCIL (shade.cl after light_stencil.cl) the loop walks the tile's list by the bits of
 * the pixels' stencil words (bit k of word k/32: entry k reaches the pixel): a lane takes light
 * k only where its bit is set, a light no lane takes is skipped, and the distance test is not
 * made (the stencil pass made it, with light_reach() on the same position). The forward passes
 * call accumulate_lights(), which counts nothing and is built without STENCIL.
 */
#ifndef CLRENDER_LIGHTING_H
#define CLRENDER_LIGHTING_H
#include "structs.h"
#include "vec.h"
#include "brdf.h"

#ifndef BRUTE_FORCE
#define BRUTE_FORCE 0
#endif
#ifndef SHADOWS
#define SHADOWS 0
#endif
#ifndef STENCIL
#define STENCIL 0
#endif
#ifndef ORTHO
#define ORTHO 0      /* 1: orthographic camera (pixel_positions) */
#endif
#include "shadow.h"

/* What every point of a frame is lit by. */
typedef struct {
    global const Light* lights;
    global const int* tile_lights;      /* unused with BRUTE_FORCE */
    int has_sun;
    global const float* sun;            /* direction the light travels (3), linear RGB (3) */
#if SHADOWS
    ShadowParams sp;
    global const ShadowView* views;     /* sun cascades, then shadowed spots from spot_view0 */
    int sun_cascades, spot_view0, spot_plane0;
#endif
} LightEnv;

/* A LightEnv from the kernel parameters of the same names (shade.cl, light_buffer.cl,
 * forward_shade.cl, forward.h). */
#if SHADOWS
#define LIGHT_ENV_INIT { lights, tile_lights, has_sun, sun, \
                         { shadow_atlas, atlas_stride, shadow_bias, shadow_slope_bias, shadow_normal_offset }, \
                         shadow_views, sun_cascades, spot_view0, spot_plane0 }
#else
#define LIGHT_ENV_INIT { lights, tile_lights, has_sun, sun }
#endif

/* The lights a tile walks: (first, count) in its list, or every light with BRUTE_FORCE. A list
 * cut short by an overflow (the frame is redone) is read only up to the capacity. */
static inline int2 tile_light_range(global const int* tile_light_offsets, global const int* tile_light_counts,
                                    int list_capacity, int tile, int n_lights)
{
#if BRUTE_FORCE
    return (int2)(0, n_lights);
#else
    const int first = tile_light_offsets[tile];
    return (int2)(first, max(min(tile_light_counts[tile], list_capacity - first), 0));
#endif
}

/* Stores the run's `valid` lanes of v into a float plane at pixel p0. */
static inline void store_plane(global float* plane, int p0, int valid, floatV v)
{
    if (valid == VEC) {
        vstoreV(v, 0, plane + p0);
        return;
    }
    for (int l = 0; l < valid; ++l) plane[p0 + l] = LANE_F(v, l);
}

/* The view rays through the run's pixel centres (px0 + lane, py) and the world positions at
 * view depth `depth` on them (report II.3, "Question du Z"): dir = F + (x - ox)·R·tan_x +
 * (y - oy)·U·tan_y (camera = (eye, ox), (F, oy), R·tan_x, U·tan_y as float4 each; (ox, oy) the
 * principal point in NDC, 0 but for an off-centre pinhole camera), P = eye + depth·dir. shade.cl and
 * light_stencil.cl rebuild positions with this one function, so their light tests agree.
 * ORTHO (orthographic camera: tan_x, tan_y are the view box's half-extents, world units): the
 * rays are parallel, dir = F, from the eye plane: P = (eye + x·R·tan_x + y·U·tan_y) + depth·F. */
static inline void pixel_positions(global const float* camera, int width, int height, int px0, int py, floatV depth,
                                   floatV* dx, floatV* dy, floatV* dz, floatV* px, floatV* py_, floatV* pz)
{
    const float3 eye = vload4(0, camera).xyz, F = vload4(1, camera).xyz;
    const float3 Rs = vload4(2, camera).xyz, Us = vload4(3, camera).xyz;
    floatV xn = (convert_floatV(px0 + LANES) + 0.5f) * (2.0f / (float)width) - (1.0f + camera[3]);
    floatV yn = (1.0f - camera[7]) - ((float)py + 0.5f) * (2.0f / (float)height);
#if ORTHO
    *dx = F.x; *dy = F.y; *dz = F.z;
    *px = (eye.x + xn * Rs.x + yn * Us.x) + depth * F.x;
    *py_ = (eye.y + xn * Rs.y + yn * Us.y) + depth * F.y;
    *pz = (eye.z + xn * Rs.z + yn * Us.z) + depth * F.z;
#else
    *dx = F.x + xn * Rs.x + yn * Us.x; *dy = F.y + xn * Rs.y + yn * Us.y; *dz = F.z + xn * Rs.z + yn * Us.z;
    *px = eye.x + depth * *dx; *py_ = eye.y + depth * *dy; *pz = eye.z + depth * *dz;
#endif
}

/* The positions P (pixel_positions) and the unit vectors V from them to the eye. */
typedef struct { floatV px, py, pz, vx, vy, vz; } ViewPointV;

static inline ViewPointV view_point(global const float* camera, int width, int height, int px0, int py, floatV depth)
{
    ViewPointV v;
    floatV dx, dy, dz;
    pixel_positions(camera, width, height, px0, py, depth, &dx, &dy, &dz, &v.px, &v.py, &v.pz);
    const floatV inv_d = RSQRT(dx * dx + dy * dy + dz * dz);
    v.vx = -dx * inv_d; v.vy = -dy * inv_d; v.vz = -dz * inv_d;
    return v;
}

/* The run's light count (the list length) and pair counts (evaluated, useful) per pixel. */
static inline void store_light_counts(global int* light_count, global int* light_pairs, int npix, int p0, int valid,
                                      int count, intV evaluated, intV useful)
{
    if (valid == VEC) {
        vstoreV((intV)count, 0, light_count + p0);
        vstoreV(evaluated, 0, light_pairs + p0);
        vstoreV(useful, 0, light_pairs + npix + p0);
        return;
    }
    for (int l = 0; l < valid; ++l) {
        light_count[p0 + l] = count;
        light_pairs[p0 + l] = LANE_I(evaluated, l);
        light_pairs[npix + p0 + l] = LANE_I(useful, l);
    }
}

/* x^p for x in [0, ~1] (N·H) and p >= 1 (the specular power): log2 and exp2 as inline VEC-wide
 * polynomials instead of PoCL's powr, an out-of-line library call per lane that took over half of
 * the light loop. Absolute error below 1e-7 of 1 (the largest value); x below FLT_MIN or results
 * below 2^-126 give 0. Branch-free, the same bits on every device and run. */
static inline floatV spec_powV(floatV x, floatV p)
{
    /* log2 x = e + ln(m) / ln 2, m in [sqrt(1/2), sqrt(2)): ln m = 2 atanh(t), t = (m - 1) / (m + 1),
     * atanh(t) / t a cubic in t² (least-squares fit on t² <= 0.0295, error < 1e-9). */
    intV bits = as_intV(fmax(x, 1.17549435e-38f));
    intV e = (bits >> 23) - 127;
    floatV m = as_floatV((bits & 0x007fffff) | 0x3f800000);
    const intV big = m > 1.41421356f;
    m = select(m, m * 0.5f, big);
    e = select(e, e + 1, big);
    floatV t = (m - 1.0f) / (m + 1.0f), t2 = t * t;
    floatV s = 1.0f + t2 * (0.333334084f + t2 * (0.199873468f + t2 * 0.149642197f));
    floatV y = p * (convert_floatV(e) + (2.0f * t * s) * 1.44269504f);
    /* exp2 y = 2^n · 2^f, n = floor(y + 1/2) (as the truncation of y + 127.5 > 0, which is also
     * n's biased exponent), f = y - n in about [-1/2, 1/2]: a degree-6 fit of 2^f (error < 2e-9). */
    y = fmin(fmax(y, -126.0f), 1.0f);
    const intV biased = convert_intV(y + 127.5f);
    floatV f = y - (convert_floatV(biased) - 127.0f);
    floatV q = 1.0f + f * (0.693147207f + f * (0.240226512f + f * (0.0555032721f + f * (0.0096180256f
              + f * (0.00134004322f + f * 0.00015469732f)))));
    floatV r = q * as_floatV(biased << 23);
    return select(r, (floatV)0.0f, (x < 1.17549435e-38f) | (y <= -126.0f));
}

/* L = light position - P (not normalized) and d² = |L|²: the arithmetic every test of a
 * light's reach makes (shade.cl, light_stencil.cl), so their answers agree bit for bit. */
static inline floatV light_vector(const Light* lt, floatV px, floatV py_, floatV pz,
                                  floatV* lx, floatV* ly, floatV* lz)
{
    *lx = lt->position[0] - px; *ly = lt->position[1] - py_; *lz = lt->position[2] - pz;
    return *lx * *lx + *ly * *ly + *lz * *lz;
}

/* cos of the angle between a spot's axis and -L, L unit. */
static inline floatV spot_cos(const Light* lt, floatV lx, floatV ly, floatV lz)
{
    return -(lx * lt->direction[0] + ly * lt->direction[1] + lz * lt->direction[2]);
}

/* The lanes whose point P the light reaches: d² < r² and, for a spot, inside its outer cone
 * (the region where A·S can be > 0). The stencil pass's test and the useful pairs' count. */
static inline intV light_reach(const Light* lt, floatV px, floatV py_, floatV pz)
{
    floatV lx, ly, lz;
    const floatV d2 = light_vector(lt, px, py_, pz, &lx, &ly, &lz);
    intV reach = d2 < lt->radius * lt->radius;
    if (lt->type == LIGHT_SPOT && ANY(reach)) {
        const floatV inv_l = RSQRT(fmax(d2, 1e-30f));
        reach &= spot_cos(lt, lx * inv_l, ly * inv_l, lz * inv_l) > lt->cos_outer;
    }
    return reach;
}

/* A(d) of the header on the lanes `near_enough` (d² < r²), 0 elsewhere: the report's window or
 * KHR_lights_punctual's I/d² with its range window (or none). Shared with layer_shading.h. */
static inline floatV light_falloff(const Light* lt, floatV d2, float r2, intV near_enough)
{
    if (lt->falloff == LIGHT_FALLOFF_REPORT) {
        floatV q = 1.0f - d2 / r2;
        return select((floatV)0.0f, q * q * q, near_enough);
    }
    floatV q = d2 / r2, win = clamp(1.0f - q * q, 0.0f, 1.0f);   /* KHR_lights_punctual: I/d², the range window */
    if (lt->falloff == LIGHT_FALLOFF_INVERSE_SQUARE_UNBOUNDED) win = 1.0f;
    return select((floatV)0.0f, win * win / fmax(d2, 1e-8f), near_enough);
}

/* A spot's S = t² of the header, cos_a = spot_cos() of the unit L. */
static inline floatV spot_cone(const Light* lt, floatV cos_a)
{
    floatV s = clamp((cos_a - lt->cos_outer) / fmax(lt->cos_inner - lt->cos_outer, 1e-4f), 0.0f, 1.0f);
    return s * s;
}

/* Light k of the run's light list (of all lights with BRUTE_FORCE) at the points (px, py_, pz): the
 * lanes of `on` within its radius (*reach), its unit direction (*lx, *ly, *lz) and its falloff × spot
 * cone (*atten; left unset when no lane is within reach). The head of the layered and the transmitted light
 * walks (layer_shading.h, transmission.h). */
static inline Light light_at(const LightEnv* env, int first, int k, intV on, floatV px, floatV py_, floatV pz,
                             intV* reach, floatV* lx, floatV* ly, floatV* lz, floatV* atten)
{
#if BRUTE_FORCE
    const Light lt = env->lights[k];
#else
    const Light lt = env->lights[env->tile_lights[first + k]];
#endif
    const floatV d2 = light_vector(&lt, px, py_, pz, lx, ly, lz);
    const float r2 = lt.radius * lt.radius;
    *reach = on & (d2 < r2);
    if (!ANY(*reach)) return lt;
    *atten = light_falloff(&lt, d2, r2, *reach);
    const floatV inv_l = RSQRT(fmax(d2, 1e-30f));
    *lx *= inv_l; *ly *= inv_l; *lz *= inv_l;
    if (lt.type == LIGHT_SPOT) *atten *= spot_cone(&lt, spot_cos(&lt, *lx, *ly, *lz));
    return lt;
}

/* The glTF lanes' terms of a light of colour c reaching them with k = A·max(N·L, 0) (`diff`):
 * diff and spec become k·(1 − w)/π and k·D·V·(1 − w) there (the caller adds them × c like the
 * Blinn-Phong ones), and k·D·V·w·c goes to T (brdf.h). */
static inline void add_gltf_terms(const BrdfV* m, floatV k, floatV ndotl, floatV ndoth, floatV vdoth, float cr,
                                  float cg, float cb, floatV* diff, floatV* spec, floatV* tr, floatV* tg, floatV* tb)
{
    floatV kd, ks, kt;
    gltf_light_terms(m, ndotl, ndoth, vdoth, &kd, &ks, &kt);
    const intV lit = m->gltf & (ndotl > 0.0f);
    *diff = select(*diff, k * kd, m->gltf);
    *spec = select(*spec, select((floatV)0.0f, k * ks, lit), m->gltf);
    const floatV t = select((floatV)0.0f, k * kt, lit);
    *tr += t * cr; *tg += t * cg; *tb += t * cb;
}

/* One light's terms added at the lanes it lights. `take` (STENCIL): the lanes whose stencil
 * bit is set, which replaces the distance test; otherwise the test is made on the lanes in
 * fg. `useful` (may be null): +1 on the lanes the light reaches (light_reach()). */
static inline void add_light(const LightEnv* env, const Light lt, intV fg, intV take,
                             floatV px, floatV py_, floatV pz, floatV nx, floatV ny, floatV nz,
                             floatV vx, floatV vy, floatV vz, const BrdfV* m,
                             intV pix_x, int pix_y, global float* shadow_out, int p0, int valid, int npix,
                             intV* useful, floatV* dr, floatV* dg, floatV* db, floatV* sr, floatV* sg, floatV* sb,
                             floatV* tr, floatV* tg, floatV* tb)
{
    floatV lx, ly, lz;
    floatV d2 = light_vector(&lt, px, py_, pz, &lx, &ly, &lz);
    float r2 = lt.radius * lt.radius;
#if STENCIL
    intV near_enough = take;               /* the stencil pass tested the distance */
    intV reach = take & (d2 < r2);
#else
    intV near_enough = fg & (d2 < r2);
    if (!ANY(near_enough)) return;
    intV reach = near_enough;
#endif
    floatV atten = light_falloff(&lt, d2, r2, near_enough);
    floatV inv_l = RSQRT(fmax(d2, 1e-30f));
    lx *= inv_l; ly *= inv_l; lz *= inv_l;
    if (lt.type == LIGHT_SPOT) {
        floatV cos_a = spot_cos(&lt, lx, ly, lz);
        reach &= cos_a > lt.cos_outer;
        atten *= spot_cone(&lt, cos_a);
    }
    if (useful) *useful += select((intV)0, (intV)1, reach);
    floatV ndotl = nx * lx + ny * ly + nz * lz;
#if SHADOWS
    if (lt.shadow >= 0) {              /* a shadowed spot: only where it lights */
        intV lit = fg & (atten > 0.0f);
        floatV vis = 1.0f;
        if (ANY(lit)) {
            vis = shadow_visibility(&env->sp, env->views + env->spot_view0 + lt.shadow, px, py_, pz,
                                    nx, ny, nz, ndotl, pix_x, pix_y);
            atten *= vis;
        }
        if (shadow_out)
            store_plane(shadow_out + (env->spot_plane0 + lt.shadow) * npix, p0, valid,
                        select((floatV)1.0f, vis, lit));
    }
#endif
    /* Nothing to add where no lane the light reaches faces it: both terms are +0 there. */
    if (!ANY(near_enough & (ndotl > 0.0f))) return;
    floatV hx = lx + vx, hy = ly + vy, hz = lz + vz;
    floatV inv_h = RSQRT(fmax(hx * hx + hy * hy + hz * hz, 1e-30f));
    floatV ndoth = fmax((nx * hx + ny * hy + nz * hz) * inv_h, 0.0f);
    floatV spec = select((floatV)0.0f, m->spec_i * spec_powV(ndoth, m->spec_p), ndotl > 0.0f);
    floatV diff = atten * fmax(ndotl, 0.0f);
    spec *= atten;
    if (m->any_gltf)
        add_gltf_terms(m, diff, ndotl, ndoth, (vx * hx + vy * hy + vz * hz) * inv_h, lt.color[0], lt.color[1],
                       lt.color[2], &diff, &spec, tr, tg, tb);
    *dr += diff * lt.color[0]; *dg += diff * lt.color[1]; *db += diff * lt.color[2];
    *sr += spec * lt.color[0]; *sg += spec * lt.color[1]; *sb += spec * lt.color[2];
}

#if STENCIL
/* OR of the lanes' words. */
static inline uint or_lanes(uintV w)
{
#if VEC == 1
    return w;
#else
#if VEC == 16
    uint8 w8 = w.lo | w.hi;
#elif VEC == 8
    uint8 w8 = w;
#endif
#if VEC >= 8
    uint4 w4 = w8.lo | w8.hi;
#else
    uint4 w4 = w;
#endif
    uint2 w2 = w4.lo | w4.hi;
    return w2.x | w2.y;
#endif
}
#endif

/* Light buffer sums of the lanes in `fg` (see the header), counting pairs. pix_x/pix_y: pixel
 * coordinates (Poisson rotation); shadow_out (may be null), p0, valid, npix: where visibilities
 * go. stencil, stencil_words (STENCIL): the run's words are stencil[w·npix + p0 + lane] for
 * w < stencil_words (a list longer than 32·stencil_words overflowed: the frame is redone).
 * evaluated, useful (may be null): per lane, += pairs evaluated / useful. tr, tg, tb: the glTF
 * lanes' third sum (brdf.h); untouched when no lane is glTF. */
static void accumulate_lights_counted(const LightEnv* env, int first, int count, intV fg,
                                      global const uint* stencil, int stencil_words, intV* evaluated, intV* useful,
                                      floatV px, floatV py_, floatV pz, floatV nx, floatV ny, floatV nz,
                                      floatV vx, floatV vy, floatV vz, const BrdfV* m, floatV depth,
                                      intV pix_x, int pix_y, global float* shadow_out, int p0, int valid, int npix,
                                      floatV* dr, floatV* dg, floatV* db, floatV* sr, floatV* sg, floatV* sb,
                                      floatV* tr, floatV* tg, floatV* tb)
{
#if STENCIL
    const int words = min((count + 31) / 32, stencil_words);
    for (int w = 0; w < words; ++w) {
        global const uint* plane = stencil + w * npix;
        uintV word = 0u;
        if (valid == VEC) {
            word = vloadV(0, plane + p0);
        } else {
            for (int l = 0; l < valid; ++l) LANE_I(word, l) = (int)plane[p0 + l];
        }
        word = select((uintV)0u, word, fg);
        uint any = or_lanes(word);
        while (any != 0u) {                /* the lights some lane takes, in list order */
            const int j = 31 - clz(any & (0u - any));
            any &= any - 1u;
            const intV take = fg & ((word & (1u << j)) != 0u);
            if (evaluated) *evaluated += select((intV)0, (intV)1, take);
            add_light(env, env->lights[env->tile_lights[first + 32 * w + j]], fg, take, px, py_, pz, nx, ny, nz,
                      vx, vy, vz, m, pix_x, pix_y, shadow_out, p0, valid, npix, useful,
                      dr, dg, db, sr, sg, sb, tr, tg, tb);
        }
    }
#else
    if (evaluated) *evaluated += select((intV)0, (intV)count, fg);
    for (int k = 0; k < count; ++k) {
#if BRUTE_FORCE
        const Light lt = env->lights[k];
#else
        const Light lt = env->lights[env->tile_lights[first + k]];
#endif
        add_light(env, lt, fg, fg, px, py_, pz, nx, ny, nz, vx, vy, vz, m, pix_x, pix_y,
                  shadow_out, p0, valid, npix, useful, dr, dg, db, sr, sg, sb, tr, tg, tb);
    }
#endif
    if (env->has_sun) {                    /* the sun: every foreground pixel, no falloff */
        global const float* sun = env->sun;
        const float lx = -sun[0], ly = -sun[1], lz = -sun[2];
        floatV ndotl = nx * lx + ny * ly + nz * lz;
        floatV vis = 1.0f;
#if SHADOWS
        if (env->sun_cascades > 0) {
            intV cascade = 0;
            for (int c = 0; c + 1 < env->sun_cascades; ++c)
                cascade += select((intV)0, (intV)1, depth > env->views[c].split);
            for (int c = 0; c < env->sun_cascades; ++c) {
                intV mine = fg & (cascade == c);
                if (ANY(mine))
                    vis = select(vis, shadow_visibility(&env->sp, env->views + c, px, py_, pz, nx, ny, nz, ndotl,
                                                        pix_x, pix_y), mine);
            }
            if (shadow_out) store_plane(shadow_out, p0, valid, select((floatV)1.0f, vis, fg));
        }
#endif
        floatV hx = lx + vx, hy = ly + vy, hz = lz + vz;
        floatV inv_h = RSQRT(fmax(hx * hx + hy * hy + hz * hz, 1e-30f));
        floatV ndoth = fmax((nx * hx + ny * hy + nz * hz) * inv_h, 0.0f);
        floatV spec = select((floatV)0.0f, vis * m->spec_i * spec_powV(ndoth, m->spec_p), ndotl > 0.0f);
        floatV diff = vis * fmax(ndotl, 0.0f);
        if (m->any_gltf) {
            add_gltf_terms(m, diff, ndotl, ndoth, (vx * hx + vy * hy + vz * hz) * inv_h, sun[3], sun[4], sun[5],
                           &diff, &spec, tr, tg, tb);
        }
        *dr += diff * sun[3]; *dg += diff * sun[4]; *db += diff * sun[5];
        *sr += spec * sun[3]; *sg += spec * sun[4]; *sb += spec * sun[5];
    }
}

/* Light buffer sums of the lanes in `fg` (see the header), counting nothing: the forward passes.
 * pix_x/pix_y: pixel coordinates (Poisson rotation); shadow_out (may be null), p0, valid, npix:
 * where visibilities go. */
static void accumulate_lights(const LightEnv* env, int first, int count, intV fg,
                              floatV px, floatV py_, floatV pz, floatV nx, floatV ny, floatV nz,
                              floatV vx, floatV vy, floatV vz, const BrdfV* m, floatV depth,
                              intV pix_x, int pix_y, global float* shadow_out, int p0, int valid, int npix,
                              floatV* dr, floatV* dg, floatV* db, floatV* sr, floatV* sg, floatV* sb,
                              floatV* tr, floatV* tg, floatV* tb)
{
    accumulate_lights_counted(env, first, count, fg, 0, 0, 0, 0, px, py_, pz, nx, ny, nz, vx, vy, vz, m,
                              depth, pix_x, pix_y, shadow_out, p0, valid, npix, dr, dg, db, sr, sg, sb, tr, tg, tb);
}
#endif
