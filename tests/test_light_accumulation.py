"""Light-accumulation variants (report V.1, docs/light_accumulation.md): `light_culling="quads"`
(each light's screen-space bounding quad, binned into tile lists without depth bounds) and
`"stencil"` (per-pixel bits over the tiled lists: only lights whose volume holds the pixel are
shaded), and the (pixel, light) pair statistics of every mode.

* both render what "tiled" renders (within the tiled == brute force tolerance; in practice the
  same bits: a light a list adds or a stencil removes contributes exactly 0), on the demo scene,
  on the room of tests/lighting_cases.py with its hard cases and up to 4096 point and spot lights,
  and against the NumPy shading reference;
* stencil's evaluated pairs are, pixel by pixel, the NumPy count of lights reaching the pixel
  (d² < r², inside a spot's cone) on positions rebuilt from the depth AOV; only pairs within a
  hair of the boundary may differ;
* useful pairs are the same in every mode; evaluated pairs order brute_force > quads > tiled >
  stencil on the room;
* the quad is the sphere's projected rectangle: it holds every projected point of the sphere
  (dense surface samples) and lies within a pixel of them; spheres at the near plane cover the
  screen, spheres behind the camera nothing;
* lists and stencil words that outgrow their buffers are grown and the frame redone, with the
  same result as a renderer whose buffers were already large.
"""
import numpy as np
import pytest

from helpers import SHADING_TOL
import clrender
from clrender import Camera
from clrender.render import memory
from clrender.abi import structs
from reference import shading as ref
from lighting_cases import (AMBIENT, BRUTE, CAMERA, lit_scene, reference_scene_lights, render, room_scene,
                           light_array, sector_bounding_sphere)

MODES = ("quads", "stencil")


def opts(mode, tile=16, **extra):
    return dict(light_culling=mode, light_tile_size=tile, tonemap="reinhard", **extra)


def pass_named(renderer, name):
    return next(p for p in renderer.pipeline.passes if p.name == name)


def assert_close_to(got, expect, what):
    peak = float(expect.color.max())
    diff = np.abs(got.color.astype(np.float64) - expect.color)
    worst = np.unravel_index(np.argmax(diff), diff.shape)
    assert diff.max() <= 1e-4 * peak, (f"{what}: max |diff| {diff.max():.3g} at (y, x, c) {worst} "
                                       f"(got {got.color[worst]:.5g}, expected {expect.color[worst]:.5g}), "
                                       f"brightest {peak:.4g}")


# -- the same image as tiled culling ---------------------------------------------------------------

@pytest.mark.parametrize("mode", MODES)
def test_demo_scene_matches_tiled(make_renderer, device, mode):
    from clrender.tools.check import REPO_SCENES
    scene = clrender.load_scene(REPO_SCENES / "demo.toml")
    w, h = 200, 120
    tiled = render(make_renderer, device, "demo", scene, scene.camera, w, h, **opts("tiled", 32))
    got = render(make_renderer, device, "demo", scene, scene.camera, w, h, **opts(mode, 32))
    assert (tiled.triangle_id >= 0).mean() > 0.5 and tiled.stats["lights"] > 60
    assert_close_to(got, tiled, f"{mode} vs tiled on the demo scene")
    np.testing.assert_array_equal(got.shadow, tiled.shadow)
    if mode == "stencil":                     # the tile lists are the tiled ones
        np.testing.assert_array_equal(got.light_count, tiled.light_count)
    else:                                     # the quads hold every light tiled culling keeps, and more
        assert (got.light_count >= tiled.light_count).all() and (got.light_count > tiled.light_count).any()


ROOM_CASES = [(17, 160, 120, 16), (1024, 100, 72, 8), (1024, 100, 72, 32), (4096, 100, 72, 16)]


@pytest.mark.parametrize("mode", MODES)
@pytest.mark.parametrize("count,width,height,tile", ROOM_CASES,
                         ids=[f"{c}lights-tile{t}" for c, _, _, t in ROOM_CASES])
def test_room_with_many_lights_matches_tiled_and_brute_force(make_renderer, device, mode, count, width, height,
                                                             tile):
    scene = lit_scene(count, width, height)
    assert (scene.lights["type"] == structs.LIGHT_SPOT).sum() > count // 8 or count < 100
    brute = render(make_renderer, device, ("room", count), scene, CAMERA, width, height, **BRUTE)
    tiled = render(make_renderer, device, ("room", count), scene, CAMERA, width, height, **opts("tiled", tile))
    got = render(make_renderer, device, ("room", count), scene, CAMERA, width, height, **opts(mode, tile))
    assert np.isfinite(got.color).all()
    assert_close_to(got, tiled, f"{mode} vs tiled (tile {tile}, {count} lights)")
    assert_close_to(got, brute, f"{mode} vs brute force (tile {tile}, {count} lights)")
    assert got.stats["lights"] == count
    for key in ("light_pairs_evaluated", "light_pairs_useful", "light_pairs_ratio", "lights_per_tile_max"):
        assert key in got.stats


