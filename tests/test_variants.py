"""Renderer variants (docs/variants.md): the light pre-pass (`pipeline="light_prepass"`, with its
multisampled colour `msaa`) and light-indexed deferred (`pipeline="light_indexed"`) against the
deferred pipeline, their NumPy references and a supersampled truth.

* light_indexed lights the same quantized surface with the same arithmetic as deferred: every
  output is bit-identical (colour, G-buffer AOVs, light counts, shadow visibility), with shadows,
  transparency and random light sets.
* light_prepass with RGB specular equals deferred within 1e-5 of the brightest pixel (the
  specular intensity multiplies the light buffer's sum instead of each light: float rounding;
  measured <= 6e-8 relative); its G-buffer AOVs are bit-identical.
* light_prepass with luminance specular equals its NumPy reference (the deferred reference's
  diffuse D and specular S, then albedo·(ambient + D) + lum(S)·D/lum(D)) within 2e-3 of the peak,
  and differs from deferred where coloured lights overlap (the classic LPP trade-off).
* float16 light buffer: within half precision (2^-11 relative) of float32.
* msaa=4 against a 16×16 supersampled truth: edge RMSE at least 40 % below msaa=1; pixels away
  from edges are bit-identical to msaa=1. Each sub-sample's visibility equals the NumPy reference
  rasterizer at that sample position (docs/raster_contract.md §10), ids exact.
"""
from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings

import clrender
from clrender import Camera, Material, Scene
from clrender.abi import structs
from clrender.passes.second_geometry import SAMPLE_PATTERNS, sample_offsets
from reference import aa
from reference import shading as ref
from reference.raster import rasterize
from lighting_cases import reference_scene_lights, room_scene
from test_properties import SETTINGS, light_sets, lit_soup
from test_raster import make_soup

CAMERA = Camera.look_at((0.0, 1.6, 4.5), (0.0, 0.8, 0.0), (0, 1, 0), 60.0, near=0.1, far=30.0)
AOVS = ("gbuffer", "light_count", "shadow", "image", "fragment_count", "transmittance")


def demo_scene():
    from pathlib import Path
    return clrender.load_scene(Path(__file__).resolve().parent.parent / "scenes" / "demo.toml")


def assert_same(a, b, what, color_exact=True):
    for name in AOVS:
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=f"{what}: {name}")
    if color_exact:
        np.testing.assert_array_equal(a.color, b.color, err_msg=f"{what}: color")


def near_peak(a, b, rel):
    peak = max(float(np.abs(b).max()), 1e-6)
    diff = float(np.abs(a.astype(np.float64) - b).max())
    assert diff <= rel * peak, f"max |Δ| {diff:.3g} > {rel:g} × peak {peak:.3g}"
    return diff / peak


# -- equality with deferred ---------------------------------------------------------------------------
@pytest.mark.parametrize("shadows", [False, True])
def test_demo_scene_every_pipeline(make_renderer, shadows):
    scene = demo_scene()
    deferred = make_renderer(160, 96, shadows=shadows).render(scene)
    indexed = make_renderer(160, 96, shadows=shadows, pipeline="light_indexed").render(scene)
    prepass = make_renderer(160, 96, shadows=shadows, pipeline="light_prepass").render(scene)
    assert (deferred.triangle_id >= 0).mean() > 0.5 and deferred.color.max() > 0.1
    assert_same(indexed, deferred, "light_indexed")
    assert_same(prepass, deferred, "light_prepass", color_exact=False)
    rel = near_peak(prepass.color, deferred.color, 1e-5)
    print(f"light_prepass vs deferred: {rel:.2g} of the peak")
    assert deferred.stats["geometry_passes"] == 1
    assert indexed.stats["geometry_passes"] == prepass.stats["geometry_passes"] == 2
    assert "forward_shade_ms" in indexed.stats and "raster_again_ms" in indexed.stats
    assert {"light_buffer_ms", "raster_again_ms", "material_ms"} <= set(prepass.stats)
    assert not any(k.startswith(("light_buffer", "material", "forward_shade")) for k in deferred.stats)
    for key in ("light_pairs_evaluated", "light_pairs_useful"):     # the same lists walked, the same reach
        assert deferred.stats[key] == indexed.stats[key] == prepass.stats[key] > 0, key


