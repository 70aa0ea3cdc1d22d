"""numpy dtypes matching kernels/structs.h (checked against the device in tests)."""
import numpy as np

PRIM_BACKFACE, PRIM_MASKED, PRIM_DITHER = 1, 2, 4
MAT_DOUBLE_SIDED, MAT_MASK, MAT_BLEND, MAT_METALLIC_ROUGHNESS, MAT_UNLIT = 1, 2, 4, 8, 16
MAT_SHARES_FIRST = 32     # MAT_SHARES(slot) = MAT_SHARES_FIRST << (slot - 1), slots 1..4
MAT_GLTF_BRDF = 512       # shaded with the glTF 2.0 BRDF (kernels/brdf.h)
MAT_TRANSMISSION = 1024   # KHR_materials_transmission (MAT_BLEND set too: kernels/transmission.h)
MAT_TX_ALPHA = 2048       # a transmissive material with alphaMode BLEND: alpha is coverage
LUT_SRGB, LUT_LINEAR = 0, 256
WRAP = {"repeat": 0, "clamp": 1, "mirror": 2}

STATUS_NAMES = {0: "emitted", 1: "invalid", 2: "culled_near", 3: "degenerate",
                4: "culled_backface", 5: "culled_offscreen", 6: "transparent"}
STATUS_CLIPPED = 16

prim_dtype = np.dtype([
    ("x", "<i4", 3), ("tri", "<i4"),
    ("y", "<i4", 3), ("flags", "<u4"),
    ("inv_w", "<f4", 3), ("material", "<i4"),
    ("bary1", "<f4", 3), ("bary2", "<f4", 3),
    ("area", "<i8"),
], align=True)

texslot_dtype = np.dtype([("uv", "<f4", 6), ("texture", "<i4"), ("texcoord", "<i4")], align=True)

material_dtype = np.dtype([
    ("base_color", "<f4", 4), ("emissive", "<f4", 3), ("emissive_strength", "<f4"),
    ("spec_intensity", "<f4"), ("spec_power", "<f4"), ("metallic", "<f4"), ("roughness", "<f4"),
    ("normal_scale", "<f4"), ("occlusion_strength", "<f4"), ("alpha_cutoff", "<f4"), ("flags", "<u4"),
    ("refraction", "<f4"), ("ext", "<i4"), ("tx", "<i4"), ("door_alpha", "<f4"), ("slots", texslot_dtype, 5),
], align=True)

# MaterialExt.layers bits (kernels/structs.h LAYER_*), by clrender.scene.material.Material.layers name
LAYER_BITS = {"specular": 1, "clearcoat": 2, "sheen": 4, "iridescence": 8, "anisotropy": 16,
              "diffuse_transmission": 32}
material_ext_dtype = np.dtype([
    ("specular_color", "<f4", 3), ("specular_factor", "<f4"), ("ior", "<f4"), ("clearcoat", "<f4"),
    ("clearcoat_roughness", "<f4"), ("clearcoat_normal_scale", "<f4"), ("sheen_color", "<f4", 3),
    ("sheen_roughness", "<f4"), ("iridescence", "<f4"), ("iridescence_ior", "<f4"),
    ("iridescence_thickness_min", "<f4"), ("iridescence_thickness_max", "<f4"), ("anisotropy_strength", "<f4"),
    ("anisotropy_cos", "<f4"), ("anisotropy_sin", "<f4"), ("layers", "<u4"), ("diffuse_transmission", "<f4"),
    ("diffuse_transmission_color", "<f4", 3), ("slots", texslot_dtype, 12),
], align=True)

# MaterialTx (kernels/structs.h): transmission, volume, dispersion of a transmissive material
material_tx_dtype = np.dtype([
    ("transmission", "<f4"), ("thickness", "<f4"), ("attenuation_distance", "<f4"), ("dispersion", "<f4"),
    ("attenuation_color", "<f4", 3), ("ior", "<f4"), ("specular_color", "<f4", 3), ("specular_factor", "<f4"),
    ("slots", texslot_dtype, 2),
], align=True)

texinfo_dtype = np.dtype([("first_level", "<i4"), ("levels", "<i4"), ("wrap_s", "<i4"), ("wrap_t", "<i4"),
                          ("lut", "<i4"), ("pad", "<i4", 3)])
texlevel_dtype = np.dtype([("offset", "<i4"), ("width", "<i4"), ("height", "<i4"), ("pad", "<i4")])

LIGHT_POINT, LIGHT_SPOT = 0, 1
# Light.falloff (kernels/structs.h): the report's window, KHR_lights_punctual's inverse square with its
# range window, or without one (culled at the radius)
FALLOFF_REPORT, FALLOFF_INVERSE_SQUARE, FALLOFF_INVERSE_SQUARE_UNBOUNDED = 0, 1, 2
light_dtype = np.dtype([
    ("position", "<f4", 3), ("radius", "<f4"), ("color", "<f4", 3), ("type", "<i4"),
    ("direction", "<f4", 3), ("cos_outer", "<f4"), ("cos_inner", "<f4"),
    ("shadow_size", "<i4"), ("shadow", "<i4"), ("falloff", "<i4"),
], align=True)

shadow_view_dtype = np.dtype([
    ("m", "<f4", 16), ("x0", "<i4"), ("y0", "<i4"), ("size", "<i4"), ("ortho", "<i4"),
    ("texel", "<f4"), ("far", "<f4"), ("split", "<f4"), ("pad", "<f4"),
], align=True)

# name in structs.h -> dtype, for the layout test
STRUCTS = {"Prim": prim_dtype, "TexSlot": texslot_dtype, "Material": material_dtype, "MaterialExt": material_ext_dtype, "MaterialTx": material_tx_dtype, "TexInfo": texinfo_dtype, "TexLevel": texlevel_dtype,
           "Light": light_dtype, "ShadowView": shadow_view_dtype}
