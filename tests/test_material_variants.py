"""KHR_materials_variants (docs/scene-format.md "Material variants"): `load_scene(path, variant=)`,
`Scene.set_variant`, `Scene.variants`, `clrender render --variant`, `clrender info`.

The expected materials come from the extension's rule, applied here to the JSON this test writes
(not from the loader's tables): a primitive shows the material of the first mapping whose
`variants` contains the active variant's index, else its own `material`. Switching must change
the triangles of exactly the primitives the variants involved map, and a switched scene must render
bit-identically to a file that gives those primitives the variant's material directly (on the same
Scene object after a render too: the upload cache must see the switch).
(tests/gltf_files.py writes the files: several primitives, nodes and primitive extensions, which
tests/reference/gltf_writer.py's one-primitive files cannot hold.)
"""
from __future__ import annotations

import copy
import json
import warnings

import numpy as np
import pytest

from clrender import Camera, SceneError, load_scene
from clrender.cli import app as cli
from gltf_files import QUAD_POSITIONS, primitive, write_gltf

NAMES = ["blue", "yellow", "empty"]
COLORS = {"red": (0.8, 0.1, 0.1, 1), "green": (0.1, 0.8, 0.1, 1), "blue": (0.1, 0.1, 0.8, 1),
          "yellow": (0.8, 0.8, 0.1, 1)}
MATERIALS = [{"name": n, "pbrMetallicRoughness": {"baseColorFactor": list(c), "metallicFactor": 0.0,
                                                  "roughnessFactor": 0.6}} for n, c in COLORS.items()]
# mesh 0: primitive 0 (red) -> blue in "blue", yellow in "yellow"; primitive 1 (green) -> yellow in
# "yellow" only. "empty" maps nothing. Materials 2 and 3 are used by variants only.
MAPPINGS = [[{"material": 2, "variants": [0]}, {"material": 3, "variants": [1]}],
            [{"material": 3, "variants": [1]}]]
OWN = [0, 1]


def _prims(own=OWN, mappings=MAPPINGS):
    prims = []
    for p, (mat, maps) in enumerate(zip(own, mappings)):
        prim = primitive(positions=QUAD_POSITIONS + np.float32([1.1 * p, 0, 0]), material=mat)
        if maps:
            prim["extensions"] = {"KHR_materials_variants": {"mappings": copy.deepcopy(maps)}}
        prims.append(prim)
    return prims


def _write(path, own=OWN, mappings=MAPPINGS, names=NAMES, materials=MATERIALS):
    top = {}
    if names is not None:
        top = {"extensions": {"KHR_materials_variants": {"variants": [{"name": n} for n in names]}},
               "extensionsUsed": ["KHR_materials_variants"]}
    # two nodes draw the mesh: a mapping belongs to the primitive, so it applies on both
    nodes = [{"mesh": 0, "name": "a"}, {"mesh": 0, "name": "b", "translation": [0, 1.2, 0]}]
    return write_gltf(path, primitives=_prims(own, mappings), materials=copy.deepcopy(materials), nodes=nodes,
                      **top)


def _expected(path, variant):
    """Per triangle, the material the extension's rule gives, from the file's JSON (triangle order:
    nodes, then primitives, then faces; each quad has 2 triangles)."""
    j = json.loads(path.read_text())
    index = None if variant is None else [v["name"] for v in j["extensions"]["KHR_materials_variants"]
                                          ["variants"]].index(variant)
    out = []
    for node in j["nodes"]:
        for prim in j["meshes"][node["mesh"]]["primitives"]:
            maps = prim.get("extensions", {}).get("KHR_materials_variants", {}).get("mappings", [])
            mat = next((m["material"] for m in maps if index in m["variants"]), prim["material"])
            out += [mat, mat]
    return np.array(out)


def test_names_default_and_variant_only_materials(tmp_path):
    path = _write(tmp_path / "v.gltf")
    scene = load_scene(path)
    assert scene.variants == tuple(NAMES)
    assert scene.variant is None
    assert [m.name for m in scene.materials[:4]] == list(COLORS)     # blue, yellow: only variants use them
    np.testing.assert_array_equal(scene.triangle_material, _expected(path, None))