def test_stencil_with_depth_mask_matches_tiled(make_renderer, device):
    scene = lit_scene(1024, 100, 72)
    extra = dict(light_depth_mask=True)
    tiled = render(make_renderer, device, ("room", 1024), scene, CAMERA, 100, 72, **opts("tiled", 16, **extra))
    got = render(make_renderer, device, ("room", 1024), scene, CAMERA, 100, 72, **opts("stencil", 16, **extra))
    assert_close_to(got, tiled, "stencil vs tiled with the depth mask")
    assert got.stats["light_pairs_useful"] == tiled.stats["light_pairs_useful"]


@pytest.mark.parametrize("mode", MODES)
def test_shading_matches_reference(make_renderer, device, mode):
    w, h = 128, 96
    scene = room_scene()
    scene.lights = reference_scene_lights()
    frame = render(make_renderer, device, "reference", scene, CAMERA, w, h, **opts(mode))
    fg = frame.triangle_id >= 0
    expect, info = ref.shade_frame(frame, CAMERA, scene.lights, AMBIENT, details=True)
    ok = fg & (info["min_abs_ndotl"] > 1e-4)         # the specular term jumps at N·L = 0
    assert ok.sum() > 0.95 * fg.sum() and info["specular"][ok].max() > 0.2
    err = np.abs(frame.color.astype(np.float64) - expect)
    err[~ok] = 0
    assert err.max() <= SHADING_TOL * float(expect.max()), f"{mode}: max |color - reference| {err.max():.4g}"
    assert np.all(frame.color[~fg] == 0)


# -- pair statistics -------------------------------------------------------------------------------

def reach_counts(frame, camera, lights, margin=2e-5):
    """Per pixel, how many lights certainly / possibly reach it (d² < r², inside a spot's outer cone),
    float64 on positions rebuilt from the depth AOV (tests/reference/shading.py): pairs within
    `margin` (relative) of either boundary are the uncertain ones."""
    P = ref.world_positions(frame.depth, camera)
    fg = frame.triangle_id >= 0
    P[~fg] = np.nan
    sure = np.zeros(fg.shape, np.int64)
    maybe = np.zeros(fg.shape, np.int64)
    for light in lights:
        lv = light["position"].astype(np.float64) - P
        d2 = (lv * lv).sum(-1)
        r2 = float(light["radius"]) ** 2
        lo, hi = d2 < r2 * (1 - margin), d2 < r2 * (1 + margin)
        if int(light["type"]) == structs.LIGHT_SPOT:
            with np.errstate(invalid="ignore", divide="ignore"):
                cos_a = -(lv @ light["direction"].astype(np.float64)) / np.sqrt(d2)
            co = float(light["cos_outer"])
            lo &= cos_a > co + margin
            hi &= cos_a > co - margin
        sure += lo & fg
        maybe += hi & fg
    return sure, maybe


def pixel_pairs(renderer, frame):
    """shade.cl's per-pixel (evaluated, useful) planes of the renderer's last frame."""
    planes = pass_named(renderer, "shade").light_pairs.get()
    n = frame.width * frame.height
    return planes[:n].reshape(frame.height, frame.width), planes[n: 2 * n].reshape(frame.height, frame.width)


@pytest.mark.parametrize("count", [64, 1024])
def test_stencil_pairs_equal_numpy_count(make_renderer, device, count):
    w, h = 100, 72
    scene = lit_scene(count, w, h)
    r = make_renderer(w, h, **opts("stencil", 16))
    frame = r.render(scene, CAMERA)
    evaluated, useful = pixel_pairs(r, frame)
    np.testing.assert_array_equal(evaluated, useful)
    sure, maybe = reach_counts(frame, CAMERA, scene.lights)
    assert sure.sum() > w * h, "the lights must reach many pixels"
    uncertain = int((maybe - sure).sum())
    assert uncertain <= 2e-3 * sure.sum(), f"{uncertain} pairs sit on a light's boundary: pick other lights"
    off = (evaluated < sure) | (evaluated > maybe)
    assert not off.any(), (f"{int(off.sum())} pixels' stencil bits disagree with the NumPy count, e.g. "
                           f"{np.argwhere(off)[:3].tolist()}: {evaluated[off][:3]} vs {sure[off][:3]}")
    stats = frame.stats
    assert stats["light_pairs_evaluated"] == stats["light_pairs_useful"] == int(evaluated.sum())
    assert sure.sum() <= stats["light_pairs_evaluated"] <= maybe.sum()
    assert stats["light_pairs_ratio"] == 1.0


