"""The render option table (clrender/config.py: OPTIONS) is the one definition: RenderConfig's
fields and checks, the CLI's render flags and a TOML scene's [render] keys all follow it, an
unknown option is an error in all three, and docs/options.md is the table as generated."""
from __future__ import annotations

import argparse
import dataclasses
import subprocess
import sys
from pathlib import Path

import pytest

from clrender.config import OPTION, OPTIONS, RenderConfig, markdown_table
from clrender.errors import CLIError, SceneError
from clrender.loaders import load_scene
from loader_cases import write_gltf

ROOT = Path(__file__).resolve().parents[1]
FLAGGED = [o for o in OPTIONS if o.cli_flag is not None]
# what an option needs beside it to be valid on its own (RenderConfig's combination rules)
NEEDS = {"msaa": {"pipeline": "light_prepass"}, "light_buffer_specular": {"pipeline": "light_prepass"},
         "light_buffer_precision": {"pipeline": "light_prepass"}, "reuse_visibility": {"pipeline": "light_prepass"}}


def _toml_value(value) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    return f'"{value}"' if isinstance(value, str) else repr(value)


def _parse(tmp_path, *flags):
    from clrender.cli.common import render_options
    from clrender.cli.app import build_parser, _join_vector_options
    scene = tmp_path / "t.gltf"
    write_gltf(scene)
    args = build_parser().parse_args(_join_vector_options(["render", str(scene), "-o", str(tmp_path / "o.png"),
                                                           *flags]))
    return render_options(args)


def test_renderconfig_fields_are_the_table():
    fields = dataclasses.fields(RenderConfig)
    assert [(f.name, f.default) for f in fields] == [(o.name, o.default) for o in OPTIONS]
    config = RenderConfig()
    for o in OPTIONS:
        assert getattr(config, o.name) == o.default
        assert RenderConfig.from_options(**{o.name: o.default}) == config


@pytest.mark.parametrize("option", OPTIONS, ids=lambda o: o.name)
def test_each_option_is_checked_as_the_table_says(option):
    """Every choice / both ends of a range pass; a value of the wrong type or just outside fails
    with the table's wording."""
    base = NEEDS.get(option.name, {})
    good = list(option.choices or ()) + ([True, False] if option.type is bool else [])
    bad = ["x"] if option.type is not str else [7]
    if option.range is not None:
        lo, hi = option.range
        step = 1 if option.type is int else 1e-6
        good += ([lo] if not option.open_lo else [lo + step]) + ([hi] if hi is not None else [])
        bad += [lo] if option.open_lo else [lo - step]
        bad += [hi + step] if hi is not None else [float("inf")]
    if option.type in (int, float):
        bad.append(True)                         # bool is no number here
    for value in good:
        RenderConfig.from_options(**base, **{option.name: value})
    for value in bad:
        with pytest.raises(ValueError, match=f"^{option.name} must be "):
            RenderConfig.from_options(**base, **{option.name: value})


def test_cli_flags_are_the_table(tmp_path):
    from clrender.cli.app import build_parser
    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    for command in ("render", "dataset"):
        flags = {s for a in sub.choices[command]._actions for s in a.option_strings}
        for o in OPTIONS:
            assert (o.cli_flag in flags) == (o.flag is not None), (command, o.name)
    assert _parse(tmp_path) == {}                # nothing given: every option at its default (or the scene's)
    for o in FLAGGED:
        base = [f"--pipeline={NEEDS[o.name]['pipeline']}"] if o.name in NEEDS else []
        if o.cli_switch:                         # a switch: off is its absence, on is the flag
            options = _parse(tmp_path, *base, o.cli_flag)
            on = True if o.type is bool else o.flag_value
            assert options[o.name] == on
        elif o.default is None:                  # chosen at render time (tile_size): no spelling, left out
            continue
        else:                                    # its default, written as a user would
            text = f"{o.default:g}" if isinstance(o.default, float) else str(o.default)
            options = _parse(tmp_path, *base, f"{o.cli_flag}={text}")
            assert options[o.name] == o.default
        RenderConfig.from_options(**options)


def test_cli_names_the_flag_of_a_bad_value(tmp_path):
    with pytest.raises(CLIError, match="^--edge-normal-threshold: edge_normal_threshold_deg must be"):
        _parse(tmp_path, "--edge-normal-threshold=200")
    with pytest.raises(CLIError, match="^--peel-layers: peel_layers must be an integer in"):
        _parse(tmp_path, "--peel-layers=65")


def test_toml_render_keys_are_the_table(tmp_path):
    write_gltf(tmp_path / "t.gltf")
    lines = [f"{o.name} = {_toml_value(o.default)}" for o in OPTIONS if o.default is not None]   # TOML has no null
    (tmp_path / "s.toml").write_text('[[mesh]]\npath = "t.gltf"\n[render]\n' + "\n".join(lines) + "\n")
    render = load_scene(tmp_path / "s.toml").settings["render"]
    assert render == {o.name: o.default for o in OPTIONS if o.default is not None}
    assert RenderConfig.from_options(**render) == RenderConfig()


def test_an_unknown_option_fails_everywhere(tmp_path):
    with pytest.raises(ValueError, match="unknown render option"):
        RenderConfig.from_options(tile_sise=8)
    with pytest.raises(TypeError):
        RenderConfig(tile_sise=8)
    with pytest.raises(CLIError, match="unrecognized arguments: --tile-sise") as info:
        _parse(tmp_path, "--tile-sise=8")
    assert info.value.code == 2
    write_gltf(tmp_path / "t.gltf")
    (tmp_path / "s.toml").write_text('[[mesh]]\npath = "t.gltf"\n[render]\ntile_sise = 8\n')
    with pytest.raises(SceneError, match="tile_sise"):
        load_scene(tmp_path / "s.toml")


def test_docs_options_table_is_generated():
    """docs/options.md holds the table exactly as `python3 -m clrender.config` prints it."""
    doc = (ROOT / "docs" / "options.md").read_text()
    assert markdown_table() in doc, "regenerate: python3 -m clrender.config > the table in docs/options.md"


def test_config_and_toml_loader_need_no_opencl():
    code = "import clrender.config, clrender.loaders.toml_scene, sys; assert 'pyopencl' not in sys.modules"
    subprocess.run([sys.executable, "-c", code], check=True, cwd=ROOT)


def test_option_lookup():
    assert OPTION["color_aa"].cli_flag == "--fxaa" and OPTION["shadow_bias"].cli_flag is None