def test_switch_changes_exactly_the_mapped_primitives(tmp_path):
    path = _write(tmp_path / "v.gltf")
    scene = load_scene(path)
    mapped = {"blue": {0}, "yellow": {0, 1}, "empty": set(), None: set()}    # primitive indices per variant
    prim_of_triangle = np.tile(np.repeat([0, 1], 2), 2)
    previous, before = None, scene.triangle_material
    for name in ["blue", "yellow", None, "empty", "yellow", "blue", None]:
        scene.set_variant(name)
        after = scene.triangle_material
        assert after is not before          # a new array: the renderer's upload cache sees the switch
        assert scene.variant == name
        np.testing.assert_array_equal(after, _expected(path, name))
        changed = set(prim_of_triangle[after != before].tolist())
        assert changed <= mapped[name] | mapped[previous], (previous, name, changed)
        previous, before = name, after


def test_load_scene_variant_equals_set_variant(tmp_path):
    path = _write(tmp_path / "v.gltf")
    scene = load_scene(path, variant="yellow")
    assert scene.variant == "yellow"
    np.testing.assert_array_equal(scene.triangle_material, _expected(path, "yellow"))


def test_unknown_variant_is_one_line_listing_the_names(tmp_path):
    path = _write(tmp_path / "v.gltf")
    with pytest.raises(SceneError) as info:
        load_scene(path, variant="purple")
    text = str(info.value)
    assert "\n" not in text and "'purple'" in text
    assert all(repr(n) in text for n in NAMES), text
    scene = load_scene(path)
    with pytest.raises(SceneError):
        scene.set_variant("Blue")           # names are exact
    assert scene.variant is None
    plain = load_scene(write_gltf(tmp_path / "plain.gltf"))
    assert plain.variants == ()
    plain.set_variant(None)
    with pytest.raises(SceneError, match="no material variants"):
        plain.set_variant("blue")


def test_bad_mappings_warn_and_are_ignored(tmp_path):
    mappings = [[{"material": 9, "variants": [0]}, {"material": 2, "variants": [0, 7]}],
                [{"material": 3, "variants": [1]}, {"material": 2, "variants": [1]}]]
    path = _write(tmp_path / "bad.gltf", mappings=mappings)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        scene = load_scene(path)
    messages = [str(w.message) for w in caught if "KHR_materials_variants" in str(w.message)]
    assert any("material 9 does not exist" in m for m in messages), messages
    assert any("variant 7 does not exist" in m for m in messages), messages
    assert any("variant 1 is already mapped to material 3" in m for m in messages), messages
    assert all("\n" not in m for m in messages)
    scene.set_variant("blue")               # primitive 0: the second mapping's variant 0 survives
    np.testing.assert_array_equal(scene.triangle_material[:4], [2, 2, 1, 1])
    scene.set_variant("yellow")             # primitive 1: the first mapping wins
    np.testing.assert_array_equal(scene.triangle_material[:4], [0, 0, 3, 3])


def test_variant_material_needing_tangents_generates_them(tmp_path):
    """A normal map on a material only a variant shows: the primitive gets generated tangents."""
    materials = copy.deepcopy(MATERIALS)
    materials[3]["normalTexture"] = {"index": 0}
    path = _write(tmp_path / "n.gltf", materials=materials)
    j = json.loads(path.read_text())
    j["images"] = [{"uri": "data:image/png;base64," + _png_base64()}]
    j["textures"] = [{"source": 0}]
    path.write_text(json.dumps(j))
    scene = load_scene(path)
    assert scene.tangents is not None
    assert np.all(np.abs(scene.tangents[:, :3]).sum(1) > 0)    # both primitives can show material 3
    plain = load_scene(_write(tmp_path / "p.gltf"))
    assert plain.tangents is None


def _png_base64() -> str:
    import base64
    import io

    from PIL import Image
    buf = io.BytesIO()
    Image.fromarray(np.full((2, 2, 4), [128, 128, 255, 255], np.uint8), "RGBA").save(buf, "PNG")
    return base64.b64encode(buf.getvalue()).decode()


