"""KHR_materials_variants: the variant names and each primitive's mappings, read from the document.

The ratified extension (KhronosGroup/glTF, extensions/2.0/Khronos/KHR_materials_variants): the root
`extensions.KHR_materials_variants.variants` is an array of {"name": string}; a primitive's
`extensions.KHR_materials_variants.mappings` is an array of {"material": index, "variants": [variant
indices]}; across one primitive's mappings each variant index is used at most once; when the active
variant is in no mapping of a primitive (or no variant is active) the primitive has its own
`material`. Every material of the document is loaded (clrender.loaders.gltf.materials), so a
material that only a variant uses is there to switch to.

Bad mappings do not stop the load (docs/bad_input.md): a variant or material index that does not
exist, a variant used twice in one primitive, a variant material reading a TEXCOORD set the
primitive lacks — one warning naming the primitive and the value, that mapping entry ignored.
"""
from __future__ import annotations

import warnings

from clrender.loaders.gltf.document import Document

NAME = "KHR_materials_variants"


def _extension(doc: Document, obj, what: str):
    """obj.extensions.KHR_materials_variants, or None; malformed containers are one SceneError."""
    ext = obj.get("extensions") if isinstance(obj, dict) else None
    if ext is None:
        return None
    if not isinstance(ext, dict):
        raise doc.err(f"{what}: extensions must be an object")
    value = ext.get(NAME)
    if value is not None and not isinstance(value, dict):
        raise doc.err(f"{what}: extensions.{NAME} must be an object")
    return value


def _warn(doc: Document, message: str) -> None:
    warnings.warn(f"{doc.path}: glTF {NAME}: {message}", stacklevel=5)


def variant_names(doc: Document) -> tuple:
    """The root's variant names, file order (() without the extension). A variant without a string
    name is called "variant<i>" (warned); a name given twice selects the first (warned)."""
    root = _extension(doc, doc.json, "the top level")
    if root is None:
        return ()
    variants = root.get("variants", [])
    if not isinstance(variants, list):
        raise doc.err(f"extensions.{NAME}.variants must be an array")
    names = []
    for i, v in enumerate(variants):
        name = v.get("name") if isinstance(v, dict) else None
        if not isinstance(name, str):
            _warn(doc, f"variants[{i}] has no string name: called 'variant{i}'")
            name = f"variant{i}"
        if name in names:
            _warn(doc, f"variants[{i}] repeats the name {name!r} of variants[{names.index(name)}]: "
                       f"the name selects variants[{names.index(name)}]")
        names.append(name)
    return tuple(names)


def primitive_mapping(doc: Document, what: str, prim: dict, n_variants: int, materials: list,
                      attrs: dict) -> dict:
    """{variant index: material index} of one primitive (see the module doc for what is ignored)."""
    ext = _extension(doc, prim, what)
    if ext is None:
        return {}
    mappings = ext.get("mappings", [])
    if not isinstance(mappings, list):
        raise doc.err(f"{what}: extensions.{NAME}.mappings must be an array")
    out: dict = {}
    for i, mapping in enumerate(mappings):
        at = f"{what} mappings[{i}]"
        if not isinstance(mapping, dict):
            _warn(doc, f"{at} is not an object: ignored")
            continue
        mat, indices = mapping.get("material"), mapping.get("variants")
        if not (isinstance(mat, int) and not isinstance(mat, bool) and 0 <= mat < len(materials)):
            _warn(doc, f"{at}: material {mat!r} does not exist (there are {len(materials)}): ignored")
            continue
        unread = _missing_texcoord(materials[mat], attrs)
        if unread is not None:
            _warn(doc, f"{at}: material {mat} ({materials[mat].name!r}) reads its {unread[0]} texture from "
                       f"TEXCOORD_{unread[1]}, which the primitive does not have: ignored")
            continue
        if not isinstance(indices, list):
            _warn(doc, f"{at}: variants must be an array of variant indices, got {indices!r}: ignored")
            continue
        for v in indices:
            if not (isinstance(v, int) and not isinstance(v, bool) and 0 <= v < n_variants):
                _warn(doc, f"{at}: variant {v!r} does not exist (there are {n_variants}): ignored")
            elif v in out:
                _warn(doc, f"{at}: variant {v} is already mapped to material {out[v]} by an earlier mapping "
                           f"(the spec allows one): ignored")
            else:
                out[v] = mat
    return out


def _missing_texcoord(material, attrs: dict):
    """(slot, set) of the first texture of `material` reading a TEXCOORD set `attrs` lacks, else None."""
    used = dict(material.textures_used())
    layer = getattr(material, "layer_textures_used", None)     # the surface extensions' slots
    if layer is not None:
        used.update(layer())
    used.update(material.tx_textures_used())                   # KHR_materials_transmission, _volume
    for slot, (_, uv) in used.items():
        if f"TEXCOORD_{uv.texcoord}" not in attrs:
            return slot, uv.texcoord
    return None


def record(mesh_maps: dict, mesh_defaults: dict, piece: int, mapping: dict, material: int) -> None:
    """Note the mapping of the Scene mesh made from `piece` (its default material beside it)."""
    if mapping:
        mesh_maps[piece], mesh_defaults[piece] = mapping, material
