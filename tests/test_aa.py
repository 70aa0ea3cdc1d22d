"""Anti-aliasing (docs/post.md "Anti-aliasing"): the edge-smoothing filter (edge_aa.cl) and
FXAA (fxaa.cl) against a supersampled ground truth (tests/reference/aa.py).

The truth is the aa_scene (flat-coloured opaque bars, a rotated square, a folded roof, a wall
leaving part of the frame empty, ambient light only, tonemap "clamp") rendered at 16·W × 16·H and
box-averaged to W × H = 64 × 48. Errors are RMSEs of the linear values of `image` (8-bit sRGB
decoded) over the edge pixels, those whose 16×16 block is not one colour (458 of 3072), and over the
band of pixels within 2 px of them. Measured on PoCL 3.1 (CPU; the same to 4 digits on an NVIDIA
H200's OpenCL):

    edge-pixel RMSE  none 0.1452  edge_aa 0.0781  fxaa 0.0872  edge_aa+fxaa 0.0713
                     supersample 2× 0.0444  4× 0.0336
    band RMSE        none 0.0767  edge_aa 0.0499  fxaa 0.0501  edge_aa+fxaa 0.0510
    a 3×3 box blur of the whole no-AA image: edge 0.1034, band 0.0835

Each filter must stay below its bound (about 10 % above the measured value) and cut the edge RMSE
by at least 30 % against no AA; the band bound (below the blur-everything value, which is worse
than no AA at all there) catches a filter that blurs everything, the 30 % rule one that blurs
nothing. Both leave every pixel farther than 2 px from a truth edge within 1 code of the no-AA
image. The edge mask (Frame.edges) equals an independent NumPy evaluation of the same test on the
frame's own depth / normal / triangle_id AOVs (exactly; the scene keeps every neighbour pair away
from the thresholds), and with nothing marked the LDR chain (tonemap_ldr -> edge_aa -> encode)
gives the fused tone-mapping kernel's image bit for bit.
"""
from __future__ import annotations

import numpy as np
import pytest

import clrender
from helpers import record_render_configs
from clrender import Camera, Scene, Texture
from reference import aa

W, H, S = 64, 48, 16
TONEMAP = dict(tonemap="clamp")      # display value = clamp(colour): the truth averages it linearly

# Bounds on the edge-pixel RMSE (measured values in the module docstring).
EDGE_AA_MAX = 0.086
FXAA_MAX = 0.097
BOTH_MAX = 0.079
SUPERSAMPLE_MAX = {2: 0.049, 4: 0.037}
BAND_MAX = 0.056                     # every filter, over the band within 2 px of an edge
MIN_REDUCTION = 0.30

FILTERS = {"none": {}, "edge_aa": {"edge_aa": True}, "fxaa": {"color_aa": "fxaa"},
           "edge_aa+fxaa": {"edge_aa": True, "color_aa": "fxaa"}}


def supersample_available(device) -> bool:
    try:
        clrender.Renderer(8, 8, device=device.id, supersample=2).render(aa.aa_scene(1.0), aa.aa_camera())
    except Exception:                   # the resolve pass not in this build
        return False
    return True


@pytest.fixture(scope="module")
def setup(device):
    """The truth (16× supersampled, box filtered) and every variant's frame at W × H."""
    scene, cam = aa.aa_scene(W / H), aa.aa_camera()
    hi = clrender.Renderer(S * W, S * H, device=device.id, **TONEMAP).render(scene, cam)
    truth, edge = aa.truth(hi.color, S), aa.edge_pixels(hi.color, S)
    del hi
    frames = {name: clrender.Renderer(W, H, device=device.id, **TONEMAP, **opts).render(scene, cam)
              for name, opts in FILTERS.items()}
    if supersample_available(device):
        for k in SUPERSAMPLE_MAX:
            frames[f"supersample {k}x"] = clrender.Renderer(W, H, device=device.id, supersample=k,
                                                            **TONEMAP).render(scene, cam)
    return dict(truth=truth, edge=edge, band=aa.dilate(edge, 2), frames=frames)


