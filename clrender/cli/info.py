"""`clrender info SCENE`: what a scene file holds, as text or JSON."""
from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np

from clrender.cli.common import CLIError, _load, allowed_folders


def cmd_info(args) -> int:
    path = Path(args.scene)
    if not path.exists():
        raise CLIError(f"{args.scene}: file not found")
    scene = _load(args.scene, args)
    summary = scene.summary()
    summary["settings"] = scene.settings
    # Frame.object_id's index; a shallow dict: asdict would deep-copy `extras` recursively
    summary["object_list"] = [{f.name: getattr(o, f.name) for f in dataclasses.fields(o)} for o in scene.objects]
    from clrender.loaders.gltf.info import empty_details, format_details, gltf_details, is_gltf
    gltf = is_gltf(path)
    from clrender.loaders.context import loading
    with loading(allowed_folders(args)):         # gltf_details reads the buffers again, as confined
        summary.update(gltf_details(path) if gltf else empty_details())   # always present: [] unless glTF
    if args.json:
        print(json.dumps(summary, indent=2, default=_json_default))
        return 0
    s = summary
    fmt = lambda v: ", ".join(f"{x:g}" for x in v)  # noqa: E731
    lines = [
        ("source", s["source"]),
        ("triangles", s["triangles"]),
        ("vertices", s["vertices"]),
        ("meshes", s["meshes"]),
        ("objects", _objects_line(s["object_list"])),
        ("materials", f"{s['materials']} ({s['alpha_masked_materials']} alpha-masked, "
                      f"{s['transparent_materials']} transparent, {s['single_sided_materials']} single-sided)"),
        ("textures", s["textures"] if not s["texture_sizes"] else
         f"{s['textures']} ({', '.join(f'{w}x{h}' for w, h in s['texture_sizes'])})"),
        ("bounds", f"min ({fmt(s['bounds_min'])})  max ({fmt(s['bounds_max'])})"),
        ("camera", "none (a default camera frames the bounds)" if s["camera"] is None else _camera_text(s["camera"])),
    ]
    if s["cameras"]:        # every camera the file defines (Scene.cameras), the first is `camera`
        lines.append(("cameras", len(s["cameras"])))
        lines.extend((f"  {i}", f"{c['name']!r}  {_camera_text(c)}") for i, c in enumerate(s["cameras"]))
    render = scene.settings.get("render") if isinstance(scene.settings, dict) else None
    if render:
        lines.append(("render", ", ".join(f"{k} {v}" for k, v in render.items())))
    if isinstance(scene.settings, dict) and scene.settings.get("lights"):
        lines.append(("lights", len(scene.settings["lights"])))
    width = max(len(k) for k, _ in lines)
    for k, v in lines:
        print(f"{k.ljust(width)}  {v}")
    if gltf:
        print("\n".join(format_details(summary)))
    return 0


def _camera_text(c: dict) -> str:
    """One camera of Scene.summary() as text."""
    fmt = lambda v: ", ".join(f"{x:g}" for x in v)  # noqa: E731
    return f"eye ({fmt(c['eye'])})  target ({fmt(c['target'])})  " + (
        f"orthographic xmag {c['xmag']:g} ymag {c['ymag']:g}" if c.get("projection") == "orthographic"
        else f"fov {c['fov_y_deg']:g} deg")


def _objects_line(objects: list) -> str:
    """The object count (Frame.object_id), the first names and how many carry extras."""
    names = ", ".join(repr(o["name"]) for o in objects[:4]) + (", ..." if len(objects) > 4 else "")
    extras = sum(o["extras"] is not None for o in objects)
    return f"{len(objects)} ({names})" + (f", {extras} with extras" if extras else "") if objects else "0"


def _json_default(obj):
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, np.generic):
        return obj.item()
    if dataclasses.is_dataclass(obj):
        return dataclasses.asdict(obj)
    return str(obj)

