/* environment_probe.cl: test-only kernel (tests/test_ibl.py). Runs environment.h's lookups on
 * given queries (Algorithm: environment.h's) so tests can compare them with NumPy implementations of the convention.
 *
 * Buffers: ENV_PARAMS (environment.h); q float[4 n] per query (x, y, z, w); out float[3 n].
 *   what 0: env_backgroundV(x, y, z); 1: env_irradianceV(x, y, z); 2: env_specularV(x, y, z,
 *   roughness w); 3: env_dfgV(n.v x, roughness w) -> (A, B, C); 4: env_radianceV(level (int)w, x, y, z).
 * Work-groups: 1-D, any size; work-item g answers queries g VEC .. g VEC + VEC - 1 (clamped, stores
 * bounds-checked); level (what 4) is the first lane's.
 */
#include "../environment.h"

kernel void env_probe(ENV_PARAMS, global const float* q, int n, int what, global float* out)
{
    const int first = get_global_id(0) * VEC;
    if (first >= n) return;
    const EnvMaps env = ENV_INIT;
    const intV i = min((intV)first + LANES, (intV)(n - 1));
    const floatV x = GATHER_F(q, 4 * i), y = GATHER_F(q, 4 * i + 1), z = GATHER_F(q, 4 * i + 2);
    const floatV w = GATHER_F(q, 4 * i + 3);
    floatV r = (floatV)0.0f, g = (floatV)0.0f, b = (floatV)0.0f;
    if (what == 0) env_backgroundV(&env, x, y, z, &r, &g, &b);
    else if (what == 1) env_irradianceV(&env, x, y, z, &r, &g, &b);
    else if (what == 2) env_specularV(&env, x, y, z, w, &r, &g, &b);
    else if (what == 3) env_dfgV(&env, x, w, &r, &g, &b);
    else env_radianceV(&env, (int)q[4 * first + 3], x, y, z, &r, &g, &b);
    for (int lane = 0; lane < VEC; ++lane) {
        if (first + lane >= n) break;
        out[3 * (first + lane)] = LANE_F(r, lane);
        out[3 * (first + lane) + 1] = LANE_F(g, lane);
        out[3 * (first + lane) + 2] = LANE_F(b, lane);
    }
}
