"""The viewer's page panels (viser GUI), made from the tables: every render option of
clrender/config.py's OPTIONS (a checkbox, a dropdown or a number by its row), every AOV of
clrender/abi/aovs.py, the scene's and the camera file's cameras. Only the grouping into folders
is this module's own fact (`GROUPS`); an option no group names lands in "other", so a new row
of the option table shows up in the page without an edit here.

Widgets only call the Viewer's setters (clrender/viewer/server.py); they hold no state of their own.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

from clrender.abi.aovs import WRITTEN
from clrender.config import OPTIONS

if TYPE_CHECKING:                                # the Viewer imports this module
    from clrender.viewer.server import Viewer

# Folder -> the options it holds, in page order ("display" opens; the others start folded).
GROUPS = (
    ("display", ("tonemap", "exposure")),
    ("pipeline", ("pipeline", "shading", "multiscatter", "light_culling", "light_depth_mask", "reuse_visibility",
                  "light_buffer_specular", "light_buffer_precision", "tile_size", "light_tile_size", "chunk_cull")),
    ("shadows", ("shadows", "shadow_filter", "shadow_filter_radius", "shadow_bias", "shadow_slope_bias",
                 "shadow_normal_offset", "sun_cascades", "sun_split_lambda", "shadow_atlas_max", "shadow_map_reuse",
                 "shadow_tile_size")),
    ("SSAO", ("ssao", "ssao_radius", "ssao_strength", "ssao_blur")),
    ("transparency", ("transparency", "peel_layers", "max_fragments_per_pixel", "refraction")),
    ("anti-aliasing", ("msaa", "supersample", "supersample_filter", "edge_aa", "edge_depth_threshold",
                       "edge_normal_threshold_deg", "color_aa")),
    ("post effects", ("bloom", "bloom_threshold", "bloom_strength", "bloom_radius", "motion_blur", "shutter",
                      "motion_blur_samples", "hatching", "hatching_scale", "hatching_saturation")),
)
AOV_CHOICES = ("image", *WRITTEN)          # what the "show" dropdown offers: the picture, then every AOV
ENVIRONMENT_CHOICES = ("scene", "none", "studio", "file")
AUTO = "auto"                              # a nullable option's "chosen at render time" (shadow_tile_size)


def _from_page(fn):
    """An update handler that ignores values the server itself assigned (viser calls handlers for
    those too, with no client): the camera list and the time slider follow the viewer's state."""
    return lambda event: None if event.client is None else fn(event)


def grouped_options() -> list[tuple[str, list]]:
    """[(folder, [Option, ...])]: GROUPS in order, then "other" with any option they do not name."""
    by_name = {o.name: o for o in OPTIONS}
    named = {n for _, names in GROUPS for n in names}
    unknown = named - set(by_name)
    if unknown:
        raise ValueError(f"viewer GROUPS name unknown options {sorted(unknown)}")
    out = [(folder, [by_name[n] for n in names]) for folder, names in GROUPS]
    rest = [o for o in OPTIONS if o.name not in named]
    return out + ([("other", rest)] if rest else [])


def _label(option) -> str:
    return option.name.replace("_", " ")


def _add_option(gui, viewer: "Viewer", option, value):
    """One widget for one option row; its change goes to viewer.set_option (which may refuse it:
    then the widget is put back)."""
    hint = option.help_text()
    if option.type is bool:
        handle = gui.add_checkbox(_label(option), initial_value=bool(value), hint=hint)
    elif option.choices is not None:
        choices = tuple(str(c) for c in option.choices) + ((AUTO,) if option.nullable else ())
        handle = gui.add_dropdown(_label(option), choices, initial_value=AUTO if value is None else str(value),
                                  hint=hint)
    else:
        lo, hi = option.range
        step = 1 if option.type is int else 0.01
        handle = gui.add_number(_label(option), initial_value=value, min=lo, max=hi, step=step, hint=hint)

    def parse(v):
        if option.nullable and v == AUTO:
            return None
        if option.type is bool:
            return bool(v)
        if option.choices is not None:
            return next(c for c in option.choices if str(c) == v)
        return option.type(v)

    @handle.on_update
    def _(_event):
        value = parse(handle.value)
        if not viewer.set_option(option.name, value):           # refused: the message is in the page
            current = getattr(viewer.config, option.name)
            handle.value = (AUTO if current is None else str(current)) if option.choices is not None else current
    return handle


class Panels:
    """The page's controls, built once on the server (shared by every connected page)."""

    def __init__(self, viewer: "Viewer"):
        gui = viewer.server.gui
        self.viewer = viewer
        self.status = gui.add_markdown("starting…")
        self.message = gui.add_markdown("")          # the last notice or error
        self.timing = gui.add_markdown("")
        with gui.add_folder("view"):
            self.aov = gui.add_dropdown("show", AOV_CHOICES, initial_value="image",
                                        hint="the picture, or an AOV drawn as `--aov` previews are")
            self.aov.on_update(lambda _: viewer.set_aov(self.aov.value))
            self.cameras = gui.add_dropdown("camera", viewer.camera_labels(), initial_value=viewer.camera_label(),
                                            hint="the scene file's cameras and the camera file's saved views")
            self.cameras.on_update(_from_page(lambda _: viewer.select_camera(self.cameras.value)))
            self.save = gui.add_button("save view", hint=f"append this camera to {viewer.camera_file}")
            self.save.on_click(lambda _: viewer.save_view())
            self.highlight = gui.add_checkbox("highlight picked object", initial_value=True)
            self.highlight.on_update(lambda _: viewer.set_highlight(self.highlight.value))
            self.pick = gui.add_markdown("click the picture to see what is there")
        if viewer.animated:
            with gui.add_folder("animation"):
                self.time = gui.add_slider("time (s)", min=0.0, max=max(viewer.duration, 1e-3), step=1.0 / 60.0,
                                           initial_value=viewer.time)
                self.time.on_update(_from_page(lambda _: viewer.set_time(self.time.value, from_slider=True)))
                self.play = gui.add_checkbox("play", initial_value=False)
                self.play.on_update(lambda _: viewer.set_playing(self.play.value))
        else:
            self.time = self.play = None
        with gui.add_folder("environment", expand_by_default=False):
            self.env_kind = gui.add_dropdown("lighting", ENVIRONMENT_CHOICES, initial_value="scene",
                                             hint="the scene's own, none, the built-in studio, or an .exr/.hdr file")
            self.env_path = gui.add_text("file", initial_value="",
                                         hint="an .exr/.hdr path, relative to the scene's folder (or a folder "
                                              "--allow-outside names)")
            self.env_intensity = gui.add_number("intensity", initial_value=1.0, min=0.0, step=0.05)
            self.env_rotation = gui.add_slider("rotation (deg)", min=-180.0, max=180.0, step=1.0, initial_value=0.0)
            self.env_message = gui.add_markdown("")
            for handle in (self.env_kind, self.env_path, self.env_intensity, self.env_rotation):
                handle.on_update(lambda _: self._environment_changed())
        self.options = {}
        for folder, options in grouped_options():
            with gui.add_folder(folder, expand_by_default=(folder == "display")):
                for option in options:
                    self.options[option.name] = _add_option(gui, viewer, option, getattr(viewer.config, option.name))

    def _environment_changed(self) -> None:
        message = self.viewer.set_environment(self.env_kind.value, self.env_path.value.strip(),
                                              float(self.env_intensity.value), float(self.env_rotation.value))
        self.env_message.content = message

    def set_camera_labels(self, labels, value) -> None:
        self.cameras.options = tuple(labels)
        self.cameras.value = value
