"""Render options: ONE table (OPTIONS) gives each option's name, type, default, choices or range
and help; RenderConfig (its fields and their checks), the CLI's render flags
(clrender/cli/parser.py: add_render_options) and a TOML scene's `[render]` keys
(clrender/loaders/toml_tables.py) all come from it, and docs/options.md is generated from it
(`python3 -m clrender.config --markdown`; tests/test_options.py keeps them equal).
NumPy only: the loaders and the CLI use it without OpenCL."""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any, Optional

import numpy as np


@dataclass(frozen=True)
class Option:
    """One render option. `help` may hold {default}, {choices} ("8, 16 or 32") and {range}
    ("1..64"); without {default}, " (default X)" is appended (a switch's default reads on/off).
    `expect` words the error ("<name> must be <expect>, got <value>") where the generic wording
    (one of / an integer in [lo, hi] / a number >= lo / in [lo, hi]) is not the one users know.
    `flag`: the CLI spelling ("" = --name-with-dashes, None = not on the command line); a
    non-bool option with `flag_value` is a switch that sets that value."""
    name: str
    type: type
    default: Any
    help: str
    choices: Optional[tuple] = None
    range: Optional[tuple] = None            # (lo, hi): hi None = no bound but finite
    open_lo: bool = False                    # lo itself refused (a positive number)
    nullable: bool = False                   # None allowed (meaning: chosen at render time)
    expect: Optional[str] = None
    unit: Optional[str] = None               # appended to the generic error: "(texels)"
    flag: Optional[str] = ""
    flag_value: Any = None
    metavar: Optional[str] = None

    @property
    def cli_flag(self) -> Optional[str]:
        if self.flag is None:
            return None
        return self.flag or "--" + self.name.replace("_", "-")

    @property
    def cli_dest(self) -> str:
        """The argparse attribute of the flag (argparse's own spelling: --fxaa -> fxaa)."""
        return self.cli_flag[2:].replace("-", "_")

    @property
    def cli_switch(self) -> bool:
        return self.type is bool or self.flag_value is not None

    def expected(self) -> str:
        if self.expect is not None:
            return self.expect
        if self.type is bool:
            return "True or False"
        if self.choices is not None:
            return f"{'None or ' if self.nullable else ''}one of {self.choices}"
        lo, hi = self.range
        if self.type is int:
            return f"an integer in [{lo}, {hi}]"
        if hi is None:
            text = f"a number {'>' if self.open_lo else '>='} {lo}"
            return f"{text} ({self.unit})" if self.unit else text
        return f"in {'(' if self.open_lo else '['}{lo}, {hi}]"

    def accepts(self, value) -> bool:
        if value is None and self.nullable:
            return True
        if self.type is bool:
            return isinstance(value, bool)
        if self.type is int and not _is_int(value):
            return False
        if self.choices is not None:
            return value in self.choices
        if self.type is float and not (_is_real(value) and np.isfinite(value)):
            return False
        lo, hi = self.range
        return (value > lo if self.open_lo else value >= lo) and (hi is None or value <= hi)

    def check(self, value) -> None:
        if not self.accepts(value):
            raise ValueError(f"{self.name} must be {self.expected()}, got {value!r}")

    def default_text(self) -> str:
        if self.cli_switch:
            return "on" if self.default is True or (self.flag_value is not None and self.default == self.flag_value) else "off"
        return f"{self.default:g}" if isinstance(self.default, float) else str(self.default)

    def help_text(self) -> str:
        words = {"default": self.default_text()}
        if self.choices is not None:
            words["choices"] = ", ".join(map(str, self.choices[:-1])) + f" or {self.choices[-1]}"
        if self.range is not None:
            words["range"] = f"{self.range[0]}..{self.range[1]}"
        text = self.help if "{default}" in self.help else self.help + " (default {default})"
        return text.format(**words)


def _is_real(x) -> bool:
    return isinstance(x, (int, float, np.integer, np.floating)) and not isinstance(x, bool)


def _is_int(x) -> bool:
    return isinstance(x, (int, np.integer)) and not isinstance(x, bool)


