"""The package layout keeps itself (issue 36): one-way layers, no circles, pass = kernel = module.

1. Every `import` in clrender/ (module level and inside functions, read with `ast`) goes DOWN the
   layer table below, or stays inside its own layer; and the module graph has no circle (a strongly
   connected component of more than one module, inside a package too).
2. Every kernels/X.cl has its clrender/passes/X.py and vice versa, except the explained exceptions
   below, whose partner files must exist.
3. The `#include` graph of kernels/*.h and *.cl has no circle, and each header builds on its own
   (it includes what it uses, so no header leans on types of a header that includes it).

Each checker takes the repository root, so the self-checks at the bottom run it on a synthetic tree
with one violation of each kind and assert it is reported: the checks can fail.
"""
from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent

# The one table of allowed directions: group -> (rank, the modules/packages it holds, relative to
# clrender). A module may import a group of LOWER rank, or its own group. Groups of equal rank are
# siblings and may not import each other; the ranks are read from the code:
# - scene and device: the host model knows no OpenCL, the device knows no scene.
# - loaders, outputs and passes: files -> Scene, Frame arrays -> files, one kernel's enqueue; none
#   needs another (a pass reading a loader's helper is against the layers, issue 36).
# - tools and dataset: the probe/warmup/check tools, and a dataset's views and file layout (numpy,
#   scene, outputs); batch runs both (warmup plugin, dataset-layout tasks), the CLI drives all.
LAYERS = {
    "base": (0, ("errors", "config", "budget", "progress", "interrupt", "_lazy")),
    "abi": (1, ("abi",)),
    "scene": (2, ("scene",)),
    "device": (2, ("device",)),
    "loaders": (3, ("loaders",)),
    "outputs": (3, ("outputs",)),
    "passes": (3, ("passes",)),
    "render": (4, ("render",)),
    "tools": (5, ("tools",)),
    "dataset": (5, ("dataset",)),
    "batch": (6, ("batch",)),
    "viewer": (6, ("viewer",)),          # the browser viewer: a loop over the API, like batch
    "cli": (7, ("cli",)),
    "root": (8, ("__init__", "__main__")),      # clrender/__init__.py (module "clrender"), __main__.py
}

# Kernel files without a passes/<same name>.py, and pass modules without a kernels/<same name>.cl:
# name -> (why, its partner file, relative to the repository root). The partner must exist and one
# of the two files must name the other (so an exception stays true when files move).
KERNEL_EXCEPTIONS = {
    "scan.cl": ("the prefix sum is a device service that passes call", "clrender/device/scan.py"),
    "timestamp.cl": ("pass-time stamps are a device service", "clrender/device/timestamps.py"),
    "mipmap.cl": ("mip chains are built by the texture pool at upload", "clrender/render/texture_pool.py"),
    "texel_decode.cl": ("the texture pool's decoded copy, made at a scene's first frame", "clrender/render/texture_pool.py"),
}
PASS_EXCEPTIONS = {
    "base.py": ("the pass contract (RenderPass, Resources) the pipeline wires", "clrender/render/pipeline.py"),
    "forward.py": ("kernels/forward.h's arguments, shared by peel and abuffer", "kernels/forward.h"),
    "shadow.py": ("shadow maps drawn with the raster pipeline's kernels", "kernels/raster.cl"),
    "second_geometry.py": ("the geometry submitted twice: raster.cl again", "kernels/raster.cl"),
    "tam.py": ("hatching's tonal art map, a helper of passes/hatching.py", "clrender/passes/hatching.py"),
    "shadow_views.py": ("shadow view matrices, a helper of passes/shadow.py", "clrender/passes/shadow.py"),
}
# Files whose .cl/.py pairing does not apply (not kernels / not passes).
IGNORED_PASS_FILES = {"__init__.py"}


# ---------------------------------------------------------------------------------------------
# 1. imports

