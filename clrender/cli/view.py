"""`clrender view SCENE`: the scene in a web page (clrender/viewer/), until Ctrl-C.

Everything that can fail on the command line fails before the server starts, in one line: the
flags, a port in use, a scene that does not load, a camera file that does not read. Ctrl-C stops
the render loop and the server and releases the device, with no traceback."""
from __future__ import annotations

import sys
import time

from clrender.cli.common import PROG, CLIError, _load, _note, _one_line, _scene_config, allowed_folders, render_options
from clrender.cli.parser import _positive_int, add_render_options


def add_parser(sub) -> None:
    v = sub.add_parser("view", help="look at a scene in the browser, pick the shots, save them for render/dataset",
                       description="Serve a web page showing SCENE rendered by clrender (viser; `pip install "
                                   "clrender[view]`): orbit, pan and zoom with the mouse; previews while the camera "
                                   "moves, the full frame when it stops; AOVs, render options, environment, "
                                   "animation time; click to pick; 'save view' appends the camera to a camera file "
                                   "that `clrender render --camera FILE` and `clrender dataset --cameras FILE` read.")
    v.add_argument("scene", metavar="SCENE", help="scene file (.toml .gltf .glb .obj .ply .stl)")
    v.add_argument("--port", type=_positive_int, default=8080, metavar="N", help="port to serve on (default 8080)")
    v.add_argument("--host", default="127.0.0.1", metavar="ADDRESS",
                   help="address to bind (default 127.0.0.1: this machine only)")
    v.add_argument("--open", action="store_true", help="open the page in the default browser")
    v.add_argument("--cameras", metavar="FILE.json|FILE.toml",
                   help="the camera file 'save view' appends to, its views listed in the page "
                        "(default: <scene-stem>.cameras.json in the current folder)")
    v.add_argument("--preview-scale", type=float, default=0.5, metavar="S",
                   help="size of the frames shown while the camera moves, as a fraction of --width/--height "
                        "(default 0.5: a quarter of the pixels)")
    add_render_options(v)
    v.add_argument("-q", "--quiet", action="store_true", help="only the URL and errors on stderr")


def cmd_view(args) -> int:
    from clrender.viewer import VIEW_MISSING, view, viser_available
    if not viser_available():
        raise CLIError(VIEW_MISSING)
    from clrender.viewer.server import LOCAL_HOSTS, check_port
    args.scenes = [args.scene]
    options = render_options(args)
    if (args.width is None) != (args.height is None):
        raise CLIError("--width and --height go together (without them the page's size is followed)")
    try:
        check_port(args.host, args.port)
    except ValueError as exc:
        raise CLIError(str(exc)) from None
    scene = _load(args.scene, args)
    config = _scene_config(scene, options)
    if args.host not in LOCAL_HOSTS:
        print(f"{PROG}: warning: listening on {args.host}:{args.port}: anyone who can reach this port can view the "
              f"scene and make the viewer read the environment files it is allowed to open", file=sys.stderr)
    try:
        viewer = view(scene, host=args.host, port=args.port, width=args.width, height=args.height,
                      device=args.device, config=config, cameras=args.cameras, allow=allowed_folders(args),
                      preview_scale=args.preview_scale, show=False)
    except ValueError as exc:
        raise CLIError(_one_line(exc)) from None
    print(f"{PROG} view: {viewer.url}  (Ctrl-C to stop)", file=sys.stderr, flush=True)
    _note(args, f"{PROG} view: {args.scene} on {viewer.device.name}; saved views go to {viewer.camera_file}")
    if args.open:
        import webbrowser
        webbrowser.open(viewer.url)
    try:
        while True:
            time.sleep(0.5)
    except KeyboardInterrupt:
        viewer.close(wait=False)         # the process exits next: no need to wait for viser's threads
        print(f"{PROG} view: stopped", file=sys.stderr, flush=True)
    return 0
