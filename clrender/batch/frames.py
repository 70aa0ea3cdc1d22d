"""Frame ranges and output patterns of a batch job, checked before anything is rendered.

A job renders frames numbered like Python ranges: `--frames 0:240` is frames 0..239, `0:240:2`
every other one, `7` the single frame 7. Frame f shows the scene at time f / fps seconds, so
`--time-range 2:4` at 24 fps is frames 48..95 and both flags name the same frames. `--frames
all` is the scene's animation, frames 0..floor(duration · fps) inclusive.

Output patterns are Python format strings over the fields {name} (scene file stem), {frame}
(frame number) and {time} (seconds, a float): `out/{name}_{frame:04d}.png`. Anything else is an
error naming the field, and a pattern that gives one file to several frames is refused.
"""
from __future__ import annotations

import math
import re
import string
from dataclasses import dataclass
from pathlib import Path
from typing import Optional, Sequence

PATTERN_FIELDS = ("name", "frame", "time")
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg")
DEFAULT_FRAME_NAME = "{name}_{frame:04d}.png"


@dataclass(frozen=True)
class FrameTime:
    """Frame number `frame` at `time` seconds (`frame / fps`)."""
    frame: int
    time: float


def _int(text: str, what: str) -> int:
    try:
        return int(text)
    except ValueError:
        raise ValueError(f"{what}: expected an integer, got {text!r}") from None


def parse_frames(text: str) -> range:
    """'A:B[:STEP]' (B exclusive) or 'N' -> range; ValueError when empty, reversed or malformed."""
    parts = text.strip().split(":")
    if len(parts) == 1:
        n = _int(parts[0], "--frames")
        if n < 0:
            raise ValueError(f"--frames {text}: frame numbers are >= 0")
        return range(n, n + 1)
    if len(parts) not in (2, 3):
        raise ValueError(f"--frames {text}: expected START:END or START:END:STEP")
    start, end = _int(parts[0], "--frames start"), _int(parts[1], "--frames end")
    step = _int(parts[2], "--frames step") if len(parts) == 3 else 1
    if start < 0:
        raise ValueError(f"--frames {text}: frame numbers are >= 0")
    if step < 1:
        raise ValueError(f"--frames {text}: the step must be >= 1")
    if end < start:
        raise ValueError(f"--frames {text}: reversed range (end {end} < start {start})")
    if end == start:
        raise ValueError(f"--frames {text}: empty range (the end is exclusive: {start}:{start + 1} is one frame)")
    return range(start, end, step)


def parse_time_range(text: str, fps: float) -> range:
    """'T0:T1' seconds -> the frames whose times lie in [T0, T1)."""
    parts = text.strip().split(":")
    try:
        t0, t1 = (float(p) for p in parts)
    except ValueError:
        raise ValueError(f"--time-range {text}: expected START:END in seconds") from None
    if not (math.isfinite(t0) and math.isfinite(t1)) or t0 < 0:
        raise ValueError(f"--time-range {text}: times must be finite and >= 0")
    if t1 <= t0:
        raise ValueError(f"--time-range {text}: {'empty' if t1 == t0 else 'reversed'} range")
    first, end = math.ceil(t0 * fps - 1e-9), math.ceil(t1 * fps - 1e-9)
    if end <= first:
        raise ValueError(f"--time-range {text}: no frame at {fps:g} fps lies in it")
    return range(first, end)


def animation_frames(duration: Optional[float], fps: float) -> range:
    """`--frames all`: frames 0..floor(duration · fps) (one frame for a static scene)."""
    if duration is None or not duration > 0:
        return range(0, 1)
    return range(0, math.floor(duration * fps + 1e-9) + 1)


def frame_times(frames: Sequence[int], fps: float) -> list[FrameTime]:
    return [FrameTime(int(f), f / fps) for f in frames]


def check_pattern(pattern: str) -> None:
    """ValueError for an unknown field, a positional field or a malformed pattern."""
    try:
        fields = [f for _, f, _, _ in string.Formatter().parse(pattern) if f is not None]
    except ValueError as exc:
        raise ValueError(f"bad output pattern {pattern!r}: {exc}") from None
    for f in fields:
        root = f.split(".")[0].split("[")[0]
        if root not in PATTERN_FIELDS:
            shown = "{}" if root == "" else "{" + f + "}"
            raise ValueError(f"bad output pattern {pattern!r}: unknown field {shown} "
                             f"(use {', '.join('{' + p + '}' for p in PATTERN_FIELDS)})")
    try:
        pattern.format(name="scene", frame=0, time=0.0)
    except (ValueError, TypeError, KeyError, IndexError, AttributeError) as exc:
        raise ValueError(f"bad output pattern {pattern!r}: {exc}") from None