def test_pair_counts_across_modes(make_renderer, device):
    """Useful pairs are a property of the scene; evaluated pairs measure each mode's waste."""
    w, h = 100, 72
    scene = lit_scene(1024, w, h)
    frames = {mode: render(make_renderer, device, ("room", 1024), scene, CAMERA, w, h, **opts(mode, 16))
              for mode in ("brute_force", "quads", "tiled", "stencil")}
    useful = {m: f.stats["light_pairs_useful"] for m, f in frames.items()}
    evaluated = {m: f.stats["light_pairs_evaluated"] for m, f in frames.items()}
    assert len(set(useful.values())) == 1, useful
    assert evaluated["brute_force"] > evaluated["quads"] > evaluated["tiled"] > evaluated["stencil"], evaluated
    assert evaluated["stencil"] == useful["stencil"] > 0
    fg = frames["tiled"].triangle_id >= 0
    assert evaluated["brute_force"] == 1024 * int(fg.sum())
    for m in ("tiled", "quads"):              # Σ over foreground pixels of their tile's list length
        assert evaluated[m] == int(frames[m].light_count[fg].sum(dtype=np.int64))
    for m, f in frames.items():
        assert f.stats["light_pairs_ratio"] == pytest.approx(evaluated[m] / useful[m])
    sure, maybe = reach_counts(frames["tiled"], CAMERA, scene.lights)
    assert sure.sum() <= useful["tiled"] <= maybe.sum()


def test_no_lights_no_pairs(make_renderer, device):
    scene = room_scene()
    for mode in ("tiled", "brute_force", *MODES):
        stats = make_renderer(48, 32, **opts(mode)).render(scene, CAMERA).stats
        assert (stats["light_pairs_evaluated"], stats["light_pairs_useful"], stats["light_pairs_ratio"]) == (0, 0, 1.0)


# -- the quads --------------------------------------------------------------------------------------

def culling_sphere(light):
    """light_cull.cl's culling sphere (float64): the light's, or its cone's bounding sphere."""
    c, r = light["position"].astype(np.float64), float(light["radius"])
    if int(light["type"]) == structs.LIGHT_SPOT:
        theta = np.degrees(np.arccos(np.clip(float(light["cos_outer"]), 1e-4, 1.0)))
        along, r = sector_bounding_sphere(r, theta)
        c = c + along * light["direction"].astype(np.float64)
    return c, r


def projected_samples(camera, width, height, center, radius, n=400):
    """Pixel coordinates (x, y) of dense samples of the boundary of the ball's part in front of the
    near plane: its surface there, and the circle where the near plane cuts it."""
    right, up, back = (np.asarray(a, np.float64) for a in camera.basis())
    eye = np.asarray(camera.eye, np.float64)
    u, v = np.meshgrid(np.linspace(0, 2 * np.pi, 2 * n), np.linspace(0, np.pi, n))
    pts = center + radius * np.stack([np.sin(v) * np.cos(u), np.cos(v), np.sin(v) * np.sin(u)], -1).reshape(-1, 3)
    pts = pts[(pts - eye) @ -back >= camera.near]
    gap = camera.near - (center - eye) @ -back            # the near plane's distance from the centre
    if abs(gap) < radius:
        a = np.linspace(0, 2 * np.pi, 8 * n)
        rim = np.sqrt(radius ** 2 - gap ** 2)
        pts = np.concatenate([pts, center - gap * back + rim * (np.cos(a)[:, None] * right + np.sin(a)[:, None] * up)])
    rel = pts - eye
    depth = rel @ -back
    t = np.tan(np.radians(camera.fov_y_deg) / 2)
    x = ((rel @ right) / depth / (t * width / height) + 1) * 0.5 * width
    y = (1 - (rel @ up) / depth / t) * 0.5 * height
    return x, y


QUAD_CAM = Camera.look_at((0.5, 1.0, 2.0), (0.0, 0.5, -4.0), fov_y_deg=60, near=0.2, far=40)