def errors(setup, image_linear):
    return (aa.rmse(image_linear, setup["truth"], setup["edge"]), aa.rmse(image_linear, setup["truth"], setup["band"]))


def test_edge_rmse_against_supersampled_truth(setup):
    edge = setup["edge"]
    assert 300 < edge.sum() < 700, "the scene must have a few hundred edge pixels"
    rmse = {name: errors(setup, aa.linear(f.image)) for name, f in setup["frames"].items()}
    print("\nRMSE vs 16x16 truth (edge pixels, band within 2 px):")
    for name, (e, b) in rmse.items():
        print(f"  {name:18s} {e:.4f} {b:.4f}")
    none = rmse["none"][0]
    assert none > 0.12, "no AA must show the aliasing the filters remove"
    for name, bound in (("edge_aa", EDGE_AA_MAX), ("fxaa", FXAA_MAX), ("edge_aa+fxaa", BOTH_MAX)):
        e, b = rmse[name]
        assert e <= bound, f"{name}: edge RMSE {e:.4f} > {bound}"
        assert e <= (1 - MIN_REDUCTION) * none, f"{name}: edge RMSE {e:.4f} is not 30 % below no AA ({none:.4f})"
        assert b <= BAND_MAX, f"{name}: band RMSE {b:.4f} > {BAND_MAX}"
    for k, bound in SUPERSAMPLE_MAX.items():
        if f"supersample {k}x" in rmse:
            assert rmse[f"supersample {k}x"][0] <= bound


def test_bounds_catch_blur_everything_and_nothing(setup):
    """A filter that blurs every pixel (3×3 box) fails the band bound and the edge bounds; one that
    does nothing (the no-AA image) fails the edge bounds and the 30 % rule."""
    none = aa.linear(setup["frames"]["none"].image)
    blur_e, blur_b = errors(setup, aa.box_blur3(none))
    assert blur_b > BAND_MAX and blur_e > max(EDGE_AA_MAX, FXAA_MAX), (blur_e, blur_b)
    none_e, none_b = errors(setup, none)
    assert none_e > max(EDGE_AA_MAX, FXAA_MAX) and none_b > BAND_MAX
    assert blur_b > none_b, "over the band, blurring everything is worse than no AA"


@pytest.mark.parametrize("name", ["edge_aa", "fxaa", "edge_aa+fxaa"])
def test_pixels_away_from_edges_unchanged(setup, name):
    """No pixel farther than 2 px from an edge of the truth changes by more than 1 code, and the
    filter does change pixels near edges."""
    far = ~setup["band"]
    none, img = setup["frames"]["none"].image.astype(int), setup["frames"][name].image.astype(int)
    diff = np.abs(img - none).max(-1)
    assert far.sum() > 1200
    assert diff[far].max() <= 1, np.argwhere(far & (diff > 1))[:10]
    assert (diff[setup["edge"]] > 1).sum() > 100