def output_pattern(out: str, several_scenes: bool) -> str:
    """The pattern for `-o OUT`: OUT itself when it holds a field, else OUT/{name}_{frame:04d}.png
    for a directory. A single file name for several frames is refused by `plan_images`."""
    if "{" in out:
        check_pattern(out)
        return out
    target = Path(out)
    if target.is_dir() or out.endswith(("/", "\\")) or target.suffix == "":
        return str(target / DEFAULT_FRAME_NAME)
    return out


def image_path(pattern: str, scene: str, ft: FrameTime) -> Path:
    """The image of `scene` at frame `ft` under `pattern` (an unsupported type gets .png when the
    pattern has fields; ValueError naming the pattern when it has none)."""
    path = Path(pattern.format(name=Path(scene).stem, frame=ft.frame, time=ft.time))
    if path.suffix.lower() not in IMAGE_SUFFIXES:
        if "{" in pattern:
            return path.with_name(path.name + ".png")
        raise ValueError(f"output {pattern!r}: unsupported image type {path.suffix!r} "
                         f"(use {', '.join(IMAGE_SUFFIXES)})")
    return path


def _shared_file(pattern: str, path: Path, first_scene: str, scene: str) -> ValueError:
    need = "{frame}" if first_scene == scene else "{name}"
    return ValueError(f"output {pattern!r} gives one file {path} to several frames; "
                      f"put {need} in it (e.g. out/{DEFAULT_FRAME_NAME})")


def plan_images(pattern: str, scenes: Sequence[str], frames: Sequence[FrameTime]) -> dict:
    """{(scene, frame number): image path} for every scene x frame; ValueError when two of them
    would share a file or an image type is unsupported."""
    images, owner = {}, {}
    for scene in scenes:
        for ft in frames:
            path = image_path(pattern, scene, ft)
            key = str(path)
            if key in owner:
                raise _shared_file(pattern, path, owner[key][0], scene)
            owner[key] = (scene, ft.frame)
            images[(scene, ft.frame)] = path
    return images


# Up to this many images a job's file names are all made and compared before it starts; a larger
# job is planned lazily (its tasks are made as they render) and its pattern must give distinct
# names by construction: `lazy_pattern_ok`.
EAGER_CHECK_LIMIT = 100_000
_PLAIN_INT_SPEC = re.compile(r"0?\d*[dn]?")


def plain_frame_field(pattern: str) -> bool:
    """Whether the file name of `pattern` (not its folders) has a {frame} field written as a plain
    decimal integer ({frame}, {frame:06d}): distinct frames then get distinct names, and a frame's
    number can be read back from a path (`frame_candidates`)."""
    name = pattern.replace("\\", "/").rsplit("/", 1)[-1]
    try:
        fields = list(string.Formatter().parse(name))
    except ValueError:
        return False
    return any(f == "frame" and conv is None and _PLAIN_INT_SPEC.fullmatch(spec or "")
               for _, f, spec, conv in fields)


def folder_has_fields(pattern: str) -> bool:
    return "{" in pattern.replace("\\", "/").rsplit("/", 1)[0] if "/" in pattern.replace("\\", "/") else False


def check_images(pattern: str, scenes: Sequence[str], frames: Sequence[int], fps: float) -> None:
    """ValueError when two of scenes x frames would share a file or an image type is unsupported,
    without keeping the names: every name for up to EAGER_CHECK_LIMIT images; beyond, the first
    ones, then the pattern itself must make the names distinct (a plain {frame} in the file name, no
    field in its folders, {name} for several scenes with distinct file stems)."""
    total = len(scenes) * len(frames)
    if total <= EAGER_CHECK_LIMIT:
        plan_images(pattern, scenes, frame_times(frames, fps))
        return
    plan_images(pattern, scenes[:1], frame_times(frames[:1000], fps))      # a shared name shows up early
    why = None
    if not plain_frame_field(pattern):
        why = "put a plain {frame} field in the file name (e.g. out/" + DEFAULT_FRAME_NAME + ")"
    elif folder_has_fields(pattern):
        why = "use no fields in its folders"
    elif len(scenes) > 1 and (len({Path(s).stem for s in scenes}) < len(scenes) or "{name" not in pattern):
        why = "put {name} in it and give the scenes distinct file names"
    if why:
        raise ValueError(f"output {pattern!r}: {total} images are too many to check every file name before "
                         f"rendering; {why}")


def frame_candidates(path: str) -> set[int]:
    """Every integer written in `path` (each run of digits and each part of one): the frame numbers
    a file of a plain-{frame} pattern could belong to."""
    out = set()
    for run in re.findall(r"\d+", str(path)):
        run = run[-40:]
        for i in range(len(run)):
            for j in range(i + 1, len(run) + 1):
                out.add(int(run[i:j]))
    return out
