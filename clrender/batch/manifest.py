"""The manifest of a batch job: `manifest.json` beside its outputs, rewritten atomically (at most
once a second while frames finish, and when the job ends), so a killed job leaves a complete
manifest of the frames finished up to a second before the kill.

    {"clrender": "0.1.0", "job": {...what makes two runs' frames interchangeable...},
     "frames": [{"scene": "a.gltf", "frame": 3, "time": 0.125, "status": "ok",
                 "outputs": [{"path": "frame_0003.png", "bytes": 81234}, ...],
                 "stats": {...Frame.stats...}, "device": "...", "worker": "...", "run": "...",
                 "wall_ms": 812.5, "skipped_by": ["..."]},      # runs that --resume'd past it
                {"scene": ..., "frame": 4, "status": "failed", "error": "..."}]}

Output paths are relative to the manifest's folder. `--resume` trusts a frame only when the
manifest says it finished with the same job settings and every output it lists is still there
with the size it had; files are renamed into place only when complete (clrender.outputs.aov_io), so such
a frame needs no second look. A manifest written by a different job (other settings, or a scene
file changed since) is an error rather than a silent mix of two jobs' frames.
"""
from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Optional

import numpy as np

from clrender.outputs.aov_io import atomic_write

MANIFEST_NAME = "manifest.json"


def _jsonable(value):
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, float) and not np.isfinite(value):
        return None
    return value


def manifest_folder(pattern: str) -> Path:
    """The folder of an output pattern before its first field: where manifest.json lives."""
    return Path(pattern.split("{", 1)[0] + "x").parent


class Manifest:
    """Per-frame records of one job, keyed by (scene, frame)."""

    def __init__(self, path, job: dict, version: str):
        self.path = Path(path)
        self.job = _jsonable(job)
        self.version = version
        self.records: dict = {}

    @classmethod
    def open(cls, path, job: dict, version: str, resume: bool) -> "Manifest":
        """The job's manifest. An existing one written by the same job keeps its records (frames
        rendered by earlier runs stay listed); one written by another job is replaced, or with
        `resume` is a ValueError, as is a manifest that cannot be read."""
        manifest = cls(path, job, version)
        if not manifest.path.exists():
            return manifest
        try:
            data = json.loads(manifest.path.read_text())
            old_job, frames = data["job"], data["frames"]
            records = {(r["scene"], int(r["frame"])): r for r in frames}
        except RecursionError:      # json.loads recurses per level: a manifest this deep is not ours
            exc = "nested too deeply"
            if resume:
                raise ValueError(f"--resume: cannot read {manifest.path}: {exc}") from None
            return manifest
        except (OSError, ValueError, KeyError, TypeError) as exc:
            if resume:
                raise ValueError(f"--resume: cannot read {manifest.path}: {exc}") from None
            return manifest
        if old_job != manifest.job:
            if resume:
                differ = sorted(k for k in set(old_job) | set(manifest.job) if old_job.get(k) != manifest.job.get(k))
                raise ValueError(f"--resume: {manifest.path} was written by a different job ({', '.join(differ)} "
                                 f"differ); render into another folder or drop --resume")
            return manifest
        manifest.records = records
        return manifest

    def relative(self, path) -> str:
        return os.path.relpath(os.path.abspath(path), os.path.abspath(self.path.parent))

    def is_done(self, scene: str, frame: int, outputs) -> bool:
        """Whether the frame finished before, with exactly `outputs`, all still complete on disk."""
        record = self.records.get((scene, frame))
        if record is None or record.get("status") != "ok":
            return False
        listed = {o["path"]: o["bytes"] for o in record.get("outputs", [])}
        if set(listed) != {self.relative(p) for p in outputs}:
            return False
        for rel, size in listed.items():
            p = self.path.parent / rel
            try:
                if p.stat().st_size != size:
                    return False
            except OSError:
                return False
        return True

    def record(self, scene: str, frame: int, record: dict) -> None:
        record = dict(record, scene=scene, frame=int(frame))
        if "outputs" in record:
            record["outputs"] = [{"path": self.relative(p), "bytes": os.path.getsize(p)} for p in record["outputs"]]
        self.records[(scene, int(frame))] = _jsonable(record)

    def mark_skipped(self, scene: str, frame: int, run: str) -> None:
        """A --resume run found the frame complete: its record keeps the run that rendered it and
        lists, in "skipped_by", the runs that skipped it."""
        record = self.records[(scene, int(frame))]
        record["skipped_by"] = [*record.get("skipped_by", []), run]

    def failed(self) -> list[dict]:
        return [r for _, r in sorted(self.records.items()) if r.get("status") != "ok"]

    def save(self) -> Path:
        data = {"clrender": self.version, "job": self.job,
                "frames": [r for _, r in sorted(self.records.items())]}
        text = json.dumps(data, separators=(",", ":"))
        return atomic_write(self.path, lambda tmp: Path(tmp).write_text(text))

    def get(self, scene: str, frame: int) -> Optional[dict]:
        return self.records.get((scene, frame))
