"""Look at a scene in the browser before rendering it (`clrender view`, `clrender.view()`).

    import clrender
    v = clrender.view("scenes/demo.toml")          # prints the URL (Jupyter: shows the page inline)
    ...                                            # orbit, pick a shot, "save view"
    v.camera, v.frame                              # the camera shown, the last full-resolution Frame
    v.close()

Layers: server.py (the viser glue, panels.py its controls) over session.py (the render loop: the
newest camera wins, previews while moving) over the one-call API (clrender.Renderer); pick.py
reads what a Frame's id buffers say about a pixel. Needs the `view` extra (viser).
"""
from __future__ import annotations

import os
from typing import Optional, Sequence

VIEW_MISSING = 'the viewer needs viser: pip install "clrender[view]"'
ENV_PNG = "CLRENDER_VIEW_PNG"        # lossless PNG frames instead of JPEG (the browser tests compare pixels)


def viser_available() -> bool:
    import importlib.util
    return importlib.util.find_spec("viser") is not None


def _in_notebook() -> bool:
    try:
        from IPython import get_ipython
    except ImportError:
        return False
    shell = get_ipython()
    return shell is not None and getattr(shell, "kernel", None) is not None


def view(scene, renderer=None, *, host: str = "127.0.0.1", port: int = 8080, width: Optional[int] = None,
         height: Optional[int] = None, device=None, config=None, cameras: Optional[str] = None,
         allow: Sequence = (), transport: Optional[str] = None, preview_scale: float = 0.5, show: bool = True,
         **options):
    """Start the viewer on `scene` (a Scene, or a path load_scene reads with `allow`) and return it
    (`.url`, `.camera`, `.frame`, `.wait_idle()`, `.close()`; a context manager). `renderer`: a
    Renderer whose device, options and size to use; else `device`, `config` or RenderConfig
    `options` (over the scene's [render] options; its [render] size is not used: without
    width/height the page's size is followed). `preview_scale`: the preview frames' size, linear (0.5: a quarter of the pixels).
    `transport`: "jpeg" (default) or "png" (lossless; $CLRENDER_VIEW_PNG=1). `cameras`: the camera file "save view" appends to (its views are listed). `show`: in
    Jupyter, display the page inline (an IFrame of the URL), else print the URL."""
    if not viser_available():
        raise ImportError(VIEW_MISSING)
    from clrender.scene.model import Scene
    from clrender.viewer.server import Viewer
    if not isinstance(scene, Scene):
        from clrender.loaders import load_scene
        scene = load_scene(scene, allow=tuple(allow))
    if options and config is not None:
        raise ValueError("pass either config= or keyword options, not both")
    if config is None and renderer is None:       # a scene file's [render] options, as `clrender render` reads them
        from clrender.config import scene_config
        config = scene_config(scene, options)
    if transport is None:
        transport = "png" if os.environ.get(ENV_PNG, "").strip() not in ("", "0") else "jpeg"
    viewer = Viewer(scene, renderer=renderer, device=device, config=config, host=host, port=port, width=width,
                    height=height, camera_file=cameras, allow=allow, transport=transport,
                    preview_scale=preview_scale)
    if show:
        if _in_notebook():
            from IPython.display import IFrame, display
            display(IFrame(viewer.url, width="100%", height=600))
        else:
            print(f"clrender view: {viewer.url}", flush=True)
    return viewer


__all__ = ["view", "viser_available", "VIEW_MISSING", "ENV_PNG"]
