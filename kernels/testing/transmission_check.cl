/* transmission_check.cl: test-only kernel (tests/test_transmission_kernel.py). Runs transmission.h's
 * transmission_eval on given queries so the test can compare it with a float64 NumPy evaluation of the
 * KHR_materials_transmission / _volume / _dispersion formulas.
 *
 * txr: MaterialTx[] records; camera float[16] (eye, F, R·tan_x, U·tan_y as float4, principal point in
 * eye.w, F.w), width, height. q float[TC_IN * n] per query: tx index, pixel x, pixel y, view depth z,
 * texture R (transmission), texture G (thickness), volume scale, back face (0/1), metallic, roughness,
 * base colour (3), alpha, shading normal (3). P and v follow from the pixel and z as forward.h builds
 * them (ORTHO: parallel rays).
 * out float[TC_OUT * n]: t, kd, w (3), offsets R (x, y), G (x, y), B (x, y), lod, exit (0/1).
 * Work-item g answers queries g VEC .. g VEC + VEC - 1 (clamped, stores bounds-checked).
 */
#pragma OPENCL FP_CONTRACT OFF
#include "../transmission.h"

#define TC_IN 17
#define TC_OUT 13

kernel void transmission_check(global const MaterialTx* txr, global const float* camera, int width, int height,
                               global const float* q, int n, global float* out)
{
    const int first = get_global_id(0) * VEC;
    if (first >= n) return;
    const intV i = min((intV)first + LANES, (intV)(n - 1));
    intV on = (intV)first + LANES < n;
#if VEC == 1
    on = on ? 1 : 0;
#endif
    const intV base = TC_IN * i;
#define Q(k) GATHER_F(q, base + (k))
    const float3 F = vload4(1, camera).xyz, Rs = vload4(2, camera).xyz, Us = vload4(3, camera).xyz;
    const floatV xn = (Q(1) + 0.5f) * (2.0f / (float)width) - (1.0f + camera[3]);
    const floatV yn = (1.0f - camera[7]) - (Q(2) + 0.5f) * (2.0f / (float)height);
#if ORTHO
    const floatV dx = F.x, dy = F.y, dz = F.z;
#else
    const floatV dx = F.x + xn * Rs.x + yn * Us.x, dy = F.y + xn * Rs.y + yn * Us.y, dz = F.z + xn * Rs.z + yn * Us.z;
#endif
    const floatV inv_d = RSQRT(dx * dx + dy * dy + dz * dz);
    const vec3V v = { -dx * inv_d, -dy * inv_d, -dz * inv_d };
    const vec3V nn = { Q(14), Q(15), Q(16) };
    const intV back = convert_intV(Q(7));
    const TransmissionV o = transmission_eval(txr, convert_intV(Q(0)), on, Q(4), Q(5), Q(6), back, Q(8), Q(9),
                                              Q(10), Q(11), Q(12), Q(13), nn, v, camera, width, height, xn, yn, Q(3));
#undef Q
    const floatV ex = select((floatV)0.0f, (floatV)1.0f, o.exit);
    const floatV res[TC_OUT] = { o.t, o.kd, o.wr, o.wg, o.wb, o.oxr, o.oyr, o.oxg, o.oyg, o.oxb, o.oyb, o.lod, ex };
    for (int lane = 0; lane < VEC; ++lane) {
        if (first + lane >= n) break;
        for (int k = 0; k < TC_OUT; ++k) out[TC_OUT * (first + lane) + k] = LANE_F(res[k], lane);
    }
}
