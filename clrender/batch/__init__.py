"""Batch rendering: frame ranges and output patterns (frames), tasks on a thread pool or a Dask
cluster (jobs, dask_plugin), a frame's task and its rendering (tasks), the job's manifest (manifest).

`clrender.batch` was a module before the package: its names stay importable from here."""
from clrender._lazy import exports

__all__, __getattr__, __dir__ = exports(__name__, {
    "jobs": ("render_frames", "plan_tasks", "run_tasks",),
    "tasks": ("FrameTask", "Outputs", "CameraOverride",),
    "manifest": ("Manifest", "MANIFEST_NAME",),
}, fallback="jobs")
