"""Confinement: a scene file reads only files in its own folder (or folders the user allowed).

Every reference a loader reads from a file (glTF buffer and image URIs, OBJ `mtllib`, MTL `map_Kd`,
PLY `comment TextureFile`, TOML `[[mesh]] path` and `[environment] source`) goes through `reference`
(or `gltf_uri`, which first decodes a URI): the path is joined to the referring file's folder and
resolved (`..`, symlinks: `Path.resolve`), and must then lie inside

* the referring file's folder,
* the folder of the scene file `load_scene` was called with (a TOML scene's mesh files may reach
  files beside the TOML file: `LoadContext.scene_dir`),
* or a folder the user allowed (`load_scene(..., allow=[...])`, `--allow-outside PATH`).

Anything else is a one-line SceneError naming the file that made the reference and the reference as
written; the outside file is never opened, so its bytes cannot become geometry or appear in a message.
Data URIs are not files and are not affected. A symlink inside the folder pointing outside is outside.
"""
from __future__ import annotations

import errno
import re
from pathlib import Path
from typing import Optional
from urllib.parse import unquote, urlsplit

from clrender.scene.model import SceneError
from clrender.loaders import context

HINT = "pass --allow-outside PATH, or load_scene(..., allow=[PATH]), to allow it"
_SCHEME = re.compile(r"^([A-Za-z][A-Za-z0-9+.-]+):")      # two letters or more: "C:/x" is a drive, not a scheme


def _shown(ref) -> str:
    """The reference as written, for a message (capped: it comes from a file)."""
    text = repr(ref)
    return text if len(text) <= 200 else text[:160] + "..." + text[-30:]


def _real(path: Path, referrer, what: str, ref) -> Path:
    try:
        return path.resolve(strict=False)
    except (OSError, RuntimeError, ValueError) as exc:    # a symlink loop (RuntimeError before 3.13), a NUL byte
        reason = "a symlink loop" if isinstance(exc, RuntimeError) or getattr(exc, "errno", None) == errno.ELOOP else \
            (getattr(exc, "strerror", None) or str(exc))
        raise SceneError(f"{referrer}: {what} {_shown(ref)}: cannot resolve the path ({reason})") from None


def roots(referrer) -> tuple[Path, ...]:
    """The resolved folders a file read by `referrer`'s references may lie in (its own first)."""
    ctx = context.current()
    own = Path(referrer).parent.resolve()
    scene = ctx.scene_dir
    return tuple(dict.fromkeys((own, *((scene,) if scene is not None else ()), *ctx.allow)))


def check(referrer, path: Path, ref, what: str) -> Path:
    """`path` (made from `ref`, as written in `referrer`) when it resolves inside an allowed folder."""
    real = _real(Path(path), referrer, what, ref)
    allowed = roots(referrer)
    if not any(real == root or real.is_relative_to(root) for root in allowed):
        scene = context.current().scene_dir or allowed[0]
        raise SceneError(f"{referrer}: {what} {_shown(ref)} resolves outside the scene's folder {scene} ({HINT})")
    context.record(real)            # Scene.source_files: the CLI never writes an output over it
    return Path(path)


def reference(referrer, ref, what: str, base: Optional[Path] = None) -> Path:
    """The file a path written in `referrer` names, relative to `base` (default: `referrer`'s folder);
    SceneError when it is not a non-empty string or resolves outside the allowed folders. Returns the
    joined, unresolved path (file names as the user wrote them stay in names and messages)."""
    if not isinstance(ref, str) or not ref.strip():
        raise SceneError(f"{referrer}: {what} must be a non-empty file path string, got {_shown(ref)}")
    base = Path(referrer).parent if base is None else Path(base)
    return check(referrer, base / ref, ref, what)


def gltf_uri(referrer, uri, what: str) -> Path:
    """The file a glTF `uri` (not a data: URI) names: a relative URI reference, percent-decoded
    (glTF 2.0 spec, "URIs"), or a `file:` URI; other schemes (http:, ...) are refused."""
    if not isinstance(uri, str) or not uri.strip():
        raise SceneError(f"{referrer}: {what} must be a non-empty URI string, got {_shown(uri)}")
    scheme = _SCHEME.match(uri)
    if scheme is None:
        return check(referrer, Path(referrer).parent / unquote(uri), uri, what)
    if scheme.group(1).lower() != "file":
        raise SceneError(f"{referrer}: {what} {_shown(uri)}: URI scheme {scheme.group(1)!r} is not supported "
                         f"(only relative paths, file: and data: URIs)")
    parts = urlsplit(uri)
    if parts.netloc not in ("", "localhost"):
        raise SceneError(f"{referrer}: {what} {_shown(uri)}: a file: URI on another host is not supported")
    path = unquote(parts.path)
    if not path:
        raise SceneError(f"{referrer}: {what} {_shown(uri)}: a file: URI without a path")
    return check(referrer, Path(referrer).parent / path, uri, what)   # an absolute path replaces the folder
