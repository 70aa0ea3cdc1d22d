"""Every subpackage's listed public names resolve, and the module paths users imported before the
package layout (issue 36) still give the same objects: clrender.scene, .batch, .dataset, .cli,
.loaders and the top-level names."""
from __future__ import annotations

import importlib
import subprocess
import sys

import pytest

PACKAGES = ("abi", "scene", "device", "loaders", "loaders.gltf", "outputs", "render", "tools", "batch", "viewer",
            "dataset", "cli")


@pytest.mark.parametrize("package", PACKAGES)
def test_every_listed_public_name_resolves(package):
    module = importlib.import_module(f"clrender.{package}")
    assert module.__all__, f"clrender.{package} lists no public names"
    for name in module.__all__:
        value = getattr(module, name)
        home = getattr(value, "__module__", None)
        if home is not None and isinstance(value, type):
            assert home.startswith("clrender."), (package, name, home)
    with pytest.raises(AttributeError):
        getattr(module, "no_such_name_anywhere")


# (old import, the object it must be) — the paths of the pre-package modules.
OLD_PATHS = [
    ("clrender.scene", "Scene", "clrender.scene.model", "Scene"),
    ("clrender.scene", "Material", "clrender.scene.material", "Material"),
    ("clrender.scene", "SceneError", "clrender.errors", "SceneError"),
    ("clrender.scene", "Texture", "clrender.scene.model", "Texture"),
    ("clrender.batch", "render_frames", "clrender.batch.jobs", "render_frames"),
    ("clrender.batch", "FrameTask", "clrender.batch.tasks", "FrameTask"),
    ("clrender.dataset", "load_dataset", "clrender.dataset.views", "load_dataset"),
    ("clrender.cli", "main", "clrender.cli.app", "main"),
    ("clrender.cli", "run", "clrender.cli.app", "run"),
    ("clrender.loaders", "load_scene", "clrender.loaders.load", "load_scene"),
    ("clrender", "load_scene", "clrender.loaders.load", "load_scene"),
    ("clrender", "Renderer", "clrender.render.renderer", "Renderer"),
    ("clrender", "RenderConfig", "clrender.config", "RenderConfig"),
    ("clrender", "Frame", "clrender.render.frame", "Frame"),
    ("clrender", "Camera", "clrender.scene.camera", "Camera"),
]


@pytest.mark.parametrize("old, name, home, home_name", OLD_PATHS, ids=[f"{o}.{n}" for o, n, _, _ in OLD_PATHS])
def test_old_module_paths_keep_working(old, name, home, home_name):
    assert getattr(importlib.import_module(old), name) is getattr(importlib.import_module(home), home_name)


def test_importing_the_package_and_the_cli_loads_no_opencl():
    code = ("import sys, clrender, clrender.scene, clrender.cli, clrender.loaders, clrender.config, "
            "clrender.abi.aovs; bad = [m for m in ('pyopencl', 'trimesh', 'dask') if m in sys.modules]; "
            "print(bad); sys.exit(1 if bad else 0)")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stdout + proc.stderr
