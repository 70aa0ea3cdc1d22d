/* layered_brdf.h: the layered surface model of issues 37 and 38 (glTF KHR_materials_ior, _specular, _clearcoat,
 * _sheen, _iridescence, _anisotropy, _diffuse_transmission) at VEC lanes (vec.h), for layer_shading.h, which
 * re-shades the pixels (surface_layers.cl) and transparent fragments (forward.h) whose material has layers. The model (the extension READMEs in KhronosGroup/glTF
 * extensions/2.0/Khronos/, and where a README leaves the evaluation open, the Khronos glTF Sample
 * Renderer's shaders: brdf.glsl, ibl.glsl, iridescence.glsl), per lane:
 *   alpha = max(r, MIN_ROUGHNESS)^2, NV = max(N.V, 1e-4), f0_d = min(((ior-1)/(ior+1))^2 * sc, 1), F90_d = sw;
 *   F_d(x) = sw f0_d + (sw - sw f0_d)(1-x)^5, F_m(x) = c + (1-c)(1-x)^5, Fc = 0.04 + 0.96 (1 - Ncc.V)^5 (coat
 *   IOR 1.5, once per pixel at the view), alpha_cc = max(ccr, 0.01)^2.
 * Punctual light (NL, NH, VH clamped to [0, 1], H = normalize(L + V)):
 *   diffuse = I NL c/pi, spec = I NL D_GGX V_GGX (brdf.h's GGX and height-correlated Smith), or with
 *   anisotropy > 0 brdf.glsl's anisotropic D and V (at = mix(r, 1, as^2)^2, ab = clamp(r^2, 0.001, 1));
 *   metal = F_m spec, diel = diffuse (1 - F_d) + spec F_d, col = mix(diel, metal, m);
 *   iridescence: metal = mix(metal, spec Fi_m, irid), diel = mix(diel, rgb_mix(diffuse, spec, Fi_d), irid),
 *   rgb_mix(a, b, F) = (1 - max3(F)) a + F b;
 *   sheen: col = I NL shc D_charlie V_sheen + col min(1 - max3(shc) E(NV), 1 - max3(shc) E(NL))
 *   (Estevez & Kulla 2017's Charlie D and the Sample Renderer's lambdaSheen fit for V);
 *   clearcoat: col = mix(col, I NccL D_GGX V_GGX (at Ncc, alpha_cc), cc Fc).
 * Diffuse transmission (dt, colour dtc; the diffuse BSDF's weight dw = 1 - transmission, 1 without it): the README's
 *   base mix(diffuse_brdf(c), diffuse_btdf(dtc), dt) inside the Fresnel mix, so every diffuse albedo c above is
 *   c dw (1 - dt) (exactly c for dt = 0, dw = 1), and a light behind the surface (N.L < 0) adds
 *   I NLb dtc dw dt / pi (NLb = -N.L) through the same weights as the diffuse term (1 - F_d, the iridescence mix,
 *   1 - m, the sheen scaling with E(NLb), 1 - cc Fc) with x = V.H' at the mirrored light, H' = normalize(L - 2 (N.L)
 *   N + V) (the Sample Renderer's l_mirror); its shadow is looked up with the flipped normal (layer_shading.h).
 * Image-based light (environment.h: Lirr = E/pi from the SH, pref = the GGX-prefiltered map, (A, B) the DFG
 * table at (NV, r)): FssEss(F0, w) = w (kS A + B), kS = F0 + (max(1 - r, F0) - F0)(1 - NV)^5 (Fdez-Aguera, the
 * Sample Renderer's getIBLGGXFresnel; with multiscatter + Ems FssEss Favg / (1 - Favg Ems), Ems = 1 - A - B,
 * Favg = w (F0 + (1 - F0)/21)); R = 2 (N.V) N - V (the raw N.V, as ambient.h), with anisotropy ibl.glsl's bent
 * normal; f_metal = FssEss(c, 1) pref, f_diel = Lirr c (1 - FssEss(f0_d, sw)) + pref FssEss(f0_d, sw), the same
 * iridescence mixes, col = mix(f_diel, f_metal, m); sheen: col = pref(R, shr) shc E(NV) + col (1 - max3(shc)
 * E(NV)) (the Sample Renderer samples a Charlie-prefiltered map: under a uniform environment the same);
 * clearcoat: col = mix(col, pref(Rcc, ccr), cc Fc). Without an environment the constant ambient a:
 * a c (1 - m)(1 - mix(sw f0_d, c, m))(1 - max3(shc) E(NV))(1 - cc Fc). Both times occlusion and ao. With diffuse
 * transmission Lirr c becomes dw (Lirr(N) c (1 - dt) + Lirr(-N) dtc dt), and the constant ambient's c (in front
 * of (1 - m)) dw (c (1 - dt) + dtc dt).
 * Emission is scaled by 1 - cc Fc (the clearcoat README).
 * Iridescence: the README's thin-film Fresnel (Belcour & Barla 2017, outside IOR 1, cosTheta1 = NV) with the
 * Sample Renderer's details the README leaves out: film IOR mix(1, irid_ior, smoothstep(0, 0.03, d)), base F0
 * clamped to 0.9999, the optical path difference at the refracted angle 2 irid_ior d cosTheta2 (the README's
 * text writes cosTheta1; every implementation uses cosTheta2). The phase shifts are 0 or pi, so
 * cos(x + m phi) = +-cos(x): the 8 cosines and exponentials are shared by Fi_d and Fi_m.
 * Frame: At is re-orthogonalized against N and Ab = cross(N, At) (the Sample Renderer takes Ab = cross(Ng, At);
 * using N for both keeps At, Ab, N orthonormal).
 * Sheen albedo E(mu, shr) = integral over the hemisphere of D_charlie V_sheen (N.L) dL, tabulated by
 * sheen_albedo_lut() in sheen_table.h (its quadrature: see there) and read bilinearly by sheen_albedoV().
 * FP_CONTRACT is off so that every implementation computes the same bits (no fused multiply-adds).
 * Speed (the light loop is most of the pass): what depends only on the pixel (the view halves of the
 * visibilities, the anisotropic alphas, lambdaSheen's fit constants and lambda(NV), D_charlie's constants) is
 * made once in layered_prepare; the per-light sheen uses layered_math.h's inline pow/exp (within ~1e-7 of the
 * library's, see there) and evaluates only the lambdaSheen branch in use; a light behind every lane's surface
 * and coat is skipped unless a lane lets it through (dt > 0); the transmitted term and the irradiance at -N are
 * made only where a lane has dt > 0; the ambient's base and sheen lookups share R's (u, v).
 */
