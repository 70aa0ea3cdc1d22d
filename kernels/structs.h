/* Structs shared by host and device. clrender/abi/structs.py holds the matching numpy dtypes
 * (tests/test_gbuffer.py::test_struct_layouts_match_device checks sizes and offsets on every
 * device). Only 32/64-bit scalars and fixed arrays: no bool, no float3, so the layout is the same
 * on every compiler. */
#ifndef CLRENDER_STRUCTS_H
#define CLRENDER_STRUCTS_H

/* Prim.flags */
#define PRIM_BACKFACE 1u   /* back face of a double-sided material: flip its normal */
#define PRIM_MASKED   2u   /* alpha MASK material: sample alpha in the raster loop */
#define PRIM_DITHER   4u   /* screen-door BLEND material: the alpha threshold is a 4x4 ordered dither */

/* Material.flags */
#define MAT_DOUBLE_SIDED 1u
#define MAT_MASK         2u
#define MAT_BLEND        4u
#define MAT_METALLIC_ROUGHNESS 8u   /* metallic/roughness mapped per pixel (docs/materials.md) */
#define MAT_UNLIT        16u        /* KHR_materials_unlit: colour = base colour */
#define MAT_SHARES(slot) (32u << ((slot) - 1))   /* slot 1..4 reads the base colour's footprint (material_eval.h) */
#define MAT_GLTF_BRDF    512u       /* shaded with the glTF 2.0 BRDF (brdf.h; set on metallic-roughness
                                       materials unless RenderConfig.shading = "blinn_phong") */
#define MAT_TRANSMISSION 1024u      /* KHR_materials_transmission: a fragment like BLEND (MAT_BLEND is set
                                       too), shaded by transmission.h with its MaterialTx (docs/transmission.md) */
#define MAT_TX_ALPHA     2048u      /* a transmissive material whose alphaMode is BLEND: alpha is its coverage
                                       (OPAQUE: coverage 1, glTF ignores alpha; MASK: alpha >= cutoff) */

/* Setup status per input triangle (a byte); STATUS_CLIPPED is or-ed in. */
#define STATUS_EMITTED    0
#define STATUS_INVALID    1   /* non-finite vertex */
#define STATUS_CULLED_NEAR 2  /* entirely in front of the near plane */
#define STATUS_DEGENERATE 3   /* zero area once snapped */
#define STATUS_BACKFACE   4   /* back face of a single-sided material */
#define STATUS_OFFSCREEN  5   /* covers no pixel center of the image */
#define STATUS_TRANSPARENT 6  /* not this setup's kind: BLEND triangles left to the transparency pass */
#define STATUS_CLIPPED    16

/* A screen-space triangle ready to rasterize: a whole input triangle or one piece of a
 * clipped one. Vertices are 24.8 fixed point and ordered so that `area` > 0. */
typedef struct {
    int   x[3];
    int   tri;        /* input triangle index = Frame.triangle_id */
    int   y[3];
    uint  flags;      /* PRIM_* */
    float inv_w[3];   /* 1 / view depth at each vertex */
    int   material;
    float bary1[3];   /* barycentric coordinates (b1, b2) of each vertex in the input triangle */
    float bary2[3];
    long  area;       /* twice the signed area, 24.8 units squared */
} Prim;

/* Material.slots: the texture slots (clrender.scene.TEXTURE_SLOTS order) */
#define SLOT_BASE      0
#define SLOT_MR        1
#define SLOT_NORMAL    2
#define SLOT_OCCLUSION 3
#define SLOT_EMISSIVE  4
#define SLOT_COUNT     5

/* Where a material's texture slot reads: uv' = (uv[0] u + uv[1] v + uv[2], uv[3] u + uv[4] v + uv[5])
 * of vertex set `texcoord` (KHR_texture_transform, texCoord). */
typedef struct {
    float uv[6];
    int   texture;        /* index into TexInfo, -1 = none */
    int   texcoord;       /* vertex uv set */
} TexSlot;

