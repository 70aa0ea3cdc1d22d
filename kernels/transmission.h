/* transmission.h: what a transmissive fragment lets through (KHR_materials_transmission, _volume,
 * _dispersion), for forward.h's shading of transparent fragments (docs/transmission.md).
 *
 * Specifications: the KHR_materials_transmission README (Transmission BTDF: the dielectric base is
 * mix(diffuse_brdf(baseColor), specular_btdf · baseColor, transmission) under fresnel_mix; metals
 * transmit nothing), KHR_materials_volume (thicknessFactor × thicknessTexture.G in the mesh's space,
 * the node's scale applies; Beer's law T(x) = attenuationColor^(x / attenuationDistance)),
 * KHR_materials_dispersion (Implementation: halfSpread = (ior − 1)·0.025·dispersion, iors =
 * (ior − s, ior, ior + s) for R, G, B; from its Abbe text, n_F − n_C = (n_d − 1)/V_d with dispersion =
 * 20/V_d, so the half spread is (ior − 1)·dispersion/40: the same; R clamped to >= 1 as the README and
 * its Cauchy form max(…, 1) say), KHR_materials_specular (F0, F90) and the Khronos Sample Renderer's
 * screen-space method (a refracted lookup of the opaque colour, blurred at a mip level from roughness).
 *
 * Algorithm, per lane (transmission_eval; all linear):
 *   t     = clamp(transmission × texR, 0, 1);  diffuse weight kd = 1 − t
 *   f0_c  = min(((ior − 1)/(ior + 1))² × specular_color_c, 1) × specular_factor;  f90 = specular_factor
 *   F_c   = f0_c + (f90 − f0_c)(1 − NV)⁵,  NV = max(n·v, 1e-4)   (Schlick at the view: exact for the
 *           roughness-0 delta lobe)
 *   d     = thickness × texG × volume_scale   (thickness 0: thin-walled, d = 0)
 *   att_c = attenuation_color_c^(d / attenuation_distance)   (1 when d = 0 or the distance is inf)
 *   w_c   = a × t × (1 − metallic) × base_c × (1 − F_c) × att_c      (the transmitted weight)
 *   r_c   = refract(−v, n, 1/ior_c) (GLSL: 0 under total internal reflection), ior_c = ior ± the half
 *           spread with a volume; exit_c = P + r_c·d; offset_c = its projection − the pixel centre
 *           (pixels, x right, y down; 0 when thin-walled), by the camera planes (eye, F, R·tan_x,
 *           U·tan_y) in closed form: perspective, with z the view depth and (xn, yn) the pixel's NDC,
 *             ox = W/2 · d (r·R̂ − xn r·F)/(z + d r·F),  oy = −H/2 · d (r·Û − yn r·F)/(z + d r·F)
 *           (R̂ = R·tan_x/|R·tan_x|²), orthographic: ox = W/2 · d r·R̂, oy = −H/2 · d r·Û
 *   lod   = log2(max(W, H)) × roughness × clamp(2 ior − 2, 0, 1)   (applyIorToRoughness; −1 where a = 0)
 *   exit  = a back face (PRIM_BACKFACE) of a volume material (thickness factor > 0): the volume's
 *           far side, whose path the thickness already carries: it contributes nothing.
 * ior 0 (KHR_materials_ior: F0 = 1) reflects everything (w = 0); it refracts as ior 1.
 *
 * Lights seen through (transmission_lights): the README's specular_btdf for a punctual light or the sun
 * behind the surface, with the light mirrored onto the viewer's side as in its implementation notes and
 * the Khronos Sample Renderer. l = unit vector from the exit point (P + r_G·d: P when thin-walled) to
 * the light, only where n·l < 0; l' = l − 2(n·l)n, H = normalize(l' + v), NL = |n·l|,
 * α_t = max(roughness·clamp(2 ior − 2, 0, 1), MIN_ROUGHNESS)² (applyIorToRoughness, brdf.h's clamp):
 *   D_T = α_t² / (π ((n·H)²(α_t² − 1) + 1)²)
 *   V_T = 1 / ((NL + sqrt(α_t² + (1 − α_t²) NL²)) (NV + sqrt(α_t² + (1 − α_t²) NV²)))
 *         (the README's separable Smith G_T / (4 NL NV); its χ⁺ are 1 with the mirrored light: l' and v
 *         lie on n's side and H between them)
 *   radiance_c += I_c · A · S · D_T · V_T · NL × t (1 − m) c_c (1 − F_c) att_c   (= w_c / a: the blend
 *         multiplies the colour by a)
 * The cosine NL is included (the README's radiance integrand f·|n·l|; the Sample Renderer leaves it
 * out). A, S: lighting.h's falloff and spot cone at the exit point; the sun: A = 1, its irradiance. No
 * shadow map (the surface itself would shadow the light). Dispersion does not split this term (G's exit).
 *
 * Buffers: MaterialTx[] (structs.h; a material's index in Material.tx), tri_volume_scale float[T] (the
 * triangle's node scale |det M|^(1/3); read only where a material has a volume). Textures through
 * material_eval.h's sample_uv_set (the base slots' uv sets, transforms and trilinear LOD).
 */
