"""Command line: `clrender render | dataset | view | devices | check | info`, a thin loop over the library API.
This module parses and dispatches; one module per command family does the work: render.py
(frames and clusters: batch.py), dataset.py, devices.py (devices, check), info.py, setup.py
(warmup, cache); parser.py is the grammar, common.py what they share (nothing imports upward).

    clrender render SCENE [SCENE ...] -o OUT [--width W --height H --device NAME, render options:
                    the flags of docs/options.md (clrender/config.py's table), e.g. --pipeline light_prepass
                    --msaa 4 --bloom; --previous-eye x,y,z --previous-target x,y,z
                    --environment PATH|studio|none --environment-intensity X --environment-rotation DEG
                    --aov depth,normal,... --camera-eye x,y,z --camera-target x,y,z --fov DEG
                    --ortho HALF_HEIGHT --bit-depth 8|16 --exr --video FILE --fps N --quiet
                    --frames A:B[:STEP]|N|all --time-range T0:T1 --resume --workers N
                    --scheduler ADDRESS --resources NAME=N]
    clrender dataset SCENE -o DIR --views N [--layout orbit|sphere|random --seed S --elevation DEG --fov DEG]
                     [--cameras FILE.json|.toml] [--format nerf|colmap] [--aov depth,object_id,...|none]
                     [--depth-scale S] [--exr] [--width W --height H --device NAME, render options]
                     [--resume] [--workers N | --scheduler ADDRESS]      (clrender/cli/dataset.py)
    clrender view SCENE [--port 8080 --host 127.0.0.1 --open --cameras FILE, --width W --height H, render options]
                  (clrender/cli/view.py: the scene in a web page)
    clrender devices [--json] [--require NAME]
    clrender warmup [--device NAME] [--all] [-q]
    clrender cache info [--json] | clear
    clrender info SCENE [--json]
    clrender check [--device NAME|all] [--scene S] [--json report.json]

Errors are one line on stderr (`clrender: error: ...`) and a non-zero exit status; set
CLRENDER_DEBUG=1 to get the traceback instead.
"""
from __future__ import annotations

import os
import sys
import warnings
from typing import Optional, Sequence

from clrender import progress
from clrender.errors import DeviceError, SceneError
from clrender.cli import dataset as cli_dataset, parser as cli_parser, setup as cli_setup, view as cli_view
from clrender.cli.parser import _join_vector_options

# Names scripts and tests reach as clrender.cli.X / clrender.cli.app.X (all of this was one module).
from clrender.outputs.aov_io import INT_AOVS, preview  # noqa: F401
from clrender.cli.parser import AOVS  # noqa: F401
from clrender.cli.common import (  # noqa: F401
    ENV_DEBUG, IMAGE_SUFFIXES, PROG, CLIError, OutputOverInput, _debug, _load, _note, _one_line, _scene_config,
    allowed_folders, batch_requested, check_output_options, check_outputs_spare_inputs, check_scene_files,
    check_writable, input_files, render_options)
from clrender.cli.render import (  # noqa: F401
    ENVIRONMENT_FLAGS, _camera, _check_distinct, _format_stats, _plan_outputs, _previous_camera,
    apply_environment, cmd_render, describe_environment, environment_option)
from clrender.cli.devices import cmd_check, cmd_devices  # noqa: F401
from clrender.cli.info import _json_default, _objects_line, cmd_info  # noqa: F401

COMMANDS = {"render": cmd_render, "devices": cmd_devices, "check": cmd_check, "info": cmd_info,
            "warmup": cli_setup.run_warmup, "cache": cli_setup.run_cache, "dataset": cli_dataset.cmd_dataset,
            "view": cli_view.cmd_view}


def build_parser():
    """The whole grammar: each command module adds its own subcommand (help lists them in this order)."""
    parser, sub = cli_parser.root_parser()
    cli_parser.add_render_parser(sub)
    cli_parser.add_devices_parser(sub)
    cli_dataset.add_parser(sub)         # dataset
    cli_view.add_parser(sub)            # view
    cli_setup.add_parsers(sub)          # warmup, cache
    cli_parser.add_check_parser(sub)
    cli_parser.add_info_parser(sub)
    return parser


def _quiet_unraisable() -> None:
    """Errors Python can only print as "Exception ignored in ..." (a writer's clean-up in __del__
    after a full disk: 3-11 tracebacks) say nothing the error line has not: hidden unless debugging."""
    if not _debug():
        sys.unraisablehook = lambda unraisable: None


def _quiet_compiler_logs() -> None:
    """OpenCL compilers' harmless notes (PoCL's AVX ABI remarks on pyopencl's own kernels) would
    bury the CLI's output on first builds; CLRENDER_DEBUG=1 shows them."""
    if _debug():
        return
    try:
        from pyopencl import CompilerWarning
    except ImportError:                          # reported properly by the command that needs it
        return
    warnings.simplefilter("ignore", CompilerWarning)


def _one_line_warnings(quiet: bool) -> None:
    """Library warnings (a device left out, a loader note) as one `clrender: note:` line each;
    none with --quiet."""
    if quiet and not _debug():
        warnings.simplefilter("ignore", UserWarning)
        return

    def show(message, category, filename, lineno, file=None, line=None):
        print(f"{PROG}: note: {message}", file=sys.stderr, flush=True)
    warnings.showwarning = show


def _log_level() -> None:
    """CLRENDER_LOG=info|debug: the library's log (builds, probes, caches) on stderr."""
    level = os.environ.get("CLRENDER_LOG", "").strip().upper()
    if level:
        import logging
        handler = logging.StreamHandler(sys.stderr)
        handler.setFormatter(logging.Formatter(f"{PROG}: %(message)s"))
        logger = logging.getLogger("clrender")
        if not logger.handlers:
            logger.addHandler(handler)
        logger.setLevel(getattr(logging, level, logging.INFO))


def main(argv: Optional[Sequence[str]] = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    from clrender import interrupt
    interrupt.install()                          # a failure a Ctrl-C caused ends as the interrupt
    _quiet_compiler_logs()
    _quiet_unraisable()
    _log_level()
    try:
        args = build_parser().parse_args(_join_vector_options(argv))
        _one_line_warnings(getattr(args, "quiet", False))
        progress.show_bars(not getattr(args, "quiet", False))    # first-run builds: a bar, not silence
        return int(COMMANDS[args.command](args) or 0)
    except SystemExit as exc:                    # --help / --version
        return exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 1)
    except KeyboardInterrupt:
        print(f"{PROG}: interrupted", file=sys.stderr)
        return 130
    except CLIError as exc:
        if _debug():
            raise
        print(f"{PROG}: error: {_one_line(exc)}", file=sys.stderr)
        return exc.code
    except Exception as exc:                     # SceneError, DeviceError, ValueError, OSError, cl.Error
        if _debug():
            raise
        known = isinstance(exc, (SceneError, DeviceError, ValueError, OSError))
        message = _one_line(exc) if known else f"{type(exc).__name__}: {_one_line(exc)}"
        print(f"{PROG}: error: {message}", file=sys.stderr)
        return 1
    finally:
        progress.show_bars(False)


def run() -> None:
    """The `clrender` program (console script and `python -m clrender`): main(), then exit. Nothing
    is left to do once main() returns (outputs renamed into place, clusters closed), and the OpenCL
    driver's teardown of every program and context cost 0.25-0.3 s of a 1.6 s warm demo run: the
    process exits without it, once its streams and logs are flushed."""
    code = main()
    import logging
    logging.shutdown()
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)



if __name__ == "__main__":
    run()
