"""The set-up commands: `clrender warmup [--device D] [--all]` compiles now what later runs use
(clrender/tools/warmup.py), and `clrender cache info [--json] | clear` shows and empties what clrender
keeps on disk (compiled programs, PoCL's kernel cache, device probe answers; clrender/device/cache.py)."""
from __future__ import annotations

import json

from clrender.device import cache


def add_parsers(sub) -> None:
    w = sub.add_parser("warmup", help="build clrender's OpenCL kernels now, so later runs start warm",
                       description="Build and first-launch the kernels the default Renderer uses on typical "
                                   "scenes (--all: every kernel file and Renderer variant) on one device, "
                                   "filling the caches (for Docker images and cluster workers).")
    w.add_argument("--device", default=None, metavar="NAME", help="the device (default: the one render picks)")
    w.add_argument("--all", action="store_true", help="every kernel file and Renderer variant, not only the defaults")
    w.add_argument("-q", "--quiet", action="store_true", help="no progress or notes on stderr")

    c = sub.add_parser("cache", help="show or clear clrender's on-disk cache (compiled kernels, probes)",
                       description="clrender keeps compiled kernels and device probe answers in "
                                   f"${cache.ENV_CACHE_DIR} (default ~/.cache/clrender), capped at "
                                   f"${cache.ENV_CACHE_MAX_MB} MB (default {cache.DEFAULT_MAX_MB}).")
    actions = c.add_subparsers(dest="cache_action", metavar="ACTION", required=True)
    i = actions.add_parser("info", help="folder, cap, size by kind")
    i.add_argument("--json", action="store_true", help="print JSON instead of text")
    actions.add_parser("clear", help="remove every entry (the next run compiles again)")


def _mb(n: int) -> str:
    return f"{n / 2**20:.1f} MB"


def run_warmup(args) -> int:
    """Build and first-launch the kernels now (Docker images, cluster workers): later runs start warm."""
    import sys

    from clrender.tools.warmup import warm_up
    result = warm_up(args.device, everything=args.all)
    if not args.quiet:
        print(f"clrender: warmed up {result['device']}: {result['programs']} program(s) built in "
              f"{result['seconds']:.1f} s; cached in {cache.cache_dir()}", file=sys.stderr, flush=True)
    return 0


def run_cache(args) -> int:
    if args.cache_action == "clear":
        freed = cache.clear()
        print(f"cleared {cache.cache_dir()}: {_mb(freed)} freed")
        return 0
    record = cache.info()
    if args.json:
        print(json.dumps(record, indent=2))
        return 0
    print(f"folder   {record['dir']}" + ("" if record["exists"] else " (not created yet)"))
    print(f"cap      {_mb(record['cap_bytes'])} (${cache.ENV_CACHE_MAX_MB})")
    print(f"total    {_mb(record['total_bytes'])} in {record['entries']} entries")
    for kind, k in record["by_kind"].items():
        print(f"  {kind:<9}{k['entries']:>6} entries  {_mb(k['bytes']):>10}")
    if record["pocl_cache_dir"] and not record["pocl_cache_dir"].startswith(record["dir"]):
        print(f"PoCL's kernel cache is elsewhere: {record['pocl_cache_dir']} (POCL_CACHE_DIR)")
    return 0
