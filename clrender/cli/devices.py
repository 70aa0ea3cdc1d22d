"""`clrender devices` (the OpenCL devices and whether clrender's kernels run on each) and
`clrender check` (the same cases rendered on several devices, every AOV compared)."""
from __future__ import annotations

import json
import sys
from pathlib import Path

from clrender.cli.common import PROG, CLIError, _note, _one_line


def cmd_devices(args) -> int:
    from clrender.device import icd
    from clrender.device.core import DeviceError, list_devices, no_device_error
    from clrender.device.probe import default_device_info
    from clrender.device.report import device_record, devices_table

    if args.no_probe and args.require:
        raise CLIError("--require needs the probe (whether a device runs clrender's kernels): drop --no-probe")
    if icd.note:                                # logged at import, before CLRENDER_LOG took effect
        icd.log.debug(icd.note)
    for line in icd.icd_problems():             # the loader skips these silently: say so, keep going
        print(f"{PROG}: {line}", file=sys.stderr)
    devices = list_devices()
    if not devices:
        raise CLIError(str(no_device_error()))
    try:                                        # the default is the first device whose probe passes
        default_id = None if args.no_probe else default_device_info().id
    except DeviceError:
        default_id = None
    records = [device_record(d, default_id, _one_line, probe=not args.no_probe) for d in devices]
    if args.json:
        print(json.dumps(records, indent=2))
    else:
        print(devices_table(records))
        if default_id is not None:
            print("* default device (override with --device NAME or $CLRENDER_DEVICE)")
    for name in args.require:                   # CI: a missing implementation is a failure, not a skip
        usable = [d.label for d, r in zip(devices, records) if d.matches(name) and r["kernels"] == "ok"]
        if not usable:
            raise CLIError(f"--require {name!r}: no OpenCL device matching it runs clrender's kernels")
    return 0


def cmd_check(args) -> int:
    from clrender.tools.check import run_check
    for s in args.scene:
        if not Path(s).is_file():
            raise CLIError(f"{s}: file not found")
    report = run_check(args.device, args.scene, args.width, args.height,
                       progress=None if args.quiet else (lambda m: print(f"rendering {m}", file=sys.stderr)))
    print(report.table())
    if len(report.devices) > 1:
        print("\nlargest difference per AOV over every case (=: bit-identical everywhere, !: past the tolerance)")
        print(report.summary())
    if args.json:
        Path(args.json).write_text(json.dumps(report.to_dict(), indent=2))
    if len(report.devices) < args.min_devices:
        raise CLIError(f"{len(report.devices)} device(s) compared ({', '.join(report.devices)}), "
                       f"--min-devices {args.min_devices} wanted")
    if len(report.devices) < 2:
        _note(args, f"{PROG}: note: only one device ({report.devices[0]}): nothing to compare")
    return 0 if report.ok else 1