def check_int(name: str, value, lo: int, hi: int) -> int:
    """`value` as an int in [lo, hi]; ValueError naming the parameter and, for a value that is not
    an integer at all, its type: bool is an int to Python but True is no width, and "160" or
    160.0 are refused rather than converted."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise ValueError(f"{name} must be an integer in [{lo}, {hi}], got {type(value).__name__} {value!r}")
    if not lo <= value <= hi:
        raise ValueError(f"{name} must be an integer in [{lo}, {hi}], got {value}")
    return int(value)


TILE_SIZES = (8, 16, 32)
LIGHT_CULLING = ("tiled", "brute_force", "quads", "stencil")   # docs/light_accumulation.md
TONEMAPS = ("reinhard", "aces", "clamp")
SHADING = ("auto", "blinn_phong")   # kernels/brdf.h: per-material models, or the report's everywhere
SHADOW_FILTERS = ("pcf3x3", "poisson", "hard")
TRANSPARENCY = ("abuffer", "depth_peeling", "screen_door")
SUPERSAMPLE_FILTERS = ("box", "lanczos2", "mitchell")
COLOR_AA = ("none", "fxaa")
PIPELINES = ("deferred", "light_prepass", "light_indexed")     # docs/variants.md
MSAA = (1, 2, 4, 8)
LIGHT_BUFFER_SPECULAR = ("rgb", "luminance")
LIGHT_BUFFER_PRECISION = ("float32", "float16")
MAX_PEEL_LAYERS = 64

_LPP = "with --pipeline light_prepass: "
# RenderConfig's fields, in this order. Help is worded for the command line (flags named as flags).
OPTIONS: tuple[Option, ...] = (
    Option("pipeline", str, "deferred", choices=PIPELINES,
           help="renderer variant: deferred shading, Engel's light pre-pass, or Trebilco's light-indexed "
                "deferred (default {default}; docs/variants.md)"),
    Option("shading", str, "auto", choices=SHADING,
           help="auto: glTF metallic-roughness materials with the glTF 2.0 BRDF, the others Blinn-Phong; "
                "blinn_phong: the report's model for every material (default {default}; docs/shading.md)"),
    Option("multiscatter", bool, False,
           help="multiple-scattering energy compensation of the image-based specular of layered glTF materials "
                "(Fdez-Agüera, as the Khronos Sample Renderer; off: glTF Appendix B's single scattering; "
                "docs/shading.md)"),
    Option("msaa", int, 1, choices=MSAA, metavar="N",
           help=_LPP + "colour sub-samples per pixel, {choices} (D3D standard patterns; default {default})"),
    Option("light_buffer_specular", str, "rgb", choices=LIGHT_BUFFER_SPECULAR,
           help=_LPP + "specular RGB, or its luminance coloured by the diffuse light (the classic LPP trade-off; "
                        "default {default})"),
    Option("light_buffer_precision", str, "float32", choices=LIGHT_BUFFER_PRECISION,
           help=_LPP + "light buffer of floats or halves"),
    Option("reuse_visibility", bool, False,
           help="with --pipeline light_prepass or light_indexed: read the first pass's visibility "
                "instead of rasterizing again (same pixels; not the report's algorithm; default {default})"),
    Option("tile_size", int, None, choices=TILE_SIZES, nullable=True, metavar="N",
           help="raster tile size in pixels: {choices}; None: measured per CPU device over its first runs "
                "(docs/devices.md, autotune), else 8 (default {default})"),
    Option("light_tile_size", int, 32, choices=TILE_SIZES, metavar="N",   # bench.lights: 32 < 16 < 8 ms
           help="light-culling tile size: {choices}"),
    Option("shadow_tile_size", int, None, choices=TILE_SIZES, nullable=True, flag=None,
           help="shadow-map raster tiles: {choices}; None: on CPUs measured per device (docs/devices.md, "
                "autotune), else 32 (bench.shadows: binning 117 -> 20 ms, raster 307 -> 262 ms vs 8); "
                "tile_size on GPUs (default {default})"),
    Option("light_culling", str, "tiled", choices=LIGHT_CULLING,
           help="light lists per tile: culled against tile frusta, every light, each light's screen "
                "quad, or tiled lists with per-pixel stencil bits (default {default}; docs/light_accumulation.md)"),
    Option("light_depth_mask", bool, False, flag=None,
           help="Harada's 2.5D culling: 32 depth slices per tile"),
    Option("tonemap", str, "reinhard", choices=TONEMAPS, help="tone-mapping operator"),
    Option("exposure", float, 1.0, range=(0, None), open_lo=True, expect="a positive number", metavar="X",
           help="exposure multiplier before tone mapping"),
    Option("ssao", bool, False, help="screen-space ambient occlusion"),   # off: on CPUs it costs several shading passes
    Option("ssao_radius", float, 1.0, range=(0, None), open_lo=True,
           expect="a positive number (world units)", metavar="R", help="with --ssao: its radius in world units"),
    Option("ssao_strength", float, 1.0, range=(0, None), metavar="S",
           help="with --ssao: ao = 1 - S·occlusion, clamped to [0, 1]"),
    Option("ssao_blur", bool, True, flag=None,
           help="with --ssao: depth-aware blur of the per-pixel-rotated samples"),
    Option("shadows", bool, True, flag=None,
           help="shadow maps for shadowed spots and the sun; off: shade.cl has no lookup"),
    Option("shadow_filter", str, "pcf3x3", choices=SHADOW_FILTERS, flag=None,
           help="pcf3x3 (smooth 3x3 box), poisson (16 rotated taps) or hard"),
    Option("shadow_filter_radius", float, 2.0, range=(0.5, None), unit="texels", flag=None,
           help="poisson disk radius, texels"),
    Option("shadow_bias", float, 1.0, range=(0.0, None), unit="texels", flag=None,
           help="constant depth bias, texels of the map at the receiver"),
    Option("shadow_slope_bias", float, 1.0, range=(0.0, None), unit="texels", flag=None,
           help="slope-scaled bias: × tan(angle to the light) × filter reach, texels"),
    Option("shadow_normal_offset", float, 1.0, range=(0.0, None), unit="texels", flag=None,
           help="receivers move along their normal by this × sin(angle), texels"),
    Option("sun_cascades", int, 3, range=(1, 4), flag=None,
           help="cascaded shadow maps of the sun, {range} (1 = one map over the whole view; default {default})"),
    Option("sun_split_lambda", float, 0.75, range=(0, 1), flag=None,
           help="cascade splits: lambda·logarithmic + (1 - lambda)·uniform"),
    Option("shadow_atlas_max", int, 16384, range=(16, 32768), flag=None,
           help="shadow atlas side limit in texels: maps that do not fit are an error, never dropped"),
    Option("shadow_map_reuse", bool, True, flag=None,
           help="keep a map whose light view and scene are unchanged since the last frame"),
    Option("decoded_textures_mb", int, 0, range=(0, 2**20), unit="MiB", flag=None,
           help="memory for the textures kept decoded to float on CPUs (16 bytes a texel, 4x the RGBA8 pool: "
                "Sponza 695 MiB), read by the G-buffer resolve instead of decoding each sample (same bits); "
                "0: off, as a scene needing more (2-core AVX2 EPYC, all three CPU implementations: the resolve "
                "within 3 % either way, docs/benchmarks.md; default {default})"),
    Option("chunk_cull", bool, True, flag=None,
           help="setup skips chunks of 128 triangles a view cannot see (passes/chunk_cull.py; bit-identical)"),
    Option("transparency", str, "abuffer", choices=TRANSPARENCY,
           help="how BLEND materials are drawn: per-pixel sorted fragment lists, depth peeling, or "
                "a stipple pattern in the G-buffer (default {default}; docs/transparency.md)"),
    Option("peel_layers", int, 4, range=(1, MAX_PEEL_LAYERS), metavar="N",
           help="with --transparency depth_peeling: layers peeled per pixel, {range}"),
    Option("max_fragments_per_pixel", int, 0, range=(0, 2**20), expect="an integer >= 0 (0 = no cap)",
           metavar="K", help="with the A-buffer: keep only the K nearest transparent fragments of a pixel "
                             "(default {default}: all of them; drops are counted)"),
    Option("refraction", bool, False,
           help="distort what lies behind transparent surfaces by their materials' refraction"),
    Option("supersample", int, 1, range=(1, 4), metavar="K",
           help="render at K·W × K·H and filter down in linear HDR, K in {range} (default {default}; docs/post.md)"),
    Option("supersample_filter", str, "box", choices=SUPERSAMPLE_FILTERS,
           help="with --supersample: the resolve filter (separable, radius 2 output pixels; default {default})"),
    Option("edge_aa", bool, False,
           help="the report's edge-smoothing filter: blur along G-buffer edges of the tone-mapped image"),
    Option("edge_depth_threshold", float, 0.05, range=(0, None), open_lo=True, expect="a positive number",
           metavar="T", help="with --edge-aa: relative view-depth jump that marks an edge"),
    Option("edge_normal_threshold_deg", float, 30.0, range=(0, 180), open_lo=True, metavar="DEG",
           flag="--edge-normal-threshold", help="with --edge-aa: normal angle in degrees that marks an edge"),
    Option("color_aa", str, "none", choices=COLOR_AA, flag="--fxaa", flag_value="fxaa",
           help="FXAA: luminance-edge anti-aliasing of the tone-mapped image (color_aa \"fxaa\"; default {default})"),
    Option("bloom", bool, False,
           help="bloom: HDR colour above --bloom-threshold, blurred and added back"),
    Option("bloom_threshold", float, 1.0, range=(0.0, None), metavar="T",
           help="with --bloom: linear HDR threshold"),
    Option("bloom_strength", float, 0.1, range=(0.0, None), metavar="S",
           help="with --bloom: strength, adding strength × the thresholded energy"),
    Option("bloom_radius", float, 16.0, range=(0.0, None), open_lo=True, metavar="PX",
           help="with --bloom: radius in output pixels (a mip pyramid keeps large radii cheap; default {default})"),
    Option("motion_blur", bool, False,
           help="motion blur along the per-pixel velocity; give motion with --previous-eye/"
                "--previous-target"),
    Option("shutter", float, 0.5, range=(0.0, None), open_lo=True, metavar="F",
           help="with --motion-blur: exposure in frames"),
    Option("motion_blur_samples", int, 8, range=(2, 64), metavar="N",
           help="with --motion-blur: samples along the velocity, {range}"),
    Option("hatching", bool, False, help="the report's non-photorealistic hatching of the image"),
    Option("hatching_scale", float, 1.0, range=(0.0, None), open_lo=True, metavar="S",
           help="with --hatching: stroke scale (1 = one texel per pixel at the finest level; default {default})"),
    Option("hatching_saturation", float, 0.3, range=(0, 1), metavar="S",
           help="with --hatching: colour kept, 0 (ink on white) .. 1"),
)
OPTION = {o.name: o for o in OPTIONS}
OPTION_NAMES = tuple(OPTION)


def unknown_options(names) -> list[str]:
    return sorted(set(names) - set(OPTION))


class _RenderConfigRules:
    """RenderConfig's behaviour; its fields are made from OPTIONS below (one definition per option)."""
    __slots__ = ()

    def __post_init__(self):
        for option in OPTIONS:                  # each value alone: type, choices, range
            option.check(getattr(self, option.name))
        self._check_pipeline_options()          # then the combinations

    def _check_pipeline_options(self):
        if self.pipeline != "light_prepass":
            for name, default in (("msaa", 1), ("light_buffer_specular", "rgb"), ("light_buffer_precision", "float32")):
                if getattr(self, name) != default:
                    raise ValueError(f"{name} applies to pipeline='light_prepass' (the light buffer and its colour "
                                     f"pass), not {self.pipeline!r}" + (
                                         "; over-sampling (supersample) anti-aliases every pipeline"
                                         if name == "msaa" else ""))
        if self.reuse_visibility and self.pipeline == "deferred":
            raise ValueError("reuse_visibility applies to pipeline='light_prepass' or 'light_indexed' (their second "
                             "geometry pass); 'deferred' rasterizes once")
        if self.reuse_visibility and self.msaa != 1:
            raise ValueError(f"reuse_visibility reads pass 1's pixel-centre visibility; msaa={self.msaa} rasterizes "
                             f"at sub-samples, which pass 1 never saw")
        if self.pipeline != "deferred" and self.light_culling not in ("tiled", "brute_force"):
            raise ValueError(f"light_culling={self.light_culling!r} is a light-accumulation variant of the deferred "
                             f"pipeline; pipeline={self.pipeline!r} takes 'tiled' or 'brute_force'")
        if self.pipeline == "light_indexed" and self.ssao:
            raise ValueError("ssao needs the G-buffer's normals, which pipeline='light_indexed' never stores "
                             "(depth and triangle id only); use 'deferred' or 'light_prepass'")

    @property
    def ldr_effects(self) -> bool:
        """Post effects on the tone-mapped image (then tone mapping and encoding are separate passes)."""
        return self.edge_aa or self.color_aa != "none" or self.hatching

    @classmethod
    def from_options(cls, **options) -> "RenderConfig":
        unknown = unknown_options(options)
        if unknown:
            raise ValueError(f"unknown render option(s) {unknown}; known: {sorted(OPTION)}")
        return cls(**options)


