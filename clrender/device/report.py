"""What `clrender devices` reports: each OpenCL device's limits (clrender/device/capabilities.py) and
whether clrender's kernels build and run on it (the probe: clrender/device/probe.py)."""
from __future__ import annotations

from typing import Callable, Optional

from clrender.device import capabilities


def device_record(d, default_id: Optional[str], describe_error: Callable[[BaseException], str] = str,
                  probe: bool = True) -> dict:
    """A JSON-able record of DeviceInfo `d`: capabilities.summary() fields plus "kernels"
    ("ok", "failed", or "not probed" when not `probe`) and "kernels_error". A failing query or
    build never raises."""
    record = {"id": d.id, "platform": d.platform, "name": d.name, "label": d.label, "default": d.id == default_id}
    try:
        record.update(capabilities.summary(d.cl_device))
    except Exception as exc:                     # a broken driver must not hide the others
        record["summary_error"] = describe_error(exc)
        record.update(capabilities.summary(d.cl_device, tolerant=True))
    for key in ("implementation", "implementation_version", "origin", "vector_widths"):
        try:                                     # DeviceInfo's: which implementation, from where
            record[key] = getattr(d, key)
        except Exception:
            record[key] = None
    from clrender.device import tuning
    record["raster"] = tuning.summary(d.cl_device)            # the tuned VEC and tiles, if any
    if not probe:
        record["kernels"], record["kernels_error"] = "not probed", None
        return record
    from clrender.device.probe import probe_error            # asked of a child process
    error = probe_error(d)
    record["kernels"], record["kernels_error"] = ("ok", None) if error is None else ("failed", error)
    return record


def format_bytes(n) -> str:
    if not isinstance(n, int):
        return "?"
    for unit in ("B", "KiB", "MiB", "GiB", "TiB"):
        if n < 1024 or unit == "TiB":
            return f"{n:.0f} {unit}" if unit == "B" or n == int(n) else f"{n:.1f} {unit}"
        n /= 1024
    return "?"


def devices_table(records: list[dict]) -> str:
    """The `clrender devices` table, then one line per kernel-build or capability failure.
    IMPLEMENTATION: key, version and (pip/conda) origin, the --device names that pick it; VEC
    P/N/PX: the driver's preferred and native float vector widths, and the pixels per work-item
    clrender's per-pixel kernels use there; RASTER V/T/S: the raster's VEC, camera tile and shadow
    tile ("tuned": measured on this machine, clrender/render/autotune.py)."""
    header = ("", "ID", "TYPE", "IMPLEMENTATION", "DEVICE", "CU", "WG", "LOCAL", "GLOBAL", "MAX ALLOC",
              "I64 ATOM", "VEC P/N/PX", "RASTER V/T/S", "KERNELS")
    rows = []
    for r in records:
        impl = " ".join(filter(None, (r.get("implementation"), r.get("implementation_version")))) or "?"
        if r.get("origin") in ("pip", "conda"):
            impl += f" ({r['origin']})"
        vec = r.get("vector_widths") or {}
        rows.append(("*" if r["default"] else "", r["id"], str(r.get("type") or "?").replace("ALL | ", ""),
                     impl, r["name"], str(r.get("compute_units", "?")),
                     str(r.get("max_work_group_size", "?")), format_bytes(r.get("local_mem_bytes")),
                     format_bytes(r.get("global_mem_bytes")), format_bytes(r.get("max_alloc_bytes")),
                     {True: "yes", False: "no"}.get(r.get("int64_atomics"), "?"),
                     "/".join(str(vec.get(k, "?")) for k in ("preferred_float", "native_float", "pixel")),
                     _raster_cell(r.get("raster")), r["kernels"]))
    widths = [max(len(row[i]) for row in (header, *rows)) for i in range(len(header))]
    lines = ["  ".join(cell.ljust(w) for cell, w in zip(row, widths)).rstrip() for row in (header, *rows)]
    for r in records:
        if r["kernels_error"]:
            lines.append(f"{r['id']}: kernels failed: {r['kernels_error']}")
        if r.get("summary_error"):
            lines.append(f"{r['id']}: capabilities unavailable: {r['summary_error']}")
    return "\n".join(lines)


def _raster_cell(raster: Optional[dict]) -> str:
    if not raster:
        return "?"
    cell = f"{raster['vec']}/{raster['tile']}/{raster['shadow_tile']}"
    if not raster.get("tuned"):
        return cell
    return cell + (" tuned" if raster.get("complete") else " tuning")