def test_edges_mask_matches_numpy(device):
    """Frame.edges on the aa_scene at an odd size (partial work-groups) with two threshold settings
    equals the NumPy test on the frame's own AOVs; it covers every silhouette (foreground against
    background) pixel, marks the roof's ridge (a normal-only edge) only below its 60° fold, and
    nothing away from the shapes' outlines."""
    w, h = 61, 45
    scene, cam = aa.aa_scene(w / h), aa.aa_camera()
    hi = clrender.Renderer(4 * w, 4 * h, device=device.id, **TONEMAP).render(scene, cam)
    near_edge = aa.dilate(aa.edge_pixels(hi.color, 4, margin=1), 1)
    ridge = None
    for depth_t, normal_t in ((0.05, 30.0), (0.8, 70.0)):
        f = clrender.Renderer(w, h, device=device.id, edge_aa=True, edge_depth_threshold=depth_t,
                              edge_normal_threshold_deg=normal_t, **TONEMAP).render(scene, cam)
        rel_margin, angle_margin = aa.threshold_margin(f.depth, f.normal, f.triangle_id, depth_t, normal_t)
        assert rel_margin > 0.1 and angle_margin > 5.0, "a neighbour pair sits on a threshold"
        expect = aa.edge_mask(f.depth, f.normal, f.triangle_id, depth_t, normal_t)
        assert f.edges.dtype == np.uint8 and f.edges.shape == (h, w)
        np.testing.assert_array_equal(f.edges, expect)
        fg = f.triangle_id >= 0
        silhouette = np.zeros_like(fg)
        for dy, dx in aa.NEIGHBOURS:
            silhouette |= fg != aa._shifted(fg, dy, dx)
        assert silhouette.sum() > 50 and f.edges[silhouette].all()
        assert not f.edges[~near_edge].any(), "marks away from the outlines (a flat interior)"
        assert f.edges[~near_edge].size > 0.5 * w * h
        # The roof's two faces (materials cyan and magenta) meet with continuous depth.
        mats = scene.triangle_material[np.maximum(f.triangle_id, 0)]
        names = [m.name for m in scene.materials]
        cyan, magenta = fg & (mats == names.index("cyan")), fg & (mats == names.index("magenta"))
        ridge = cyan & (aa._shifted(magenta, 0, 1) | aa._shifted(magenta, 0, -1)) & ~silhouette
        assert ridge.sum() > 10
        assert f.edges[ridge].all() == (normal_t < 60.0) and f.edges[ridge].any() == (normal_t < 60.0)