def _modules(root: Path) -> dict[str, Path]:
    """{dotted module name: file} for every .py under root/clrender."""
    pkg = root / "clrender"
    out = {}
    for path in sorted(pkg.rglob("*.py")):
        parts = list(path.relative_to(root).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = path
    return out


def _lazy_table(path: Path) -> tuple[dict[str, str], str | None]:
    """A package __init__'s `exports(__name__, {submodule: (names,)}, fallback=...)` table as
    {name: submodule}, and the fallback submodule (clrender/_lazy.py)."""
    where, fallback = {}, None
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Call) and getattr(node.func, "id", None) == "exports" and len(node.args) >= 2:
            table = node.args[1]
            if isinstance(table, ast.Dict):
                for key, value in zip(table.keys, table.values):
                    if isinstance(key, ast.Constant) and isinstance(value, (ast.Tuple, ast.List)):
                        for elt in value.elts:
                            if isinstance(elt, ast.Constant):
                                where[elt.value] = key.value
            for kw in node.keywords:
                if kw.arg == "fallback" and isinstance(kw.value, ast.Constant):
                    fallback = kw.value.value
    return where, fallback


def _resolve(name: str, modules: dict) -> str | None:
    """The longest clrender module that `name` (dotted) names or lies in."""
    while name:
        if name in modules:
            return name
        name = name.rpartition(".")[0]
    return None


def _type_only(tree: ast.AST) -> set:
    """ids of the nodes inside `if TYPE_CHECKING:` bodies (annotations only: never run)."""
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            out |= {id(sub) for stmt in node.body for sub in ast.walk(stmt)}
    return out


def _imports(root: Path) -> list[tuple[str, str, Path, int, bool]]:
    """Every (importer, imported module, file, line, type_only) inside clrender/, module level and
    nested; type_only: under `if TYPE_CHECKING:`.
    `from pkg import name` goes to pkg.name when that is a module, else through pkg's lazy table
    (or its fallback) to the submodule that defines name, else to pkg itself. importlib.import_module("clrender.x")
    with a constant name counts; a string such as "python -m clrender.x" does not."""
    modules = _modules(root)
    lazy = {m: _lazy_table(p) for m, p in modules.items() if p.name == "__init__.py"}
    found = []
    for importer, path in modules.items():
        package = importer if path.name == "__init__.py" else importer.rpartition(".")[0]
        tree = ast.parse(path.read_text(), str(path))
        type_only = _type_only(tree)
        for node in ast.walk(tree):
            targets = []
            if isinstance(node, ast.Import):
                targets = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    up = package.split(".")
                    up = up[: len(up) - (node.level - 1)]
                    base = ".".join(up + ([base] if base else []))
                for alias in node.names:
                    full = f"{base}.{alias.name}"
                    if full in modules:
                        targets.append(full)
                    elif base in lazy and alias.name in lazy[base][0]:
                        targets.append(f"{base}.{lazy[base][0][alias.name]}")
                    elif base in lazy and lazy[base][1] is not None:      # exports(..., fallback=)
                        targets.append(f"{base}.{lazy[base][1]}")
                    else:
                        targets.append(base)
            elif (isinstance(node, ast.Call) and node.args and isinstance(node.args[0], ast.Constant)
                  and isinstance(node.args[0].value, str)
                  and getattr(node.func, "attr", getattr(node.func, "id", None)) in ("import_module", "__import__")):
                targets = [node.args[0].value]
            for target in targets:
                if target != "clrender" and not target.startswith("clrender."):
                    continue
                module = _resolve(target, modules)
                if module is not None and module != importer:
                    found.append((importer, module, path, node.lineno, id(node) in type_only))
    return found


def _group(module: str) -> str:
    parts = module.split(".")
    head = parts[1] if len(parts) > 1 else "__init__"
    for group, (_, members) in LAYERS.items():
        if head in members:
            return group
    raise AssertionError(f"{module} is in no group of the layer table (tests/test_layout.py LAYERS)")


