/* layout_probe.cl: test-only kernels. Reports struct sizes/offsets as the device compiler
 * sees them, and runs the G-buffer pack functions on given inputs, so tests can compare
 * them with clrender/abi/structs.py and the NumPy codecs in clrender/abi/gbuffer.py.
 * Work-groups: 1-D, any size. */
#define VEC 1
#include "../structs.h"
#include "../gbuffer.h"

#define OFF(T, f) ((int)(size_t)&(((T*)0)->f))

kernel void struct_layout(global int* out)
{
    if (get_global_id(0) != 0) return;
    int i = 0;
    out[i++] = sizeof(Prim);     out[i++] = OFF(Prim, x);     out[i++] = OFF(Prim, tri);
    out[i++] = OFF(Prim, y);     out[i++] = OFF(Prim, flags); out[i++] = OFF(Prim, inv_w);
    out[i++] = OFF(Prim, material); out[i++] = OFF(Prim, bary1); out[i++] = OFF(Prim, bary2);
    out[i++] = OFF(Prim, area);
    out[i++] = sizeof(TexSlot);  out[i++] = OFF(TexSlot, uv); out[i++] = OFF(TexSlot, texture);
    out[i++] = OFF(TexSlot, texcoord);
    out[i++] = sizeof(Material); out[i++] = OFF(Material, base_color); out[i++] = OFF(Material, emissive);
    out[i++] = OFF(Material, emissive_strength); out[i++] = OFF(Material, spec_intensity);
    out[i++] = OFF(Material, spec_power); out[i++] = OFF(Material, metallic); out[i++] = OFF(Material, roughness);
    out[i++] = OFF(Material, normal_scale); out[i++] = OFF(Material, occlusion_strength);
    out[i++] = OFF(Material, alpha_cutoff); out[i++] = OFF(Material, flags); out[i++] = OFF(Material, refraction);
    out[i++] = OFF(Material, ext); out[i++] = OFF(Material, tx); out[i++] = OFF(Material, door_alpha);
    out[i++] = OFF(Material, slots);
    out[i++] = sizeof(TexInfo);  out[i++] = OFF(TexInfo, first_level); out[i++] = OFF(TexInfo, levels);
    out[i++] = OFF(TexInfo, wrap_s); out[i++] = OFF(TexInfo, wrap_t); out[i++] = OFF(TexInfo, lut);
    out[i++] = OFF(TexInfo, pad);
    out[i++] = sizeof(TexLevel); out[i++] = OFF(TexLevel, offset); out[i++] = OFF(TexLevel, width);
    out[i++] = OFF(TexLevel, height); out[i++] = OFF(TexLevel, pad);
    out[i++] = sizeof(Light);    out[i++] = OFF(Light, position); out[i++] = OFF(Light, radius);
    out[i++] = OFF(Light, color); out[i++] = OFF(Light, type); out[i++] = OFF(Light, direction);
    out[i++] = OFF(Light, cos_outer); out[i++] = OFF(Light, cos_inner); out[i++] = OFF(Light, shadow_size);
    out[i++] = OFF(Light, shadow); out[i++] = OFF(Light, falloff);
    out[i++] = sizeof(ShadowView); out[i++] = OFF(ShadowView, m); out[i++] = OFF(ShadowView, x0);
    out[i++] = OFF(ShadowView, y0); out[i++] = OFF(ShadowView, size); out[i++] = OFF(ShadowView, ortho);
    out[i++] = OFF(ShadowView, texel); out[i++] = OFF(ShadowView, far); out[i++] = OFF(ShadowView, split);
    out[i++] = OFF(ShadowView, pad);
    out[i++] = sizeof(MaterialExt); out[i++] = OFF(MaterialExt, specular_color);
    out[i++] = OFF(MaterialExt, specular_factor); out[i++] = OFF(MaterialExt, ior); out[i++] = OFF(MaterialExt, clearcoat);
    out[i++] = OFF(MaterialExt, clearcoat_roughness); out[i++] = OFF(MaterialExt, clearcoat_normal_scale);
    out[i++] = OFF(MaterialExt, sheen_color); out[i++] = OFF(MaterialExt, sheen_roughness);
    out[i++] = OFF(MaterialExt, iridescence); out[i++] = OFF(MaterialExt, iridescence_ior);
    out[i++] = OFF(MaterialExt, iridescence_thickness_min); out[i++] = OFF(MaterialExt, iridescence_thickness_max);
    out[i++] = OFF(MaterialExt, anisotropy_strength); out[i++] = OFF(MaterialExt, anisotropy_cos);
    out[i++] = OFF(MaterialExt, anisotropy_sin); out[i++] = OFF(MaterialExt, layers);
    out[i++] = OFF(MaterialExt, diffuse_transmission); out[i++] = OFF(MaterialExt, diffuse_transmission_color);
    out[i++] = OFF(MaterialExt, slots);
    out[i++] = sizeof(MaterialTx); out[i++] = OFF(MaterialTx, transmission); out[i++] = OFF(MaterialTx, thickness);
    out[i++] = OFF(MaterialTx, attenuation_distance); out[i++] = OFF(MaterialTx, dispersion);
    out[i++] = OFF(MaterialTx, attenuation_color); out[i++] = OFF(MaterialTx, ior);
    out[i++] = OFF(MaterialTx, specular_color); out[i++] = OFF(MaterialTx, specular_factor);
    out[i++] = OFF(MaterialTx, slots);
    out[i++] = -12345;                 /* end marker: the test checks that every entry above was read */
}

/* in: float4 per item (x, y, z, w); out: uint4 per item: srgb8x3(xyz), oct12x2(xyz),
 * log2unorm8(w), half2(x, y); out2: pack_float2((x, y), 16) — the report's packing. */
kernel void pack_probe(global const float4* in, constant float2* srgb_encode, int n, global uint4* out,
                       global uint* out2)
{
    int i = get_global_id(0);
    if (i >= n) return;
    float4 v = in[i];
    out[i] = (uint4)(pack_srgb8x3V(v.x, v.y, v.z, srgb_encode), pack_oct12x2V(v.x, v.y, v.z), pack_log2unorm8V(v.w),
                     pack_half2V(v.x, v.y));
    out2[i] = pack_float2V(v.x, v.y, 16);
}