def quad_lights():
    """Spheres for the quad tests: the first 9 have a finite on-screen quad, 9 and 10 cover the
    screen, 11 and 12 nothing."""
    right, up, back = (np.asarray(a, np.float64) for a in QUAD_CAM.basis())
    eye = np.asarray(QUAD_CAM.eye, np.float64)
    recs = [dict(position=(0.0, 0.5, -4.0), radius=1.0, color=(1, 1, 1)),        # centre
            dict(position=(-3.0, 2.5, -6.0), radius=1.5, color=(1, 1, 1)),       # off-centre: skewed ellipse
            dict(position=(4.0, -1.0, -3.0), radius=0.7, color=(1, 1, 1)),
            dict(position=(6.0, 0.5, -3.0), radius=2.5, color=(1, 1, 1)),        # partly off screen
            dict(position=(0.3, 0.9, -0.6), radius=1.5, color=(1, 1, 1)),        # close: a large quad
            dict(position=(1.0, 3.0, -8.0), radius=6.0, color=(1, 1, 1),         # spot: its cone's sphere
                 direction=(-0.2, -1.0, 0.3), inner=15.0, outer=25.0),
            dict(position=(-2.0, 0.0, -5.0), radius=4.0, color=(1, 1, 1),
                 direction=(1.0, 0.2, -0.3), inner=40.0, outer=60.0),
            # crossing the near plane beside the eye: clipped, only the screen's right or bottom part
            dict(position=eye + 1.1 * right - 0.1 * back, radius=1.0, color=(1, 1, 1)),
            dict(position=eye - 0.8 * up - 0.5 * back, radius=0.9, color=(1, 1, 1)),
            dict(position=eye, radius=0.5, color=(1, 1, 1)),                       # holds the eye
            dict(position=eye - 0.5 * back, radius=0.7, color=(1, 1, 1)),          # holds the eye's view
            dict(position=eye + 3.0 * back, radius=1.0, color=(1, 1, 1)),          # behind the camera
            dict(position=eye + 20.0 * right, radius=1.0, color=(1, 1, 1))]        # crossing, far beside
    return light_array(recs)


@pytest.mark.parametrize("size", [(96, 64), (61, 47)])
def test_quad_is_the_projected_rectangle(make_renderer, device, size):
    w, h = size
    scene = room_scene()
    scene.lights = quad_lights()
    r = make_renderer(w, h, **opts("quads", 8))
    r.render(scene, QUAD_CAM)
    rects = pass_named(r, "light_quads").quad_rects(len(scene.lights)).astype(np.float64)
    for i, light in enumerate(scene.lights[:9]):
        x, y = projected_samples(QUAD_CAM, w, h, *culling_sphere(light))
        lo, hi = np.array([x.min(), y.min()]), np.array([x.max(), y.max()])
        assert (lo < [w, h]).all() and (hi > 0).all(), f"light {i} must be on screen"
        got_lo, got_hi = rects[i, :2], rects[i, 2:]
        assert (got_lo <= lo).all() and (got_hi >= hi).all(), f"light {i}: quad {rects[i]} misses {lo}, {hi}"
        assert (lo - got_lo < 1).all() and (got_hi - hi < 1).all(), f"light {i}: quad {rects[i]} vs {lo}, {hi}"
    for i in (9, 10):
        assert (rects[i, :2] <= 0).all() and (rects[i, 2:] >= [w, h]).all(), f"light {i}: {rects[i]}"
    for i in (11, 12):
        empty = rects[i, 0] > rects[i, 2] or rects[i, 0] > w or rects[i, 2] < 0 or rects[i, 1] > h or rects[i, 3] < 0
        assert empty, f"light {i} is not in view: {rects[i]}"
    # the clipped ones do not cover the screen
    assert rects[7, 0] > w / 4 and rects[8, 1] > h / 8, rects[7:9]


def test_quad_tiles_hold_every_lit_pixel(make_renderer, device):
    """Per light alone: each tile holding a pixel the light reaches lists it (quads are conservative)."""
    w, h, tile = 96, 64, 8
    scene = room_scene()
    lights = quad_lights()
    r = make_renderer(w, h, **opts("quads", tile))
    for i in range(len(lights)):
        scene.lights = lights[i:i + 1]
        frame = r.render(scene, QUAD_CAM)
        truth = ref.tile_light_truth(frame, QUAD_CAM, scene.lights, tile)
        assert (frame.light_count[::tile, ::tile] >= truth).all(), f"light {i} dropped from a tile it reaches"