RenderConfig = dataclasses.make_dataclass(
    "RenderConfig",
    [(o.name, Optional[o.type] if o.nullable else o.type, dataclasses.field(default=o.default)) for o in OPTIONS],
    bases=(_RenderConfigRules,), frozen=True,
    namespace={"__module__": __name__, "__doc__": (
        "Render options, frozen: one field per row of OPTIONS, in its order and with its default "
        "(docs/options.md). Unknown names are errors (RenderConfig.from_options); each value is checked "
        "against its row, then the pipeline's combinations.")})


for _option in OPTIONS:                         # every default passes its own row's check
    _option.check(_option.default)



# -- a scene file's [render] table (the CLI, batch tasks and the viewer read it the same way) ----
DEFAULT_SIZE = (1280, 720)


def scene_size(scene, width: Optional[int], height: Optional[int]) -> tuple[int, int]:
    """width/height, else the scene's [render] size, else 1280x720; one given keeps the aspect."""
    settings = scene.settings.get("render", {}) if isinstance(scene.settings, dict) else {}
    dw, dh = settings.get("width"), settings.get("height")
    dw = dw if isinstance(dw, int) and dw > 0 else DEFAULT_SIZE[0]
    dh = dh if isinstance(dh, int) and dh > 0 else DEFAULT_SIZE[1]
    if width is None and height is None:
        return dw, dh
    if width is None:
        width = max(1, round(height * dw / dh))
    if height is None:
        height = max(1, round(width * dh / dw))
    return width, height