#ifndef CLRENDER_LAYERED_BRDF_H
#define CLRENDER_LAYERED_BRDF_H
#include "vec.h"
#include "brdf.h"              /* MIN_ROUGHNESS, INV_PI */
#include "surface_types.h"     /* vec3V, dot3V */
#include "environment.h"       /* EnvMaps, env_irradianceV, env_specularV, env_dfgV, ENV_INLINE */
#include "layered_film.h"      /* the thin film (LbFilm, lb_irid_film, lb_irid_eval), lb_pow5 .. lb_max3, LB_PI */
#pragma OPENCL FP_CONTRACT OFF

#ifndef SHEEN_LUT_SIZE
#define SHEEN_LUT_SIZE 32
#endif
#define LB_CC_F0 0.04f              /* clearcoat IOR 1.5 */
#define LB_MIN_CC_ROUGHNESS 0.01f
#define LB_MIN_NV 1e-4f
#define LB_MIN_SHEEN_ROUGHNESS 0.000001f   /* brdf.glsl's clamp of the sheen roughness */

typedef struct {
    intV on;                         /* lanes shaded by the layered model */
    vec3V n, ng, ncc, at, ab, v;     /* shading normal, geometric normal, clearcoat normal, anisotropy frame, view */
    floatV nv;                       /* max(N.V, 1e-4) */
    floatV cr, cg, cb, metallic, rough, alpha;
    floatV f0r, f0g, f0b, sw;        /* dielectric f0 = min(f0_ior * specular colour, 1), specular weight (= F90) */
    floatV cc, cc_rough, cc_alpha, fc;     /* clearcoat factor, roughness, alpha, Fresnel at Ncc.V */
    floatV shr, shg, shb, sh_rough, sh_ev; /* sheen colour, roughness, E(NV, roughness) */
    floatV irid;                     /* iridescence factor (0 where thickness is 0) */
    floatV fidr, fidg, fidb, fimr, fimg, fimb;  /* thin-film Fresnel at NV: dielectric, metal */
    floatV aniso;                    /* anisotropy strength */
    floatV dt, dw;                   /* diffuse transmission [0, 1]; the diffuse BSDF's weight (1 - transmission) */
    floatV kfr, kfg, kfb;            /* the reflected diffuse albedo c dw (1 - dt): c itself when dt = 0, dw = 1 */
    floatV kbr, kbg, kbb;            /* the transmitted diffuse albedo dtc dw dt */
    int any_cc, any_sheen, any_irid, any_aniso; /* ANY over `on` of each layer: skip the math of absent layers */
    int any_dt;                      /* ANY over `on` of dt > 0 */
    int all_aniso;                   /* every `on` lane anisotropic: the isotropic GGX is not needed */
    /* Per-pixel parts of the per-light terms (the same arithmetic, hoisted out of the light loop): */
    floatV vis_v;                    /* sqrt(NV^2 (1 - alpha^2) + alpha^2): the view half of V_GGX */
    floatV cc_nv, cc_vis_v;          /* max(clamp01(Ncc.V), 1e-4) and the coat's view half of V_GGX */
    floatV an_at, an_ab, an_tv, an_bv, an_gv;   /* anisotropic alphas, T.V, B.V, the view half of V_aniso */
    floatV sh_max, sh_dk, sh_dn;     /* max3(sheen colour); D_charlie's exponent 1/(2a) and (2 + 1/a)/(2 pi) */
    floatV sh_la, sh_lb, sh_lc, sh_ld, sh_le, sh_lh2, sh_lv1;  /* lambdaSheen's fit at a; 2 helper(0.5); 1 + lambda(NV) */
} LayeredV;