def test_switched_scene_renders_like_the_direct_file(tmp_path, make_renderer):
    renderer = make_renderer(64, 48)
    variant_path = _write(tmp_path / "v.gltf")
    scene = load_scene(variant_path)
    camera = Camera.look_at((1.05, 1.1, 2.6), (1.05, 1.1, 0), (0, 1, 0), 60.0, near=0.1, far=10)
    default = renderer.render(scene, camera).image.copy()
    for name in ["blue", "yellow", None]:
        scene.set_variant(name)             # the same Scene object, already uploaded once
        switched = renderer.render(scene, camera).image
        direct_own = [int(m) for m in _expected(variant_path, name)[[0, 2]]]
        direct = load_scene(_write(tmp_path / f"direct_{name}.gltf", own=direct_own, mappings=[[], []], names=None))
        assert direct.variants == ()
        want = renderer.render(direct, camera).image
        np.testing.assert_array_equal(switched, want, err_msg=f"variant {name}")
        assert (name is None) == np.array_equal(switched, default), name     # the test can see a change
    fresh = renderer.render(load_scene(variant_path, variant="yellow"), camera).image
    scene.set_variant("yellow")
    np.testing.assert_array_equal(fresh, renderer.render(scene, camera).image)


# -- CLI -------------------------------------------------------------------------------------------
@pytest.fixture
def _no_debug(monkeypatch):
    monkeypatch.delenv(cli.ENV_DEBUG, raising=False)


def test_cli_render_variant(tmp_path, capsys, _no_debug, device):
    from PIL import Image
    path = _write(tmp_path / "v.gltf")
    common = ["--width", "32", "--height", "24", "--device", device.id, "-q"]
    assert cli.main(["render", str(path), "-o", str(tmp_path / "blue.png"), "--variant", "blue", *common]) == 0
    assert cli.main(["render", str(path), "-o", str(tmp_path / "plain.png"), *common]) == 0
    direct = _write(tmp_path / "direct.gltf", own=[2, 1], mappings=[[], []], names=None)
    assert cli.main(["render", str(direct), "-o", str(tmp_path / "direct.png"), *common]) == 0
    image = lambda name: np.asarray(Image.open(tmp_path / name))   # noqa: E731
    np.testing.assert_array_equal(image("blue.png"), image("direct.png"))
    assert not np.array_equal(image("blue.png"), image("plain.png"))
    capsys.readouterr()
    assert cli.main(["render", str(path), "-o", str(tmp_path / "x.png"), "--variant", "nope", *common]) != 0
    err = capsys.readouterr().err.strip().splitlines()
    assert err and err[-1].startswith("clrender: error: ") and "'nope'" in err[-1] and "'yellow'" in err[-1], err