typedef struct {
    float base_color[4];  /* linear RGBA factor (opacity folded into alpha) */
    float emissive[3];    /* linear factor in [0, 1] */
    float emissive_strength;
    float spec_intensity; /* Blinn-Phong terms (MAT_METALLIC_ROUGHNESS clear) */
    float spec_power;
    float metallic;       /* metallic-roughness factors (MAT_METALLIC_ROUGHNESS set) */
    float roughness;
    float normal_scale;
    float occlusion_strength;
    float alpha_cutoff;
    uint  flags;          /* MAT_* */
    float refraction;     /* BLEND: screen-space distortion strength of what lies behind (docs/transparency.md) */
    int   ext;            /* index into MaterialExt[] (the surface layers), -1 = none */
    int   tx;             /* index into MaterialTx[] (transmission, volume, dispersion), -1 = none */
    float door_alpha;     /* screen door: the dither's alpha scale, 1 - transmission (1 - metallic); 1 = none */
    TexSlot slots[SLOT_COUNT];
} Material;

/* MaterialExt.slots: the layer texture slots (clrender.scene.material.EXT_TEXTURE_SLOTS order) */
#define XSLOT_SPECULAR              0   /* A: specular weight */
#define XSLOT_SPECULAR_COLOR        1   /* RGB (sRGB) */
#define XSLOT_CLEARCOAT             2   /* R */
#define XSLOT_CLEARCOAT_ROUGHNESS   3   /* G */
#define XSLOT_CLEARCOAT_NORMAL      4   /* tangent-space normal */
#define XSLOT_SHEEN_COLOR           5   /* RGB (sRGB) */
#define XSLOT_SHEEN_ROUGHNESS       6   /* A */
#define XSLOT_IRIDESCENCE           7   /* R */
#define XSLOT_IRIDESCENCE_THICKNESS 8   /* G */
#define XSLOT_ANISOTROPY            9   /* RG direction, B strength */
#define XSLOT_DIFFUSE_TRANSMISSION  10  /* A */
#define XSLOT_DIFFUSE_TRANSMISSION_COLOR 11  /* RGB (sRGB) */
#define XSLOT_COUNT                 12

/* MaterialExt.layers: which layers a material has (clrender.scene.material.Material.layers) */
#define LAYER_SPECULAR    1u    /* KHR_materials_ior and/or KHR_materials_specular */
#define LAYER_CLEARCOAT   2u
#define LAYER_SHEEN       4u
#define LAYER_IRIDESCENCE 8u
#define LAYER_ANISOTROPY  16u
#define LAYER_DIFFUSE_TRANSMISSION 32u   /* KHR_materials_diffuse_transmission */

/* The glTF surface-extension parameters of a material with layers (kernels/surface_layers.cl,
 * docs/shading.md): factors here, textures in the slots. */
typedef struct {
    float specular_color[3];   /* linear; may exceed 1 (KHR_materials_specular) */
    float specular_factor;
    float ior;                 /* >= 1, or 0: F0 = 1 */
    float clearcoat;
    float clearcoat_roughness;
    float clearcoat_normal_scale;
    float sheen_color[3];
    float sheen_roughness;
    float iridescence;
    float iridescence_ior;
    float iridescence_thickness_min;   /* nm */
    float iridescence_thickness_max;   /* nm; the thickness without a texture */
    float anisotropy_strength;
    float anisotropy_cos;      /* cos, sin of anisotropy_rotation */
    float anisotropy_sin;
    uint  layers;              /* LAYER_* */
    float diffuse_transmission;            /* [0, 1]; texture A multiplies */
    float diffuse_transmission_color[3];   /* linear [0, 1]; texture RGB (sRGB) multiplies */
    TexSlot slots[XSLOT_COUNT];
} MaterialExt;