#ifndef CLRENDER_TRANSMISSION_H
#define CLRENDER_TRANSMISSION_H
#pragma OPENCL FP_CONTRACT OFF
#include "structs.h"
#include "vec.h"
#include "surface_types.h"
#include "material_eval.h"     /* sample_uv_set */
#include "lighting.h"          /* LightEnv, light_at */

#ifndef ORTHO
#define ORTHO 0
#endif
#define TX_DISPERSION_HALF_SPREAD 0.025f   /* KHR_materials_dispersion: (ior − 1)·0.025·dispersion */

/* What the transmissive lanes let through; the other lanes: t = 0, kd = 1, w = 0, offsets 0, lod −1. */
typedef struct {
    floatV t, kd;                       /* transmission and the diffuse weight 1 − t */
    floatV wr, wg, wb;                  /* transmitted weight per channel */
    floatV oxr, oyr, oxg, oyg, oxb, oyb;   /* refracted lookup offsets per channel, pixels (x right, y down) */
    floatV lod;                         /* blur level of the lookup (>= 0); −1: the lane sets no lookup */
    floatV ur, ug, ub;                  /* w without the coverage a (the lights seen through: the blend × a) */
    floatV a2;                          /* α_t² of the lights seen through */
    floatV ex, ey, ez;                  /* exit − P = r_G·d (0 when thin-walled) */
    intV exit;                          /* exit face of a volume: contributes nothing */
} TransmissionV;

/* Texture slot `slot` of the MaterialTx records txi where `on` and the slot has a texture (*hit);
 * (1, 1, 1, 1) elsewhere. */
static rgbaV sample_tx_slot(const SceneV* sc, const BaryV* b, global const MaterialTx* txr, intV txi, int slot,
                            intV on, intV* hit)
{
    const intV tex = GATHER_MS(intV, txr, txi, slots[slot].texture);
    intV active = on & (tex >= 0);
#if VEC == 1
    active = active ? 1 : 0;
#endif
    *hit = active;
    rgbaV out = { 1.0f, 1.0f, 1.0f, 1.0f };
    if (!ANY(active)) return out;
    FootprintV fp;
    const rgbaV t = sample_uv_set(sc, b, tex, GATHER_MS(intV, txr, txi, slots[slot].texcoord),
                                  GATHER_MS(floatV, txr, txi, slots[slot].uv[0]),
                                  GATHER_MS(floatV, txr, txi, slots[slot].uv[1]),
                                  GATHER_MS(floatV, txr, txi, slots[slot].uv[2]),
                                  GATHER_MS(floatV, txr, txi, slots[slot].uv[3]),
                                  GATHER_MS(floatV, txr, txi, slots[slot].uv[4]),
                                  GATHER_MS(floatV, txr, txi, slots[slot].uv[5]), active, &fp);
    out.r = select(out.r, t.r, active); out.g = select(out.g, t.g, active);
    out.b = select(out.b, t.b, active); out.a = select(out.a, t.a, active);
    return out;
}

/* The unit refracted direction r = refract(−v, n, 1/ior) (GLSL: 0 under total internal reflection). */
static inline vec3V tx_refract(floatV ior, floatV nv, vec3V n, vec3V v)
{
    const floatV eta = 1.0f / ior;
    const floatV k = 1.0f - eta * eta * (1.0f - nv * nv);
    const floatV kn = eta * nv - sqrt(fmax(k, 0.0f));
    const intV tir = k < 0.0f;
    vec3V r = { select(-eta * v.x + kn * n.x, (floatV)0.0f, tir), select(-eta * v.y + kn * n.y, (floatV)0.0f, tir),
                select(-eta * v.z + kn * n.z, (floatV)0.0f, tir) };
    const floatV r2 = dot3V(r, r);
    const floatV inv_r = select((floatV)0.0f, RSQRT(fmax(r2, 1e-30f)), r2 > 0.0f);
    r.x *= inv_r; r.y *= inv_r; r.z *= inv_r;
    return r;
}