def test_cli_info_lists_variants(tmp_path, capsys, _no_debug):
    materials = copy.deepcopy(MATERIALS)
    materials[0]["extensions"] = {"KHR_materials_clearcoat": {"clearcoatFactor": 0.5}}
    materials[1]["extensions"] = {"KHR_materials_sheen": {"sheenColorFactor": [1, 1, 1]},
                                  "KHR_materials_clearcoat": {"clearcoatFactor": 1.0}}
    path = _write(tmp_path / "v.gltf", materials=materials)
    assert cli.main(["info", str(path), "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert [v["name"] for v in info["variants"]] == NAMES
    # primitives each variant maps (a primitive counts once, however many nodes draw it)
    assert [v["primitives"] for v in info["variants"]] == [1, 2, 0]
    assert [v["materials"] for v in info["variants"]] == [[2], [3], []]
    assert info["material_extensions"] == [{"name": "KHR_materials_clearcoat", "materials": 2},
                                           {"name": "KHR_materials_sheen", "materials": 1}]
    assert cli.main(["info", str(path)]) == 0
    text = capsys.readouterr().out
    assert "material variants: 3" in text
    assert "  variant 0 'blue': 1 primitive(s), material(s) 2" in text
    assert "  variant 2 'empty': 0 primitive(s)" in text
    assert "material extensions: KHR_materials_clearcoat (2 materials), KHR_materials_sheen (1 material)" in text


def test_batch_tasks_carry_the_variant(tmp_path):
    """A frame task names its variant; the worker's scene cache keeps one scene per variant; the
    --resume signature holds the variant only when one is given."""
    import pickle

    from clrender.batch import jobs, tasks
    path = _write(tmp_path / "v.gltf")
    plan, _ = jobs.plan_tasks([str(path)], range(2), str(tmp_path / "out"), variant="blue")
    assert plan[1].variant == "blue" and pickle.loads(pickle.dumps(plan[1])).variant == "blue"
    assert jobs.job_signature(plan, 24.0)["variant"] == "blue"
    plain, _ = jobs.plan_tasks([str(path)], range(2), str(tmp_path / "out"))
    assert plain[0].variant is None and "variant" not in jobs.job_signature(plain, 24.0)
    blue, default = tasks._scene(str(path), (), "blue"), tasks._scene(str(path), ())
    assert blue is not default and blue.variant == "blue" and default.variant is None
    assert tasks._scene(str(path), (), "blue") is blue
    np.testing.assert_array_equal(blue.triangle_material, _expected(path, "blue"))


def test_cli_frames_and_dataset_render_the_variant(tmp_path, capsys, _no_debug, device):
    from PIL import Image
    path = _write(tmp_path / "v.gltf")
    direct = _write(tmp_path / "direct.gltf", own=[2, 1], mappings=[[], []], names=None)
    common = ["--width", "32", "--height", "24", "--device", device.id, "-q"]
    for scene, out in ((path, "var"), (direct, "dir")):
        extra = ["--variant", "blue"] if scene == path else []
        assert cli.main(["render", str(scene), "--frames", "0:1", "-o", str(tmp_path / out / "{frame:04d}.png"),
                         *extra, *common]) == 0
        assert cli.main(["dataset", str(scene), "-o", str(tmp_path / f"{out}_ds"), "--views", "2", "--aov", "none",
                         *extra, *common]) == 0
    image = lambda rel: np.asarray(Image.open(tmp_path / rel))   # noqa: E731
    np.testing.assert_array_equal(image("var/0000.png"), image("dir/0000.png"))
    for v in ("0000", "0001"):
        np.testing.assert_array_equal(image(f"var_ds/images/{v}.png"), image(f"dir_ds/images/{v}.png"))
    meta = json.loads((tmp_path / "var_ds" / "dataset.json").read_text())
    assert meta["variant"] == "blue"
    assert "variant" not in json.loads((tmp_path / "dir_ds" / "dataset.json").read_text())


@pytest.mark.parametrize("extension, value", [
    ("KHR_materials_clearcoat", {"clearcoatFactor": 1.0, "clearcoatNormalTexture": {"index": 0}}),
    ("KHR_materials_anisotropy", {"anisotropyStrength": 0.5}),
])
def test_clearcoat_normal_map_and_anisotropy_generate_tangents(tmp_path, extension, value):
    """Without TANGENT, a clearcoat normal map or anisotropy (no base normal map) gets generated
    tangents (from the set the coat's map reads / TEXCOORD_0), as a base normal map does."""
    materials = copy.deepcopy(MATERIALS)
    materials[0]["extensions"] = {extension: value}
    path = _write(tmp_path / "t.gltf", materials=materials, names=None, mappings=[[], []])
    j = json.loads(path.read_text())
    j["images"] = [{"uri": "data:image/png;base64," + _png_base64()}]
    j["textures"] = [{"source": 0}]
    j["extensionsUsed"] = [extension]
    path.write_text(json.dumps(j))
    scene = load_scene(path)
    assert scene.tangents is not None
    on_material_0 = np.isin(np.arange(len(scene.positions)), scene.triangles[scene.triangle_material == 0])
    # the quad lies in z = 0 with u along +X: the generated tangent is +X, handedness from v down
    np.testing.assert_allclose(scene.tangents[on_material_0, :3], np.tile([1.0, 0.0, 0.0], (4 * 2, 1)), atol=1e-6)
    assert np.all(scene.tangents[~on_material_0, :3] == 0)      # material 1 needs none: "no tangent"