/* MaterialTx.slots (clrender.scene.material.TX_TEXTURE_SLOTS order) */
#define TXSLOT_TRANSMISSION 0   /* R */
#define TXSLOT_THICKNESS    1   /* G */
#define TXSLOT_COUNT        2

/* The see-through extensions of a transmissive material (kernels/transmission.h,
 * docs/transmission.md): KHR_materials_transmission, _volume, _dispersion, with the IOR and the
 * specular factors that set the Fresnel weight of what is let through. */
typedef struct {
    float transmission;          /* factor, (0, 1]; texture R multiplies */
    float thickness;             /* mesh units, 0 = thin-walled (no volume); texture G multiplies */
    float attenuation_distance;  /* world units; INFINITY = no attenuation */
    float dispersion;            /* 20 / Abbe number; 0 = none */
    float attenuation_color[3];  /* linear */
    float ior;                   /* KHR_materials_ior: >= 1, or 0 */
    float specular_color[3];     /* KHR_materials_specular factors (linear) */
    float specular_factor;
    TexSlot slots[TXSLOT_COUNT];
} MaterialTx;

#define WRAP_REPEAT 0
#define WRAP_CLAMP  1
#define WRAP_MIRROR 2

/* Texel decode tables (the lut buffer): sRGB colour textures at 0, linear data textures at 256. */
#define LUT_SRGB   0
#define LUT_LINEAR 256

typedef struct {
    int first_level;   /* index into TexLevel */
    int levels;
    int wrap_s;
    int wrap_t;
    int lut;           /* LUT_SRGB or LUT_LINEAR: how the R, G, B bytes decode */
    int pad[3];
} TexInfo;

typedef struct {
    int offset;        /* first texel (RGBA8 in one uint, R in the low byte) */
    int width;
    int height;
    int pad;
} TexLevel;

/* Light.type */
#define LIGHT_POINT 0
#define LIGHT_SPOT  1

/* Light.falloff: the report's (1 - (d/r)^2)^3, or KHR_lights_punctual's inverse square (intensity
 * in candela) with the extension's range window, or without it (a light with no range: culled at
 * its radius, where I/d^2 has fallen below 1/256 of I; clrender/scene/lights.py). */
#define LIGHT_FALLOFF_REPORT 0
#define LIGHT_FALLOFF_INVERSE_SQUARE 1
#define LIGHT_FALLOFF_INVERSE_SQUARE_UNBOUNDED 2

/* A punctual light with a finite radius of influence (the report's attenuation reaches 0 at
 * `radius`). Spot lights fade from cos_inner to cos_outer around `direction` (unit). */
typedef struct {
    float position[3];
    float radius;
    float color[3];      /* linear RGB, intensity included */
    int   type;          /* LIGHT_* */
    float direction[3];
    float cos_outer;
    float cos_inner;
    int   shadow_size;   /* requested shadow map side in texels, 0 = casts no shadow (Scene) */
    int   shadow;        /* index among the shadowed spot lights, -1 = none (set at upload) */
    int   falloff;       /* LIGHT_FALLOFF_*: how A depends on the distance (lighting.h) */
} Light;

/* One shadow map: a light's view rendered by setup/binning/raster into a square region of
 * the shadow atlas (clrender/passes/shadow_views.py builds them). For p in world space:
 * ndc = (r0·p, r1·p) / (r3·p), depth = r2·p (linear: view depth for a spot, distance along
 * the sun direction for an orthographic sun cascade, whose r3 = (0, 0, 0, 1)). */
typedef struct {
    float m[16];      /* world -> light clip, row-major */
    int   x0, y0;     /* atlas texel of the map's top-left corner */
    int   size;       /* map side in texels */
    int   ortho;      /* 1: orthographic (sun cascade), 0: perspective (spot) */
    float texel;      /* world size of a texel: per unit depth (perspective) or absolute (ortho) */
    float far;        /* receivers deeper than this are outside the map: lit */
    float split;      /* sun cascade: camera view depth where the next cascade takes over */
    float pad;
} ShadowView;

#endif
