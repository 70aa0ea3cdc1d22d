/* particles.cl: animated light particles (report V.1), updated on the device every frame.
 *
 * Algorithm: one work-item per particle light. A particle is a pure function of (seed, index,
 * time): it has a lifetime drawn once; at time t it is in generation g = floor((t + phase) /
 * lifetime) at age a = t + phase - g·lifetime; each generation respawns at a hashed position
 * in the system's box, moving in a hashed direction at `speed`, its intensity fading in and
 * out over the lifetime (4·x·(1 - x), x = a/lifetime). No state is integrated, so every device, thread
 * count and frame order gives the same lights for the same seed and time (integer hashing;
 * float steps in a fixed order without contraction).
 *
 * Buffers: lights Light[*] (the system's slice [first, first + count) is rewritten).
 * Work-groups: 1-D, any size; no barriers.
 */
#pragma OPENCL FP_CONTRACT OFF
#include "structs.h"

static inline uint hash_u32(uint x)   /* lowbias32 (C. Wellons) */
{
    x ^= x >> 16; x *= 0x7feb352dU; x ^= x >> 15; x *= 0x846ca68bU; x ^= x >> 16;
    return x;
}

/* Uniform float in [0, 1) from (seed, particle, generation, channel). */
static inline float rand01(uint seed, uint particle, uint generation, uint channel)
{
    uint h = hash_u32(seed ^ hash_u32(particle * 0x9e3779b9U ^ hash_u32(generation * 0x85ebca6bU + channel)));
    return (float)(h >> 8) * (1.0f / 16777216.0f);
}

kernel void update_particles(global Light* lights, int first, int count, uint seed, float time,
                             float lo_x, float lo_y, float lo_z, float hi_x, float hi_y, float hi_z,
                             float speed, float life_min, float life_max, float radius_min, float radius_max,
                             float intensity)
{
    int i = get_global_id(0);
    if (i >= count) return;
    uint p = (uint)i;
    float life = life_min + rand01(seed, p, 0xffffffffU, 0) * (life_max - life_min);
    float phase = rand01(seed, p, 0xffffffffU, 1) * life;
    float cycles = floor((time + phase) / life);
    float age = (time + phase) - cycles * life;
    uint g = (uint)(int)cycles;
    float3 start = (float3)(lo_x + rand01(seed, p, g, 2) * (hi_x - lo_x),
                            lo_y + rand01(seed, p, g, 3) * (hi_y - lo_y),
                            lo_z + rand01(seed, p, g, 4) * (hi_z - lo_z));
    /* Direction and fade use only +, -, *, / (correctly rounded): no sin/cos/sqrt whose
     * precision differs between devices. The direction is uniform in a cube, not normalized. */
    float3 dir = (float3)(rand01(seed, p, g, 5) * 2.0f - 1.0f, rand01(seed, p, g, 6) * 2.0f - 1.0f,
                          rand01(seed, p, g, 7) * 2.0f - 1.0f);
    float3 pos = (float3)(start.x + dir.x * (speed * age), start.y + dir.y * (speed * age),
                          start.z + dir.z * (speed * age));
    float a = age / life;
    float fade = 4.0f * a * (1.0f - a);
    Light l;
    l.position[0] = pos.x; l.position[1] = pos.y; l.position[2] = pos.z;
    l.radius = radius_min + rand01(seed, p, 0xffffffffU, 2) * (radius_max - radius_min);
    l.color[0] = intensity * fade * (0.2f + 0.8f * rand01(seed, p, 0xffffffffU, 8));
    l.color[1] = intensity * fade * (0.2f + 0.8f * rand01(seed, p, 0xffffffffU, 9));
    l.color[2] = intensity * fade * (0.2f + 0.8f * rand01(seed, p, 0xffffffffU, 10));
    l.type = LIGHT_POINT;
    l.direction[0] = 0.0f; l.direction[1] = 0.0f; l.direction[2] = -1.0f;
    l.cos_outer = 0.0f; l.cos_inner = 0.0f;
    l.shadow_size = 0; l.shadow = -1;     /* particles cast no shadow */
    l.falloff = LIGHT_FALLOFF_REPORT;      /* the report's window, like every light made by the API */
    lights[first + i] = l;
}
