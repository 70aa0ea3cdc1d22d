/* lighting.h: the light loop of the report's Blinn-Phong model, shared by the deferred pass
 * (shade.cl, from the G-buffer) and the forward passes over transparent fragments (abuffer.cl,
 * peel.cl: the report's Light-Indexed idea, light lists consumed by a forward pass).
 *
 * accumulate_lights(): for surface points P (world), unit normals N, unit view vectors V and
 * specular terms (s, p), walks `count` lights from `first` of the tile's list (or, with
 * BRUTE_FORCE, every light) in index order, then the sun, adding to the light buffer's sums:
 *     A = (1 - (d/r)^2)^3 for d < r, else 0;  S = 1, or t^2 for spots with
 *     t = clamp((dot(-L, dir) - cos_outer) / max(cos_inner - cos_outer, 1e-4), 0, 1);
 *     diffuse += A·S·vis·color·max(N·L, 0);  specular += A·S·vis·color·s·max(N·H, 0)^p where N·L > 0.
 * vis (SHADOWS 1): a shadowed spot's map visibility where A·S > 0; the sun's cascade picked
 * from the view depth. When `shadow_out` is not null each visibility is also written to its
 * plane (the opaque pass's Frame.shadow); fragments pass null.
 * VEC-wide (vec.h): the loop is uniform across lanes, light records are scalar loads.
 */
#ifndef CLRENDER_LIGHTING_H
#define CLRENDER_LIGHTING_H
#include "structs.h"
#include "vec.h"

#ifndef BRUTE_FORCE
#define BRUTE_FORCE 0
#endif
#ifndef SHADOWS
#define SHADOWS 0
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

/* Stores the run's `valid` lanes of v into a float plane at pixel p0. */
static inline void store_plane(global float* plane, int p0, int valid, floatV v)
{
    if (valid == VEC) {
        vstoreV(v, 0, plane + p0);
        return;
    }
    for (int l = 0; l < valid; ++l) plane[p0 + l] = LANE_F(v, l);
}

/* Light buffer sums of the lanes in `fg` (see the header). pix_x/pix_y: pixel coordinates
 * (Poisson rotation); shadow_out (may be null), p0, valid, npix: where visibilities go. */
static void accumulate_lights(const LightEnv* env, int first, int count, intV fg,
                              floatV px, floatV py_, floatV pz, floatV nx, floatV ny, floatV nz,
                              floatV vx, floatV vy, floatV vz, floatV spec_i, floatV spec_p, floatV depth,
                              intV pix_x, int pix_y, global float* shadow_out, int p0, int valid, int npix,
                              floatV* dr, floatV* dg, floatV* db, floatV* sr, floatV* sg, floatV* sb)
{
    for (int k = 0; k < count; ++k) {
#if BRUTE_FORCE
        const Light lt = env->lights[k];
#else
        const Light lt = env->lights[env->tile_lights[first + k]];
#endif
        floatV lx = lt.position[0] - px, ly = lt.position[1] - py_, lz = lt.position[2] - pz;
        floatV d2 = lx * lx + ly * ly + lz * lz;
        float r2 = lt.radius * lt.radius;
        intV near_enough = fg & (d2 < r2);
        if (!ANY(near_enough)) continue;
        floatV q = 1.0f - d2 / r2;
        floatV atten = select((floatV)0.0f, q * q * q, near_enough);
        floatV inv_l = rsqrt(fmax(d2, 1e-30f));
        lx *= inv_l; ly *= inv_l; lz *= inv_l;
        if (lt.type == LIGHT_SPOT) {
            floatV cos_a = -(lx * lt.direction[0] + ly * lt.direction[1] + lz * lt.direction[2]);
            floatV s = clamp((cos_a - lt.cos_outer) / fmax(lt.cos_inner - lt.cos_outer, 1e-4f), 0.0f, 1.0f);
            atten *= s * s;
        }
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
        floatV hx = lx + vx, hy = ly + vy, hz = lz + vz;
        floatV inv_h = rsqrt(fmax(hx * hx + hy * hy + hz * hz, 1e-30f));
        floatV ndoth = fmax((nx * hx + ny * hy + nz * hz) * inv_h, 0.0f);
        floatV spec = select((floatV)0.0f, spec_i * powr(ndoth, spec_p), ndotl > 0.0f);
        floatV diff = atten * fmax(ndotl, 0.0f);
        spec *= atten;
        *dr += diff * lt.color[0]; *dg += diff * lt.color[1]; *db += diff * lt.color[2];
        *sr += spec * lt.color[0]; *sg += spec * lt.color[1]; *sb += spec * lt.color[2];
    }
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
        floatV inv_h = rsqrt(fmax(hx * hx + hy * hy + hz * hz, 1e-30f));
        floatV ndoth = fmax((nx * hx + ny * hy + nz * hz) * inv_h, 0.0f);
        floatV spec = select((floatV)0.0f, vis * spec_i * powr(ndoth, spec_p), ndotl > 0.0f);
        floatV diff = vis * fmax(ndotl, 0.0f);
        *dr += diff * sun[3]; *dg += diff * sun[4]; *db += diff * sun[5];
        *sr += spec * sun[3]; *sg += spec * sun[4]; *sb += spec * sun[5];
    }
}
#endif