@pytest.mark.parametrize("pipeline", ["light_prepass", "light_indexed"])
def test_reuse_visibility_is_bit_identical_without_the_second_raster(make_renderer, pipeline):
    """reuse_visibility: pass 1's visibility buffer instead of the raster again (docs/variants.md):
    the same frame bit for bit, one geometry pass, no raster_again kernel; with BLEND surfaces,
    shadows and a moving camera (velocity) in the frame."""
    scene = demo_scene()
    previous = Camera.look_at((0.2, 1.7, 4.6), (0.0, 0.8, 0.0), (0, 1, 0), 60.0, near=0.1, far=30.0)
    again = make_renderer(160, 96, pipeline=pipeline).render(scene, CAMERA, previous_camera=previous)
    reused = make_renderer(160, 96, pipeline=pipeline, reuse_visibility=True).render(
        scene, CAMERA, previous_camera=previous)
    assert (again.triangle_id >= 0).mean() > 0.5 and again.color.max() > 0.1
    assert_same(reused, again, f"{pipeline} reuse_visibility")
    for name in ("velocity", "object_id", "material_id", "depth"):
        np.testing.assert_array_equal(getattr(reused, name), getattr(again, name), err_msg=name)
    assert "raster_again_ms" in again.stats and "raster_again_ms" not in reused.stats
    assert again.stats["geometry_passes"] == 2 and reused.stats["geometry_passes"] == 1


@settings(max_examples=8, **SETTINGS)
@given(p=light_sets())
def test_random_light_sets(make_renderer, p):
    """Random soups, materials and point/spot lights: light_indexed bit-identical to deferred,
    light_prepass (RGB specular) within 1e-5 of the peak, with tiled and brute-force lists."""
    scene, cam = lit_soup(p)
    w, h = p["size"]
    culling = "brute_force" if p["seed"] % 3 == 0 else "tiled"
    opts = dict(light_tile_size=p["tile"], light_culling=culling)
    deferred = make_renderer(w, h, **opts).render(scene, camera=cam)
    assert_same(make_renderer(w, h, pipeline="light_indexed", **opts).render(scene, camera=cam), deferred,
                "light_indexed")
    prepass = make_renderer(w, h, pipeline="light_prepass", **opts).render(scene, camera=cam)
    assert_same(prepass, deferred, "light_prepass", color_exact=False)
    near_peak(prepass.color, deferred.color, 1e-5)


def blend_scene() -> Scene:
    """The room with a red glass pane (BLEND) in front of the camera."""
    scene = room_scene()
    glass = len(scene.materials)
    pane = np.array([[-0.8, 0.2, 2.0], [0.8, 0.2, 2.0], [0.8, 1.4, 2.0], [-0.8, 1.4, 2.0]], np.float32)
    base = len(scene.positions)
    scene2 = Scene(np.concatenate([scene.positions, pane]),
                   np.concatenate([scene.normals, np.tile([[0, 0, 1.0]], (4, 1))]),
                   np.concatenate([scene.uvs, np.zeros((4, 2))]),
                   np.concatenate([scene.triangles, [[base, base + 1, base + 2], [base, base + 2, base + 3]]]),
                   np.concatenate([scene.triangle_material, [glass, glass]]),
                   list(scene.materials) + [Material("glass", (0.9, 0.1, 0.1, 0.5), alpha_mode="BLEND")])
    scene2.lights, scene2.ambient = reference_scene_lights(), 0.1
    return scene2


@pytest.mark.parametrize("transparency", ["abuffer", "depth_peeling"])
def test_transparency_in_every_pipeline(make_renderer, transparency):
    """The transparent fragments are forward-shaded with the same light lists in every pipeline,
    the report's selling point for light-indexed: the frames match deferred's."""
    scene = blend_scene()
    deferred = make_renderer(128, 96, transparency=transparency).render(scene, CAMERA)
    assert deferred.stats["fragments"] > 500 and (deferred.transmittance < 0.9).mean() > 0.05
    assert_same(make_renderer(128, 96, transparency=transparency, pipeline="light_indexed").render(scene, CAMERA),
                deferred, "light_indexed")
    prepass = make_renderer(128, 96, transparency=transparency, pipeline="light_prepass").render(scene, CAMERA)
    assert_same(prepass, deferred, "light_prepass", color_exact=False)
    near_peak(prepass.color, deferred.color, 1e-5)


