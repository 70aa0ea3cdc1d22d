"""What `clrender info` reports about a glTF file beyond the Scene summary: skins, morph targets,
animations and extensions, read from the glTF document itself (not from the loaded Scene, which may
leave skins and morph targets out).

    details = gltf_details("model.gltf")   # {"skins": [...], "morph_targets": [...], "animations": [...],
                                            #  "extensions_used": [...], "extensions_required": [...],
                                            #  "variants": [...], "material_extensions": [...]}
    lines = format_details(details)         # the text sections of `clrender info`

`empty_details()` is the same shape for the other scene formats (every list empty).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from clrender.scene.model import SceneError

GLTF_SUFFIXES = (".gltf", ".glb")
DETAIL_KEYS = ("skins", "morph_targets", "animations", "extensions_used", "extensions_required", "variants",
               "material_extensions")
PATH_ORDER = ("translation", "rotation", "scale", "weights")
MORPH_ORDER = ("POSITION", "NORMAL", "TANGENT")


def is_gltf(path) -> bool:
    return Path(path).suffix.lower() in GLTF_SUFFIXES


def empty_details() -> dict:
    return {key: [] for key in DETAIL_KEYS}


def gltf_details(path) -> dict:
    """Skins, morph targets, animations and extensions of the glTF file `path` (see module doc).
    Malformed skins / animations are a SceneError naming the file."""
    from clrender.loaders.gltf.document import load_document

    doc = load_document(path)
    try:
        return {"skins": _skins(doc), "morph_targets": _morph_targets(doc), "animations": _animations(doc),
                "extensions_used": _names(doc, "extensionsUsed"),
                "extensions_required": _names(doc, "extensionsRequired"),
                "variants": _variants(doc), "material_extensions": _material_extensions(doc)}
    except SceneError:
        raise
    except (KeyError, TypeError, ValueError, AttributeError, IndexError) as exc:
        detail = f"missing property {exc}" if isinstance(exc, KeyError) else f"{type(exc).__name__}: {exc}"
        raise doc.err(f"malformed glTF ({detail})") from None


# -- reading ----------------------------------------------------------------------------------------
def _names(doc, key: str) -> list[str]:
    value = doc.json.get(key) or []
    if not isinstance(value, list):
        raise doc.err(f"{key} must be an array of extension names")
    return [str(v) for v in value]


def _name(item: dict):
    name = item.get("name")
    return name if isinstance(name, str) else None


def _sets(attrs: dict, kind: str) -> list[int]:
    from clrender.loaders.gltf.spec import attribute_sets
    return attribute_sets(attrs, kind)


def _accessor_max(doc, index: int, what: str) -> float:
    """The largest value of a SCALAR accessor: its JSON `max` when given, else decoded."""
    acc = doc.get("accessors", index, what)
    if isinstance(acc.get("max"), list) and acc["max"] and "sparse" not in acc:
        return float(acc["max"][0])
    values = doc.accessor(index)
    return float(values.max()) if values.size else 0.0


def _nonzero_weights(doc, prim: dict, what: str) -> int:
    """The most non-zero WEIGHTS_n components any vertex of the primitive has (over all its sets)."""
    per_vertex = None
    attrs = prim.get("attributes") or {}
    for k in _sets(attrs, "WEIGHTS"):
        index = attrs[f"WEIGHTS_{k}"]
        doc.get("accessors", index, f"{what} WEIGHTS_{k}")
        counts = np.count_nonzero(doc.accessor(index), axis=1)
        if per_vertex is None:
            per_vertex = counts
        else:
            n = max(len(per_vertex), len(counts))
            per_vertex = np.pad(per_vertex, (0, n - len(per_vertex))) + np.pad(counts, (0, n - len(counts)))
    return int(per_vertex.max()) if per_vertex is not None and per_vertex.size else 0


def _skins(doc) -> list[dict]:
    nodes = doc.list("nodes")
    out = []
    for s, skin in enumerate(doc.list("skins")):
        if not isinstance(skin, dict):
            raise doc.err(f"skins[{s}] must be an object")
        joints = skin.get("joints")
        if not isinstance(joints, list):
            raise doc.err(f"skin {s} has no joints array")
        skeleton = skin.get("skeleton")
        if skeleton is not None:
            doc.get("nodes", skeleton, f"skin {s} skeleton")
        users = [n for n, node in enumerate(nodes) if isinstance(node, dict) and node.get("skin") == s]
        meshes = sorted({nodes[n]["mesh"] for n in users if "mesh" in nodes[n]})
        joint_sets, most_weights = 0, 0
        for m in meshes:
            mesh = doc.get("meshes", m, f"node using skin {s}")
            for p, prim in enumerate(mesh.get("primitives") or []):
                what = f"mesh {m} primitive {p}"
                joint_sets = max(joint_sets, len(_sets(prim.get("attributes") or {}, "JOINTS")))
                most_weights = max(most_weights, _nonzero_weights(doc, prim, what))
        out.append({"index": s, "name": _name(skin), "joints": len(joints),
                    "skeleton": skeleton,
                    "skeleton_name": _name(nodes[skeleton]) if skeleton is not None else None,
                    "meshes": meshes, "nodes": users,
                    "joint_sets": joint_sets,
                    "influences_per_vertex": 4 * joint_sets,
                    "max_nonzero_weights": most_weights})
    return out


def _morph_targets(doc) -> list[dict]:
    out = []
    for m, mesh in enumerate(doc.list("meshes")):
        if not isinstance(mesh, dict):
            continue
        prims = [p for p in mesh.get("primitives") or [] if isinstance(p, dict)]
        counts = [len(p.get("targets") or []) for p in prims]
        if not any(counts):
            continue
        moved = {name for p in prims for t in p.get("targets") or [] for name in t}
        attributes = [a for a in MORPH_ORDER if a in moved] + sorted(moved - set(MORPH_ORDER))
        n = max(counts)
        given = mesh.get("weights")
        if given is not None and not isinstance(given, list):
            raise doc.err(f"mesh {m}: weights must be an array of numbers")
        names = (mesh.get("extras") or {}).get("targetNames") if isinstance(mesh.get("extras"), dict) else None
        out.append({"mesh": m, "name": _name(mesh), "targets": n, "attributes": attributes,
                    "weights": [float(w) for w in given] if given is not None else [0.0] * n,
                    "weights_given": given is not None,
                    "target_names": [str(x) for x in names] if isinstance(names, list) else None})
    return out


def _ordered_counts(values: list[str], order: tuple) -> dict[str, int]:
    counts: dict[str, int] = {}
    for v in sorted(values, key=lambda v: (order.index(v) if v in order else len(order), v)):
        counts[v] = counts.get(v, 0) + 1
    return counts


def _animations(doc) -> list[dict]:
    out = []
    for a, anim in enumerate(doc.list("animations")):
        if not isinstance(anim, dict):
            raise doc.err(f"animations[{a}] must be an object")
        channels = anim.get("channels") or []
        samplers = anim.get("samplers") or []
        if not isinstance(channels, list) or not isinstance(samplers, list):
            raise doc.err(f"animation {a}: channels and samplers must be arrays")
        paths = [str((c.get("target") or {}).get("path")) for c in channels]
        interpolations = [str(s.get("interpolation", "LINEAR")) for s in samplers]
        inputs = sorted({s["input"] for s in samplers})
        duration = max((_accessor_max(doc, i, f"animation {a} sampler input") for i in inputs), default=0.0)
        out.append({"index": a, "name": _name(anim), "channels": len(channels),
                    "paths": _ordered_counts(paths, PATH_ORDER),
                    "samplers": len(samplers),
                    "interpolations": _ordered_counts(interpolations, ("LINEAR", "STEP", "CUBICSPLINE")),
                    "duration": duration})
    return out


def _variants(doc) -> list[dict]:
    """KHR_materials_variants: per variant its name, how many primitives map it and to which materials
    (the mappings as written; the loader warns about and ignores invalid ones)."""
    from clrender.loaders.gltf.variants import NAME
    def part(obj, key, kind):           # obj[key] when obj is an object and it is of `kind`, else empty
        value = obj.get(key) if isinstance(obj, dict) else None
        return value if isinstance(value, kind) else kind()

    root = part(part(doc.json, "extensions", dict), NAME, dict)
    out = [{"index": i, "name": part(v, "name", str) or None, "primitives": 0, "materials": []}
           for i, v in enumerate(part(root, "variants", list))]
    for mesh in doc.list("meshes"):
        for prim in part(mesh, "primitives", list):
            seen = set()
            for mapping in part(part(part(prim, "extensions", dict), NAME, dict), "mappings", list):
                for v in part(mapping, "variants", list):
                    if isinstance(v, int) and 0 <= v < len(out) and v not in seen:
                        seen.add(v)
                        out[v]["primitives"] += 1
                        if mapping.get("material") not in out[v]["materials"]:
                            out[v]["materials"].append(mapping.get("material"))
    for v in out:
        v["materials"] = sorted(m for m in v["materials"] if isinstance(m, int))
    return out


def _material_extensions(doc) -> list[dict]:
    """Per KHR_materials_* extension (sorted by name), how many materials use it."""
    counts: dict = {}
    for mat in doc.list("materials"):
        ext = mat.get("extensions") if isinstance(mat, dict) else None
        for name in ext if isinstance(ext, dict) else ():
            if str(name).startswith("KHR_materials_"):
                counts[str(name)] = counts.get(str(name), 0) + 1
    return [{"name": k, "materials": counts[k]} for k in sorted(counts)]


# -- text -------------------------------------------------------------------------------------------
def _label(index: int, name) -> str:
    return f"{index} {name!r}" if name else str(index)


def _counted(counts: dict) -> str:
    return ", ".join(k if n == 1 else f"{k} x{n}" for k, n in counts.items()) or "none"


def format_details(details: dict) -> list[str]:
    """The text sections of `clrender info` for a glTF file (one string per line)."""
    lines = [f"skins: {len(details['skins']) or 'none'}"]
    for s in details["skins"]:
        skeleton = ("skeleton root not given" if s["skeleton"] is None
                    else f"skeleton root node {_label(s['skeleton'], s['skeleton_name'])}")
        used = (f"used by mesh(es) {', '.join(map(str, s['meshes'])) or 'none'} "
                f"on node(s) {', '.join(map(str, s['nodes'])) or 'none'}")
        lines.append(f"  skin {_label(s['index'], s['name'])}: {s['joints']} joints, {skeleton}, {used}, "
                     f"{s['influences_per_vertex']} influences per vertex ({s['joint_sets']} JOINTS set(s)), "
                     f"at most {s['max_nonzero_weights']} non-zero weights")
    morphs = details["morph_targets"]
    lines.append(f"morph targets: {f'{len(morphs)} mesh(es)' if morphs else 'none'}")
    for t in morphs:
        weights = ", ".join(f"{w:g}" for w in t["weights"])
        lines.append(f"  mesh {_label(t['mesh'], t['name'])}: {t['targets']} targets moving "
                     f"{', '.join(t['attributes'])}, default weights [{weights}]"
                     + ("" if t["weights_given"] else " (not given)"))
    lines.append(f"animations: {len(details['animations']) or 'none'}")
    for a in details["animations"]:
        lines.append(f"  animation {_label(a['index'], a['name'])}: {a['channels']} channels "
                     f"({_counted(a['paths'])}), {a['samplers']} samplers ({_counted(a['interpolations'])}), "
                     f"duration {a['duration']:g} s")
    variants = details.get("variants", [])
    lines.append(f"material variants: {len(variants) or 'none'}")
    for v in variants:
        used = f", material(s) {', '.join(map(str, v['materials']))}" if v["materials"] else ""
        lines.append(f"  variant {_label(v['index'], v['name'])}: {v['primitives']} primitive(s){used}")
    counted = details.get("material_extensions", [])
    lines.append("material extensions: " + (", ".join(
        f"{e['name']} ({e['materials']} material{'s' if e['materials'] != 1 else ''})" for e in counted) or "none"))
    lines.append(f"extensions used: {', '.join(details['extensions_used']) or 'none'}")
    lines.append(f"extensions required: {', '.join(details['extensions_required']) or 'none'}")
    return lines