/* One channel's refracted lookup offset (header) of the unit refracted direction r: exit = P + r·d. */
static inline void tx_offset(vec3V r, floatV d, float3 F, float3 Rh, float3 Uh, floatV xn, floatV yn, floatV z,
                             int width, int height, floatV* ox, floatV* oy)
{
    const floatV rr = r.x * Rh.x + r.y * Rh.y + r.z * Rh.z, ru = r.x * Uh.x + r.y * Uh.y + r.z * Uh.z;
#if ORTHO
    *ox = (0.5f * (float)width) * (d * rr);
    *oy = -(0.5f * (float)height) * (d * ru);
    (void)xn; (void)yn; (void)z; (void)F;
#else
    const floatV rf = r.x * F.x + r.y * F.y + r.z * F.z;
    const floatV ze = fmax(z + d * rf, 1e-6f);      /* the exit point's view depth (in front of the eye) */
    *ox = (0.5f * (float)width) * (d * (rr - xn * rf)) / ze;
    *oy = -(0.5f * (float)height) * (d * (ru - yn * rf)) / ze;
#endif
}

/* The header's per-lane quantities for the lanes `on` with MaterialTx index txi (>= 0 there):
 * tex_t, tex_d the transmission (R) and thickness (G) texture values (1 without a texture),
 * volume_scale the triangle's node scale, backface PRIM_BACKFACE, metallic, roughness (perceptual),
 * base colour c, coverage alpha a, the unit shading normal n (facing the viewer) and direction v
 * to the eye, the pixel's NDC (xn, yn; lighting.h pixel_positions) and view depth z, the camera
 * block (eye, F, R·tan_x, U·tan_y) and the image size. */