# -- the light pre-pass's own trade-offs --------------------------------------------------------------
def coloured_lights() -> np.ndarray:
    """A red and a blue point light overlapping on the room's floor and sphere, plus a white one."""
    lights = np.zeros(3, structs.light_dtype)
    lights["position"] = [(-0.6, 1.2, 0.6), (0.6, 1.2, 0.4), (0.0, 2.2, -1.0)]
    lights["radius"] = [3.0, 3.0, 4.0]
    lights["color"] = [(1.6, 0.1, 0.05), (0.05, 0.2, 1.8), (0.6, 0.6, 0.6)]
    lights["direction"] = (0, 0, -1)
    return lights


def test_luminance_specular_matches_reference(make_renderer):
    scene = room_scene()
    scene.lights, scene.ambient = coloured_lights(), 0.05
    lum = make_renderer(128, 96, pipeline="light_prepass", light_buffer_specular="luminance").render(scene, CAMERA)
    deferred = make_renderer(128, 96).render(scene, CAMERA)
    np.testing.assert_array_equal(lum.gbuffer, deferred.gbuffer)
    rgb, info = ref.shade_frame(lum, CAMERA, scene.lights, scene.ambient, details=True)
    d, s = info["diffuse"], info["specular"]
    w = np.array([0.2126, 0.7152, 0.0722])
    d_lum = d @ w
    with np.errstate(invalid="ignore", divide="ignore"):
        spec = np.where(d_lum[..., None] > 0, (s @ w)[..., None] * d / d_lum[..., None], 0.0)
    expect = lum.albedo * (scene.ambient + d) + spec
    fg = lum.triangle_id >= 0
    expect[~fg] = 0
    ok = fg & (info["min_abs_ndotl"] > 1e-4)
    assert ok.mean() > 0.5 * fg.mean()
    peak = float(expect.max())
    err = np.abs(lum.color - expect)[ok]
    assert err.max() <= 2e-3 * peak, f"luminance specular vs reference: {err.max():.3g} (peak {peak:.3g})"
    # The trade-off is visible: highlights take the diffuse light's colour, not their own.
    moved = np.abs(expect - rgb)[ok].max(-1)
    assert (moved > 0.02 * peak).sum() > 20, "the scene must have coloured highlights"
    got_moved = np.abs(lum.color - deferred.color)[ok].max(-1)
    assert (got_moved > 0.02 * peak).sum() > 20
    assert np.abs(got_moved - moved).max() <= 2e-3 * peak


def test_float16_light_buffer(make_renderer):
    scene = room_scene()
    scene.lights, scene.ambient = coloured_lights(), 0.05
    full = make_renderer(128, 96, pipeline="light_prepass").render(scene, CAMERA)
    half = make_renderer(128, 96, pipeline="light_prepass", light_buffer_precision="float16").render(scene, CAMERA)
    np.testing.assert_array_equal(half.gbuffer, full.gbuffer)
    diff = np.abs(half.color.astype(np.float64) - full.color)
    assert diff.max() > 0, "halves must round something"
    assert np.all(diff <= 2.0 ** -11 * np.abs(full.color) + 1e-7)
    # D, S and the glTF BRDF's T sums, RGB (kernels/brdf.h; 6 planes with shading="blinn_phong")
    assert full.stats["bytes_per_pixel"]["light_buffer"] == 36
    assert half.stats["bytes_per_pixel"]["light_buffer"] == 18


def test_bytes_per_pixel_stats(make_renderer):
    scene = demo_scene()
    bpp = {name: make_renderer(64, 48, **opts).render(scene).stats["bytes_per_pixel"] for name, opts in (
        ("deferred", {}), ("indexed", dict(pipeline="light_indexed")),
        ("prepass", dict(pipeline="light_prepass", light_buffer_specular="luminance")),
        ("msaa4", dict(pipeline="light_prepass", msaa=4)),
        ("prepass_bp", dict(pipeline="light_prepass", light_buffer_specular="luminance", shading="blinn_phong")))}
    assert bpp["deferred"]["gbuffer_geometry_pass"] == 24 and bpp["deferred"]["gbuffer_aov_planes"] == 0
    assert bpp["indexed"]["gbuffer_geometry_pass"] == 8 and bpp["indexed"]["gbuffer_aov_planes"] == 16
    assert bpp["prepass"]["gbuffer_geometry_pass"] == 16 and bpp["prepass"]["light_buffer"] == 20   # D.rgb, S, T
    assert bpp["prepass_bp"]["light_buffer"] == 16                                                 # D.rgb, S
    assert bpp["msaa4"]["msaa_visibility"] == 20 and bpp["msaa4"]["msaa_resolve"] == 36   # 4 prim planes + depth;
    # sum + 2 samples' deltas
    assert bpp["msaa4"]["gbuffer_geometry_pass"] == 24 and bpp["msaa4"]["gbuffer_aov_planes"] == 0
    for b in bpp.values():
        assert b["total"] == sum(v for k, v in b.items() if k != "total")