def lit_plane_scene():
    """A tilted plane filling the frame, lit by two point lights (smoothly varying colour), with a
    low-contrast stripe texture (sRGB 150 / 154, stripes several pixels wide): detail below FXAA's
    contrast thresholds that any blur of unmarked pixels would change."""
    v = np.array([[-40, -30, -4], [40, -30, -30], [40, 30, -30], [-40, 30, -4]], np.float32)
    uvs = np.array([[0, 1], [1, 1], [1, 0], [0, 0]], np.float32)
    rgba = np.full((16, 16, 4), 255, np.uint8)
    rgba[..., :3] = np.where((np.arange(16) // 2) % 2 == 0, 150, 154)[None, :, None]
    n = np.cross(v[1] - v[0], v[3] - v[0])
    scene = Scene(v, np.tile(n / np.linalg.norm(n), (4, 1)).astype(np.float32), uvs,
                  np.array([[0, 1, 2], [0, 2, 3]], np.int32), np.zeros(2, np.int32),
                  [clrender.Material("striped", (1.0, 0.8, 0.6, 1.0), base_color_texture=0, specular_intensity=0.0)],
                  textures=[Texture("stripes", rgba)])
    scene.add_point_light((0.0, 0.0, -8.0), (1.5, 1.35, 1.1), 200.0)
    scene.add_point_light((3.0, -2.0, -10.0), (0.4, 0.6, 1.5), 200.0)
    return scene


def test_ldr_chain_without_marks_is_bit_identical(device):
    """With edge_aa on but nothing marked (a plane filling the frame, thresholds out of reach), the
    image through tonemap_ldr, edge_blur (copies) and encode equals the fused tonemap kernel's, for
    every operator; with the effects off the pipeline runs no LDR pass and Frame.edges is zero."""
    scene = lit_plane_scene()
    cam = Camera.look_at((0, 0, 0), (0, 0, -1), fov_y_deg=60.0, near=0.1, far=100.0)
    for tonemap in ("reinhard", "aces", "clamp"):
        plain = clrender.Renderer(37, 23, device=device.id, tonemap=tonemap, exposure=1.7).render(scene, cam)
        chain = clrender.Renderer(37, 23, device=device.id, tonemap=tonemap, exposure=1.7, edge_aa=True,
                                  edge_depth_threshold=1e6, edge_normal_threshold_deg=180.0).render(scene, cam)
        assert (plain.triangle_id >= 0).all()
        assert len(np.unique(plain.image.reshape(-1, 3), axis=0)) > 100, "the plane must not be flat"
        assert not chain.edges.any()
        np.testing.assert_array_equal(chain.image, plain.image)
        np.testing.assert_array_equal(chain.color, plain.color)
        assert {"edge_aa_ms", "encode_ms"} <= set(chain.stats)
        assert not {"edge_aa_ms", "fxaa_ms", "encode_ms"} & set(plain.stats)
        assert plain.edges.dtype == np.uint8 and not plain.edges.any()
    explicit = clrender.Renderer(37, 23, device=device.id, edge_aa=False, color_aa="none").render(scene, cam)
    default = clrender.Renderer(37, 23, device=device.id).render(scene, cam)
    np.testing.assert_array_equal(explicit.image, default.image)


def test_fxaa_leaves_smooth_gradients_alone(device):
    """FXAA's contrast test: a smoothly lit plane (no luma step above the thresholds) comes out
    unchanged, bit for bit."""
    scene = lit_plane_scene()
    cam = Camera.look_at((0, 0, 0), (0, 0, -1), fov_y_deg=60.0, near=0.1, far=100.0)
    plain = clrender.Renderer(37, 23, device=device.id).render(scene, cam)
    fxaa = clrender.Renderer(37, 23, device=device.id, color_aa="fxaa").render(scene, cam)
    np.testing.assert_array_equal(fxaa.image, plain.image)
    assert "fxaa_ms" in fxaa.stats


def test_cli_flags_and_edges_aov(device, tmp_path, capsys, monkeypatch):
    """--edge-aa/--edge-depth-threshold/--edge-normal-threshold/--fxaa reach the RenderConfig;
    --aov edges writes the uint8 mask (.npy) and a white-on-black preview, no .exr."""
    import imageio.v3 as iio
    from clrender.cli import app as cli
    from clrender.render import renderer as renderer_module

    monkeypatch.delenv(cli.ENV_DEBUG, raising=False)
    seen = record_render_configs(monkeypatch)
    obj = tmp_path / "quad.obj"
    obj.write_text("v -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\nf 1 2 3\nf 1 3 4\n")
    common = [str(obj), "--width", "24", "--height", "16", "--device", device.id, "-q",
              "--camera-eye", "0,0,3", "--camera-target", "0,0,0", "--fov", "50"]
    assert cli.main(["render", *common, "-o", str(tmp_path / "a.png"), "--edge-aa", "--edge-depth-threshold",
                     "0.2", "--edge-normal-threshold", "45", "--fxaa", "--aov", "edges"]) == 0, capsys.readouterr().err
    assert cli.main(["render", *common, "-o", str(tmp_path / "b.png")]) == 0, capsys.readouterr().err
    fields = lambda c: (c.edge_aa, c.edge_depth_threshold, c.edge_normal_threshold_deg, c.color_aa)  # noqa: E731
    assert fields(seen[0]) == (True, 0.2, 45.0, "fxaa")
    assert fields(seen[1]) == fields(renderer_module.RenderConfig()) == (False, 0.05, 30.0, "none")
    mask = np.load(tmp_path / "a.edges.npy")
    assert mask.dtype == np.uint8 and mask.shape == (16, 24) and 0 < mask.sum() < mask.size
    png = iio.imread(tmp_path / "a.edges.png")
    np.testing.assert_array_equal(png, mask * 255)
    assert not (tmp_path / "a.edges.exr").exists()
    for option, word in ((["--edge-normal-threshold", "0"], "--edge-normal-threshold"),
                         (["--edge-depth-threshold", "-1"], "--edge-depth-threshold")):
        assert cli.main(["render", *common, "-o", str(tmp_path / "c.png"), *option]) != 0
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith("clrender: error: ") and word in err[0], err