def upward_imports(root: Path) -> list[str]:
    """Imports that go up the layer table or sideways into a sibling group."""
    bad = []
    for importer, module, path, line, _ in sorted(set(_imports(root))):
        a, b = _group(importer), _group(module)
        if a != b and LAYERS[b][0] >= LAYERS[a][0]:
            how = "sideways" if LAYERS[b][0] == LAYERS[a][0] else "upward"
            bad.append(f"{path.relative_to(root)}:{line}: {importer} imports {module} ({how}: {a} -> {b})")
    return bad


def import_circles(root: Path) -> list[str]:
    """Strongly connected components of more than one module, each with the imports inside it.
    Imports under `if TYPE_CHECKING:` never run: an annotation may name a module that imports it
    (the layer check still counts them)."""
    edges: dict[str, set] = {}
    where: dict[tuple, list] = {}
    for importer, module, path, line, type_only in _imports(root):
        if type_only:
            continue
        edges.setdefault(importer, set()).add(module)
        at = f"{path.relative_to(root)}:{line}"
        if at not in where.setdefault((importer, module), []):
            where[importer, module].append(at)
    components = _sccs(set(_modules(root)), edges)
    out = []
    for comp in components:
        if len(comp) > 1:
            inside = sorted(f"{a} -> {b} ({', '.join(where[a, b])})"
                            for a in comp for b in edges.get(a, ()) if b in comp)
            out.append("circle " + " <-> ".join(sorted(comp)) + ": " + "; ".join(inside))
    return out


def _sccs(nodes: set, edges: dict) -> list[set]:
    """Tarjan's strongly connected components, iterative."""
    index, low, on_stack, stack, out, counter = {}, {}, set(), [], [], [0]
    for start in sorted(nodes):
        if start in index:
            continue
        work = [(start, iter(sorted(edges.get(start, ()))))]
        index[start] = low[start] = counter[0]; counter[0] += 1
        stack.append(start); on_stack.add(start)
        while work:
            node, children = work[-1]
            for child in children:
                if child not in index:
                    index[child] = low[child] = counter[0]; counter[0] += 1
                    stack.append(child); on_stack.add(child)
                    work.append((child, iter(sorted(edges.get(child, ())))))
                    break
                if child in on_stack:
                    low[node] = min(low[node], index[child])
            else:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[node])
                if low[node] == index[node]:
                    comp = set()
                    while True:
                        top = stack.pop(); on_stack.discard(top); comp.add(top)
                        if top == node:
                            break
                    out.append(comp)
    return out


# ---------------------------------------------------------------------------------------------
# 2. pass = kernel = module

def unpaired_kernels(root: Path) -> list[str]:
    kernels = {p.stem for p in (root / "kernels").glob("*.cl")}
    passes = {p.stem for p in (root / "clrender" / "passes").glob("*.py") if p.name not in IGNORED_PASS_FILES}
    bad = []
    for name in sorted(kernels - passes):
        if f"{name}.cl" not in KERNEL_EXCEPTIONS:
            bad.append(f"kernels/{name}.cl has no clrender/passes/{name}.py (nor a listed exception)")
    for name in sorted(passes - kernels):
        if f"{name}.py" not in PASS_EXCEPTIONS:
            bad.append(f"clrender/passes/{name}.py has no kernels/{name}.cl (nor a listed exception)")
    for table, folder in ((KERNEL_EXCEPTIONS, "kernels"), (PASS_EXCEPTIONS, "clrender/passes")):
        for name, (_, partner) in table.items():
            if not (root / folder / name).is_file():
                bad.append(f"exception {name}: {folder}/{name} does not exist (a stale exception)")
            if not (root / partner).is_file():
                bad.append(f"exception {name}: its partner {partner} does not exist")
            elif (root / folder / name).is_file():
                mine, theirs = (root / folder / name).read_text(), (root / partner).read_text()
                if Path(partner).name not in mine and Path(name).stem not in theirs:
                    bad.append(f"exception {name}: neither it nor its partner {partner} names the other")
    return bad