# -- multisampled colour ------------------------------------------------------------------------------
W, H, S = 64, 48, 16


@pytest.fixture(scope="module")
def msaa_frames(device):
    scene, cam = aa.aa_scene(W / H), aa.aa_camera()
    hi = clrender.Renderer(S * W, S * H, device=device.id, tonemap="clamp").render(scene, cam)
    truth, edge = aa.truth(hi.color, S), aa.edge_pixels(hi.color, S)
    del hi
    frames = {n: clrender.Renderer(W, H, device=device.id, tonemap="clamp", pipeline="light_prepass",
                                   msaa=n).render(scene, cam) for n in (1, 2, 4, 8)}
    return dict(truth=truth, edge=edge, band=aa.dilate(edge, 1), frames=frames)


def test_msaa_edge_rmse_against_supersampled_truth(msaa_frames):
    f, truth, edge = msaa_frames["frames"], msaa_frames["truth"], msaa_frames["edge"]
    assert 300 < edge.sum() < 700
    rmse = {n: aa.rmse(aa.linear(fr.image), truth, edge) for n, fr in f.items()}
    print("\nedge RMSE vs 16x16 truth: " + ", ".join(f"msaa {n}: {e:.4f}" for n, e in rmse.items()))
    assert rmse[1] > 0.12, "msaa=1 must show the aliasing"
    assert rmse[4] <= 0.6 * rmse[1], f"msaa=4 edge RMSE {rmse[4]:.4f} not 40 % below msaa=1 ({rmse[1]:.4f})"
    assert rmse[8] <= rmse[4] <= rmse[2] < rmse[1]


def test_msaa_interior_pixels_unchanged(msaa_frames):
    """Away from edges (no triangle id change within 1 pixel, no edge in the truth), every msaa
    frame is bit-identical to msaa=1: the surface is shaded once, at the pixel centre."""
    one = msaa_frames["frames"][1]
    ids = np.pad(one.triangle_id, 1, mode="edge")
    same = np.ones(ids.shape[0:2], bool)[1:-1, 1:-1]
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            same &= ids[1 + dy:ids.shape[0] - 1 + dy, 1 + dx:ids.shape[1] - 1 + dx] == one.triangle_id
    interior = same & ~msaa_frames["band"]
    assert interior.mean() > 0.5
    for n in (2, 4, 8):
        fr = msaa_frames["frames"][n]
        np.testing.assert_array_equal(fr.color[interior], one.color[interior])
        np.testing.assert_array_equal(fr.gbuffer, one.gbuffer)
        assert (np.abs(fr.color - one.color).max(-1) > 0.05)[msaa_frames["edge"]].mean() > 0.3
        assert fr.stats["geometry_passes"] == 2


@pytest.mark.parametrize("samples", [2, 4, 8])
def test_sub_sample_visibility_matches_reference(device, samples, monkeypatch):
    """Each sub-sample's visibility (one setup and binning widened to the samples, one raster
    keeping a fragment per sample point) against the NumPy reference rasterizer evaluated at
    that sample point: triangle ids exact (contract §10)."""
    from helpers import reach_the_raster_guard
    reach_the_raster_guard(monkeypatch)          # the soup holds non-finite vertices on purpose
    import pyopencl.array as cla  # noqa: F401  (the passes use it)
    from clrender.passes.second_geometry import SampleGeometryPass
    size = (61, 47)
    scene, cam = make_soup(size, 120, 3 + samples, "perspective", 0.3)
    r = clrender.Renderer(*size, device=device.id, pipeline="light_prepass", msaa=samples, shadows=False)
    r.render(scene, cam)
    geo = next(p for p in r.pipeline.passes if isinstance(p, SampleGeometryPass))
    offsets = sample_offsets(samples)
    assert offsets == tuple((16 * x, 16 * y) for x, y in SAMPLE_PATTERNS[samples])
    planes = geo.raster.vis_prim.get().reshape(samples, -1)
    prims = geo.sub["prims"].get()
    for s, (dx, dy) in enumerate(offsets):
        vis = planes[s][: size[0] * size[1]].reshape(size[1], size[0])
        got = np.where(vis >= 0, prims["tri"][np.maximum(vis, 0)], -1)
        expect, _, _ = rasterize(scene, cam, *size, sample=(dx, dy))
        assert (expect >= 0).mean() > 0.3
        np.testing.assert_array_equal(got, expect, err_msg=f"sample {s} at ({dx}, {dy})/256")
    centre, _, _ = rasterize(scene, cam, *size)
    assert not np.array_equal(centre, rasterize(scene, cam, *size, sample=offsets[0])[0])


