"""The glTF 2.0 specification's tables as clrender reads them: component types, accessor types,
attribute formats, texture slots, the GLB container's constants and the extensions implemented.

Data only (and the small functions that read a table), so the document, its validation and the
compression decoders all import it and none of them imports another for a table.
"""
from __future__ import annotations

import numpy as np

COMPONENT_TYPES = {5120: "<i1", 5121: "<u1", 5122: "<i2", 5123: "<u2", 5125: "<u4", 5126: "<f4"}
TYPE_SIZES = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}
WRAP_MODES = {10497: "repeat", 33071: "clamp", 33648: "mirror"}
MODE_TRIANGLES, MODE_STRIP, MODE_FAN = 4, 5, 6
# extensions decoded by clrender.loaders.gltf.compression
DRACO, MESHOPT, QUANTIZATION = "KHR_draco_mesh_compression", "EXT_meshopt_compression", "KHR_mesh_quantization"
WEBP, BASISU = "EXT_texture_webp", "KHR_texture_basisu"
COMPRESSION_EXTENSIONS = frozenset({DRACO, MESHOPT, QUANTIZATION})
# The extensions clrender implements. A file that lists any other in extensionsRequired is refused
# (SceneError naming it); other extensions it merely uses are ignored with one warning each
# (clrender.loaders.gltf). EXT_texture_webp: `texture_source` reads its image (Pillow decodes WebP;
# KHR_texture_basisu: clrender.loaders.ktx2);
# KHR_mesh_quantization, KHR_draco_mesh_compression, EXT_meshopt_compression: `compression`.
# The surface extensions (clrender.loaders.gltf.materials reads them into Material's fields).
SURFACE_EXTENSIONS = frozenset({"KHR_materials_ior", "KHR_materials_specular", "KHR_materials_clearcoat",
                                "KHR_materials_sheen", "KHR_materials_iridescence", "KHR_materials_anisotropy",
                                # see-through materials (issue 38; docs/transmission.md)
                                "KHR_materials_transmission", "KHR_materials_volume", "KHR_materials_dispersion",
                                "KHR_materials_diffuse_transmission"})
# This is the single table of implemented extension names: add a name here when it is implemented.
SUPPORTED_EXTENSIONS = frozenset({"KHR_materials_emissive_strength", "KHR_materials_unlit", "KHR_texture_transform",
                                  "KHR_lights_punctual", WEBP, BASISU,
                                  "KHR_materials_pbrSpecularGlossiness",     # converted at load: specgloss.py
                                  "KHR_materials_variants",                  # loaders/gltf/variants.py
                                  "EXT_mesh_gpu_instancing",                 # expanded: loaders/gltf/instancing.py
                                  }) | COMPRESSION_EXTENSIONS | SURFACE_EXTENSIONS
# Vertex attribute component types (glTF 2.0, "Meshes"): (componentType, normalized)
FLOAT = {(5126, False)}
UNORM_8_16 = {(5121, True), (5123, True)}
SNORM_8_16 = {(5120, True), (5122, True)}
COMPONENT_NAMES = {5120: "BYTE", 5121: "UNSIGNED_BYTE", 5122: "SHORT", 5123: "UNSIGNED_SHORT",
                   5125: "UNSIGNED_INT", 5126: "FLOAT"}
