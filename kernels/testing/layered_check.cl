/* layered_check.cl: test-only kernel (tests/test_layered_brdf_kernel.py). Runs layered_brdf.h on given
 * queries so the test can compare it with a float64 NumPy evaluation of the layered model, and the base glTF
 * BRDF (brdf.h gltf_light_terms, composed as compose_gltf does) for the degenerate-layer identity.
 *
 * q float[LC_IN * n] per query: n(3) ng(3) ncc(3) at(3) v(3) c(3) metallic rough ior sw sc(3) cc cc_rough
 *   sheen(3) sheen_rough irid irid_ior thickness_nm aniso L(3) I(3) ao occlusion dt dtc(3) dw (diffuse
 *   transmission, its colour, the diffuse weight; the light's back-side intensity is I too).
 * out float[LC_OUT * n]: light rgb, ambient rgb, emission scale, base glTF light rgb, Fi_d rgb, Fi_m rgb.
 * Work-item g answers queries g VEC .. g VEC + VEC - 1 (clamped, stores bounds-checked).
 */
#include "../layered_brdf.h"
#include "../sheen_table.h"

#define LC_IN 48
#define LC_OUT 16

kernel void layered_check(ENV_PARAMS, global const float* sheen_lut, global const float* q, int n, int has_env,
                          float ambient, int multiscatter, global float* out)
{
    const int first = get_global_id(0) * VEC;
    if (first >= n) return;
    const EnvMaps env = ENV_INIT;
    const intV i = min((intV)first + LANES, (intV)(n - 1));
    const intV base = LC_IN * i;
#define Q(k) GATHER_F(q, base + (k))
#define Q3(k) { Q(k), Q((k) + 1), Q((k) + 2) }
    const vec3V nn = Q3(0), ng = Q3(3), ncc = Q3(6), at = Q3(9), v = Q3(12);
    const intV on = (intV)first + LANES < n;
    LayeredV s = layered_prepare(on, nn, ng, ncc, at, v, Q(15), Q(16), Q(17), Q(18), Q(19), Q(20), Q(21),
                                 Q(22), Q(23), Q(24), Q(25), Q(26), Q(27), Q(28), Q(29), Q(30), Q(31), Q(32),
                                 Q(33), Q(34), Q(43), Q(44), Q(45), Q(46), Q(47), sheen_lut);
    floatV lr = 0.0f, lg = 0.0f, lb = 0.0f, ar = 0.0f, ag = 0.0f, ab = 0.0f;
    const floatV lx = Q(35), ly = Q(36), lz = Q(37), ir = Q(38), ig = Q(39), ib = Q(40);
    layered_light(&s, sheen_lut, lx, ly, lz, ir, ig, ib, ir, ig, ib, &lr, &lg, &lb);
    layered_ambient(&s, has_env, &env, ambient, Q(41), Q(42), multiscatter, &ar, &ag, &ab);
    const floatV es = layered_emission_scale(&s);
    /* the base glTF BRDF: brdf.h's factors composed as compose_gltf (albedo (1 - F0) kd + F0 ks + kt) */
    const BrdfV m = brdf_inputs(on, Q(18), Q(19), nn.x, nn.y, nn.z, v.x, v.y, v.z);
    const vec3V hv = lb_normalize((vec3V){ lx + v.x, ly + v.y, lz + v.z });
    const vec3V L = { lx, ly, lz };
    const floatV nl = fmax(dot3V(nn, L), 0.0f);
    floatV kd, ks, kt;
    gltf_light_terms(&m, nl, fmax(dot3V(nn, hv), 0.0f), dot3V(v, hv), &kd, &ks, &kt);
    floatV cr = Q(15), cg = Q(16), cb = Q(17), f0r, f0g, f0b;
    gltf_albedo_f0(on, Q(18), &cr, &cg, &cb, &f0r, &f0g, &f0b);
    const floatV br = ir * nl * (cr * (1.0f - f0r) * kd + f0r * ks + kt);
    const floatV bg = ig * nl * (cg * (1.0f - f0g) * kd + f0g * ks + kt);
    const floatV bb = ib * nl * (cb * (1.0f - f0b) * kd + f0b * ks + kt);
    const floatV res[LC_OUT] = { lr, lg, lb, ar, ag, ab, es, br, bg, bb, s.fidr, s.fidg, s.fidb, s.fimr, s.fimg, s.fimb };
    for (int lane = 0; lane < VEC; ++lane) {
        if (first + lane >= n) break;
        for (int k = 0; k < LC_OUT; ++k) out[LC_OUT * (first + lane) + k] = LANE_F(res[k], lane);
    }
}