def test_kernel_sample_patterns_match_host():
    """kernels/samples.h carries the same D3D patterns as SAMPLE_PATTERNS (the NumPy reference's)."""
    import re
    from clrender.device.core import kernels_dir
    text = (kernels_dir() / "samples.h").read_text()
    for n, pattern in SAMPLE_PATTERNS.items():
        m = re.search(rf"#(?:el)?if SAMPLES == {n}\n#define SAMPLE_PATTERN ([-\d, ]+)\n#define PATTERN_SPREAD (\d+)", text)
        assert m, f"no SAMPLES == {n} block in samples.h"
        values = [int(v) for v in m.group(1).split(",")]
        assert values == [c for xy in pattern for c in xy], n
        assert int(m.group(2)) == max(max(abs(x), abs(y)) for x, y in pattern), n


# -- options ------------------------------------------------------------------------------------------
@pytest.mark.parametrize("opts, message", [
    (dict(pipeline="forward"), "pipeline must be one of"),
    (dict(pipeline="light_prepass", msaa=3), "msaa must be one of"),
    (dict(msaa=4), "msaa applies to pipeline='light_prepass'"),
    (dict(pipeline="light_indexed", light_buffer_specular="luminance"), "applies to pipeline='light_prepass'"),
    (dict(pipeline="light_prepass", light_buffer_precision="float8"), "light_buffer_precision must be"),
    (dict(pipeline="light_indexed", ssao=True), "never stores"),
    (dict(reuse_visibility=True), "rasterizes once"),
    (dict(pipeline="light_prepass", msaa=4, reuse_visibility=True), "sub-samples"),
    (dict(pipeline="light_indexed", reuse_visibility=1), "True or False"),
])
def test_bad_options(opts, message):
    with pytest.raises(ValueError, match=message):
        clrender.RenderConfig(**opts)


def test_cli_and_toml_options(device, tmp_path, monkeypatch):
    from clrender.cli import app as cli
    from helpers import record_render_configs
    configs = record_render_configs(monkeypatch)
    toml = tmp_path / "s.toml"
    scenes = __import__("pathlib").Path(__file__).resolve().parent.parent / "scenes"
    toml.write_text(f'[[mesh]]\npath = "{(scenes / "demo.gltf").as_posix()}"\n\n[render]\npipeline = "light_indexed"\n')
    allow = ["--allow-outside", str(scenes)]           # the TOML names the repository's demo mesh
    assert cli.main(["render", str(toml), "-o", str(tmp_path / "a.png"), "--width", "32", "--height", "24",
                     "--device", device.id, "-q", *allow]) == 0
    assert configs[-1].pipeline == "light_indexed"
    assert cli.main(["render", str(toml), "-o", str(tmp_path / "b.png"), "--width", "32", "--height", "24",
                     "--device", device.id, "-q", "--pipeline", "light_prepass", "--msaa", "4",
                     "--light-buffer-specular", "luminance", "--light-buffer-precision", "float16", *allow]) == 0
    c = configs[-1]
    assert (c.pipeline, c.msaa, c.light_buffer_specular, c.light_buffer_precision) == (
        "light_prepass", 4, "luminance", "float16")
    assert cli.main(["render", str(toml), "-o", str(tmp_path / "c.png"), "--device", device.id, "-q",
                     "--msaa", "4", *allow]) != 0
    assert cli.main(["render", str(toml), "-o", str(tmp_path / "d.png"), "--width", "32", "--height", "24",
                     "--device", device.id, "-q", "--pipeline", "light_indexed", "--reuse-visibility", *allow]) == 0
    assert (configs[-1].pipeline, configs[-1].reuse_visibility) == ("light_indexed", True)