# ---------------------------------------------------------------------------------------------
# 3. kernel headers

INCLUDE = re.compile(r'^\s*#\s*include\s+"([^"]+)"', re.M)


def header_circles(root: Path) -> list[str]:
    kernels = root / "kernels"
    edges = {}
    for path in sorted([*kernels.glob("*.h"), *kernels.glob("*.cl")]):
        text = re.sub(r"/\*.*?\*/|//[^\n]*", "", path.read_text(), flags=re.S)
        edges[path.name] = {inc for inc in INCLUDE.findall(text)}
    return ["header circle " + " <-> ".join(sorted(comp))
            for comp in _sccs(set(edges), edges) if len(comp) > 1
            ] + [f"{name} includes itself" for name, incs in edges.items() if name in incs]


# ---------------------------------------------------------------------------------------------
# The tests on this repository

def test_every_module_is_in_the_layer_table():
    for module in _modules(ROOT):
        _group(module)


def test_imports_go_down_the_layers():
    bad = upward_imports(ROOT)
    assert not bad, "imports against the layers (tests/test_layout.py LAYERS):\n" + "\n".join(bad)


def test_no_import_circles():
    bad = import_circles(ROOT)
    assert not bad, "import circles:\n" + "\n".join(bad)


def test_every_kernel_has_its_pass_and_every_pass_its_kernel():
    bad = unpaired_kernels(ROOT)
    assert not bad, "\n".join(bad)


def test_no_kernel_header_circles():
    bad = header_circles(ROOT)
    assert not bad, "\n".join(bad)


@pytest.mark.parametrize("name", sorted(p.name for p in (ROOT / "kernels").glob("*.h")))
def test_each_header_builds_alone(device, name):
    """A header includes what it uses, so it builds as the only include of a program. This catches
    the circle the #include graph cannot show: a header using types of a header that includes it
    (material_eval.h used surface_vec.h's types before surface_types.h)."""
    import warnings

    import pyopencl as cl
    from clrender.device.core import Device
    dev = Device.get(device)
    source = f'#include "{name}"\nkernel void alone(global int* x) {{ x[0] = 0; }}\n'
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", cl.CompilerWarning)
        cl.Program(dev.context, source).build(options=[*dev.base_options, f"-I{ROOT / 'kernels'}"])


# ---------------------------------------------------------------------------------------------
# Self-checks: each checker reports a planted violation in a synthetic tree

def _tree(tmp_path: Path, files: dict[str, str]) -> Path:
    for name, text in files.items():
        path = tmp_path / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
    return tmp_path


def _clean_tree() -> dict[str, str]:
    files = {
        "clrender/__init__.py": "from clrender.scene.model import Scene\n",
        "clrender/errors.py": "",
        "clrender/scene/__init__.py": ("from clrender._lazy import exports\n"
                                       "__all__, __getattr__, __dir__ = exports(__name__, {'model': ('Scene',)})\n"),
        "clrender/_lazy.py": "",
        "clrender/scene/model.py": "from clrender.errors import *\nclass Scene: pass\n",
        "clrender/render/__init__.py": "",
        "clrender/render/renderer.py": ("from clrender.scene import Scene\n"
                                        "CMD = 'python -m clrender.cli.main'\n"),
        "clrender/passes/__init__.py": "",
        "clrender/passes/base.py": "",
        "clrender/passes/gbuffer.py": "from clrender.passes.base import *\n",
        "clrender/device/__init__.py": "",
        "clrender/device/scan.py": "",
        "kernels/gbuffer.cl": '#include "a.h"\n',
        "kernels/scan.cl": "",
        "kernels/a.h": '#include "b.h"\n',
        "kernels/b.h": "/* #include \"a.h\" in a comment is no include */\n",
    }
    for table, folder in ((KERNEL_EXCEPTIONS, "kernels"), (PASS_EXCEPTIONS, "clrender/passes")):
        for name, (_, partner) in table.items():         # each exception file names its partner
            comment = "#" if name.endswith(".py") else "//"
            files[f"{folder}/{name}"] = files.get(f"{folder}/{name}", "") + f"{comment} {Path(partner).name}\n"
            files.setdefault(partner, "")
    files["clrender/passes/raster.py"] = files["clrender/passes/hatching.py"] = files["kernels/hatching.cl"] = ""
    return files