def scene_config(scene, options: dict):
    """The scene's [render] options (TOML) with `options` on top; ValueError names the table."""
    names = OPTION_NAMES
    settings = scene.settings.get("render", {}) if isinstance(scene.settings, dict) else {}
    try:
        return RenderConfig.from_options(**{**{k: v for k, v in settings.items() if k in names}, **options})
    except ValueError as exc:
        raise ValueError(f"{scene.source}: [render]: {exc}") from None


def markdown_table() -> str:
    """docs/options.md's table: one row per option (its TOML key and RenderConfig field)."""
    rows = ["| option (`[render]` key, `RenderConfig` field) | CLI flag | type | default | values | what |",
            "|---|---|---|---|---|---|"]
    for o in OPTIONS:
        if o.type is bool:
            values = "true / false"
        elif o.choices is not None:
            values = " / ".join(f"`{c}`" for c in o.choices) + (" / none" if o.nullable else "")
        else:
            values = o.expected()
        default = "none" if o.default is None else str(o.default).lower() if o.type is bool else f"`{o.default}`"
        flag = f"`{o.cli_flag}`" if o.cli_flag else ""
        help_ = o.help_text().replace("|", "\\|")
        rows.append(f"| `{o.name}` | {flag} | {o.type.__name__} | {default} | {values} | {help_} |")
    return "\n".join(rows) + "\n"


if __name__ == "__main__":
    print(markdown_table(), end="")