static TransmissionV transmission_eval(global const MaterialTx* txr, intV txi, intV on, floatV tex_t, floatV tex_d,
                                       floatV volume_scale, intV backface, floatV metallic, floatV rough, floatV cr,
                                       floatV cg, floatV cb, floatV a, vec3V n, vec3V v, global const float* camera,
                                       int width, int height, floatV xn, floatV yn, floatV z)
{
    TransmissionV o;
    const intV i = select((intV)0, txi, on);
#define TXF(m) GATHER_MS(floatV, txr, i, m)
    const floatV t = select((floatV)0.0f, clamp(TXF(transmission) * tex_t, 0.0f, 1.0f), on);
    const floatV thick = TXF(thickness);
    intV volume = on & (thick > 0.0f);
    const floatV d = select((floatV)0.0f, thick * tex_d * volume_scale, volume);
    const floatV ior = TXF(ior), sfac = TXF(specular_factor);
    const floatV q = (ior - 1.0f) / (ior + 1.0f), f0 = q * q;
    const floatV nv_raw = dot3V(n, v), nv = fmax(nv_raw, 1e-4f);
    const floatV u = 1.0f - nv, u2 = u * u, u5 = u2 * u2 * u;
    const floatV f0r = fmin(f0 * TXF(specular_color[0]), 1.0f) * sfac;
    const floatV f0g = fmin(f0 * TXF(specular_color[1]), 1.0f) * sfac;
    const floatV f0b = fmin(f0 * TXF(specular_color[2]), 1.0f) * sfac;
    const floatV dist = TXF(attenuation_distance);
    const floatV expo = d / dist;
    const intV absorbs = (d > 0.0f) & (dist < INFINITY);
    const floatV kt = a * t * (1.0f - metallic), kt1 = t * (1.0f - metallic);
    const floatV ftr = 1.0f - (f0r + (sfac - f0r) * u5), ftg = 1.0f - (f0g + (sfac - f0g) * u5);
    const floatV ftb = 1.0f - (f0b + (sfac - f0b) * u5);
    const floatV wr = kt * cr * ftr, wg = kt * cg * ftg, wb = kt * cb * ftb;
    const floatV ur = kt1 * cr * ftr, ug = kt1 * cg * ftg, ub = kt1 * cb * ftb;
    o.exit = volume & (backface != 0);
#if VEC == 1
    o.exit = o.exit ? 1 : 0;
#endif
    const intV lets = on & !o.exit;
    o.t = t;
    o.kd = 1.0f - t;
    const floatV attr = pow(TXF(attenuation_color[0]), expo), attg = pow(TXF(attenuation_color[1]), expo);
    const floatV attb = pow(TXF(attenuation_color[2]), expo);
    o.wr = select((floatV)0.0f, select(wr, wr * attr, absorbs), lets);
    o.wg = select((floatV)0.0f, select(wg, wg * attg, absorbs), lets);
    o.wb = select((floatV)0.0f, select(wb, wb * attb, absorbs), lets);
    o.ur = select((floatV)0.0f, select(ur, ur * attr, absorbs), lets);
    o.ug = select((floatV)0.0f, select(ug, ug * attg, absorbs), lets);
    o.ub = select((floatV)0.0f, select(ub, ub * attb, absorbs), lets);

    const float3 F = vload4(1, camera).xyz, Rs = vload4(2, camera).xyz, Us = vload4(3, camera).xyz;
    const float3 Rh = Rs / dot(Rs, Rs), Uh = Us / dot(Us, Us);
    const floatV ior_g = fmax(ior, 1.0f);           /* ior 0 (F0 = 1): nothing goes through; no bend */
    const floatV s = select((floatV)0.0f, (ior_g - 1.0f) * TX_DISPERSION_HALF_SPREAD * TXF(dispersion), volume);
    o.oxr = 0.0f; o.oyr = 0.0f; o.oxg = 0.0f; o.oyg = 0.0f; o.oxb = 0.0f; o.oyb = 0.0f;
    o.ex = 0.0f; o.ey = 0.0f; o.ez = 0.0f;
    if (ANY(volume & lets)) {
        const vec3V rg = tx_refract(ior_g, nv_raw, n, v);
        tx_offset(rg, d, F, Rh, Uh, xn, yn, z, width, height, &o.oxg, &o.oyg);
        o.ex = select((floatV)0.0f, rg.x * d, volume & lets);
        o.ey = select((floatV)0.0f, rg.y * d, volume & lets);
        o.ez = select((floatV)0.0f, rg.z * d, volume & lets);
        if (ANY(s > 0.0f)) {
            tx_offset(tx_refract(fmax(ior_g - s, 1.0f), nv_raw, n, v), d, F, Rh, Uh, xn, yn, z, width, height, &o.oxr,
                      &o.oyr);
            tx_offset(tx_refract(ior_g + s, nv_raw, n, v), d, F, Rh, Uh, xn, yn, z, width, height, &o.oxb, &o.oyb);
        } else {
            o.oxr = o.oxg; o.oyr = o.oyg; o.oxb = o.oxg; o.oyb = o.oyg;
        }
        const intV keep = volume & lets;
        o.oxr = select((floatV)0.0f, o.oxr, keep); o.oyr = select((floatV)0.0f, o.oyr, keep);
        o.oxg = select((floatV)0.0f, o.oxg, keep); o.oyg = select((floatV)0.0f, o.oyg, keep);
        o.oxb = select((floatV)0.0f, o.oxb, keep); o.oyb = select((floatV)0.0f, o.oyb, keep);
    }
    const floatV rt = rough * clamp(2.0f * ior - 2.0f, 0.0f, 1.0f);   /* applyIorToRoughness */
    const floatV lod = log2((float)max(width, height)) * rough * clamp(2.0f * ior - 2.0f, 0.0f, 1.0f);
    const floatV at = fmax(rt, MIN_ROUGHNESS) * fmax(rt, MIN_ROUGHNESS);
    o.a2 = at * at;
    o.lod = select((floatV)-1.0f, lod, lets & (a > 0.0f));   /* a surface that is not there refracts nothing */
#undef TXF
    return o;
}

/* transmission_eval for the surface sf of the lanes `on` (txi their MaterialTx index; a their coverage
 * alpha): its textures sampled, the volume scale read where a material has a volume. */
static TransmissionV transmission_lanes(const SceneV* sc, const BaryV* b, const SurfaceV* sf,
                                        global const MaterialTx* txr, global const float* tri_volume_scale, intV txi,
                                        intV on, floatV a, vec3V v, global const float* camera, int width,
                                        int height, floatV xn, floatV yn, floatV z)
{
    const intV i = select((intV)0, txi, on);
    intV hit;
    const floatV tex_t = sample_tx_slot(sc, b, txr, i, TXSLOT_TRANSMISSION, on, &hit).r;
    intV volume = on & (GATHER_MS(floatV, txr, i, thickness) > 0.0f);
#if VEC == 1
    volume = volume ? 1 : 0;
#endif
    floatV tex_d = 1.0f, scale = 1.0f;
    if (ANY(volume)) {
        tex_d = sample_tx_slot(sc, b, txr, i, TXSLOT_THICKNESS, volume, &hit).g;
        scale = select((floatV)1.0f, GATHER_FS(tri_volume_scale, select((intV)0, sf->tri, volume)), volume);
    }
    return transmission_eval(txr, i, on, tex_t, tex_d, scale, sf->flags & (int)PRIM_BACKFACE, sf->spec_i, sf->spec_p,
                             sf->r, sf->g, sf->b, a, sf->n, v, camera, width, height, xn, yn, z);
}

