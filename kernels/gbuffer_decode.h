/* gbuffer_decode.h: what the lighting passes read back from the G-buffer's planes, decoded as
 * shade.cl, the light pre-pass's light buffer (light_buffer.cl) and the light-indexed forward
 * pass (forward_shade.cl, which decodes the planes it has just packed, so every pipeline lights
 * the same quantized surface).
 */
#ifndef CLRENDER_GBUFFER_DECODE_H
#define CLRENDER_GBUFFER_DECODE_H
#include "gbuffer.h"

typedef struct {
    floatV nx, ny, nz;          /* unit normal */
    floatV spec_p;              /* specular power */
    floatV depth;               /* view depth (linear depth · far), 0 on background */
} LitPointV;

/* Normal, power and depth from the normal/power and linear-depth words of foreground lanes fg. */
static inline LitPointV decode_lit_point(uintV w_nrm, uintV w_depth, intV fg, float far)
{
    LitPointV s;
    s.depth = select((floatV)0.0f, as_floatV(w_depth) * far, fg);
    s.spec_p = exp2(convert_floatV((w_nrm >> GB_SPECULAR_POWER_SHIFT) & 255u) * (SPEC_POWER_LOG2_MAX / 255.0f));
    floatV fx, fy, fz;
    unpack_oct12x2V(w_nrm >> GB_NORMAL_SHIFT, &fx, &fy, &fz);
    const floatV inv_n = rsqrt(fx * fx + fy * fy + fz * fz);
    s.nx = fx * inv_n; s.ny = fy * inv_n; s.nz = fz * inv_n;
    return s;
}

/* Linear albedo and specular intensity from the albedo/specular word. */
static inline void decode_albedo(uintV w_alb, constant float* srgb_lut, floatV* ar, floatV* ag, floatV* ab,
                                 floatV* spec_i)
{
    const uintV alb = w_alb >> GB_ALBEDO_SHIFT;
    *ar = GATHER_F(srgb_lut, as_intV(alb & 255u));
    *ag = GATHER_F(srgb_lut, as_intV((alb >> 8) & 255u));
    *ab = GATHER_F(srgb_lut, as_intV((alb >> 16) & 255u));
    *spec_i = convert_floatV((w_alb >> GB_SPECULAR_INTENSITY_SHIFT) & 255u) * (1.0f / 255.0f);
}
#endif