# -- overflow: grow and redo -------------------------------------------------------------------------

@pytest.mark.parametrize("mode", MODES)
def test_overflow_grows_and_renders_the_same(device, mode):
    w, h = 64, 48
    scene = lit_scene(512, w, h)
    renderer = clrender.Renderer(w, h, device=device.id, **opts(mode, 32))
    first = renderer.render(scene, CAMERA)
    again = renderer.render(scene, CAMERA)          # the grown buffers are kept: no overflow now
    assert first.stats["retries"] >= 1 and again.stats["retries"] == 0
    if mode == "stencil":                      # tile lists of more than 32 lights: 2+ words per pixel
        from clrender.passes.light_stencil import INITIAL_WORDS
        assert INITIAL_WORDS == 1 and first.stats["lights_per_tile_max"] > 32
        assert pass_named(renderer, "light_stencil").words >= 2
    else:                                      # more entries than the initial 16 per tile
        assert first.stats["light_list_entries"] > 16 * 2 * 2
    np.testing.assert_array_equal(first.color, again.color)
    np.testing.assert_array_equal(first.light_count, again.light_count)
    for key in ("light_pairs_evaluated", "light_pairs_useful"):
        assert first.stats[key] == again.stats[key]
    tiled = clrender.Renderer(w, h, device=device.id, **opts("tiled", 32)).render(scene, CAMERA)
    assert_close_to(first, tiled, f"{mode} after growing")


# -- plumbing -----------------------------------------------------------------------------------------

def test_disabled_modes_launch_nothing_new(make_renderer, device):
    scene = lit_scene(17, 64, 48)
    for mode, absent in (("tiled", ("light_quads", "light_stencil")), ("brute_force", ("light_quads",
                                                                                       "light_stencil", "light_cull")),
                         ("quads", ("light_stencil", "light_cull")), ("stencil", ("light_quads",))):
        r = make_renderer(64, 48, **opts(mode))
        names = {p.name for p in r.pipeline.passes}
        stats = r.render(scene, CAMERA).stats
        for name in absent:
            assert name not in names and f"{name}_ms" not in stats, (mode, name)
        if mode in MODES:
            assert f"light_{mode}_ms" in stats


@pytest.mark.parametrize("mode", MODES)
def test_memory_estimate_covers_the_new_buffers(make_renderer, device, mode):
    w, h = 96, 64
    scene = lit_scene(17, w, h)
    r = make_renderer(w, h, **opts(mode))
    stats = r.render(scene, CAMERA).stats
    by_owner = stats["device_bytes_by_owner"]
    known = {"scene", "pipeline", "setup", "binning", "raster", "gbuffer", "light_cull", "light_quads",
             "light_stencil", "shade", "tonemap", "particles"}
    held = sum(v for k, v in by_owner.items() if k in known)
    est = memory.estimate(w, h, r.config, scene)["total"]
    assert 0.98 * held <= est <= 1.02 * held + 4096, (est, by_owner)
    assert by_owner[f"light_{mode}"] > 0


def test_cli_and_toml_reach_render_config(tmp_path, device, monkeypatch):
    from clrender.cli import app as cli
    from helpers import record_render_configs
    seen = record_render_configs(monkeypatch)
    obj = tmp_path / "quad.obj"
    obj.write_text("v -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\nf 1 2 3\nf 1 3 4\n")
    common = [str(obj), "--width", "16", "--height", "12", "--device", device.id, "-q",
              "--camera-eye", "0,0,3", "--camera-target", "0,0,0"]
    for mode in MODES:
        assert cli.main(["render", *common, "-o", str(tmp_path / f"{mode}.png"), "--light-culling", mode]) == 0
        assert seen[-1].light_culling == mode
    toml = tmp_path / "scene.toml"
    toml.write_text(f'[[mesh]]\npath = "{obj.name}"\n\n[camera]\neye = [0, 0, 3]\ntarget = [0, 0, 0]\n\n'
                    f'[render]\nwidth = 16\nheight = 12\nlight_culling = "stencil"\n')
    assert cli.main(["render", str(toml), "-o", str(tmp_path / "t.png"), "--device", device.id, "-q"]) == 0
    assert seen[-1].light_culling == "stencil"
    assert cli.main(["render", str(toml), "-o", str(tmp_path / "t.png"), "--device", device.id, "-q",
                     "--light-culling", "quads"]) == 0
    assert seen[-1].light_culling == "quads"
    with pytest.raises(ValueError, match="light_culling"):
        clrender.RenderConfig(light_culling="stencils")