/* One light's specular BTDF term (header, "Lights seen through") at the lanes `on`, light direction l
 * (unit, from the exit point towards the light) and A·(spot) `atten`: adds A·D_T·V_T·|n·l|·colour to the
 * sums where n·l < 0 (the light behind the surface). */
static inline void tx_light_add(intV on, vec3V n, vec3V v, floatV nv, floatV a2, floatV lx, floatV ly, floatV lz,
                                floatV atten, float cr, float cg, float cb, floatV* sr, floatV* sg, floatV* sb)
{
    const floatV nl = n.x * lx + n.y * ly + n.z * lz;
    const intV behind = on & (nl < 0.0f) & (atten > 0.0f);
    if (!ANY(behind)) return;
    const floatV mx = lx - 2.0f * nl * n.x, my = ly - 2.0f * nl * n.y, mz = lz - 2.0f * nl * n.z;   /* mirrored */
    const floatV hx = mx + v.x, hy = my + v.y, hz = mz + v.z;
    const floatV inv_h = RSQRT(fmax(hx * hx + hy * hy + hz * hz, 1e-30f));
    const floatV nh = fmax((n.x * hx + n.y * hy + n.z * hz) * inv_h, 0.0f), anl = -nl;
    /* D_T, with q = nh²α² + (1 − nh)(1 + nh): 1 − nh² kept in float32 where α² ≪ 1 */
    const floatV q = nh * nh * a2 + (1.0f - nh) * (1.0f + nh);
    const floatV d = a2 * INV_PI / fmax(q * q, 1e-30f);
    const floatV vis = 1.0f / ((anl + sqrt(a2 + (1.0f - a2) * (anl * anl)))
                               * (nv + sqrt(a2 + (1.0f - a2) * (nv * nv))));
    const floatV k = select((floatV)0.0f, atten * d * vis * anl, behind);
    *sr += k * cr; *sg += k * cg; *sb += k * cb;
}

/* The punctual lights (the tile's `count` from `first`, or all with BRUTE_FORCE; then the sun) seen
 * through the transmissive lanes `on` of tx at points P (wx, wy, wz), unit normal n facing the viewer,
 * unit v: adds Σ I·D_T·V_T·|n·l| × (t (1 − m) c_c (1 − F_c) att_c) to (*r, *g, *b) (header). No shadows. */
static void transmission_lights(const LightEnv* env, int first, int count, intV on, const TransmissionV* tx,
                                floatV wx, floatV wy, floatV wz, vec3V n, vec3V v, floatV* r, floatV* g, floatV* b)
{
    const floatV qx = wx + tx->ex, qy = wy + tx->ey, qz = wz + tx->ez;   /* the exit point */
    const floatV nv = fmax(n.x * v.x + n.y * v.y + n.z * v.z, 1e-4f);
    floatV sr = 0.0f, sg = 0.0f, sb = 0.0f;
    for (int k = 0; k < count; ++k) {
        floatV lx, ly, lz, atten;
        intV near_enough;
        const Light lt = light_at(env, first, k, on, qx, qy, qz, &near_enough, &lx, &ly, &lz, &atten);
        if (!ANY(near_enough)) continue;
        tx_light_add(near_enough, n, v, nv, tx->a2, lx, ly, lz, atten, lt.color[0], lt.color[1], lt.color[2],
                     &sr, &sg, &sb);
    }
    if (env->has_sun) {                    /* the sun: no falloff, the irradiance as colour */
        global const float* sun = env->sun;
        tx_light_add(on, n, v, nv, tx->a2, (floatV)-sun[0], (floatV)-sun[1], (floatV)-sun[2], (floatV)1.0f, sun[3],
                     sun[4], sun[5], &sr, &sg, &sb);
    }
    *r = select(*r, *r + sr * tx->ur, on);
    *g = select(*g, *g + sg * tx->ug, on);
    *b = select(*b, *b + sb * tx->ub, on);
}
#endif