INTS_8_16 = {(c, n) for c in (5120, 5121, 5122, 5123) for n in (False, True)}
# attribute -> (allowed types, allowed (componentType, normalized)); TANGENT allows the snorm forms of
# KHR_mesh_quantization, which Document.accessor decodes like any normalized accessor
ATTRIBUTE_FORMATS = {
    "NORMAL": (("VEC3",), None),                       # checked loosely, as before (any component type)
    "TEXCOORD": (("VEC2",), FLOAT | UNORM_8_16),
    "COLOR": (("VEC3", "VEC4"), FLOAT | UNORM_8_16),
    "TANGENT": (("VEC4",), FLOAT | SNORM_8_16),
}
# KHR_mesh_quantization's table, where it widens the core formats (NORMAL, TANGENT: already allowed)
QUANTIZED_FORMATS = {"POSITION": (("VEC3",), FLOAT | INTS_8_16), "TEXCOORD": (("VEC2",), FLOAT | INTS_8_16)}
# vertex attributes whose integer data are values (dequantized to float32 by Document.accessor);
# JOINTS_n and the indices stay integers
FLOAT_ATTRIBUTES = ("POSITION", "NORMAL", "TANGENT", "TEXCOORD", "COLOR")
# material texture slots: (clrender slot, JSON path of its textureInfo, sRGB image)
TEXTURE_INFOS = (("base_color", ("pbrMetallicRoughness", "baseColorTexture"), True),
                 ("metallic_roughness", ("pbrMetallicRoughness", "metallicRoughnessTexture"), False),
                 ("normal", ("normalTexture",), False),
                 ("occlusion", ("occlusionTexture",), False),
                 ("emissive", ("emissiveTexture",), True))
# the surface extensions' texture slots (Material.EXT_TEXTURE_SLOTS, then Material.TX_TEXTURE_SLOTS):
# (clrender slot, extension, its textureInfo property, sRGB image)
EXT_TEXTURE_INFOS = (("specular", "KHR_materials_specular", "specularTexture", False),
                     ("specular_color", "KHR_materials_specular", "specularColorTexture", True),
                     ("clearcoat", "KHR_materials_clearcoat", "clearcoatTexture", False),
                     ("clearcoat_roughness", "KHR_materials_clearcoat", "clearcoatRoughnessTexture", False),
                     ("clearcoat_normal", "KHR_materials_clearcoat", "clearcoatNormalTexture", False),
                     ("sheen_color", "KHR_materials_sheen", "sheenColorTexture", True),
                     ("sheen_roughness", "KHR_materials_sheen", "sheenRoughnessTexture", False),
                     ("iridescence", "KHR_materials_iridescence", "iridescenceTexture", False),
                     ("iridescence_thickness", "KHR_materials_iridescence", "iridescenceThicknessTexture", False),
                     ("anisotropy", "KHR_materials_anisotropy", "anisotropyTexture", False),
                     ("diffuse_transmission", "KHR_materials_diffuse_transmission", "diffuseTransmissionTexture",
                      False),
                     ("diffuse_transmission_color", "KHR_materials_diffuse_transmission",
                      "diffuseTransmissionColorTexture", True),
                     ("transmission", "KHR_materials_transmission", "transmissionTexture", False),
                     ("thickness", "KHR_materials_volume", "thicknessTexture", False))
GLB_MAGIC, GLB_JSON, GLB_BIN = 0x46546C67, 0x4E4F534A, 0x004E4942
LIGHT_TYPES = ("directional", "point", "spot")


def accessor_bytes(acc: dict) -> int:
    """What decoding an accessor costs: its data, and the float64 copy every loader path makes of it."""
    n = acc["count"] * TYPE_SIZES[acc["type"]]
    return n * (np.dtype(COMPONENT_TYPES[acc["componentType"]]).itemsize + 8)


def accessor_field(index: int, acc: dict) -> str:
    """'accessors[3].count (402653184 x VEC3 of FLOAT)': the field a budget error names."""
    return f"accessors[{index}].count ({acc['count']} x {acc['type']} of {COMPONENT_NAMES[acc['componentType']]})"


def attribute_kind(name: str) -> str:
    """'TEXCOORD_1' -> 'TEXCOORD', 'COLOR_0' -> 'COLOR', 'NORMAL' -> 'NORMAL'."""
    head, _, tail = name.rpartition("_")
    return head if head and tail.isdigit() else name


def attribute_sets(attrs: dict, kind: str) -> list[int]:
    """The set indices n of the `kind`_n attributes (e.g. TEXCOORD_0, TEXCOORD_2 -> [0, 2]), sorted."""
    return sorted(int(a.rpartition("_")[2]) for a in attrs if attribute_kind(a) == kind and a != kind)