def test_self_check_clean_tree_passes(tmp_path):
    root = _tree(tmp_path, _clean_tree())
    assert upward_imports(root) == []
    assert import_circles(root) == []
    assert unpaired_kernels(root) == []
    assert header_circles(root) == []


def test_self_check_reports_an_upward_import(tmp_path):
    files = _clean_tree()
    files["clrender/scene/model.py"] += "def f():\n    from clrender.render.renderer import X\n"
    files["clrender/device/scan.py"] = "from clrender.scene import Scene\n"          # sibling
    files["clrender/errors.py"] = "import clrender\n"                                 # to the root
    files["clrender/abi/__init__.py"] = "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    import clrender.device.scan\n"
    bad = upward_imports(_tree(tmp_path, files))
    assert any(b.startswith("clrender/scene/model.py:4:") and "upward: scene -> render" in b for b in bad), bad
    assert any(b.startswith("clrender/device/scan.py:1:") and "sideways: device -> scene" in b for b in bad), bad
    assert any(b.startswith("clrender/errors.py:1:") and "base -> root" in b for b in bad), bad
    assert any(b.startswith("clrender/abi/__init__.py:3:") and "upward: abi -> device" in b for b in bad), bad


def test_self_check_reports_a_circle(tmp_path):
    files = _clean_tree()
    files["clrender/passes/base.py"] = "def f():\n    import clrender.passes.gbuffer\n"   # inside a package
    files["clrender/scene/camera.py"] = "from clrender.scene import Scene\n"             # via the lazy table
    files["clrender/scene/model.py"] += "from . import camera\n"
    bad = import_circles(_tree(tmp_path, files))
    assert any("clrender.passes.base <-> clrender.passes.gbuffer" in b and "clrender/passes/base.py:2" in b
               for b in bad), bad
    assert any("clrender.scene.camera <-> clrender.scene.model" in b for b in bad), bad


def test_self_check_strings_and_lazy_tables_are_not_imports(tmp_path):
    files = _clean_tree()
    # the lazy table of clrender.scene names model, model imports scene's package: no circle
    files["clrender/scene/model.py"] += "import clrender.scene\n"
    files["clrender/scene/camera.py"] = "HELP = 'run python -m clrender.render.renderer'\n"
    # an annotation-only back reference is no circle
    files["clrender/passes/base.py"] = "import typing\nif typing.TYPE_CHECKING:\n    from clrender.passes.gbuffer import G\n"
    root = _tree(tmp_path, files)
    assert import_circles(root) == [] and upward_imports(root) == []


def test_self_check_reports_an_unpaired_kernel(tmp_path):
    files = _clean_tree()
    files["kernels/lonely.cl"] = ""
    files["clrender/passes/orphan.py"] = ""
    del files["clrender/device/scan.py"]                 # an exception's partner missing
    bad = unpaired_kernels(_tree(tmp_path, files))
    assert any("kernels/lonely.cl" in b for b in bad), bad
    assert any("clrender/passes/orphan.py" in b for b in bad), bad
    assert any("clrender/device/scan.py does not exist" in b for b in bad), bad


def test_self_check_reports_a_header_circle(tmp_path):
    files = _clean_tree()
    files["kernels/b.h"] += '#include "a.h"\n'
    bad = header_circles(_tree(tmp_path, files))
    assert bad == ["header circle a.h <-> b.h"], bad