/* ---- small helpers ---------------------------------------------------------------------------------- */
/* (lb_pow5, lb_clamp01, lb_mix, lb_max3 and LB_PI: layered_film.h) */
static inline ENV_INLINE vec3V lb_cross(vec3V a, vec3V b)
{
    vec3V r = { a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x };
    return r;
}
static inline ENV_INLINE vec3V lb_normalize(vec3V a)
{
    const floatV inv = 1.0f / fmax(sqrt(dot3V(a, a)), 1e-30f);
    vec3V r = { a.x * inv, a.y * inv, a.z * inv };
    return r;
}

#include "layered_math.h"     /* lb_log2V, lb_exp2V, lb_powV, lb_expV */

/* D_GGX(NH, alpha) V_GGX(NL, NV, alpha), written as brdf.h's gltf_light_terms (the same bits). */
static inline ENV_INLINE floatV lb_ggx_dv(floatV alpha, floatV nl, floatV nh, floatV nv)
{
    const floatV a2 = alpha * alpha;
    const floatV q = nh * nh * (a2 - 1.0f) + 1.0f;
    const floatV d = a2 * INV_PI / fmax(q * q, 1e-30f);
    const floatV vis = 0.5f / fmax(nl * sqrt(nv * nv * (1.0f - a2) + a2) + nv * sqrt(nl * nl * (1.0f - a2) + a2),
                                   1e-30f);
    return d * vis;
}

/* Sheen (brdf.glsl): the Charlie distribution and the lambdaSheen visibility fit, as scalar (_s, for the
 * table kernel) and VEC-wide (V) functions; T is float or floatV. */
#define LB_SHEEN_FUNCS(T, SUF) \
static inline T lb_lambda_helper##SUF(T x, T ag) \
{ \
    const T o = (1.0f - ag) * (1.0f - ag); \
    const T a = 21.5473f * (1.0f - o) + 25.3245f * o, b = 3.82987f * (1.0f - o) + 3.32435f * o; \
    const T c = 0.19823f * (1.0f - o) + 0.16801f * o, d = -1.97760f * (1.0f - o) + -1.27393f * o; \
    const T e = -4.32054f * (1.0f - o) + -4.85967f * o; \
    return a / (1.0f + b * pow(fmax(x, 0.0f), c)) + d * x + e; \
} \
static inline T lb_lambda_sheen##SUF(T x, T ag) \
{ \
    const T lo = lb_lambda_helper##SUF(x, ag); \
    const T hi = 2.0f * lb_lambda_helper##SUF((T)0.5f, ag) - lb_lambda_helper##SUF(1.0f - x, ag); \
    return exp(select(hi, lo, fabs(x) < 0.5f)); \
} \
static inline T lb_d_charlie##SUF(T shr, T nh) \
{ \
    const T s = fmax(shr, LB_MIN_SHEEN_ROUGHNESS), ag = s * s, inv = 1.0f / ag; \
    return (2.0f + inv) * pow(fmax(1.0f - nh * nh, 0.0f), inv * 0.5f) * (0.5f / LB_PI); \
} \
/* 1 / ((1 + lambda(NV) + lambda(NL)) 4 NV NL), without the clamp to [0, 1] */ \
static inline T lb_v_sheen_raw##SUF(T nl, T nv, T shr) \
{ \
    const T s = fmax(shr, LB_MIN_SHEEN_ROUGHNESS), ag = s * s; \
    return 1.0f / ((1.0f + lb_lambda_sheen##SUF(nv, ag) + lb_lambda_sheen##SUF(nl, ag)) * (4.0f * nv * nl)); \
}
LB_SHEEN_FUNCS(float, _s)
#if VEC > 1
LB_SHEEN_FUNCS(floatV, V)
#else
#define lb_lambda_sheenV lb_lambda_sheen_s
#define lb_d_charlieV lb_d_charlie_s
#define lb_v_sheen_rawV lb_v_sheen_raw_s
#endif

/* The light loop's sheen (the same model as lb_d_charlieV and lb_v_sheen_rawV, the fit's constants and
 * lambda(NV) taken per pixel from LayeredV, lb_powV/lb_expV for pow/exp, and of lambdaSheen's two branches only
 * the one in use evaluated: one power and one exponential per lambda instead of three and one). */
static inline ENV_INLINE floatV lb_lambda_sheen_fastV(floatV x, floatV a, floatV b, floatV c, floatV d, floatV e,
                                                      floatV h2)
{
    const intV lo = fabs(x) < 0.5f;
    const floatV y = select(1.0f - x, x, lo);                    /* the helper's argument on either branch */
    const floatV h = a / (1.0f + b * lb_powV(fmax(y, 0.0f), c)) + d * y + e;
    return lb_expV(select(h2 - h, h, lo));
}

/* E(mu, rough) from the table (sheen_albedo_lut): bilinear between the entries at (i + 0.5)/N, clamped. */
static inline ENV_INLINE floatV sheen_albedoV(global const float* lut, floatV mu, floatV rough)
{
    const float top = (float)(SHEEN_LUT_SIZE - 1);
    const floatV fx = fmin(fmax(mu * (float)SHEEN_LUT_SIZE - 0.5f, 0.0f), top);      /* NaN -> 0 */
    const floatV fy = fmin(fmax(rough * (float)SHEEN_LUT_SIZE - 0.5f, 0.0f), top);
    const intV x0 = convert_intV(fx), y0 = convert_intV(fy);
    const intV x1 = min(x0 + 1, (intV)(SHEEN_LUT_SIZE - 1)), y1 = min(y0 + 1, (intV)(SHEEN_LUT_SIZE - 1));
    const floatV ax = fx - convert_floatV(x0), ay = fy - convert_floatV(y0);
    const floatV t00 = GATHER_F(lut, y0 * SHEEN_LUT_SIZE + x0), t01 = GATHER_F(lut, y0 * SHEEN_LUT_SIZE + x1);
    const floatV t10 = GATHER_F(lut, y1 * SHEEN_LUT_SIZE + x0), t11 = GATHER_F(lut, y1 * SHEEN_LUT_SIZE + x1);
    const floatV a = t00 + (t01 - t00) * ax, b = t10 + (t11 - t10) * ax;
    return a + (b - a) * ay;
}

/* ---- preparation ------------------------------------------------------------------------------------- */
static inline LayeredV layered_prepare(intV on, vec3V n, vec3V ng, vec3V ncc, vec3V at, vec3V v,
                         floatV cr, floatV cg, floatV cb, floatV metallic, floatV rough,
                         floatV ior, floatV sw, floatV scr, floatV scg, floatV scb,
                         floatV cc, floatV cc_rough, floatV shr, floatV shg, floatV shb, floatV sh_rough,
                         floatV irid, floatV irid_ior, floatV irid_thickness_nm, floatV aniso,
                         floatV dt, floatV dtr, floatV dtg, floatV dtb, floatV dw, global const float* sheen_lut)
{
    LayeredV s;
    s.on = on != 0;                                      /* -1/0 lanes (1/0 for VEC 1), whatever was passed */
    s.n = n; s.ng = ng; s.ncc = ncc; s.v = v;
    /* At made orthogonal to N (Gram-Schmidt); a tangent along N gets any perpendicular instead */
    const floatV tn = dot3V(at, n);
    vec3V t = { at.x - tn * n.x, at.y - tn * n.y, at.z - tn * n.z };
    const intV bad = dot3V(t, t) < 1e-12f;
    if (ANY(bad)) {
        const intV use_x = fabs(n.x) < 0.9f;
        const vec3V e = { select((floatV)0.0f, (floatV)1.0f, use_x), select((floatV)1.0f, (floatV)0.0f, use_x),
                          (floatV)0.0f };
        const vec3V p = lb_cross(n, e);
        t.x = select(t.x, p.x, bad); t.y = select(t.y, p.y, bad); t.z = select(t.z, p.z, bad);
    }
    s.at = lb_normalize(t);
    s.ab = lb_cross(n, s.at);
    s.nv = fmax(dot3V(n, v), LB_MIN_NV);
    s.cr = cr; s.cg = cg; s.cb = cb; s.metallic = metallic;
    s.rough = lb_clamp01(rough);
    const floatV r = fmax(s.rough, MIN_ROUGHNESS);
    s.alpha = r * r;
    const floatV q = (ior - 1.0f) / (ior + 1.0f), f0_ior = q * q;     /* ior 0 (the spec's special value): 1 */
    s.f0r = fmin(f0_ior * scr, 1.0f); s.f0g = fmin(f0_ior * scg, 1.0f); s.f0b = fmin(f0_ior * scb, 1.0f);
    s.sw = sw;
    s.cc = cc;
    s.cc_rough = lb_clamp01(cc_rough);
    const floatV rc = fmax(s.cc_rough, LB_MIN_CC_ROUGHNESS);
    s.cc_alpha = rc * rc;
    s.fc = LB_CC_F0 + (1.0f - LB_CC_F0) * lb_pow5(1.0f - lb_clamp01(dot3V(ncc, v)));
    s.shr = shr; s.shg = shg; s.shb = shb; s.sh_rough = sh_rough;
    s.irid = select((floatV)0.0f, irid, irid_thickness_nm > 0.0f);
    s.aniso = aniso;
    s.dt = dt; s.dw = dw;
    {   /* dw (1 - dt) is exactly 1 for dt = 0, dw = 1: c * 1 = c, the albedo of a material without either */
        const floatV kf = dw * (1.0f - dt), kb = dw * dt;
        s.kfr = cr * kf; s.kfg = cg * kf; s.kfb = cb * kf;
        s.kbr = dtr * kb; s.kbg = dtg * kb; s.kbb = dtb * kb;
    }
    s.any_dt = ANY(s.on & (dt > 0.0f)) ? 1 : 0;
    s.any_cc = ANY(s.on & (cc > 0.0f)) ? 1 : 0;
    s.any_sheen = ANY(s.on & (lb_max3(shr, shg, shb) > 0.0f)) ? 1 : 0;
    s.any_irid = ANY(s.on & (s.irid > 0.0f)) ? 1 : 0;
    s.any_aniso = ANY(s.on & (aniso > 0.0f)) ? 1 : 0;
    s.all_aniso = s.any_aniso && !ANY(s.on & !(aniso > 0.0f));
    s.sh_ev = s.any_sheen ? sheen_albedoV(sheen_lut, s.nv, sh_rough) : (floatV)0.0f;
    /* the per-pixel parts of layered_light's terms */
    {
        const floatV a2 = s.alpha * s.alpha;
        s.vis_v = sqrt(s.nv * s.nv * (1.0f - a2) + a2);
    }
    s.cc_nv = 0.0f; s.cc_vis_v = 0.0f;
    if (s.any_cc) {
        const floatV a2 = s.cc_alpha * s.cc_alpha;
        s.cc_nv = fmax(lb_clamp01(dot3V(ncc, v)), LB_MIN_NV);
        s.cc_vis_v = sqrt(s.cc_nv * s.cc_nv * (1.0f - a2) + a2);
    }
    s.an_at = 0.0f; s.an_ab = 0.0f; s.an_tv = 0.0f; s.an_bv = 0.0f; s.an_gv = 0.0f;
    if (s.any_aniso) {
        const floatV tr = mix(s.rough, (floatV)1.0f, aniso * aniso);
        s.an_at = tr * tr;
        s.an_ab = clamp(s.rough * s.rough, 0.001f, 1.0f);
        s.an_tv = dot3V(s.at, v); s.an_bv = dot3V(s.ab, v);
        s.an_gv = sqrt(s.an_at * s.an_at * s.an_tv * s.an_tv + s.an_ab * s.an_ab * s.an_bv * s.an_bv + s.nv * s.nv);
    }
    s.sh_max = lb_max3(shr, shg, shb);
    s.sh_dk = 0.0f; s.sh_dn = 0.0f; s.sh_la = 0.0f; s.sh_lb = 0.0f; s.sh_lc = 0.0f; s.sh_ld = 0.0f;
    s.sh_le = 0.0f; s.sh_lh2 = 0.0f; s.sh_lv1 = 0.0f;
    if (s.any_sheen) {
        const floatV sr = fmax(sh_rough, LB_MIN_SHEEN_ROUGHNESS), ag = sr * sr, inv = 1.0f / ag;
        s.sh_dk = inv * 0.5f;
        s.sh_dn = (2.0f + inv) * (0.5f / LB_PI);
        const floatV o = (1.0f - ag) * (1.0f - ag);
        s.sh_la = 21.5473f * (1.0f - o) + 25.3245f * o; s.sh_lb = 3.82987f * (1.0f - o) + 3.32435f * o;
        s.sh_lc = 0.19823f * (1.0f - o) + 0.16801f * o; s.sh_ld = -1.97760f * (1.0f - o) + -1.27393f * o;
        s.sh_le = -4.32054f * (1.0f - o) + -4.85967f * o;
        s.sh_lh2 = 2.0f * (s.sh_la / (1.0f + s.sh_lb * lb_powV((floatV)0.5f, s.sh_lc)) + s.sh_ld * 0.5f + s.sh_le);
        s.sh_lv1 = 1.0f + lb_lambda_sheen_fastV(s.nv, s.sh_la, s.sh_lb, s.sh_lc, s.sh_ld, s.sh_le, s.sh_lh2);
    }
    s.fidr = 0.0f; s.fidg = 0.0f; s.fidb = 0.0f; s.fimr = 0.0f; s.fimg = 0.0f; s.fimb = 0.0f;
    if (s.any_irid) {
        const LbFilm film = lb_irid_film(s.nv, irid_ior, irid_thickness_nm);
        lb_irid_eval(&film, s.f0r, s.f0g, s.f0b, &s.fidr, &s.fidg, &s.fidb);
        lb_irid_eval(&film, cr, cg, cb, &s.fimr, &s.fimg, &s.fimb);
    }
    return s;
}

/* 1 - cc Fc: what multiplies the emission. */
static inline floatV layered_emission_scale(const LayeredV* s) { return 1.0f - s->cc * s->fc; }

/* ---- one punctual light ------------------------------------------------------------------------------ */
/* The base's colour terms shared by the light and the ambient: diel and metal from (diffuse, specular) radiances
 * and the Fresnel terms of one channel. */
static inline ENV_INLINE floatV lb_base_mix(const LayeredV* s, floatV dif, floatV spec, floatV fd, floatV fm,
                                            floatV fid, floatV fim, floatV fid_max)
{
    floatV diel = dif * (1.0f - fd) + spec * fd;
    floatV metal = fm * spec;
    if (s->any_irid) {
        metal = lb_mix(metal, spec * fim, s->irid);
        diel = lb_mix(diel, (1.0f - fid_max) * dif + fid * spec, s->irid);
    }
    return lb_mix(diel, metal, s->metallic);
}

/* The light through the surface (diffuse transmission) from behind it: I NLb dtc dw dt / pi with NLb = -N.L, weighted as
 * the diffuse term at the mirrored light Lm = L - 2 (N.L) N (H' = normalize(Lm + V), the sheen's E at NLb), added on
 * the lanes `back`. */
static inline void lb_light_back(const LayeredV* s, global const float* sheen_lut, vec3V L, floatV nlb, intV back,
                                 floatV ir, floatV ig, floatV ib, floatV* r, floatV* g, floatV* b)
{
    const floatV k2 = 2.0f * nlb;
    const vec3V H = lb_normalize((vec3V){ L.x + k2 * s->n.x + s->v.x, L.y + k2 * s->n.y + s->v.y,
                                          L.z + k2 * s->n.z + s->v.z });
    const floatV w = lb_pow5(1.0f - lb_clamp01(dot3V(s->v, H))), k = nlb * INV_PI;
    const floatV fid_max = lb_max3(s->fidr, s->fidg, s->fidb);
    floatV scale = 1.0f - s->metallic;      /* mix(diel, metal, m) with no specular: the metal adds nothing */
    if (s->any_sheen)
        scale *= fmax(fmin(1.0f - s->sh_max * s->sh_ev, 1.0f - s->sh_max * sheen_albedoV(sheen_lut, nlb, s->sh_rough)),
                      0.0f);
    if (s->any_cc) scale *= 1.0f - s->cc * s->fc;   /* mix(col, coat, cc Fc) with no coat lobe */
#define LB_BACK(kb, f0, fid, I) \
    { \
        const floatV dif = (I) * (k * s->kb); \
        floatV diel = dif * (1.0f - (s->sw * s->f0 + (s->sw - s->sw * s->f0) * w)); \
        if (s->any_irid) diel = lb_mix(diel, (1.0f - fid_max) * dif, s->irid); \
        out = diel * scale; \
    }
    floatV out;
    LB_BACK(kbr, f0r, fidr, ir) *r += select((floatV)0.0f, out, back);
    LB_BACK(kbg, f0g, fidg, ig) *g += select((floatV)0.0f, out, back);
    LB_BACK(kbb, f0b, fidb, ib) *b += select((floatV)0.0f, out, back);
#undef LB_BACK
}

/* Adds one punctual light (L unit towards it, (ir, ig, ib) its intensity at the point, (bir, big, bib) the same with
 * the shadow looked up from the back side) to *r, *g, *b on the lanes `on`; lanes facing away from both the base and
 * the coat add 0, or only the light they let through (dt > 0). */
static inline ENV_INLINE void layered_light(const LayeredV* s, global const float* sheen_lut, floatV lx, floatV ly, floatV lz,
                   floatV ir, floatV ig, floatV ib, floatV bir, floatV big, floatV bib, floatV* r, floatV* g, floatV* b)
{
    const vec3V L = { lx, ly, lz };
    const floatV nl = lb_clamp01(dot3V(s->n, L));
    const floatV nccl = s->any_cc ? lb_clamp01(dot3V(s->ncc, L)) : (floatV)0.0f;
    const intV add = s->on & ((nl > 0.0f) | (nccl > 0.0f));
    if (s->any_dt) {
        const floatV nlb = lb_clamp01(-dot3V(s->n, L));
        const intV back = s->on & (s->dt > 0.0f) & (nlb > 0.0f);
        if (ANY(back)) lb_light_back(s, sheen_lut, L, nlb, back, bir, big, bib, r, g, b);
    }
    if (!ANY(add)) return;                  /* behind every lane's surface and coat: those lanes add 0 */
    const vec3V H = lb_normalize((vec3V){ lx + s->v.x, ly + s->v.y, lz + s->v.z });
    const floatV nh = lb_clamp01(dot3V(s->n, H)), vh = lb_clamp01(dot3V(s->v, H));
    floatV dv;
    if (!s->all_aniso) {                    /* lb_ggx_dv with its view half from layered_prepare */
        const floatV a2 = s->alpha * s->alpha;
        const floatV q = nh * nh * (a2 - 1.0f) + 1.0f;
        const floatV d = a2 * INV_PI / fmax(q * q, 1e-30f);
        dv = d * (0.5f / fmax(nl * s->vis_v + s->nv * sqrt(nl * nl * (1.0f - a2) + a2), 1e-30f));
    }
    if (s->any_aniso) {
        const floatV at = s->an_at, ab = s->an_ab, a2 = at * ab;
        const floatV th = dot3V(s->at, H), bh = dot3V(s->ab, H);
        const floatV fx = ab * th, fy = at * bh, fz = a2 * nh;
        const floatV w2 = a2 / fmax(fx * fx + fy * fy + fz * fz, 1e-30f);
        const floatV d = a2 * w2 * w2 * INV_PI;
        const floatV tl = dot3V(s->at, L), bl = dot3V(s->ab, L);
        const floatV gv = nl * s->an_gv;
        const floatV gl = s->nv * sqrt(at * at * tl * tl + ab * ab * bl * bl + nl * nl);
        const floatV vis = lb_clamp01(0.5f / fmax(gv + gl, 1e-30f));
        dv = s->all_aniso ? d * vis : select(dv, d * vis, s->aniso > 0.0f);
    }
    const floatV w = lb_pow5(1.0f - vh);
    const floatV spec = nl * dv, k = nl * INV_PI;
    const floatV fid_max = lb_max3(s->fidr, s->fidg, s->fidb);
#define LB_CHANNEL(c, kf, f0, fid, fim, I) \
    (I) * lb_base_mix(s, k * s->kf, spec, s->sw * s->f0 + (s->sw - s->sw * s->f0) * w, s->c + (1.0f - s->c) * w, \
                      s->fid, s->fim, fid_max)
    floatV cr = LB_CHANNEL(cr, kfr, f0r, fidr, fimr, ir);
    floatV cg = LB_CHANNEL(cg, kfg, f0g, fidg, fimg, ig);
    floatV cb = LB_CHANNEL(cb, kfb, f0b, fidb, fimb, ib);
#undef LB_CHANNEL
    if (s->any_sheen) {
        const floatV sm = s->sh_max;
        /* E exceeds 1 at grazing angles (the Charlie visibility's fit): the base never goes negative */
        const floatV scale = fmax(fmin(1.0f - sm * s->sh_ev, 1.0f - sm * sheen_albedoV(sheen_lut, nl, s->sh_rough)),
                                  0.0f);
        const floatV d = s->sh_dn * lb_powV(fmax(1.0f - nh * nh, 0.0f), s->sh_dk);          /* D_charlie */
        const floatV lam_l = lb_lambda_sheen_fastV(nl, s->sh_la, s->sh_lb, s->sh_lc, s->sh_ld, s->sh_le, s->sh_lh2);
        const floatV sh = nl * d * lb_clamp01(1.0f / ((s->sh_lv1 + lam_l) * (4.0f * s->nv * nl)));
        cr = ir * sh * s->shr + cr * scale;
        cg = ig * sh * s->shg + cg * scale;
        cb = ib * sh * s->shb + cb * scale;
    }
    if (s->any_cc) {
        const floatV ncch = lb_clamp01(dot3V(s->ncc, H));
        const floatV a2 = s->cc_alpha * s->cc_alpha, nccv = s->cc_nv;   /* lb_ggx_dv, view half precomputed */
        const floatV q = ncch * ncch * (a2 - 1.0f) + 1.0f;
        const floatV dcc = a2 * INV_PI / fmax(q * q, 1e-30f);
        const floatV vcc = 0.5f / fmax(nccl * s->cc_vis_v + nccv * sqrt(nccl * nccl * (1.0f - a2) + a2), 1e-30f);
        const floatV t = s->cc * s->fc, coat = nccl * (dcc * vcc);
        cr = lb_mix(cr, ir * coat, t); cg = lb_mix(cg, ig * coat, t); cb = lb_mix(cb, ib * coat, t);
    }
    *r += select((floatV)0.0f, cr, add); *g += select((floatV)0.0f, cg, add); *b += select((floatV)0.0f, cb, add);
}

/* ---- ambient ----------------------------------------------------------------------------------------- */
/* FssEss(F0, w) (+ the multiple-scattering term when ms) from the DFG terms (A, B). */
static inline ENV_INLINE floatV lb_fss_ess(floatV f0, floatV w, floatV rough, floatV nv5, floatV A, floatV B, int ms)
{
    const floatV ks = f0 + (fmax(1.0f - rough, f0) - f0) * nv5;
    floatV f = w * (ks * A + B);
    if (ms) {
        const floatV ems = 1.0f - (A + B), favg = w * (f0 + (1.0f - f0) * (1.0f / 21.0f));
        f = f + ems * f * favg / (1.0f - favg * ems);
    }
    return f;
}

/* env_levelV, with one scalar read where every lane reads the same level (a roughness without texture) */
static inline ENV_INLINE void lb_env_levelV(global const int* levels, intV level, intV* offset, intV* w, intV* h)
{
#if VEC > 1
    if (all(level == (intV)level.s0)) {
        const int at = level.s0 * ENV_LEVEL_STRIDE;
        *offset = (intV)levels[at]; *w = (intV)levels[at + 1]; *h = (intV)levels[at + 2];
        return;
    }
#endif
    env_levelV(levels, level, offset, w, h);
}

/* env_specularV's lookup from (u, v) already made by env_dir_uvV (the same arithmetic): the base and the sheen
 * read the prefiltered map along the same R at two roughnesses, and the direction's acos and atan2 are made once. */
static inline ENV_INLINE void lb_env_specular_uvV(const EnvMaps* e, floatV u, floatV v, floatV roughness,
                                                  floatV* r, floatV* g, floatV* b)
{
    const int K = (int)e->params[ENV_P_SPEC_LEVELS];
    const floatV f = fmin(fmax(roughness, 0.0f), 1.0f) * (float)(K - 1);   /* NaN -> 0 */
    const intV k0 = min(convert_intV(f), (intV)max(K - 2, 0));
    const intV k1 = min(k0 + 1, (intV)(K - 1));
    const floatV t = f - convert_floatV(k0);
    intV off, w, h;
    lb_env_levelV(e->levels, 1 + k0, &off, &w, &h);
    env_bilinearV(e->texels, off, w, h, u, v, r, g, b);
    if (ANY(t > 0.0f)) {
        floatV r1, g1, b1;
        lb_env_levelV(e->levels, 1 + k1, &off, &w, &h);
        env_bilinearV(e->texels, off, w, h, u, v, &r1, &g1, &b1);
        *r += (r1 - *r) * t; *g += (g1 - *g) * t; *b += (b1 - *b) * t;
    }
    const float si = e->params[ENV_P_INTENSITY];
    *r *= si; *g *= si; *b *= si;
}

/* Adds the ambient light times occlusion and ao to *r, *g, *b on the lanes `on`: the environment's (has_env) or
 * the constant `ambient`. */
static inline void layered_ambient(const LayeredV* s, int has_env, const EnvMaps* env, float ambient, floatV ao, floatV occlusion,
                     int multiscatter, floatV* r, floatV* g, floatV* b)
{
    const floatV sm = lb_max3(s->shr, s->shg, s->shb);
    const floatV sheen_scale = s->any_sheen ? fmax(1.0f - sm * s->sh_ev, 0.0f) : (floatV)1.0f;
    const floatV occ = occlusion * ao;
    floatV cr, cg, cb;
    if (!has_env) {
        const floatV k = ambient * occ * (1.0f - s->metallic) * sheen_scale * (1.0f - s->cc * s->fc);
        /* reflected + transmitted albedo: a constant ambient lights both sides alike */
        const floatV ar = s->any_dt ? s->kfr + s->kbr : s->kfr, ag = s->any_dt ? s->kfg + s->kbg : s->kfg;
        const floatV ab = s->any_dt ? s->kfb + s->kbb : s->kfb;
        cr = k * ar * (1.0f - lb_mix(s->sw * s->f0r, s->cr, s->metallic));
        cg = k * ag * (1.0f - lb_mix(s->sw * s->f0g, s->cg, s->metallic));
        cb = k * ab * (1.0f - lb_mix(s->sw * s->f0b, s->cb, s->metallic));
    } else {
        floatV er, eg, eb, A, B, C;
        env_irradianceV(env, s->n.x, s->n.y, s->n.z, &er, &eg, &eb);
        er *= s->kfr; eg *= s->kfg; eb *= s->kfb;         /* the diffuse radiance: E(N) c dw (1 - dt) ... */
        if (s->any_dt) {                                  /* ... + E(-N) dtc dw dt, the light through the surface */
            floatV tr, tg, tb;
            env_irradianceV(env, -s->n.x, -s->n.y, -s->n.z, &tr, &tg, &tb);
            er += tr * s->kbr; eg += tg * s->kbg; eb += tb * s->kbb;
        }
        env_dfgV(env, s->nv, s->rough, &A, &B, &C);
        vec3V nr = s->n;                        /* the normal R reflects about: ibl.glsl's bent normal with anisotropy */
        if (s->any_aniso) {
            const vec3V atan_ = lb_cross(s->ab, s->v);
            const vec3V an = lb_cross(atan_, s->ab);
            const floatV bf = 1.0f - s->aniso * (1.0f - s->rough), bf2 = bf * bf, bf4 = bf2 * bf2;
            const vec3V bent = lb_normalize((vec3V){ lb_mix(an.x, s->n.x, bf4), lb_mix(an.y, s->n.y, bf4),
                                                     lb_mix(an.z, s->n.z, bf4) });
            const intV on = s->aniso > 0.0f;
            nr.x = select(nr.x, bent.x, on); nr.y = select(nr.y, bent.y, on); nr.z = select(nr.z, bent.z, on);
        }
        const floatV kr = 2.0f * dot3V(nr, s->v);
        floatV pr, pg, pb, ru, rv;
        env_dir_uvV(kr * nr.x - s->v.x, kr * nr.y - s->v.y, kr * nr.z - s->v.z, env->params[ENV_P_ROTATION_U],
                    &ru, &rv);
        lb_env_specular_uvV(env, ru, rv, s->rough, &pr, &pg, &pb);
        const floatV nv5 = lb_pow5(1.0f - s->nv);
        const floatV fid_max = lb_max3(s->fidr, s->fidg, s->fidb);
#define LB_CHANNEL(c, f0, fid, fim, E, P) \
        lb_base_mix(s, E, P, lb_fss_ess(s->f0, s->sw, s->rough, nv5, A, B, multiscatter), \
                    lb_fss_ess(s->c, (floatV)1.0f, s->rough, nv5, A, B, multiscatter), s->fid, s->fim, fid_max)
        cr = LB_CHANNEL(cr, f0r, fidr, fimr, er, pr);
        cg = LB_CHANNEL(cg, f0g, fidg, fimg, eg, pg);
        cb = LB_CHANNEL(cb, f0b, fidb, fimb, eb, pb);
#undef LB_CHANNEL
        if (s->any_sheen) {
            lb_env_specular_uvV(env, ru, rv, s->sh_rough, &pr, &pg, &pb);
            cr = pr * s->shr * s->sh_ev + cr * sheen_scale;
            cg = pg * s->shg * s->sh_ev + cg * sheen_scale;
            cb = pb * s->shb * s->sh_ev + cb * sheen_scale;
        }
        if (s->any_cc) {
            const floatV kc = 2.0f * dot3V(s->ncc, s->v);
            env_dir_uvV(kc * s->ncc.x - s->v.x, kc * s->ncc.y - s->v.y, kc * s->ncc.z - s->v.z,
                        env->params[ENV_P_ROTATION_U], &ru, &rv);
            lb_env_specular_uvV(env, ru, rv, s->cc_rough, &pr, &pg, &pb);
            const floatV t = s->cc * s->fc;
            cr = lb_mix(cr, pr, t); cg = lb_mix(cg, pg, t); cb = lb_mix(cb, pb, t);
        }
        cr *= occ; cg *= occ; cb *= occ;
    }
    *r += select((floatV)0.0f, cr, s->on); *g += select((floatV)0.0f, cg, s->on);
    *b += select((floatV)0.0f, cb, s->on);
}

#endif
